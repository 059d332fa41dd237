"""Liveness: which watched participant has gone silent, decided on the check grid.

Node N is stale at the first grid point ``g`` (:class:`folder_line.core.supervision.grid.CheckGrid`)
with no stamp of N in ``[g - k P_N, g]`` (``k = stale_periods``, ``P_N`` its publishing
period) — and, with ``clock_ticks``, at least ``ceil(k)`` clock messages after its last
stamp (it missed ``k`` chances to publish). A node is watched from its first stamp on (a
node that is not part of the run is not missed), an ``expected`` one from ``t_start``.
Staleness is edge-triggered: one stale episode until the node is heard again.

The names of the watched participants are the caller's (the ROS side passes its node
names); the core treats them as labels.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from folder_line.core.numerics.validate import positive
from folder_line.core.supervision.grid import CheckGrid
from folder_line.errors import ParameterError

__all__ = ['Liveness']


@dataclass
class _Watch:
    """Liveness of one known node."""

    period: float
    expected: bool  # watched from t_start (else from its first stamp)
    last: float | None = None  # latest stamp taken into account (t_start for an expected node)
    first: float = math.inf  # earliest stamp ever fed
    stale_at: float | None = None  # decision time of the current stale episode
    pending: list[np.ndarray] = field(default_factory=list)


class Liveness:
    """The stamps at which each watched node was heard, and its stale episodes.

    Parameters
    ----------
    periods : mapping of str to float, optional
        Known node -> its publishing period, s of line time (each > 0).
    expected : iterable of str
        Known nodes that must be heard from ``t_start`` on.
    t_start : float or None
        When an expected node is first expected, s (None: set by :meth:`start`).
    k : float
        Periods (and clock ticks) a node may stay silent (> 0).
    grid : CheckGrid
        Where staleness is decided.
    clock_ticks : bool
        Staleness also needs ``ceil(k)`` clock messages after the node's last stamp.

    Raises
    ------
    ParameterError
        An expected node without a period; a period that is not finite and > 0.
    """

    def __init__(
        self,
        periods: Mapping[str, float] | None,
        expected: Iterable[str],
        t_start: float | None,
        k: float,
        grid: CheckGrid,
        clock_ticks: bool,
    ) -> None:
        self.k = k
        self.grid = grid
        self.nodes: dict[str, _Watch] = {}
        expected = set(expected)
        unknown = expected - set(periods or {})
        if unknown:
            raise ParameterError('expected', sorted(unknown), 'expected nodes need a period')
        for node, period in (periods or {}).items():
            st = _Watch(positive(f'periods.{node}', period), node in expected)
            if st.expected:
                st.last = t_start
            self.nodes[node] = st
        self.clock_ticks = bool(clock_ticks)
        self._clock = np.zeros(0)
        self._clock_pending: list[np.ndarray] = []

    @property
    def watched(self) -> dict[str, float]:
        """Watched node -> period, s."""
        return {n: s.period for n, s in self.nodes.items()}

    def stale_nodes(self) -> list[str]:
        """Nodes in a stale episode now."""
        return [n for n, s in self.nodes.items() if s.stale_at is not None]

    def start(self, t: float) -> None:
        """The expected nodes are expected from ``t`` on (the first watermark, when ``t_start`` was None)."""
        for s in self.nodes.values():
            if s.expected:
                s.last = t

    def never_heard_by(self, node: str | None, t: float) -> bool:
        """``node`` is watched and had not been heard at or before ``t``."""
        st = self.nodes.get(node) if node is not None else None
        return st is not None and not st.first <= t

    # ------------------------------------------------------------------ inputs

    def heard(self, node: str, t: float | Sequence[float] | np.ndarray, now: float) -> int:
        """Node ``node`` was heard at stamp(s) ``t`` (s); nodes not watched are ignored.

        Returns the number of stamps at or before the watermark ``now`` (late ones).
        """
        state = self.nodes.get(node)
        if state is None:
            return 0
        stamps = np.asarray(t, dtype=float).reshape(-1)
        stamps = stamps[np.isfinite(stamps)]
        if not stamps.size:
            return 0
        state.first = min(state.first, float(stamps.min()))
        state.pending.append(stamps)
        return int(np.count_nonzero(stamps <= now))

    def clock(self, t: float | Sequence[float] | np.ndarray) -> None:
        """Clock message(s) stamped ``t`` (s) received (used with ``clock_ticks``)."""
        if not self.clock_ticks:
            return
        stamps = np.asarray(t, dtype=float).reshape(-1)
        stamps = stamps[np.isfinite(stamps)]
        if stamps.size:
            self._clock_pending.append(stamps)

    # ------------------------------------------------------------------ decisions

    def merge_clock(self) -> None:
        """Merge the clock stamps fed so far into the sorted clock array."""
        if self._clock_pending:
            self._clock = np.unique(np.concatenate([self._clock, *self._clock_pending]))
            self._clock_pending = []

    def candidates(self, W: float) -> list[tuple[float, str, float]]:
        """``(grid time, node, its last stamp before)`` of each node found stale by ``W``, in node order."""
        out = []
        for node in self.nodes:
            s = self._stale_candidate(node, W)
            if s is not None:
                out.append((s[0], node, s[1]))
        return out

    def _stale_candidate(self, node: str, W: float) -> tuple[float, float] | None:
        """(grid time at which ``node`` is found stale, its last stamp before) if by ``W``."""
        st = self.nodes[node]
        s = np.concatenate(st.pending) if st.pending else np.zeros(0)
        lo = -math.inf if st.last is None else st.last
        s = np.unique(s[(s > lo) & (s <= W)])
        if st.stale_at is not None:
            s = s[s > st.stale_at]
            if s.size == 0:
                return None
            seq = s  # heard again: watched from there
        elif st.last is None:
            if s.size == 0:
                return None
            seq = s  # watched from its first stamp
        else:
            seq = np.concatenate([[st.last], s])
        g = self.grid.first_after(seq + self.k * st.period)
        if self.clock_ticks:
            clk = self._clock
            idx = np.searchsorted(clk, seq, side='right') + (math.ceil(self.k) - 1)
            c = np.where(idx < clk.size, clk[np.minimum(idx, max(clk.size - 1, 0))] if clk.size else np.inf, np.inf)
            g = np.maximum(g, self.grid.first_at_or_after(c))
        nxt = np.append(seq[1:], np.inf)
        gap = np.flatnonzero((nxt > g) & (g <= W))
        if gap.size == 0:
            return None
        i = int(gap[0])
        return float(g[i]), float(seq[i])

    def stale(self, node: str, last: float, when: float) -> tuple[float, str]:
        """Node ``node``, last heard at ``last``, is found stale at ``when``: the margin (s) and the cause."""
        st = self.nodes[node]
        st.last, st.stale_at = last, when
        silence = when - last
        cause = f'{node} not heard for {silence:.6g} s (> {self.k:g} periods of {st.period:g} s)'
        return self.k * st.period - silence, cause

    def consume_heard(self, W: float) -> None:
        """Take the stamps up to the watermark ``W`` into account (the tick is over)."""
        for st in self.nodes.values():
            if not st.pending:
                continue
            s = np.concatenate(st.pending)
            keep = s[s > W]
            lo = -math.inf if st.last is None else st.last
            s = s[(s <= W) & (s > lo)]
            if st.stale_at is not None:
                s = s[s > st.stale_at]
                if s.size:
                    st.stale_at = None
            if s.size:
                st.last = float(s.max())
            st.pending = [keep] if keep.size else []
        if self.clock_ticks and self._clock.size:
            lasts = [st.last for st in self.nodes.values() if st.last is not None]
            lo = min(lasts) if lasts else W
            self._clock = self._clock[self._clock > min(lo, W)]
