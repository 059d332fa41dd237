"""Planar loop-closure primitives: circle–circle intersection and its derivatives.

A dyad (two links of lengths ``r0`` and ``r1`` hinged together, their other ends at
the centres ``c0`` and ``c1``) closes where the circles ``|X - c0| = r0`` and
``|X - c1| = r1`` meet. This module solves that on an explicit *branch*, reports
toggles and unassemblable inputs, and gives the velocity and acceleration of the
joint from the differentiated loop equations (a 2×2 linear solve).

Branch
    ``branch = +1`` picks the point with ``(c1 - c0) × (X - c0) > 0`` (``X`` to the
    left of the directed line ``c0 → c1``), ``branch = -1`` the one with ``< 0``.
    ``×`` is the z component of the 2-D cross product, ``u × v = ux vy - uy vx``.
    Swapping the two centres flips the branch sign.

Normalised discriminant
    ``D = ((r0 + r1)² - d²) (d² - (r0 - r1)²) / (4 r0² r1²)`` with ``d = |c1 - c0|``
    (Heron's formula, factored so it keeps its relative accuracy near tangency).
    Where the circles meet, ``D = sin² μ``, ``μ`` the angle between the two radii at
    the joint (the transmission angle of a four-bar): ``D = 1`` is the best
    conditioned position, ``D = 0`` a toggle (tangent circles, the joint velocity is
    unbounded), ``D < 0`` no intersection.

Tolerance
    ``|D| <= tol`` (default :data:`TOGGLE_TOL`) counts as a toggle: the point is
    clamped to the tangent point, so a position a rounding error past the tangent
    still gives a finite answer; it then misses the circles by at most about
    ``|D| r0 r1 max(r0, r1) / (2 d²)`` (1e-11 m for the default ``tol`` and links of
    about a metre). ``D < -tol`` is unassemblable and raises
    :class:`folder_line.errors.AssemblyError` naming the first failing input.

Every function comes vectorised over NumPy arrays (broadcasting), and the
intersection also as a pure-``math`` scalar function for per-tick use.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TypeAlias, overload

import numpy as np
import numpy.typing as npt

from folder_line.core.numerics.arrays import FloatArray, FloatOrArray
from folder_line.core.numerics.dyad import joint
from folder_line.errors import AssemblyError

__all__ = [
    'TOGGLE_TOL',
    'Intersection',
    'circle_intersection',
    'circle_intersection_scalar',
    'circle_point_acceleration',
    'circle_point_velocity',
    'normalised_discriminant',
    'solve2x2',
    'tracked_intersection',
]

#: ``|normalised discriminant|`` at or below which two circles count as tangent (a toggle).
TOGGLE_TOL = 1e-10

ArrayLike: TypeAlias = npt.ArrayLike


@overload
def normalised_discriminant(d2: float, r0: float, r1: float) -> float: ...
@overload
def normalised_discriminant(d2: FloatArray, r0: FloatOrArray, r1: FloatOrArray) -> FloatArray: ...
@overload
def normalised_discriminant(d2: ArrayLike, r0: ArrayLike, r1: ArrayLike) -> FloatOrArray: ...
def normalised_discriminant(d2: ArrayLike, r0: ArrayLike, r1: ArrayLike) -> FloatOrArray:
    """Normalised discriminant ``D = sin² μ`` of two circles.

    Parameters
    ----------
    d2 : float or array_like
        Squared distance between the centres, m².
    r0, r1 : float or array_like
        Radii, m (> 0).

    Returns
    -------
    float or ndarray
        ``((r0 + r1)² - d2) (d2 - (r0 - r1)²) / (4 r0² r1²)``, dimensionless: in
        ``[0, 1]`` where the circles meet (``sin²`` of the angle between the radii
        at the intersection), ``< 0`` where they do not.
    """
    if isinstance(d2, float) and isinstance(r0, float) and isinstance(r1, float):
        return ((r0 + r1) ** 2 - d2) * (d2 - (r0 - r1) ** 2) / (4.0 * r0 * r0 * r1 * r1)
    d2a = np.asarray(d2, dtype=np.float64)
    r0a = np.asarray(r0, dtype=np.float64)
    r1a = np.asarray(r1, dtype=np.float64)
    return ((r0a + r1a) ** 2 - d2a) * (d2a - (r0a - r1a) ** 2) / (4.0 * r0a * r0a * r1a * r1a)


@dataclass(frozen=True)
class Intersection:
    """Result of :func:`circle_intersection` (all arrays of the broadcast shape).

    Attributes
    ----------
    x, y : ndarray
        The joint on the requested branch, m. At a toggle, the tangent point.
    disc : ndarray
        Normalised discriminant ``sin² μ`` (dimensionless), unclamped.
    toggle : ndarray of bool
        ``|disc| <= tol``: tangent within tolerance; the joint velocity is unbounded there.
    """

    x: FloatArray
    y: FloatArray
    disc: FloatArray
    toggle: npt.NDArray[np.bool_]

    @property
    def margin(self) -> FloatArray:
        """Toggle margin ``sin μ = sqrt(max(disc, 0))``, dimensionless in [0, 1]."""
        return np.sqrt(np.maximum(self.disc, 0.0))


def _miss_reason(d2: float, r0: float, r1: float, disc: float, tol: float) -> str:
    d = math.sqrt(d2) if d2 >= 0.0 else math.nan
    if not (math.isfinite(d2) and math.isfinite(r0) and math.isfinite(r1)):
        return f'non-finite geometry (centre distance {d!r} m, radii {r0!r} m, {r1!r} m)'
    if d2 == 0.0:
        return f'concentric circles (radii {r0:.9g} m and {r1:.9g} m)'
    if d > r0 + r1:
        gap = f'the circles are {d - (r0 + r1):.3g} m apart'
    else:
        gap = f'one circle lies {abs(r0 - r1) - d:.3g} m inside the other'
    return (
        f'{gap} (centre distance {d:.9g} m, radii {r0:.9g} m and {r1:.9g} m, '
        f'normalised discriminant {disc:.3g} < -{tol:g})'
    )


def circle_intersection(
    x0: ArrayLike,
    y0: ArrayLike,
    r0: ArrayLike,
    x1: ArrayLike,
    y1: ArrayLike,
    r1: ArrayLike,
    branch: ArrayLike,
    *,
    inputs: ArrayLike,
    tol: float = TOGGLE_TOL,
    mechanism: str = 'circle-circle dyad',
) -> Intersection:
    """Intersect circle(c0, r0) with circle(c1, r1) on an explicit branch, vectorised.

    Parameters
    ----------
    x0, y0 : array_like
        Centre ``c0``, m.
    r0 : array_like
        Radius about ``c0``, m (> 0).
    x1, y1 : array_like
        Centre ``c1``, m.
    r1 : array_like
        Radius about ``c1``, m (> 0).
    branch : array_like of {+1, -1}
        Sign of ``(c1 - c0) × (X - c0)`` of the wanted point.
    inputs : array_like
        The driving input of each element (e.g. crank angle, rad), broadcast with the
        other arguments; used only to name the first failing element in the error.
    tol : float, optional
        Toggle tolerance on the normalised discriminant (dimensionless).
    mechanism : str, optional
        Name of the loop, for the error message.

    Returns
    -------
    Intersection
        Point, discriminant and toggle mask, arrays of the broadcast shape.

    Raises
    ------
    AssemblyError
        Where the circles do not meet (``disc < -tol``), are concentric, or the
        geometry is not finite; names the first such element's input (C order).
    """
    x0a, y0a, r0a, x1a, y1a, r1a, br, inp = np.broadcast_arrays(
        *(np.asarray(v, dtype=np.float64) for v in (x0, y0, r0, x1, y1, r1, branch, inputs))
    )
    dx = x1a - x0a
    dy = y1a - y0a
    d2 = dx * dx + dy * dy
    disc = normalised_discriminant(d2, r0a, r1a)
    ok = (disc >= -tol) & (d2 > 0.0)
    if not ok.all():
        i = int(np.flatnonzero(~ok.reshape(-1))[0])
        flat = [float(v.reshape(-1)[i]) for v in (d2, r0a, r1a, disc, inp)]
        raise AssemblyError(mechanism, flat[4], _miss_reason(flat[0], flat[1], flat[2], flat[3], tol))
    # the dyad kernel about c0, with s = ±sqrt(e) = ±2 r0 r1 sin(mu) (the tangent point at a toggle)
    s = np.sqrt(np.maximum(disc, 0.0)) * (2.0 * r0a * r1a) * np.sign(br)
    jx, jy = joint(dx, dy, d2, s, 0.5 * (r0a * r0a - r1a * r1a))
    return Intersection(x=x0a + jx, y=y0a + jy, disc=disc, toggle=np.abs(disc) <= tol)


def circle_intersection_scalar(
    x0: float,
    y0: float,
    r0: float,
    x1: float,
    y1: float,
    r1: float,
    branch: float,
    *,
    inputs: float,
    tol: float = TOGGLE_TOL,
    mechanism: str = 'circle-circle dyad',
) -> tuple[float, float, float]:
    """Scalar (pure ``math``) twin of :func:`circle_intersection`.

    Parameters
    ----------
    x0, y0, r0, x1, y1, r1 : float
        Centres and radii, m.
    branch : float
        +1 or -1, sign of ``(c1 - c0) × (X - c0)``.
    inputs : float
        Driving input (e.g. crank angle, rad), named in the error.
    tol : float, optional
        Toggle tolerance on the normalised discriminant.
    mechanism : str, optional
        Name of the loop, for the error message.

    Returns
    -------
    x, y : float
        The joint, m (the tangent point at a toggle).
    disc : float
        Normalised discriminant ``sin² μ``, unclamped.

    Raises
    ------
    AssemblyError
        The circles do not meet (``disc < -tol``), are concentric or not finite.
    """
    dx = x1 - x0
    dy = y1 - y0
    d2 = dx * dx + dy * dy
    disc = ((r0 + r1) ** 2 - d2) * (d2 - (r0 - r1) ** 2) / (4.0 * r0 * r0 * r1 * r1)
    if not (disc >= -tol and d2 > 0.0):
        raise AssemblyError(mechanism, float(inputs), _miss_reason(d2, r0, r1, disc, tol))
    s = math.sqrt(disc) * (2.0 * r0 * r1) if disc > 0.0 else 0.0
    jx, jy = joint(dx, dy, d2, -s if branch < 0 else s, 0.5 * (r0 * r0 - r1 * r1))
    return x0 + jx, y0 + jy, disc


def tracked_intersection(
    x0: float,
    y0: float,
    r0: float,
    x1: float,
    y1: float,
    r1: float,
    prev_x: float,
    prev_y: float,
    *,
    inputs: float,
    tol: float = TOGGLE_TOL,
    mechanism: str = 'circle-circle dyad',
) -> tuple[float, float, int]:
    """The intersection nearest a previous joint position (tracked mode, for stepping).

    Choosing by proximity instead of by a fixed branch sign keeps the assembly
    continuous from step to step (as pylinkage does), including through a toggle,
    where the explicit branch label changes side; the step must be small compared
    with the distance between the two candidates away from toggles.

    Parameters
    ----------
    x0, y0, r0, x1, y1, r1 : float
        Centres and radii, m.
    prev_x, prev_y : float
        The joint at the previous step, m.
    inputs : float
        Driving input (e.g. crank angle, rad), named in the error.
    tol : float, optional
        Toggle tolerance on the normalised discriminant.
    mechanism : str, optional
        Name of the loop, for the error message.

    Returns
    -------
    x, y : float
        The chosen joint, m.
    branch : int
        +1 or -1, the explicit branch it lies on (+1 at an exact toggle).

    Raises
    ------
    AssemblyError
        The circles do not meet.
    """
    xp, yp, _ = circle_intersection_scalar(x0, y0, r0, x1, y1, r1, 1.0, inputs=inputs, tol=tol, mechanism=mechanism)
    xm, ym, _ = circle_intersection_scalar(x0, y0, r0, x1, y1, r1, -1.0, inputs=inputs, tol=tol, mechanism=mechanism)
    if (xm - prev_x) ** 2 + (ym - prev_y) ** 2 < (xp - prev_x) ** 2 + (yp - prev_y) ** 2:
        return xm, ym, -1
    return xp, yp, 1


def solve2x2(
    a11: FloatOrArray, a12: FloatOrArray, a21: FloatOrArray, a22: FloatOrArray, b1: FloatOrArray, b2: FloatOrArray
) -> tuple[FloatOrArray, FloatOrArray]:
    """Solve ``[[a11, a12], [a21, a22]] @ [x1, x2] = [b1, b2]`` by Cramer's rule, elementwise.

    Parameters
    ----------
    a11, a12, a21, a22 : float or ndarray
        Matrix entries (any consistent units).
    b1, b2 : float or ndarray
        Right-hand side.

    Returns
    -------
    x1, x2 : float or ndarray
        The solution. A singular matrix (a toggle) gives ±inf or NaN there
        (IEEE division, no warning suppression): callers must check the toggle mask.
    """
    det = a11 * a22 - a12 * a21
    return (b1 * a22 - a12 * b2) / det, (a11 * b2 - b1 * a21) / det


def circle_point_velocity(
    x: FloatOrArray,
    y: FloatOrArray,
    x0: FloatOrArray,
    y0: FloatOrArray,
    vx0: FloatOrArray,
    vy0: FloatOrArray,
    x1: FloatOrArray,
    y1: FloatOrArray,
    vx1: FloatOrArray,
    vy1: FloatOrArray,
) -> tuple[FloatOrArray, FloatOrArray]:
    """Velocity of the joint of a dyad from the differentiated loop equations.

    Differentiating ``|X - c0|² = r0²`` and ``|X - c1|² = r1²`` (constant radii) gives
    ``(X - ci) · (V - vi) = 0``, i.e. the 2×2 system
    ``[(X - c0)ᵀ; (X - c1)ᵀ] V = [(X - c0)·v0, (X - c1)·v1]``, solved by :func:`solve2x2`.

    Parameters
    ----------
    x, y : float or ndarray
        The joint, m.
    x0, y0, vx0, vy0 : float or ndarray
        Centre ``c0``, m, and its velocity, m/s.
    x1, y1, vx1, vy1 : float or ndarray
        Centre ``c1``, m, and its velocity, m/s.

    Returns
    -------
    vx, vy : float or ndarray
        Joint velocity, m/s (unbounded at a toggle; see :func:`solve2x2`).
    """
    # np.subtract, not `-`: float inputs become NumPy scalars, so a toggle divides by zero
    # the IEEE way (inf/nan) instead of raising ZeroDivisionError
    ex0: FloatOrArray = np.subtract(x, x0)
    ey0: FloatOrArray = np.subtract(y, y0)
    ex1: FloatOrArray = np.subtract(x, x1)
    ey1: FloatOrArray = np.subtract(y, y1)
    return solve2x2(ex0, ey0, ex1, ey1, ex0 * vx0 + ey0 * vy0, ex1 * vx1 + ey1 * vy1)


def circle_point_acceleration(
    x: FloatOrArray,
    y: FloatOrArray,
    vx: FloatOrArray,
    vy: FloatOrArray,
    x0: FloatOrArray,
    y0: FloatOrArray,
    vx0: FloatOrArray,
    vy0: FloatOrArray,
    ax0: FloatOrArray,
    ay0: FloatOrArray,
    x1: FloatOrArray,
    y1: FloatOrArray,
    vx1: FloatOrArray,
    vy1: FloatOrArray,
    ax1: FloatOrArray,
    ay1: FloatOrArray,
) -> tuple[FloatOrArray, FloatOrArray]:
    """Acceleration of the joint of a dyad from the twice-differentiated loop equations.

    ``(X - ci) · (A - ai) = -|V - vi|²`` for i = 0, 1; the same matrix as the velocity.

    Parameters
    ----------
    x, y, vx, vy : float or ndarray
        The joint, m, and its velocity, m/s (from :func:`circle_point_velocity`).
    x0, y0, vx0, vy0, ax0, ay0 : float or ndarray
        Centre ``c0``: position m, velocity m/s, acceleration m/s².
    x1, y1, vx1, vy1, ax1, ay1 : float or ndarray
        Centre ``c1``: position m, velocity m/s, acceleration m/s².

    Returns
    -------
    ax, ay : float or ndarray
        Joint acceleration, m/s² (unbounded at a toggle).
    """
    ex0: FloatOrArray = np.subtract(x, x0)
    ey0: FloatOrArray = np.subtract(y, y0)
    ex1: FloatOrArray = np.subtract(x, x1)
    ey1: FloatOrArray = np.subtract(y, y1)
    ux0: FloatOrArray = np.subtract(vx, vx0)
    uy0: FloatOrArray = np.subtract(vy, vy0)
    ux1: FloatOrArray = np.subtract(vx, vx1)
    uy1: FloatOrArray = np.subtract(vy, vy1)
    b1 = ex0 * ax0 + ey0 * ay0 - (ux0 * ux0 + uy0 * uy0)
    b2 = ex1 * ax1 + ey1 * ay1 - (ux1 * ux1 + uy1 * uy1)
    return solve2x2(ex0, ey0, ex1, ey1, b1, b2)
