"""``leaf_flight`` — a leaf's flight from the chute exit to the container floor (L).

Model (ours: docs/scenes.md, "Effects"; paper 000, docs/machines.md section L, is about the
uniformity of the layup across the container width, which this effect measures).
Project frame: x toward O3, y up; gravity ``g = 9.80665 m/s²`` along −y. From the
exit point (x0, y0) with the exit velocity (vx, vy), the leaf flies under gravity and
an optional linear air drag ``−k v`` per unit mass (k > 0, 1/s; terminal speed g/k):

    ẍ = −k ẋ ,   ÿ = −g − k ẏ

Closed form, written without the cancellations of the textbook form for small k·t
(``φ1(z) = (1 − e^{−z})/z = −expm1(−z)/z``, ``φ2(z) = (z − 1 + e^{−z})/z²``, both → 1
and 1/2 as z → 0, φ2 by its Taylor series for z < 1/2):

    x(t) = x0 + vx t φ1(kt)                 ẋ(t) = vx e^{−kt}
    y(t) = y0 + vy t φ1(kt) − g t² φ2(kt)   ẏ(t) = vy e^{−kt} − g t φ1(kt)

which for k = 0 is exactly the drag-free parabola, so the drag → 0 limit is continuous.

Landing time (y(t) = y_floor, H = y0 − y_floor > 0):

* no drag: the positive root of ``g t²/2 − vy t − H = 0`` in its cancellation-free
  form, ``t = (vy + sqrt(vy² + 2gH))/g`` for vy >= 0 and ``t = 2H/(sqrt(vy² + 2gH) − vy)``
  for vy < 0;
* drag: root of ``f(t) = y(t) − y_floor`` in the analytic bracket
  ``[0, t_hi]``, ``t_hi = (k H + max(vy + g/k, 0))/g`` (from ``φ1 <= 1/(k t)``:
  ``f(t_hi) < 0``; ``f(0) = H > 0``). f has one sign of curvature
  (``f'' = −k (vy + g/k) e^{−kt}``), so Newton's method from the drag-free landing
  time (past the apex, where f' < 0) converges monotonically after at most one step;
  it is safeguarded by bisection of the bracket and run vectorised over all leaves
  until the step is below 2 ulp of t. (A bracketed root-finder like
  :func:`folder_line.core.numerics.roots.brentq` returns the same root to ~1e-15 s, tested; this
  vectorised form avoids a Python call per leaf.)

Landing x is ``x(t_land)``; leaves landing in [x_left, x_right] are counted in the
histogram of ``container.bins`` equal bins across the width, those outside spill.
The uniformity figure ``landing_cv`` is the coefficient of variation (population
standard deviation over mean) of the bin counts.

Suggested parameter: ``drag = 0.0`` (the drag-free picture of docs/scenes.md, "What the scenes show"); a
tobacco leaf is light and broad, so ``drag`` of a few 1/s is defensible (terminal
speed g/k ≈ 3.3 m/s at k = 3).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from folder_line.core.numerics.constants import G
from folder_line.core.numerics.validate import check_fields, within
from folder_line.errors import ParameterError

__all__ = [
    'Histogram',
    'Params',
    'histogram',
    'histogram_of_counts',
    'landing',
    'landing_time',
    'phi1',
    'phi2',
    'state',
]

#: below this k·t, φ2 is summed from its Taylor series
_SERIES_BELOW = 0.5
_SERIES_TERMS = 18
_NEWTON_MAXITER = 100


@dataclass(frozen=True)
class Params:
    """Parameters of ``leaf_flight``.

    Attributes
    ----------
    drag : float
        Linear drag coefficient k per unit mass, 1/s, in [0, 1000] (0 = no drag). Terminal
        speed g/k. Suggested 0.0.
    """

    drag: float

    def __post_init__(self) -> None:
        check_fields(self, 'effects.leaf_flight', drag=within(0.0, 1e3))


class Histogram(NamedTuple):
    """Landing histogram across the container width.

    Fields: ``edges`` (bins + 1 bin edges, m), ``counts`` (leaves per bin),
    ``cv`` (std/mean of the counts, None when no leaf landed).
    """

    edges: np.ndarray
    counts: np.ndarray
    cv: float | None


def phi1(z: npt.ArrayLike) -> np.ndarray:
    """``(1 − e^{−z})/z`` for z >= 0 (1 at z = 0), to a few ulp."""
    z = np.asarray(z, dtype=float)
    safe = np.where(z > 0.0, z, 1.0)
    return np.where(z > 0.0, -np.expm1(-safe) / safe, 1.0)


def phi2(z: npt.ArrayLike) -> np.ndarray:
    """``(z − 1 + e^{−z})/z²`` for z >= 0 (1/2 at z = 0), to a few ulp.

    Taylor series ``Σ (−z)^n/(n+2)!`` below z = 1/2 (18 terms: truncation < 1e-22),
    the closed form ``(z + expm1(−z))/z²`` above (cancellation <= 4 ulp there).
    """
    z = np.asarray(z, dtype=float)
    small = z < _SERIES_BELOW
    zs = np.where(small, z, 0.0)
    acc = np.zeros_like(z)
    term = np.ones_like(z)
    fact = 2.0
    for n in range(_SERIES_TERMS):
        acc = acc + term / fact
        term = term * (-zs)
        fact *= n + 3
    zl = np.where(small, 1.0, z)
    return np.where(small, acc, (zl + np.expm1(-zl)) / (zl * zl))


def state(
    params: Params, x0: npt.ArrayLike, y0: npt.ArrayLike, vx: npt.ArrayLike, vy: npt.ArrayLike, t: npt.ArrayLike
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Position and velocity after flying for ``t`` s (closed form, see the module docstring).

    Returns
    -------
    x, y, vx_t, vy_t : ndarray
        m, m, m/s, m/s.
    """
    t = np.asarray(t, dtype=float)
    x0, y0, vx, vy = (np.asarray(a, dtype=float) for a in (x0, y0, vx, vy))
    k = params.drag
    z = k * t
    p1 = phi1(z)
    decay = np.exp(-z)
    x = x0 + vx * t * p1
    y = y0 + vy * t * p1 - G * t * t * phi2(z)
    return x, y, vx * decay, vy * decay - G * t * p1


def _no_drag_time(height: np.ndarray, vy: np.ndarray) -> np.ndarray:
    root = np.sqrt(vy * vy + 2.0 * G * height)
    up = vy >= 0.0
    return np.where(up, (np.where(up, vy, 0.0) + root) / G, 2.0 * height / np.where(up, 1.0, root - vy))


def landing_time(params: Params, y0: npt.ArrayLike, vy: npt.ArrayLike, y_floor: float) -> np.ndarray:
    """Flight time from height ``y0`` with vertical speed ``vy`` down to ``y_floor``, s.

    Parameters
    ----------
    params : Params
        The effect's parameters.
    y0 : array_like
        Start heights, m (> y_floor).
    vy : array_like
        Vertical start velocities, m/s (positive up).
    y_floor : float
        Floor height, m.

    Returns
    -------
    ndarray
        Landing times, s (> 0).

    Raises
    ------
    ParameterError
        A start point is not above the floor.
    """
    y0 = np.asarray(y0, dtype=float)
    vy = np.asarray(vy, dtype=float)
    height = y0 - y_floor
    if height.size and not height.min() > 0.0:
        raise ParameterError(
            'container.y_floor', y_floor, f'must be below every chute exit; an exit is at y = {float(y0.min())!r} m'
        )
    t0 = _no_drag_time(height, vy)
    k = params.drag
    if k == 0.0 or height.size == 0:
        return t0
    c = vy + G / k
    lo = np.zeros_like(height)
    hi = (k * height + np.maximum(c, 0.0)) / G
    t: npt.NDArray[np.float64] = np.clip(t0, lo, hi)
    live = np.ones(t.shape, dtype=bool)
    for _ in range(_NEWTON_MAXITER):
        z = k * t
        p1 = phi1(z)
        f = height + vy * t * p1 - G * t * t * phi2(z)
        df = vy * np.exp(-z) - G * t * p1
        lo = np.where(f > 0.0, t, lo)
        hi = np.where(f < 0.0, t, hi)
        newton = t - np.where(df < 0.0, f / np.where(df < 0.0, df, -1.0), 0.0)
        conv = (f == 0.0) | (np.abs(newton - t) <= 4.0 * np.spacing(t))
        bad = ~((newton > lo) & (newton < hi)) | (df >= 0.0)
        new = np.where(conv, newton, np.where(bad, 0.5 * (lo + hi), newton))
        t = np.where(live, new, t)
        live &= ~conv
        if not live.any():
            break
    return t


def landing(
    params: Params, x0: npt.ArrayLike, y0: npt.ArrayLike, vx: npt.ArrayLike, vy: npt.ArrayLike, y_floor: float
) -> tuple[np.ndarray, np.ndarray]:
    """Landing time and landing x of leaves leaving the exits.

    Parameters
    ----------
    params : Params
        The effect's parameters.
    x0, y0 : array_like
        Exit points, m.
    vx, vy : array_like
        Exit velocities, m/s.
    y_floor : float
        Floor height, m.

    Returns
    -------
    t_flight : ndarray
        Flight times, s.
    x_land : ndarray
        Landing x, m.
    """
    t = landing_time(params, y0, vy, y_floor)
    x = np.asarray(x0, dtype=float) + np.asarray(vx, dtype=float) * t * phi1(params.drag * t)
    return t, x


def histogram_of_counts(counts: npt.ArrayLike, x_left: float, x_right: float) -> Histogram:
    """The :class:`Histogram` of bin counts over ``[x_left, x_right]`` (counts added up window by window)."""
    c = np.asarray(counts, dtype=np.int64).reshape(-1)
    edges = np.linspace(x_left, x_right, c.size + 1)
    total = int(c.sum())
    cv = None if total == 0 else float(np.std(c) / np.mean(c))
    return Histogram(edges, c, cv)


def histogram(x_landed: npt.ArrayLike, x_left: float, x_right: float, bins: int) -> Histogram:
    """Histogram of landing x over [x_left, x_right] and its coefficient of variation.

    Parameters
    ----------
    x_landed : array_like
        Landing x of the leaves inside the walls, m.
    x_left, x_right : float
        Container walls, m.
    bins : int
        Equal bins across the width.

    Returns
    -------
    Histogram
        ``cv = std(counts)/mean(counts)`` (population std), None if no leaf landed.
    """
    counts, edges = np.histogram(np.asarray(x_landed, dtype=float), bins=bins, range=(x_left, x_right))
    total = int(counts.sum())
    cv = None if total == 0 else float(np.std(counts) / np.mean(counts))
    return Histogram(edges, counts.astype(np.int64), cv)
