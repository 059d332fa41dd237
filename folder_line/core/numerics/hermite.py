"""The cubic Hermite interpolant of one step, and where it reaches a level (vectorised bisection).

A step of length ``h`` from ``(y0, d0)`` to ``(y1, d1)`` (values and derivatives) is interpolated
at the step fraction ``theta`` in [0, 1] by the cubic that matches both ends (local error O(h⁴)).
"""

from __future__ import annotations

from typing import TypeVar

import numpy as np

from folder_line.core.numerics.arrays import FloatArray

__all__ = ['hermite', 'hermite_level']

#: float (one step) or float64 array (many): the interpolant's inputs and value share it
_F = TypeVar('_F', float, FloatArray)


def hermite(theta: _F, y0: _F, d0: _F, y1: _F, d1: _F, h: _F) -> _F:
    """Cubic Hermite interpolant on a step of length h at fraction theta in [0, 1] (one step or many)."""
    t2 = theta * theta
    t3 = t2 * theta
    return (
        (2.0 * t3 - 3.0 * t2 + 1.0) * y0
        + (t3 - 2.0 * t2 + theta) * h * d0
        + (3.0 * t2 - 2.0 * t3) * y1
        + (t3 - t2) * h * d1
    )


def hermite_level(
    y0: FloatArray, d0: FloatArray, y1: FloatArray, d1: FloatArray, h: FloatArray, level: FloatArray, passes: int
) -> FloatArray:
    """Step fraction where the Hermite interpolant of each step reaches ``level`` (y0 < level <= y1), by
    ``passes`` bisections of [0, 1]: the upper end of the last bracket."""
    lo = np.zeros(y0.size)
    hi = np.ones(y0.size)
    for _ in range(passes):
        mid = 0.5 * (lo + hi)
        above = hermite(mid, y0, d0, y1, d1, h) >= level
        hi = np.where(above, mid, hi)
        lo = np.where(above, lo, mid)
    return hi
