"""Figures accumulated as the windows of a streamed line pass: counts, extremes, means, binned means.

A mean over a run cut into windows must be the mean of the run in one window, bit for
bit. :class:`BlockSum` adds values in blocks of a fixed number of *items* (not of
windows): each full block is summed by numpy's pairwise sum, and the block sums are
added one after the other. Which values form a block depends only on their order, so
the sum is the same however the values arrive. The memory is one block.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

__all__ = ['BLOCK', 'BinnedSum', 'BlockSum', 'RunningStats']

#: values per block of :class:`BlockSum`
BLOCK = 4096


@dataclass
class BlockSum:
    """A sum of values taken in order, the same however they are split into calls (module docstring)."""

    total: float = 0.0
    count: int = 0
    _pending: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def add(self, values: npt.ArrayLike) -> None:
        """Add ``values`` (in order)."""
        v = np.asarray(values, dtype=float).reshape(-1)
        if v.size == 0:
            return
        self.count += v.size
        buf = np.concatenate((self._pending, v)) if self._pending.size else v
        full = buf.size // BLOCK
        for b in range(full):
            self.total += float(np.sum(buf[b * BLOCK : (b + 1) * BLOCK]))
        self._pending = buf[full * BLOCK :].copy()

    @property
    def value(self) -> float:
        """The sum of every value added."""
        return self.total + float(np.sum(self._pending)) if self._pending.size else self.total


@dataclass
class RunningStats:
    """Count, minimum, maximum and mean of values added in order."""

    sum: BlockSum = field(default_factory=BlockSum)
    low: float = math.inf
    high: float = -math.inf

    def add(self, values: npt.ArrayLike) -> None:
        """Add ``values``."""
        v = np.asarray(values, dtype=float).reshape(-1)
        if v.size:
            self.sum.add(v)
            self.low = min(self.low, float(v.min()))
            self.high = max(self.high, float(v.max()))

    @property
    def count(self) -> int:
        """Values added."""
        return self.sum.count

    @property
    def mean(self) -> float | None:
        """Their mean (None if none)."""
        return self.sum.value / self.count if self.count else None


@dataclass
class BinnedSum:
    """Per-bin counts and sums of values taken in order, the same however they are split into calls: every
    :data:`BLOCK` values, the block's per-bin sums (``np.bincount``, in order) are added to the totals."""

    bins: int
    totals: np.ndarray = field(init=False)
    counts: np.ndarray = field(init=False)
    _pending_bin: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    _pending: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def __post_init__(self) -> None:
        self.totals = np.zeros(self.bins)
        self.counts = np.zeros(self.bins, dtype=np.int64)

    def add(self, where: npt.ArrayLike, values: npt.ArrayLike) -> None:
        """Add ``values`` to the bins ``where`` (in order)."""
        b = np.asarray(where, dtype=np.int64).reshape(-1)
        v = np.asarray(values, dtype=float).reshape(-1)
        if v.size == 0:
            return
        self.counts += np.bincount(b, minlength=self.bins)
        pb = np.concatenate((self._pending_bin, b))
        pv = np.concatenate((self._pending, v))
        full = pv.size // BLOCK
        for k in range(full):
            sl = slice(k * BLOCK, (k + 1) * BLOCK)
            self.totals += np.bincount(pb[sl], weights=pv[sl], minlength=self.bins)
        self._pending_bin, self._pending = pb[full * BLOCK :].copy(), pv[full * BLOCK :].copy()

    def means(self) -> list[float | None]:
        """The mean of each bin (None where empty)."""
        tot = self.totals + np.bincount(self._pending_bin, weights=self._pending, minlength=self.bins)
        return [float(tot[i] / self.counts[i]) if self.counts[i] else None for i in range(self.bins)]
