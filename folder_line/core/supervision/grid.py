"""The check grid ``t = n h``: where the supervisor decides liveness and the end of acting states.

A decision on the grid has an exact time that depends on the inputs only, never on when
the supervisor was called (:mod:`folder_line.core.supervision`). The rounding of
``t / h`` is corrected in both directions, so a grid point is ``n h`` as a float product,
whatever the rounding of the division.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ['CheckGrid']


@dataclass(frozen=True)
class CheckGrid:
    """The grid ``t = n h`` of spacing ``h`` (s, > 0; checked by the caller)."""

    h: float

    def index_after(self, t: float) -> int:
        """The smallest n with ``n h > t``."""
        n = math.floor(t / self.h) + 1
        while n * self.h <= t:
            n += 1
        while (n - 1) * self.h > t:
            n -= 1
        return n

    def index_at_or_after(self, t: float) -> int:
        """The smallest n with ``n h >= t``."""
        n = math.ceil(t / self.h)
        while n * self.h < t:
            n += 1
        while (n - 1) * self.h >= t:
            n -= 1
        return n

    def first_after(self, t: np.ndarray) -> np.ndarray:
        """The first grid point strictly after each ``t`` (finite), s."""
        g = (np.floor(t / self.h) + 1.0) * self.h
        g = np.where(g <= t, g + self.h, g)
        return np.where(g - self.h > t, g - self.h, g)

    def first_at_or_after(self, t: np.ndarray) -> np.ndarray:
        """The first grid point at or after each ``t``, s (``inf`` where ``t`` is not finite)."""
        fin = np.isfinite(t)
        tt = np.where(fin, t, 0.0)
        g = np.ceil(tt / self.h) * self.h
        g = np.where(g < tt, g + self.h, g)
        g = np.where(g - self.h >= tt, g - self.h, g)
        return np.where(fin, g, np.inf)
