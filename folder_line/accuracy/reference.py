"""mpmath references for the layup linkages: the six-bar's chute angles and rates at 50 digits.

Derived independently of :mod:`folder_line.core.numerics.loop` and :mod:`folder_line.core.mechanisms.layup`:
the unknowns are the link angles, the equations the vector loop closures

    loop 1 (O1-A-B-O2):  O1 + R_kr e(φ) + l2 e(θ2) - O2B e(θ3) = 0
    loop 2 (O2-C-E-O3):  l3 e(θ3) + l4 e(θ4) - O3 - l5 e(θ5) = 0

with ``e(x) = (cos x, sin x)``, O2 at the origin, O1 = (a, b), O3 = (O2O3, 0) (the
project frame, docs/machines.md, section L). Positions: a float start from the law of
cosines (triangles O2-A-B and O3-C-E, on the assembly branches the layup model takes:
``(A - O2) × (B - O2) > 0`` and ``(C - O3) × (E - O3) > 0``), polished by Newton's
method in mpmath at :data:`DPS` digits until the step is below ``10^-(DPS-5)``.
Rates: the loop equations differentiated in time, ``J(θ) θ' = -∂F/∂φ · ω``, solved
in mpmath (Cramer's rule on each loop's 2×2 block). The checks (``test/accuracy``):
the loop residuals are below 1e-30 m, the branch conditions hold, the angles agree
with the core's closed form to 1e-13 rad and the rates with an mpmath central
difference of the reference's own positions.

Angles are rad (θ3 of O2C, θ5 of O3E, from +x, wrapped to (-π, π] like the core's),
rates rad/s. The float crank angles given are taken exactly (``mpf(float)``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import mpmath as mp
import numpy as np
import numpy.typing as npt

from folder_line.core.mechanisms.layup import LayupParams
from folder_line.errors import AssemblyError

__all__ = [
    'DPS',
    'MpFourbar',
    'MpSixbar',
    'ReferenceArrays',
    'fourbar_mp',
    'loop_residuals_mp',
    'sixbar_mp',
    'sixbar_reference',
]

#: decimal digits of the reference
DPS = 50
_MAX_ITER = 30


@dataclass(frozen=True)
class MpFourbar:
    """Loop O1-A-B-O2 at one crank angle, in mpmath.

    Attributes
    ----------
    phi : mpf
        Crank angle, rad.
    theta2, theta3 : mpf
        Angles of the rod A→B and of O2→B (= O2→C, chute 3) from +x, rad (not wrapped).
    dtheta2, dtheta3 : mpf
        Their rates, rad/s, at the crank speed given.
    """

    phi: mp.mpf
    theta2: mp.mpf
    theta3: mp.mpf
    dtheta2: mp.mpf
    dtheta3: mp.mpf


@dataclass(frozen=True)
class MpSixbar:
    """The six-bar at one crank angle, in mpmath: loop 1 and loop 2 (O2-C-E-O3).

    Attributes
    ----------
    loop1 : MpFourbar
    theta4, theta5 : mpf
        Angles of the coupler C→E and of O3→E (chute 4) from +x, rad (not wrapped).
    dtheta4, dtheta5 : mpf
        Their rates, rad/s.
    """

    loop1: MpFourbar
    theta4: mp.mpf
    theta5: mp.mpf
    dtheta4: mp.mpf
    dtheta5: mp.mpf


def _mp_params(p: LayupParams) -> tuple[mp.mpf, ...]:
    return tuple(mp.mpf(float(v)) for v in (p.R_kr, p.a, p.b, p.l2, p.O2B, p.l3, p.l4, p.l5, p.O2O3))


def _triangle_start(cx: float, cy: float, r_near: float, r_far: float, px: float, py: float) -> float:
    """Angle about centre c of the apex X with |X - c| = r_near, |X - p| = r_far, X counter-clockwise of p."""
    d = math.hypot(px - cx, py - cy)
    cos_g = (d * d + r_near * r_near - r_far * r_far) / (2.0 * d * r_near)
    return math.atan2(py - cy, px - cx) + math.acos(max(-1.0, min(1.0, cos_g)))


def _newton2(
    f: Callable[[mp.mpf, mp.mpf], tuple[mp.mpf, mp.mpf, mp.mpf, mp.mpf, mp.mpf, mp.mpf]],
    x: mp.mpf,
    y: mp.mpf,
    what: str,
    phi: float | mp.mpf,
) -> tuple[mp.mpf, mp.mpf]:
    """Newton on a 2×2 system ``f(x, y) -> (F1, F2, J11, J12, J21, J22)`` to 10^-(dps-5)."""
    step_tol = mp.mpf(10) ** (-(mp.mp.dps - 5))
    for _ in range(_MAX_ITER):
        f1, f2, j11, j12, j21, j22 = f(x, y)
        det = j11 * j22 - j12 * j21
        dx = -(f1 * j22 - j12 * f2) / det
        dy = -(j11 * f2 - f1 * j21) / det
        x += dx
        y += dy
        if max(abs(dx), abs(dy)) <= step_tol:
            return x, y
    raise AssemblyError(
        f'mpmath reference, {what}', float(phi), f'Newton did not converge in {_MAX_ITER} steps (a toggle?)'
    )


def _fourbar(phi: float | mp.mpf, P: tuple[mp.mpf, ...], omega: mp.mpf) -> MpFourbar:
    R, a, b, l2, p, *_ = P
    ph = mp.mpf(phi)
    c, s = mp.cos(ph), mp.sin(ph)
    ax, ay = a + R * c, b + R * s
    # float start: B counter-clockwise of A about O2 at |O2B|, |AB| = l2
    axf, ayf = float(ax), float(ay)
    t3 = _triangle_start(0.0, 0.0, float(p), float(l2), axf, ayf)
    t2 = math.atan2(float(p) * math.sin(t3) - ayf, float(p) * math.cos(t3) - axf)

    def f(x: mp.mpf, y: mp.mpf) -> tuple[mp.mpf, ...]:
        c2, s2, c3, s3 = mp.cos(x), mp.sin(x), mp.cos(y), mp.sin(y)
        return (ax + l2 * c2 - p * c3, ay + l2 * s2 - p * s3, -l2 * s2, p * s3, l2 * c2, -p * c3)

    t2m, t3m = _newton2(f, mp.mpf(t2), mp.mpf(t3), 'loop O1-A-B-O2', phi)
    # rates: J [θ2', θ3'] = -dA/dt, dA/dt = R ω (-sin φ, cos φ)
    _, _, j11, j12, j21, j22 = f(t2m, t3m)
    r1, r2 = R * omega * s, -R * omega * c
    det = j11 * j22 - j12 * j21
    return MpFourbar(ph, t2m, t3m, (r1 * j22 - j12 * r2) / det, (j11 * r2 - r1 * j21) / det)


def _sixbar(phi: float | mp.mpf, P: tuple[mp.mpf, ...], omega: mp.mpf) -> MpSixbar:
    one = _fourbar(phi, P, omega)
    *_, l3, l4, l5, d0 = P
    c3, s3 = mp.cos(one.theta3), mp.sin(one.theta3)
    cx, cy = l3 * c3, l3 * s3
    # float start: E counter-clockwise of C about O3 at |O3E| = l5, |CE| = l4
    t5 = _triangle_start(float(d0), 0.0, float(l5), float(l4), float(cx), float(cy))
    t4 = math.atan2(float(l5) * math.sin(t5) - float(cy), float(d0) + float(l5) * math.cos(t5) - float(cx))

    def f(x: mp.mpf, y: mp.mpf) -> tuple[mp.mpf, ...]:
        c4, s4, c5, s5 = mp.cos(x), mp.sin(x), mp.cos(y), mp.sin(y)
        return (cx + l4 * c4 - d0 - l5 * c5, cy + l4 * s4 - l5 * s5, -l4 * s4, l5 * s5, l4 * c4, -l5 * c5)

    t4m, t5m = _newton2(f, mp.mpf(t4), mp.mpf(t5), 'loop O2-C-E-O3', phi)
    # rates: J2 [θ4', θ5'] = -dC/dt, dC/dt = l3 θ3' (-sin θ3, cos θ3)
    _, _, j11, j12, j21, j22 = f(t4m, t5m)
    r1, r2 = l3 * one.dtheta3 * s3, -l3 * one.dtheta3 * c3
    det = j11 * j22 - j12 * j21
    return MpSixbar(one, t4m, t5m, (r1 * j22 - j12 * r2) / det, (j11 * r2 - r1 * j21) / det)


def _angle(phi: float | mp.mpf) -> float | mp.mpf:
    return phi if isinstance(phi, mp.mpf) else float(phi)


def fourbar_mp(params: LayupParams, phi: float | mp.mpf, omega: float | None = None) -> MpFourbar:
    """Loop O1-A-B-O2 at one crank angle, at :data:`DPS` digits.

    Parameters
    ----------
    params : LayupParams
        The layup (only R_kr, a, b, l2, O2B are used).
    phi : float or mpf
        Crank angle, rad (a float is taken exactly; an mpf is rounded to ``DPS`` digits).
    omega : float, optional
        Crank angular velocity, rad/s; default ``params.omega``.

    Returns
    -------
    MpFourbar
        Computed at ``DPS`` digits (the caller's mpmath precision is restored).

    Raises
    ------
    AssemblyError
        Newton's method did not converge (a toggle; validated parameters exclude it).
    """
    with mp.workdps(DPS):
        w = mp.mpf(params.omega if omega is None else float(omega))
        return _fourbar(_angle(phi), _mp_params(params), w)


def sixbar_mp(params: LayupParams, phi: float | mp.mpf, omega: float | None = None) -> MpSixbar:
    """The six-bar at one crank angle, at :data:`DPS` digits.

    Parameters
    ----------
    params : LayupParams
        The layup.
    phi : float or mpf
        Crank angle, rad (a float is taken exactly; an mpf is rounded to ``DPS`` digits).
    omega : float, optional
        Crank angular velocity, rad/s; default ``params.omega``.

    Returns
    -------
    MpSixbar

    Raises
    ------
    AssemblyError
        Newton's method did not converge.
    """
    with mp.workdps(DPS):
        w = mp.mpf(params.omega if omega is None else float(omega))
        return _sixbar(_angle(phi), _mp_params(params), w)


def loop_residuals_mp(params: LayupParams, sol: MpSixbar) -> tuple[mp.mpf, mp.mpf, mp.mpf, mp.mpf]:
    """The four loop-closure residuals of a solution, m (x, y of loop 1, then of loop 2).

    Parameters
    ----------
    params : LayupParams
    sol : MpSixbar

    Returns
    -------
    tuple of mpf
        Evaluated at :data:`DPS` digits.
    """
    with mp.workdps(DPS):
        R, a, b, l2, p, l3, l4, l5, d0 = _mp_params(params)
        one = sol.loop1
        ph = one.phi
        e = [(mp.cos(t), mp.sin(t)) for t in (one.theta2, one.theta3, sol.theta4, sol.theta5)]
        return (
            a + R * mp.cos(ph) + l2 * e[0][0] - p * e[1][0],
            b + R * mp.sin(ph) + l2 * e[0][1] - p * e[1][1],
            l3 * e[1][0] + l4 * e[2][0] - d0 - l5 * e[3][0],
            l3 * e[1][1] + l4 * e[2][1] - l5 * e[3][1],
        )


def _wrap(t: mp.mpf) -> float:
    """An mpmath angle wrapped to (-π, π] and rounded to float."""
    return float(mp.atan2(mp.sin(t), mp.cos(t)))


@dataclass(frozen=True)
class ReferenceArrays:
    """Reference values rounded to float (errors of at most half an ulp), shape of ``phi``.

    Attributes
    ----------
    phi : ndarray
        Crank angles, rad.
    theta3, theta5 : ndarray
        Chute angles (O2C, O3E) from +x, rad in (-π, π]; ``theta5`` NaN for the four-bar.
    omega3, omega5 : ndarray
        Their rates, rad/s; ``omega5`` NaN for the four-bar.
    """

    phi: np.ndarray
    theta3: np.ndarray
    theta5: np.ndarray
    omega3: np.ndarray
    omega5: np.ndarray


_CACHE: dict[tuple[object, ...], ReferenceArrays] = {}


def sixbar_reference(
    params: LayupParams, phi: npt.ArrayLike | Sequence[float], omega: float | None = None, *, loops: int = 2
) -> ReferenceArrays:
    """θ3, θ5, ω3, ω5 of the six-bar at many crank angles (cached per module).

    Parameters
    ----------
    params : LayupParams
    phi : array_like
        Crank angles, rad (flattened; taken exactly).
    omega : float, optional
        Crank angular velocity, rad/s; default ``params.omega``.
    loops : {2, 1}, optional
        2: the six-bar. 1: loop O1-A-B-O2 alone, the four-bar (θ3 of its rocker O2B and
        ω3); ``theta5`` and ``omega5`` are then NaN.

    Returns
    -------
    ReferenceArrays
        Under 1 ms per angle the first time; the same object again from the cache.
    """
    if loops not in (1, 2):
        raise ValueError(f'loops must be 1 or 2, got {loops!r}')
    ph = np.ascontiguousarray(np.asarray(phi, dtype=float).reshape(-1))
    w = params.omega if omega is None else float(omega)
    key = (params, w, loops, ph.tobytes())
    hit = _CACHE.get(key)
    if hit is not None:
        return hit
    n = ph.size
    out = np.full((4, n), np.nan)
    with mp.workdps(DPS):
        P = _mp_params(params)
        wm = mp.mpf(w)
        for i, x in enumerate(ph.tolist()):
            if loops == 2:
                s = _sixbar(x, P, wm)
                out[:, i] = (_wrap(s.loop1.theta3), _wrap(s.theta5), float(s.loop1.dtheta3), float(s.dtheta5))
            else:
                f = _fourbar(x, P, wm)
                out[0, i], out[2, i] = _wrap(f.theta3), float(f.dtheta3)
    res = ReferenceArrays(ph, *out)
    if len(_CACHE) >= 16:
        _CACHE.pop(next(iter(_CACHE)))
    _CACHE[key] = res
    return res
