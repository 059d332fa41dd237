"""Figures' data gathered as the windows of a replay pass, in memory that does not grow with line time.

The analysis of a recorded run goes through it window by window
(:mod:`folder_line.analysis.replay`); what a figure shows of the whole run is gathered as the
windows pass, by one of three bounded methods, each giving the same result however the run
is cut into windows:

:class:`MarginHistogram`
    a constraint's margins binned on a binary grid: bins of width ``2**e`` m, s, ... starting at
    whole multiples of the width, at most :data:`GRID_BINS` of them; when a margin falls
    outside, the width doubles and each pair of neighbouring bins merges into one (exactly:
    the grid's bins nest). ``e`` is the smallest exponent whose grid holds every margin seen,
    so the final grid depends only on the margins, not on the windows. The figure's bars are
    the grid's bins regrouped (:meth:`MarginHistogram.counts`): each bar's count is exact but
    for the margins within one grid bin of its edges (a grid bin is at most 1/2048 of the
    margins' range wide). The count, the smallest and the largest margin, and the split at 0
    between passed and violated are exact.
:class:`Thinned`
    the rows of a stream kept to at most ``cap``: a pseudo-random ``1/2**level`` of them,
    chosen by a hash of each row's key (its time in ns: :func:`stamp_priority`), with
    ``level`` the smallest that keeps ``cap`` or fewer of all the rows. The kept sets nest,
    so the rows kept do not depend on the windows (the joint states of a recording are
    thinned the same way, :mod:`folder_line.analysis.recording`).
fixed-edge histograms
    the leaves' landing positions across the container (:func:`numpy.histogram` with the
    container's own bins, added up window by window: exact).

:func:`event_chunks` hands out a recording's event table in slices of :data:`CHUNK` rows (views,
no copy), for the scans that pick a few rows out of a long run; :func:`window_ends` cuts a span of
line time into the replay's windows (:data:`WINDOW`).
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np

from folder_line.errors import ParameterError

__all__ = [
    'CHUNK',
    'GRID_BINS',
    'WINDOW',
    'MarginHistogram',
    'Thinned',
    'event_chunks',
    'stamp_priority',
    'window_ends',
]

#: line time per window of the replay, s (a minute of the ``line`` scene is about 10 000 events)
WINDOW = 60.0

#: largest number of bins of a :class:`MarginHistogram`'s grid
GRID_BINS = 4096
#: rows of an event table scanned at once (:func:`event_chunks`)
CHUNK = 1 << 16
#: largest |margin| / bin width: the bin index of a float stays exact
_INDEX_LIMIT = 2.0**52


def window_ends(start: float, end: float, window: float) -> list[float]:
    """Window ends after ``start``: the whole multiples of ``window`` before ``end``, then ``end``.

    Parameters
    ----------
    start, end : float
        The span of line time, s.
    window : float
        Line time per window, s (> 0).

    Returns
    -------
    list of float
        The ends of the windows, s; the last is ``end``.
    """
    if not (math.isfinite(window) and window > 0.0):
        raise ParameterError('window', window, 'must be a positive number of seconds')
    k = math.floor(start / window) + 1
    cuts = []
    while k * window < end:
        cuts.append(k * window)
        k += 1
    cuts.append(end)
    return cuts


def stamp_priority(stamp_ns: np.ndarray) -> np.ndarray:
    """A stamp's place in a thinning: splitmix64 of the stamp in ns (uniform on uint64, no pattern in time)."""
    z = np.asarray(stamp_ns).astype(np.uint64) + np.uint64(0x9E3779B97F4A7C15)
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    out: np.ndarray = z ^ (z >> np.uint64(31))
    return out


def event_chunks(
    events: np.ndarray, event_ns: np.ndarray, size: int = CHUNK
) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """``(events, ns)`` in consecutive slices of at most ``size`` rows (views of the tables, in their order)."""
    for i in range(0, int(events.size), size):
        yield events[i : i + size], event_ns[i : i + size]


class MarginHistogram:
    """One constraint's margins, binned on a binary grid as they come (see the module docstring).

    Parameters
    ----------
    bins : int
        Most bins of the grid.

    Attributes
    ----------
    count : int
        Margins added.
    violations : int
        Margins below 0.
    low, high : float
        The smallest and largest margin (``inf``, ``-inf`` before any), in the margin's unit.
    exponent : int or None
        The grid's bins are ``2**exponent`` wide (None before any margin).
    """

    def __init__(self, bins: int = GRID_BINS) -> None:
        if bins < 2:
            raise ValueError(f'MarginHistogram: bins must be >= 2, got {bins!r}')
        self.bins = int(bins)
        self.count = 0
        self.violations = 0
        self.low = math.inf
        self.high = -math.inf
        self.exponent: int | None = None
        self._first = 0  # grid index of the first bin
        self._passed = np.zeros(0, dtype=np.int64)
        self._violated = np.zeros(0, dtype=np.int64)

    def _exponent_for(self, low: float, high: float) -> int:
        """The smallest exponent (at least the current one) whose grid holds ``[low, high]`` in :attr:`bins`."""
        big = max(abs(low), abs(high))
        e = math.frexp(big)[1] - 52 if big > 0.0 else -1074
        if self.exponent is not None:
            e = max(e, self.exponent)
        while math.floor(math.ldexp(high, -e)) - math.floor(math.ldexp(low, -e)) + 1 > self.bins:
            e += 1
        return e

    def add(self, margins: np.ndarray) -> None:
        """Add margins (finite, in the constraint's unit)."""
        m = np.asarray(margins, dtype=float).reshape(-1)
        if m.size == 0:
            return
        if not np.all(np.isfinite(m)):
            raise ValueError('MarginHistogram.add: margins must be finite')
        low, high = min(self.low, float(m.min())), max(self.high, float(m.max()))
        e = self._exponent_for(low, high)
        if self.exponent is not None and e > self.exponent:  # coarser: neighbouring bins merge
            shift = e - self.exponent
            index = self._first + np.arange(self._passed.size, dtype=np.int64)
            merged = index >> shift  # floor division by 2**shift: the bins nest
            first = int(merged[0]) if merged.size else 0
            size = int(merged[-1]) - first + 1 if merged.size else 0
            self._passed = np.bincount(merged - first, weights=self._passed, minlength=size).astype(np.int64)
            self._violated = np.bincount(merged - first, weights=self._violated, minlength=size).astype(np.int64)
            self._first = first
        self.exponent = e
        first = math.floor(math.ldexp(low, -e))
        last = math.floor(math.ldexp(high, -e))
        if self._passed.size == 0:
            self._first = first
            self._passed = np.zeros(last - first + 1, dtype=np.int64)
            self._violated = np.zeros(last - first + 1, dtype=np.int64)
        else:  # widen to [first, last]
            before = self._first - first
            after = last - (self._first + self._passed.size - 1)
            if before > 0 or after > 0:
                pad = (max(before, 0), max(after, 0))
                self._passed = np.pad(self._passed, pad)
                self._violated = np.pad(self._violated, pad)
                self._first = min(self._first, first)
        index = np.floor(np.ldexp(m, -e)).astype(np.int64) - self._first
        bad = m < 0.0
        self._passed += np.bincount(index[~bad], minlength=self._passed.size)
        self._violated += np.bincount(index[bad], minlength=self._violated.size)
        self.count += int(m.size)
        self.violations += int(np.count_nonzero(bad))
        self.low, self.high = low, high

    def grid(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The grid: ``(left edges, passed counts, violated counts)`` of its bins (empty before any margin)."""
        if self.exponent is None:
            return np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
        index = self._first + np.arange(self._passed.size, dtype=np.int64)
        return np.ldexp(index.astype(float), self.exponent), self._passed.copy(), self._violated.copy()

    def counts(self, edges: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The passed and the violated margins in the bars ``edges`` (ascending, covering
        ``[low, high]``): each grid bin counted in the bar holding its left edge (clipped to
        ``[low, high]``); the last bar holds its right edge, as :func:`numpy.histogram` does."""
        e = np.asarray(edges, dtype=float)
        n = e.size - 1
        left, passed, violated = self.grid()
        if n < 1 or left.size == 0:
            return np.zeros(max(n, 0), dtype=np.int64), np.zeros(max(n, 0), dtype=np.int64)
        x = np.clip(left, self.low, self.high)
        bar = np.clip(np.searchsorted(e, x, side='right') - 1, 0, n - 1)
        return (
            np.bincount(bar, weights=passed, minlength=n).astype(np.int64),
            np.bincount(bar, weights=violated, minlength=n).astype(np.int64),
        )


class Thinned:
    """At most ``cap`` rows of a stream of rows, thinned by a hash of their keys (see the module docstring).

    Parameters
    ----------
    cap : int
        Most rows kept.
    dtype : numpy dtype
        The rows' dtype.

    Attributes
    ----------
    seen : int
        Rows added, kept or not.
    level : int
        The rows kept are those whose :func:`stamp_priority` is below ``2**64 / 2**level``.
    """

    def __init__(self, cap: int, dtype: np.dtype) -> None:
        if cap < 1:
            raise ValueError(f'Thinned: cap must be >= 1, got {cap!r}')
        self.cap = int(cap)
        self.level = 0
        self.seen = 0
        self._rows = np.zeros(0, dtype=dtype)
        self._priority = np.zeros(0, dtype=np.uint64)

    def _keep(self, priority: np.ndarray) -> np.ndarray:
        if self.level == 0:
            return np.ones(priority.shape, dtype=bool)
        out: np.ndarray = (priority >> np.uint64(64 - self.level)) == 0
        return out

    def add(self, keys: np.ndarray, rows: np.ndarray) -> None:
        """Add ``rows`` with their ``keys`` (int64, e.g. the event times in ns)."""
        self.seen += int(rows.size)
        if rows.size == 0:
            return
        priority = stamp_priority(np.asarray(keys))
        keep = self._keep(priority)
        self._rows = np.concatenate((self._rows, rows[keep]))
        self._priority = np.concatenate((self._priority, priority[keep]))
        while self._rows.size > self.cap and self.level < 64:
            self.level += 1
            keep = self._keep(self._priority)
            self._rows, self._priority = self._rows[keep], self._priority[keep]

    @property
    def rows(self) -> np.ndarray:
        """The rows kept, in the order they were added."""
        return self._rows

    @property
    def fraction(self) -> float:
        """The fraction of the rows kept (1: all of them)."""
        return 0.5**self.level
