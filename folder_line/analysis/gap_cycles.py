"""The cycles and leaves a gap of a repaired bag leaves unjudged, and the events without them.

A gap (:mod:`folder_line.bag.gaps`) is line time whose messages may be lost, events among
them. A folder cycle or a leaf with an event lost is not judged at all: judged on the events
left, it would show a sheet missing or a release never made that the line never had. A
cycle's events span its *lifetime* (a signature's handover to its release on the pile), a
leaf's its entry to its landing: every cycle (leaf) with an event within two lifetimes of a
gap, and every one numbered between those, is unjudged. The lifetime is the longest among the
recorded ones. Folder events are counted by their ``cycle``, leaf events (``leaf_*``) by their
``sheet`` (a leaf's ``cycle`` is its chute); the belt's slow-downs belong to neither.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from folder_line.bag.gaps import Gap
from folder_line.core.types.events import EVENT_KINDS

__all__ = ['Unjudged', 'unjudged', 'without_unjudged']

_LEAF_KINDS = np.array([i for i, k in enumerate(EVENT_KINDS) if k.startswith('leaf_')], dtype=np.int16)
_CYCLE_KINDS = np.array([i for i, k in enumerate(EVENT_KINDS) if not k.startswith(('leaf_', 'belt_'))], dtype=np.int16)


@dataclass(frozen=True)
class Unjudged:
    """Folder cycles and leaves (by number) that a gap may have taken events from."""

    cycles: np.ndarray
    leaves: np.ndarray

    def __bool__(self) -> bool:
        return bool(self.cycles.size or self.leaves.size)

    def text(self) -> str:
        """``'cycles 41..43, leaves 17..20'`` ('' if none)."""
        parts = [
            f'{what} {_ranges(nums)}' for what, nums in (('cycles', self.cycles), ('leaves', self.leaves)) if nums.size
        ]
        return ', '.join(parts)


def _ranges(nums: np.ndarray) -> str:
    breaks = np.flatnonzero(np.diff(nums) != 1)
    starts = np.r_[nums[0], nums[breaks + 1]]
    ends = np.r_[nums[breaks], nums[-1]]
    return ', '.join(f'{a}' if a == b else f'{a}..{b}' for a, b in zip(starts.tolist(), ends.tolist(), strict=True))


def _units(events: np.ndarray, event_ns: np.ndarray, kinds: np.ndarray, field: str, gaps: Sequence[Gap]) -> np.ndarray:
    mine = np.isin(events['kind'], kinds)
    nums, t = events[field][mine].astype(np.int64), event_ns[mine]
    if not nums.size:
        return np.zeros(0, dtype=np.int64)
    order = np.argsort(nums, kind='stable')
    n_sorted, t_sorted = nums[order], t[order]
    starts = np.flatnonzero(np.r_[True, n_sorted[1:] != n_sorted[:-1]])
    reach = 2 * int(np.max(np.maximum.reduceat(t_sorted, starts) - np.minimum.reduceat(t_sorted, starts)))
    out: list[np.ndarray] = []
    for g in gaps:
        near = (t >= g.first_ns - reach) & (t <= g.last_ns + reach)
        if near.any():
            out.append(np.arange(int(nums[near].min()), int(nums[near].max()) + 1, dtype=np.int64))
    return np.unique(np.concatenate(out)) if out else np.zeros(0, dtype=np.int64)


def unjudged(events: np.ndarray, event_ns: np.ndarray, gaps: Sequence[Gap]) -> Unjudged:
    """The folder cycles and leaves ``gaps`` may have taken events from (see the module docstring).

    Parameters
    ----------
    events : ndarray of EVENT_DTYPE
        The recorded events.
    event_ns : ndarray of int64
        Their times, ns of line time.
    gaps : sequence of Gap
    """
    return Unjudged(
        _units(events, event_ns, _CYCLE_KINDS, 'cycle', gaps), _units(events, event_ns, _LEAF_KINDS, 'sheet', gaps)
    )


def without_unjudged(events: np.ndarray, skip: Unjudged) -> np.ndarray:
    """The mask of the ``events`` of no unjudged cycle or leaf."""
    cycle_kind = np.isin(events['kind'], _CYCLE_KINDS)
    leaf_kind = np.isin(events['kind'], _LEAF_KINDS)
    drop = (cycle_kind & np.isin(events['cycle'], skip.cycles)) | (leaf_kind & np.isin(events['sheet'], skip.leaves))
    keep: np.ndarray = ~drop
    return keep
