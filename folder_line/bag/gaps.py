"""Gaps of a repaired bag: spans of line time whose messages were written but are lost.

:func:`folder_line.bag.repair.repair` finds them (a segment file missing, a chunk whose
checksum fails, an unfinished file before the last) and records them in the bag's
``custom_data`` under :data:`KEY_GAPS` as JSON, ``[[first_ns, last_ns], ...]``: every
message logged between the two (both included) may be missing. ``bag info`` names them and
``analyze`` judges nothing across them.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from folder_line.errors import BagError
from folder_line.interfaces import NS_PER_S

__all__ = ['KEY_GAPS', 'Gap', 'describe_gaps', 'format_gaps', 'merge_gaps', 'read_gaps']

KEY_GAPS = 'folder_line.gaps'
"""``custom_data`` key of a repaired bag's gaps (JSON list of ``[first_ns, last_ns]``)."""

_MAX_GAPS = 100_000


@dataclass(frozen=True, order=True)
class Gap:
    """Line time, ns, over which messages may be missing: ``first_ns`` to ``last_ns``, both included."""

    first_ns: int
    last_ns: int

    @property
    def seconds(self) -> float:
        """Its length, s."""
        return (self.last_ns - self.first_ns) / NS_PER_S

    def text(self) -> str:
        """``'0.995 s at 2.005 s'``."""
        return f'{self.seconds:.3f} s at {self.first_ns / NS_PER_S:.3f} s'


def merge_gaps(gaps: Iterable[Gap]) -> list[Gap]:
    """``gaps`` sorted, overlapping or touching ones merged."""
    out: list[Gap] = []
    for g in sorted(gaps):
        if out and g.first_ns <= out[-1].last_ns + 1:
            out[-1] = Gap(out[-1].first_ns, max(out[-1].last_ns, g.last_ns))
        else:
            out.append(g)
    return out


def format_gaps(gaps: Iterable[Gap]) -> str:
    """The ``custom_data`` value of ``gaps``."""
    return json.dumps([[g.first_ns, g.last_ns] for g in merge_gaps(gaps)])


def read_gaps(custom: Mapping[str, str]) -> list[Gap]:
    """The gaps a bag's ``custom_data`` records (none if it records none).

    Raises
    ------
    BagError
        The value is not a list of ``[first_ns, last_ns]`` pairs of integers with first <= last.
    """
    text = custom.get(KEY_GAPS)
    if text is None:
        return []
    try:
        pairs = json.loads(text)
    except ValueError:
        pairs = None
    ok = (
        isinstance(pairs, list)
        and len(pairs) <= _MAX_GAPS
        and all(
            isinstance(pair, list) and len(pair) == 2 and all(type(v) is int for v in pair) and 0 <= pair[0] <= pair[1]
            for pair in pairs
        )  # no bool, no float, in order
    )
    if not ok:
        msg = f'custom_data {KEY_GAPS}={text[:80]!r}: not a list of [first_ns, last_ns] integer pairs'
        raise BagError(msg)
    return merge_gaps(Gap(a, b) for a, b in pairs)


def describe_gaps(gaps: Iterable[Gap]) -> str:
    """``'a gap of 0.995 s at 2.005 s'``, ``'2 gaps: 0.995 s at 2.005 s, 0.100 s at 4.200 s'``."""
    listed = merge_gaps(gaps)
    if len(listed) == 1:
        return f'a gap of {listed[0].text()}'
    shown = ', '.join(g.text() for g in listed[:5]) + (', ...' if len(listed) > 5 else '')
    return f'{len(listed)} gaps: {shown}'
