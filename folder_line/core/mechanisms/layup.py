"""L — the leaf layup six-bar: crank-rocker O1-A-B-O2 driving the double rocker O2-C-E-O3.

Project frame (docs/machines.md, section L): O2 at the origin, x toward O3, y up;
O3 = (O2O3, 0); O1 = (a, b); crank pin ``A = O1 + R_kr (cos φ, sin φ)``, φ increasing
(counter-clockwise) at ``ω = 2π n_kr / 60``.

Loop 1 (O1-A-B-O2)
    B is the intersection of circle(A, l2) and circle(O2, O2B) with
    ``(O2 - A) × (B - A) < 0`` (equivalently ``(A - O2) × (B - O2) > 0``, i.e. branch
    +1 of the pair (O2, A) in :mod:`folder_line.core.numerics.loop`). C = B · l3 / O2B.
Loop 2 (O2-C-E-O3)
    E is the intersection of circle(C, l4) and circle(O3, l5) with
    ``(O3 - C) × (E - C) < 0`` (branch +1 of the pair (O3, C)).

Outputs: :mod:`folder_line.core.mechanisms.layup_state`.

Method. Positions are closed-form circle–circle intersections (Heron's discriminant,
see :mod:`folder_line.core.numerics.loop`). Velocities come from differentiating
``|B - A|² = l2²`` (B turning about O2: ``dB/dt = ω3 B⊥``) and ``|E - C|² = l4²``;
the 2×2 system of each dyad has the closed Cramer solution
``ω3 = (B - A)·(dA/dt) / ((A - O2) × (B - O2))`` and
``ω5 = (E - C)·(dC/dt) / ((C - O3) × (E - O3))``, whose denominators are twice the
dyads' triangle areas; they vanish only at a toggle, which validation excludes.
The paper's projection-theorem formulas live in :mod:`folder_line.core.mechanisms.layup_paper`,
as a cross-check only.

Validation. :class:`LayupParams` checks every value, requires loop 1 to be a Grashof
crank-rocker with the crank the shortest link, and runs :func:`check_assembly`: both
loops must assemble, away from toggles, over a whole crank turn. So every accepted
parameter set has finite kinematics at every crank angle.

Crank-angle range: every entry point reduces φ to [-π, π] exactly (:mod:`~.layup_angles`).

Speed. :meth:`LayupModel.point` is a pure-``math`` scalar path for node ticks;
:meth:`LayupModel.arrays` is vectorised, processes the angles in cache-sized chunks
with in-place ufuncs, and gets cos φ and sin φ from one ``t = tan(φ/2)``:
``cos φ = 2/(1 + t²) - 1``, ``sin φ = t · 2/(1 + t²)`` (finite for φ in [-π, π], few-ulp
accurate); NumPy's float64 tan is SIMD-vectorised on this class of CPU (about 1 ns per
element) while its sin and cos are scalar libm calls (8-14 ns).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass
from types import ModuleType
from typing import NoReturn, Protocol

import numpy as np
import numpy.typing as npt

from folder_line.core.limits import CRANK_SPEED, LINEAR_SPEED
from folder_line.core.mechanisms.layup_angles import (
    _PI,
    TAU,
    _reduce_chunk,
    classify_fourbar,
    reduce_angle,
)
from folder_line.core.mechanisms.layup_state import _ROWS, AssemblyMargins, LayupPoint, LayupState
from folder_line.core.numerics.dyad import DyadLinks, F, heron, heron_into, joint, joint_into
from folder_line.core.numerics.loop import TOGGLE_TOL
from folder_line.core.numerics.roots import golden_section
from folder_line.core.numerics.validate import as_float, check_fields, non_negative, positive
from folder_line.errors import AssemblyError, ParameterError

__all__ = [
    'LOOP1',
    'LOOP2',
    'LayupModel',
    'LayupParams',
    'cached_model',
    'check_assembly',
    'layup_kinematics',
    'layup_point',
]

#: mechanism names used in AssemblyError
LOOP1 = 'layup loop O1-A-B-O2'
LOOP2 = 'layup loop O2-C-E-O3'
#: crank angles sampled per turn by check_assembly before refinement
ASSEMBLY_SAMPLES = 4096
#: angles per chunk in LayupModel.arrays (keeps the scratch arrays in L2 cache)
CHUNK = 16384


def _belt_speed(key: str, value: object) -> float:
    """The check of ``v_tr``: 0 (chutes without belts) or a linear speed in range."""
    return 0.0 if non_negative(key, value) == 0.0 else LINEAR_SPEED.check(key, value)


@dataclass(frozen=True)
class LayupParams:
    """Validated dimensions and speeds of the layup six-bar (defaults: ``config/layup.yaml``).

    Parameters
    ----------
    R_kr : float
        Crank radius O1A, m (> 0).
    n_kr : float
        Crank speed, rev/min (> 0; counter-clockwise in the project frame).
    a, b : float
        Position of the crank pivot O1 relative to O2, m (any finite values).
    l2 : float
        Rod AB, m (> 0).
    O2B : float
        Rod attachment B on transporter 3, distance from its pivot O2, m (> 0).
    l3 : float
        Transporter 3 (chute) O2C, exit C, m (> 0).
    l4 : float
        Coupler CE, m (> 0).
    l5 : float
        Transporter 4 (chute) O3E, exit E, m (> 0).
    O2O3 : float
        Distance between the chute pivots, m (> 0).
    v_tr : float
        Belt speed along the chutes, m/s (>= 0).

    Raises
    ------
    ParameterError
        A value is not a finite number or out of range, or loop O1-A-B-O2 is not a
        Grashof crank-rocker with the crank the shortest link (the message names the
        keys and gives the classification; the Grashof boundary is a change point).
    AssemblyError
        A loop cannot be assembled, or passes a toggle, somewhere in a crank turn
        (see :func:`check_assembly`); the message gives the crank angle.
    """

    R_kr: float
    n_kr: float
    a: float
    b: float
    l2: float
    O2B: float
    l3: float
    l4: float
    l5: float
    O2O3: float
    v_tr: float

    def __post_init__(self) -> None:
        check_fields(
            self,
            'layup',
            R_kr=positive,
            n_kr=CRANK_SPEED.check,
            a=as_float,
            b=as_float,
            **dict.fromkeys(('l2', 'O2B', 'l3', 'l4', 'l5', 'O2O3'), positive),
            v_tr=_belt_speed,
        )
        ground = math.hypot(self.a, self.b)
        kind = classify_fourbar(ground, self.R_kr, self.l2, self.O2B)
        if kind != 'crank-rocker':
            links = {'R_kr': self.R_kr, '|O1O2|=hypot(a,b)': ground, 'l2': self.l2, 'O2B': self.O2B}
            srt = sorted(links.values())
            detail = f'shortest + longest = {srt[0] + srt[3]:.12g} m vs the other two = {srt[1] + srt[2]:.12g} m'
            if kind == 'change-point':
                why = 'is on the Grashof boundary (a change-point linkage that can flip branch)'
            elif kind == 'non-Grashof':
                why = 'is non-Grashof (a triple rocker: the crank cannot turn fully)'
            else:
                why = f'is a {kind}'
            msg = (
                f'loop O1-A-B-O2 {why}; {detail}; it must be a Grashof crank-rocker '
                f'(crank R_kr the shortest link, s + l < p + q)'
            )
            raise ParameterError('layup.R_kr,a,b,l2,O2B', links, msg)
        check_assembly(self)

    @property
    def omega(self) -> float:
        """Crank angular velocity ``2π n_kr / 60``, rad/s."""
        return TAU * self.n_kr / 60.0


class _PointFn(Protocol):
    """Signature of :attr:`LayupModel.point`."""

    def __call__(self, phi: float, omega: float | None = None) -> LayupPoint: ...


class LayupModel:
    """Prepared layup kinematics: constants computed once, scalar and vectorised paths.

    Parameters
    ----------
    params : LayupParams
        Validated parameters. (Any object with the same attributes is accepted; an
        unvalidated one may raise :class:`AssemblyError` from the evaluations.)

    Notes
    -----
    With ``d² = |A - O2|²``, loop 1 gives ``B = k1 A + k2 A⊥`` where
    ``k1 = 1/2 + (O2B² - l2²) / (2 d²)``, ``k2 = S1 / (2 d²)``,
    ``S1 = sqrt(((O2B + l2)² - d²) (d² - (O2B - l2)²)) = 2 (A × B)``; loop 2 likewise
    about O3 with ``C - O3``, ``l5`` and ``l4``.
    """

    #: the scalar path, ``point(phi, omega=None) -> LayupPoint`` (a closure over the constants)
    point: _PointFn

    def __init__(self, params: LayupParams) -> None:
        self.params = params
        p = params
        self._R = p.R_kr
        self._a = p.a
        self._b = p.b
        self._omega = TAU * p.n_kr / 60.0
        self._p = p.O2B
        self._l2 = p.l2
        self._r3 = p.l3 / p.O2B
        self._l3 = p.l3
        self._l4 = p.l4
        self._l5 = p.l5
        self._d0 = p.O2O3
        self._vt2 = p.v_tr * p.v_tr
        self._loop1 = DyadLinks(p.O2B, p.l2)  # about O2: B from A
        self._loop2 = DyadLinks(p.l5, p.l4)  # about O3: E from C
        self.point = self._make_point()

    # ------------------------------------------------------------------ scalar path
    def _make_point(self) -> _PointFn:
        R, a, b, w_default = self._R, self._a, self._b, self._omega
        loop1, loop2 = self._loop1, self._loop2
        r3, l3, l5, d0, vt2 = self._r3, self._l3, self._l5, self._d0, self._vt2
        cos, sin, sqrt, atan2 = math.cos, math.sin, math.sqrt, math.atan2
        fail = self._fail_scalar
        Point = LayupPoint
        lo, hi = -_PI, _PI

        def dyad(px: float, py: float, links: DyadLinks, phi: float, loop: int) -> tuple[float, float, float]:
            # the joint relative to the loop's pivot, and S (the dyad kernel, class notes)
            d2 = px * px + py * py
            e = heron(d2, links.plus2, links.minus2)
            if not e > 0.0:
                fail(phi, loop)
            sq = sqrt(e)
            x, y = joint(px, py, d2, sq, links.half_diff)
            return x, y, sq

        def point(phi: float, omega: float | None = None) -> LayupPoint:
            """Kinematics at one crank angle, pure ``math`` (a few µs).

            Parameters
            ----------
            phi : float
                Crank angle, rad (reduced with :func:`reduce_angle`).
            omega : float, optional
                Crank angular velocity, rad/s; default ``params.omega``.

            Returns
            -------
            LayupPoint

            Raises
            ------
            AssemblyError
                Only for unvalidated parameters: a loop fails at ``phi``.
            """
            if not lo <= phi <= hi:
                phi = reduce_angle(phi)
            w = w_default if omega is None else omega
            c = cos(phi)
            s = sin(phi)
            ax = a + R * c
            ay = b + R * s
            bx, by, s1 = dyad(ax, ay, loop1, phi, 1)
            w3 = 2.0 * w * R * ((by - ay) * c - (bx - ax) * s) / s1
            cx = r3 * bx
            cy = r3 * by
            dx = cx - d0
            wx, wy, s2 = dyad(dx, cy, loop2, phi, 2)
            w5 = 2.0 * w3 * ((wy - cy) * cx - (wx - dx) * cy) / s2
            vc = w3 * l3
            ve = w5 * l5
            return Point(
                cx,
                cy,
                wx + d0,
                wy,
                atan2(by, bx),
                atan2(wy, wx),
                w3,
                w5,
                vc,
                ve,
                sqrt(vc * vc + vt2),
                sqrt(ve * ve + vt2),
            )

        return point

    def discriminants_scalar(self, phi: float) -> tuple[float, float]:
        """Normalised discriminants (sin² of the transmission angles) of both loops at one angle.

        Parameters
        ----------
        phi : float
            Crank angle, rad.

        Returns
        -------
        D1, D2 : float
            Loop O1-A-B-O2 and loop O2-C-E-O3; ``< 0`` where a loop does not close.
            Where loop 1 does not close, D2 is evaluated with B at the tangent point.
        """
        return self._discriminants(math, max, reduce_angle(phi))

    def discriminants(self, phi: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Vectorised :meth:`discriminants_scalar`.

        Parameters
        ----------
        phi : array_like
            Crank angles, rad.

        Returns
        -------
        D1, D2 : ndarray
            Normalised discriminants of loops 1 and 2, shape of ``phi``.
        """
        return self._discriminants(np, np.maximum, reduce_angle(np.asarray(phi, dtype=float)))

    def _discriminants(self, xp: ModuleType, maximum: Callable[[F, float], F], phi: F) -> tuple[F, F]:
        """Both loops' normalised discriminants with the namespace ``xp`` (``math`` for a float,
        ``numpy`` for an array; ``maximum`` its elementwise max) at reduced crank angle(s)."""
        loop1, loop2 = self._loop1, self._loop2
        ax = self._a + self._R * xp.cos(phi)
        ay = self._b + self._R * xp.sin(phi)
        d2 = ax * ax + ay * ay
        e1 = heron(d2, loop1.plus2, loop1.minus2)
        bx, by = joint(ax, ay, d2, xp.sqrt(maximum(e1, 0.0)), loop1.half_diff)
        cx = self._r3 * bx
        cy = self._r3 * by
        dx = cx - self._d0
        e2 = dx * dx + cy * cy
        f2 = heron(e2, loop2.plus2, loop2.minus2)
        return e1 * loop1.norm * loop1.norm, f2 * loop2.norm * loop2.norm

    def _fail_scalar(self, phi: float, loop: int) -> NoReturn:
        d1, d2 = self.discriminants_scalar(phi)
        if loop == 1:
            raise AssemblyError(LOOP1, phi, _disc_reason(d1))
        raise AssemblyError(LOOP2, phi, _disc_reason(d2))

    # ------------------------------------------------------------- vectorised path
    def arrays(
        self, phi: npt.ArrayLike, *, omega: float | None = None, alpha: float = 0.0, accelerations: bool = True
    ) -> LayupState:
        """Kinematics at many crank angles.

        Parameters
        ----------
        phi : array_like
            Crank angles, rad, any shape (reduced with :func:`reduce_angle`).
        omega : float, optional
            Crank angular velocity, rad/s; default ``params.omega``.
        alpha : float, optional
            Crank angular acceleration, rad/s² (enters ε3, ε5 only); default 0.
        accelerations : bool, optional
            Compute ``eps3``, ``eps5`` (else they are None; about 30 % faster).

        Returns
        -------
        LayupState
            Arrays of the shape of ``phi``.

        Raises
        ------
        AssemblyError
            Only for unvalidated parameters: names the first crank angle (C order)
            where a loop fails.
        ParameterError
            A crank angle is NaN or infinite.
        """
        phi_in = np.asarray(phi, dtype=float)
        shape = phi_in.shape
        flat = phi_in.reshape(-1)
        n = flat.size
        w = self._omega if omega is None else float(omega)
        nrows = 20 if accelerations else 18
        out = np.empty((nrows, n))
        m = min(CHUNK, max(n, 1))
        scratch = np.empty((9, m))
        mask = np.empty(m, dtype=bool)
        for start in range(0, n, CHUNK):
            stop = min(start + CHUNK, n)
            ph = flat[start:stop]
            if not (ph.min() >= -_PI and ph.max() <= _PI):
                ph = _reduce_chunk(ph, scratch[8, : stop - start], mask[: stop - start])
            self._kernel(ph, out[:, start:stop], scratch[:8, : stop - start], w, flat[start:stop])
            if accelerations:
                self._accel(out[:, start:stop], w, float(alpha))
        rows = {name: out[i].reshape(shape) for i, name in enumerate(_ROWS[:nrows])}
        if not accelerations:
            rows['eps3'] = rows['eps5'] = None
        return LayupState(phi=phi_in, **rows)

    def _kernel(self, ph: np.ndarray, o: np.ndarray, t: np.ndarray, w: float, phi_given: np.ndarray) -> None:
        """Positions and velocities for one chunk, in place: 78 ufunc passes and 2 reductions."""
        mul, add, sub, div, sqrt = np.multiply, np.add, np.subtract, np.divide, np.sqrt
        xA, yA, xB, yB, xC, yC, xE, yE, th3, th5, w3, w5, vC, vE, vaC, vaE, mg1, mg2 = o[:18]
        T, G, S, Cc, U, V, W, Z = t
        # cos, sin from t = tan(phi/2): cos = 2/(1+t²) - 1, sin = t·2/(1+t²) (phi in [-π, π])
        mul(ph, 0.5, out=T)
        np.tan(T, out=T)
        mul(T, T, out=G)
        add(G, 1.0, out=G)
        div(2.0, G, out=G)
        mul(T, G, out=S)
        sub(G, 1.0, out=Cc)
        # crank pin A
        mul(Cc, self._R, out=xA)
        add(xA, self._a, out=xA)
        mul(S, self._R, out=yA)
        add(yA, self._b, out=yA)
        # loop 1 about O2: G = S1 = sqrt(((p+l2)² - d²)(d² - (p-l2)²))
        self._dyad(1, xA, yA, xB, yB, mg1, G, T, U, V, phi_given)
        # omega3 = 2 ω R ((B - A) · (cos, sin)⊥) / S1
        _cross_over(w3, xB, yB, xA, yA, Cc, S, G, U, V)
        mul(w3, 2.0 * w * self._R, out=w3)
        np.arctan2(yB, xB, out=th3)
        mul(xB, self._r3, out=xC)
        mul(yB, self._r3, out=yC)
        # loop 2 about O3: U = C - O3 (x), V = S2; (xE, yE) = E - O3
        sub(xC, self._d0, out=U)
        self._dyad(2, U, yC, xE, yE, mg2, V, T, W, T, phi_given)
        np.arctan2(yE, xE, out=th5)
        # omega5 = 2 ω3 ((E - C) · C⊥) / S2 (x of E and C still relative to O3)
        _cross_over(w5, xE, yE, U, yC, xC, yC, V, W, Z)
        mul(w5, 2.0, out=w5)
        mul(w5, w3, out=w5)
        add(xE, self._d0, out=xE)
        mul(w3, self._l3, out=vC)
        mul(w5, self._l5, out=vE)
        mul(vC, vC, out=vaC)
        add(vaC, self._vt2, out=vaC)
        sqrt(vaC, out=vaC)
        mul(vE, vE, out=vaE)
        add(vaE, self._vt2, out=vaE)
        sqrt(vaE, out=vaE)

    def _dyad(
        self,
        loop: int,
        px: np.ndarray,
        py: np.ndarray,
        ox: np.ndarray,
        oy: np.ndarray,
        mg: np.ndarray,
        S: np.ndarray,
        D: np.ndarray,
        K1: np.ndarray,
        K2: np.ndarray,
        phi_given: np.ndarray,
    ) -> None:
        """Joint of loop ``loop`` for one chunk, in place, with the dyad kernel (:mod:`..numerics.dyad`).

        ``(px, py)`` is the moving centre P (A, or C - O3) relative to the loop's pivot. On
        return ``(ox, oy)`` is the joint (B, or E - O3) relative to the pivot, ``S`` the root
        of Heron's discriminant (S1, S2) and ``mg`` the toggle margin. ``D``, ``K1`` and ``K2``
        are scratch; ``K2`` may be ``D``.
        """
        links = self._loop1 if loop == 1 else self._loop2
        heron_into(px, py, links.plus2, links.minus2, D, S, K1)
        if not S.min() > 0.0:
            self._fail_array(phi_given, S, loop)
        np.sqrt(S, out=S)
        np.multiply(S, links.norm, out=mg)
        joint_into(px, py, D, S, links.half_diff, ox, oy, K1, K2)

    def _accel(self, o: np.ndarray, w: float, alpha: float) -> None:
        """ε3, ε5 for one chunk from the twice-differentiated loop equations."""
        xA, yA, xB, yB, xC, yC, xE, yE, _, _, w3, w5 = o[:12]
        mg1, mg2 = o[16], o[17]
        a, b = self._a, self._b
        # loop 1: ε3 (A × B) = ω3² (B - A)·B + (B - A)·Ä - |dB/dt - dA/dt|²,
        # Ä = α R (-sin, cos) - ω² R (cos, sin),  A × B = S1/2 = margin1 · O2B · l2
        rc = xA - a  # R cos
        rs = yA - b  # R sin
        ux = xB - xA
        uy = yB - yA
        bdotu = xB * ux + yB * uy
        acc_dot = alpha * (uy * rc - ux * rs) - w * w * (ux * rc + uy * rs)
        rvx = -w3 * yB + w * rs  # dB/dt - dA/dt
        rvy = w3 * xB - w * rc
        num = w3 * w3 * bdotu + acc_dot - (rvx * rvx + rvy * rvy)
        e3 = o[18]
        np.divide(num, mg1 * (self._p * self._l2), out=e3)
        # loop 2: ε5 ((C - O3) × (E - O3)) = ω5² (E - C)·(E - O3) + (E - C)·C̈ - |dE/dt - dC/dt|²,
        # C̈ = ε3 C⊥ - ω3² C
        wx = xE - self._d0
        wy = yE
        ux = xE - xC
        uy = yE - yC
        cddot = e3 * (uy * xC - ux * yC) - w3 * w3 * (ux * xC + uy * yC)
        rvx = -w5 * wy + w3 * yC  # dE/dt - dC/dt
        rvy = w5 * wx - w3 * xC
        num = w5 * w5 * (ux * wx + uy * wy) + cddot - (rvx * rvx + rvy * rvy)
        np.divide(num, mg2 * (self._l4 * self._l5), out=o[19])

    def _fail_array(self, phi_given: np.ndarray, e: np.ndarray, loop: int) -> None:
        i = int(np.flatnonzero(~(e > 0.0))[0])
        self._fail_scalar(float(phi_given[i]), loop)


def _cross_over(
    out: np.ndarray,
    xX: np.ndarray,
    yX: np.ndarray,
    xP: np.ndarray,
    yP: np.ndarray,
    dx: np.ndarray,
    dy: np.ndarray,
    S: np.ndarray,
    t1: np.ndarray,
    t2: np.ndarray,
) -> None:
    """``out = ((X - P) · d⊥) / S = ((yX - yP) dx - (xX - xP) dy) / S``, in place (``t1``, ``t2`` scratch):
    a dyad's output rate per unit input rate, up to the factor 2 and the input link's length."""
    np.subtract(yX, yP, out=t1)
    np.multiply(t1, dx, out=t1)
    np.subtract(xX, xP, out=t2)
    np.multiply(t2, dy, out=t2)
    np.subtract(t1, t2, out=out)
    np.divide(out, S, out=out)


def _disc_reason(d: float) -> str:
    if d < -TOGGLE_TOL:
        return f'the circles do not meet (normalised discriminant {d:.3g} < 0)'
    return (
        f'the loop is at a toggle (transmission angle {math.asin(math.sqrt(max(d, 0.0))):.3g} rad, '
        f'normalised discriminant {d:.3g} <= {TOGGLE_TOL:g}): the linkage locks there'
    )


def _crossing_reason(dmin: float, phimin: float) -> str:
    return (
        f'the circles stop meeting here: the normalised discriminant changes sign '
        f'(turning forward; it falls to {dmin:.3g} near phi={phimin % TAU:.6g} rad)'
    )


def _first_crossing(f: Callable[[float], float], lo: float, hi: float) -> float:
    """Bisect ``f(lo) >= 0 > f(hi)`` down to adjacent floats or 1e-13 rad; first failing angle."""
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if hi - lo <= 1e-13 or mid in (lo, hi):
            break
        if f(mid) >= 0.0:
            lo = mid
        else:
            hi = mid
    return hi


def check_assembly(params: LayupParams, n: int = ASSEMBLY_SAMPLES) -> AssemblyMargins:
    """Check that both loops close, away from toggles, over a whole crank turn.

    ``n`` equally spaced crank angles in [0, 2π) are evaluated; a sign change of a
    loop's normalised discriminant is refined by bisection to about 1e-13 rad, and
    every sampled local minimum of it by a golden-section search, so a failure
    between samples is found too.

    Parameters
    ----------
    params : LayupParams
        The parameters (called by ``LayupParams.__post_init__``).
    n : int, optional
        Samples per turn.

    Returns
    -------
    AssemblyMargins
        Smallest toggle margin of each loop and where it occurs.

    Raises
    ------
    AssemblyError
        Names the loop and the first crank angle in [0, 2π) (turning forward) where
        it stops closing (the discriminant changes sign there), or where it reaches
        a toggle (normalised discriminant <= ``TOGGLE_TOL``: it would lock). Loop
        O1-A-B-O2 is checked first.
    """
    model = LayupModel(params)
    phis = np.arange(n) * (TAU / n)
    with np.errstate(over='ignore', invalid='ignore', divide='ignore'):  # a non-finite one is refused below
        discs = model.discriminants(phis)
    result: list[float] = []
    for k, name in enumerate((LOOP1, LOOP2)):
        D = discs[k]

        def f(x: float, k: int = k) -> float:
            return model.discriminants_scalar(x)[k]

        if not np.all(np.isfinite(D)):  # a length so extreme (~1e154 m and up, ~1e-154 m down) the arithmetic fails
            bad = float(D[~np.isfinite(D)][0])
            links = ('R_kr', 'a', 'b', 'l2', 'O2B') if k == 0 else ('l3', 'l4', 'l5', 'O2O3')
            given = ', '.join(f'layup.{f}={getattr(params, f):g}' for f in links)
            raise AssemblyError(
                name, 0.0, f'cannot be computed: its normalised discriminant is {bad}, a link too extreme ({given})'
            )
        neg = D < 0.0
        if neg.all():
            raise AssemblyError(
                name, 0.0, f'cannot be assembled at any crank angle (largest normalised discriminant {D.max():.3g} < 0)'
            )
        if not neg.any():
            # refine the sampled local minima (at most the 4 lowest)
            lows = np.flatnonzero((np.roll(D, 1) >= D) & (np.roll(D, -1) >= D))
            lows = lows[np.argsort(D[lows])][:4]
            best_i, best_phi, best = int(lows[0]), float(phis[lows[0]]), float(D[lows[0]])
            for low in lows:
                x, fx = golden_section(f, float(phis[low]) - TAU / n, float(phis[low]) + TAU / n, maxiter=60).best
                if fx < best:
                    best_i, best_phi, best = int(low), x, fx
            if best < 0.0:
                # a failure between samples: it starts after the sample before the minimum
                lo = float(phis[best_i]) - TAU / n
                crossing = _first_crossing(f, lo, best_phi)
                raise AssemblyError(name, float(np.remainder(crossing, TAU)), _crossing_reason(best, best_phi))
            if best <= TOGGLE_TOL:
                raise AssemblyError(name, float(np.remainder(best_phi, TAU)), _disc_reason(best))
            result += [math.sqrt(best), float(np.remainder(best_phi, TAU))]
            continue
        entries = np.flatnonzero(neg & ~np.roll(neg, 1))
        i = int(entries[0])
        lo = float(phis[i - 1]) - (TAU if i == 0 else 0.0)
        crossing = _first_crossing(f, lo, float(phis[i]))
        j = int(np.argmin(D))
        raise AssemblyError(name, float(np.remainder(crossing, TAU)), _crossing_reason(float(D[j]), float(phis[j])))
    return AssemblyMargins(*result)


@functools.lru_cache(maxsize=32)
def cached_model(params: LayupParams) -> LayupModel:
    """The :class:`LayupModel` of ``params``, cached (the 32 most recent parameter sets)."""
    return LayupModel(params)


def layup_kinematics(
    params: LayupParams,
    phi: npt.ArrayLike,
    *,
    omega: float | None = None,
    alpha: float = 0.0,
    accelerations: bool = True,
) -> LayupState:
    """Vectorised kinematics; see :meth:`LayupModel.arrays` (same arguments, model cached).

    Parameters
    ----------
    params : LayupParams
        Validated parameters.
    phi : array_like
        Crank angles, rad.
    omega : float, optional
        Crank angular velocity, rad/s; default ``params.omega``.
    alpha : float, optional
        Crank angular acceleration, rad/s².
    accelerations : bool, optional
        Compute ε3, ε5.

    Returns
    -------
    LayupState
    """
    return cached_model(params).arrays(phi, omega=omega, alpha=alpha, accelerations=accelerations)


def layup_point(params: LayupParams, phi: float) -> LayupPoint:
    """Scalar kinematics at one crank angle; see :meth:`LayupModel.point`.

    For per-tick use keep a :class:`LayupModel` and call its ``point`` (no cache lookup).

    Parameters
    ----------
    params : LayupParams
        Validated parameters.
    phi : float
        Crank angle, rad.

    Returns
    -------
    LayupPoint
    """
    return cached_model(params).point(phi)
