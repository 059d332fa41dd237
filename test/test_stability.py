"""Stability suite: every hard numerical case of the stability issue, proven in one place.

One section per bullet of the issue:

1. dead centres and toggles of every linkage at +-1e-12 rad; Grashof and change-point
   geometries; branch tracking across delta3 = 90 deg;
2. the delivery transporter at alpha_m -> 90 deg, K_v -> 0, eta -> 0;
3. 1e9 crank turns and line times of 1e7 s (exact rational references);
4. motor start-up from standstill (stiff), tiny (1e-9 s) and huge (1 s) steps;
5. grazing events (a touch is detected once or not at all, never twice);
6. random scenes within the documented parameter ranges.

References are independent of the code under test wherever possible: mpmath at
40 digits re-implements the loop closures and the knife, ``fractions.Fraction`` does
the long-time arithmetic exactly (pi to 50 digits where the crank angle enters), and
the motor and RK4 have closed forms. pytest.ini turns RuntimeWarning into errors, so
every test here also proves "no numpy warning".
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from fractions import Fraction
from typing import Any

import mpmath as mp
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from folder_line.config.params import config_dir, load_params, read_yaml_mapping
from folder_line.config.scenes import load_scene
from folder_line.core.effects import motor_dynamics as md
from folder_line.core.line.events import event_kind
from folder_line.core.line.model import MAX_DURATION, LineModel, simulate
from folder_line.core.line.scene import parse_scene
from folder_line.core.mechanisms import delivery as dlv
from folder_line.core.mechanisms import knife as knf
from folder_line.core.mechanisms.cyclogram import cycle_timing
from folder_line.core.mechanisms.drive import Command
from folder_line.core.mechanisms.layup import (
    LOOP1,
    TAU,
    LayupModel,
    LayupParams,
    classify_fourbar,
    swing_extremes,
)
from folder_line.core.numerics import loop
from folder_line.core.numerics.roots import find_sign_changes
from folder_line.core.numerics.timebase import ShaftClock
from folder_line.errors import AssemblyError, IntegrationError, ParameterError
from folder_line.interfaces import NS_PER_S

EPS = float(np.finfo(float).eps)
DELTAS = (-1e-12, 1e-12)
LAYUP = load_params('layup')
KNIFE = load_params('knife')
#: pi to 50 digits, for exact-rational references of angles
PI_50 = Fraction('3.14159265358979323846264338327950288419716939937510')


def ulp(x: float) -> float:
    """Unit in the last place of ``x``."""
    return math.ulp(abs(x))


# =========================================================================== 1. linkages
# ---- independent mpmath models (40 digits) ---------------------------------------------


def mp_circle(x0: Any, y0: Any, r0: Any, x1: Any, y1: Any, r1: Any, branch: int) -> tuple[Any, Any]:
    """Circle-circle intersection left (+1) or right (-1) of c0 -> c1, in mpmath."""
    dx, dy = x1 - x0, y1 - y0
    d2 = dx * dx + dy * dy
    along = mp.mpf(1) / 2 + (r0 * r0 - r1 * r1) / (2 * d2)
    across = mp.sqrt(r0 * r0 / d2 - along * along) * branch
    return x0 + along * dx - across * dy, y0 + along * dy + across * dx


def mp_sixbar(p: LayupParams, phi: Any) -> dict[str, Any]:
    """L six-bar at crank angle ``phi`` (mpmath), from MACHINES.md's definitions."""
    R, a, b, l2, q, l3, l4, l5, d0 = (mp.mpf(v) for v in (p.R_kr, p.a, p.b, p.l2, p.O2B, p.l3, p.l4, p.l5, p.O2O3))
    ax, ay = a + R * mp.cos(phi), b + R * mp.sin(phi)
    bx, by = mp_circle(0, 0, q, ax, ay, l2, 1)
    cx, cy = bx * l3 / q, by * l3 / q
    ex, ey = mp_circle(d0, 0, l5, cx, cy, l4, 1)
    return {'theta3': mp.atan2(cy, cx), 'theta5': mp.atan2(ey, ex - d0), 'C': (cx, cy), 'E': (ex, ey)}


def mp_rate(f: Callable[[Any], Any], x: float, order: int = 1) -> float:
    """d^order f / dphi^order at the float ``x`` (taken exactly), 40 digits."""
    with mp.workdps(40):
        return float(mp.diff(f, mp.mpf(x), order))


def crank_turns_fully(ground: float, crank: float, coupler: float, rocker: float) -> bool:
    """The input link turns fully: the dyad (coupler, rocker) closes at every |A - O2| in
    [|ground - crank|, ground + crank] (exact rational arithmetic on the float lengths)."""
    g, c, cl, r = (Fraction(x) for x in (ground, crank, coupler, rocker))
    return g + c <= cl + r and abs(g - c) >= abs(cl - r)


class TestDeadCentresAndToggles:
    """Bullet 1: toggles/dead centres at +-1e-12 rad, Grashof/change points, delta3 = 90 deg."""

    # ---- L six-bar: the rocker dead centres (swing extremes), both loops ----------------
    @pytest.mark.parametrize('which', [0, 1])
    def test_sixbar_swing_extremes(self, which: int) -> None:
        """At the closed-form dead centres O1, A, B are collinear: omega3 = omega5 = 0.

        Exact references: the dead-centre angle is the mpmath root of d(theta3)/dphi;
        omega3, omega5 at phi_e +- 1e-12 are mpmath derivatives of the mpmath loop
        closure at the same float angles; eps3 likewise (second derivative).
        """
        model = LayupModel(LAYUP)
        w = LAYUP.omega
        ext = swing_extremes(LAYUP)[which]
        with mp.workdps(40):

            def th3(x: Any) -> Any:
                return mp_sixbar(LAYUP, x)['theta3']

            def th5(x: Any) -> Any:
                return mp_sixbar(LAYUP, x)['theta5']

            root = mp.findroot(lambda x: mp.diff(th3, x), mp.mpf(ext.phi))
            assert abs(float(root) - ext.phi) <= 4 * EPS  # the closed form is exact to rounding (of O(1) terms)
            slope3 = float(mp.diff(th3, root, 2)) * w  # d(omega3)/dphi at the dead centre, rad/s per rad
        pts = {d: model.point(ext.phi + d) for d in (*DELTAS, 0.0)}
        arr = model.arrays(np.array([ext.phi + d for d in (*DELTAS, 0.0)]))
        for pt in pts.values():
            assert all(math.isfinite(v) for v in pt)
        assert np.all(np.isfinite(np.stack([arr.eps3, arr.eps5])))
        for d in DELTAS:
            x = ext.phi + d
            w3, w5 = pts[d].omega3, pts[d].omega5
            w3_ref, w5_ref = mp_rate(th3, x) * w, mp_rate(th5, x) * w
            with mp.workdps(40):
                off = float(mp.mpf(x) - root)  # d, up to the 4.5e-17 of phi_e
            # magnitude ~ |slope| 1e-12 and the sign of slope * d: a smooth sign change through 0
            assert math.copysign(1.0, w3) == math.copysign(1.0, slope3 * d) == math.copysign(1.0, w3_ref)
            assert abs(w3_ref - slope3 * off) <= 1e-6 * abs(slope3 * d)  # the reference is linear here
            assert abs(w3 - w3_ref) <= 1e-14  # absolute rounding of omega3
            assert abs(w3 - w3_ref) <= 1e-3 * abs(w3_ref)  # i.e. 0.1 % of a 1e-12-size value
            assert abs(w5 - w5_ref) <= 1e-14 and math.copysign(1.0, w5) == math.copysign(1.0, w5_ref)
            # positions continuous: the exits move by O(d^2) at a dead centre
            assert math.hypot(pts[d].xC - pts[0.0].xC, pts[d].yC - pts[0.0].yC) <= 1e-15
            assert math.hypot(pts[d].xE - pts[0.0].xE, pts[d].yE - pts[0.0].yE) <= 1e-15
        # accelerations finite, continuous across, and equal to the mpmath second derivative
        eps_ref = mp_rate(th3, ext.phi, 2) * w * w
        assert np.allclose(arr.eps3, eps_ref, rtol=1e-9, atol=0.0)
        assert abs(float(arr.eps3[0]) - float(arr.eps3[1])) <= 1e-9 * abs(eps_ref)

    def test_sixbar_chute4_has_no_dead_centre_of_its_own(self) -> None:
        """omega5 = 2 omega3 (E-C).C_perp / S2 vanishes only with omega3 on the defaults (O2, C, E never
        in line): so the dead centres of both loops are the two swing extremes tested above."""
        model = LayupModel(LAYUP)
        phi = np.linspace(0.0, TAU, 20001)
        s = model.arrays(phi, accelerations=False)
        ratio = s.omega5 / np.where(s.omega3 == 0.0, 1.0, s.omega3)
        assert ratio.min() > 0.5  # omega5 / omega3 bounded away from 0: no extra turning point of chute 4

    def test_sixbar_toggle_geometry_is_rejected_and_finite_just_inside(self) -> None:
        """Loop 1 on the Grashof boundary reaches a toggle (all four links in line) once a turn:
        LayupParams rejects it (ParameterError naming the lengths); the raw model is finite at
        phi_t - 1e-12 and +1e-12, or raises the documented AssemblyError naming phi, never NaN."""
        base = dataclasses.asdict(LAYUP)
        ground = math.hypot(LAYUP.a, LAYUP.b)
        # ground longest: toggle where |A - O2| = ground + R_kr = l2 + O2B (crank pointing away from O2)
        over = {**base, 'l2': ground + LAYUP.R_kr - LAYUP.O2B}
        assert classify_fourbar(ground, LAYUP.R_kr, over['l2'], LAYUP.O2B) == 'change-point'
        with pytest.raises(ParameterError, match='Grashof boundary') as info:
            LayupParams(**over)
        assert info.value.key == 'layup.R_kr,a,b,l2,O2B'
        raw = LayupModel(type('Raw', (), over)())  # unvalidated: the model itself must stay finite or raise
        phi_t = math.atan2(LAYUP.b, LAYUP.a)  # A farthest from O2
        for d in (-1e-12, 1e-12, 0.0, -1e-9, 1e-9, -1e-6, 1e-6):
            d1, d2 = raw.discriminants_scalar(phi_t + d)
            assert math.isfinite(d1) and math.isfinite(d2)
            assert -16 * EPS <= d1 <= 2 * d * d + 16 * EPS  # loop 1 touches its toggle: D1 ~ c d^2 >= 0
            try:
                pt = raw.point(phi_t + d)
            except AssemblyError as exc:  # the documented error, naming the loop and the angle
                assert exc.phi == phi_t + d and (exc.mechanism == LOOP1 or d2 < 0.0)
            else:
                assert all(math.isfinite(v) for v in pt)

    # ---- F crank-slider knife: outer and inner dead centres --------------------------------
    @pytest.mark.parametrize('e', [0.0, 0.012, -0.02])
    @pytest.mark.parametrize('which', ['outer', 'inner'])
    def test_knife_dead_centres(self, e: float, which: str) -> None:
        """v changes sign through 0 with slope omega s''(phi_dc) (mpmath), a finite and continuous."""
        p = knf.KnifeParams(r_k=0.04, L_k=0.16, e=e, n_k=50000.0, s_clear=0.1656)
        dc = knf.dead_centres(p)
        phi0 = dc.phi_outer if which == 'outer' else dc.phi_inner
        with mp.workdps(40):
            r, L, ee = mp.mpf(p.r_k), mp.mpf(p.L_k), mp.mpf(e)

            def s(x: Any) -> Any:
                return r * mp.cos(x) + mp.sqrt(L * L - (r * mp.sin(x) - ee) ** 2)

            exact = mp.asin(ee / (L + r)) if which == 'outer' else mp.pi + mp.asin(ee / (L - r))
            assert abs(float(exact) - phi0) <= ulp(phi0)
            s2 = float(mp.diff(s, exact, 2))
            s3 = float(mp.diff(s, exact, 3))
        w = p.omega_k
        assert (s2 < 0) == (which == 'outer')  # a maximum of s at the outer, a minimum at the inner dead centre
        for d in DELTAS:
            st = knf.state(p, phi0 + d)
            assert all(math.isfinite(float(v)) for v in (st.s, st.v, st.a))
            with mp.workdps(40):
                off = float(mp.mpf(phi0 + d) - exact)  # d as represented, from the exact centre
            v_ref = w * (s2 * off + 0.5 * s3 * off * off)
            assert math.copysign(1.0, st.v) == math.copysign(1.0, s2 * d)
            assert abs(st.v - v_ref) <= 4 * EPS * w * p.r_k + 1e-6 * abs(v_ref)
            assert abs(st.s - (dc.s_max if which == 'outer' else dc.s_min)) <= 4 * ulp(p.L_k)
            assert abs(st.a - w * w * s2) <= 1e-9 * abs(w * w * s2)

    # ---- the four-bar of core/loop.py -------------------------------------------------------
    @staticmethod
    def fourbar(
        phi: np.ndarray, d: float, R: float, coupler: float, q: float, w: float = 1.0, tol: float = loop.TOGGLE_TOL
    ) -> tuple[loop.Intersection, np.ndarray, np.ndarray]:
        """Crank O1 = 0 (radius R, speed w), rocker pivot O2 = (d, 0) (radius q), coupler of length ``coupler``:
        B = circle(O2, q) x circle(A, coupler) on branch +1; velocity and acceleration of B."""
        ax, ay = R * np.cos(phi), R * np.sin(phi)
        vx, vy = -w * ay, w * ax
        accx, accy = -w * w * ax, -w * w * ay
        it = loop.circle_intersection(d, 0.0, q, ax, ay, coupler, 1, inputs=phi, tol=tol, mechanism='four-bar')
        zero = np.zeros_like(phi)
        vb = np.array(loop.circle_point_velocity(it.x, it.y, ax, ay, vx, vy, d, 0.0, zero, zero))
        ab = np.array(
            loop.circle_point_acceleration(
                it.x, it.y, vb[0], vb[1], ax, ay, vx, vy, accx, accy, d, 0.0, zero, zero, zero, zero
            )
        )
        return it, vb, ab

    @staticmethod
    def mp_fourbar_B(phi: Any, d: float, R: float, coupler: float, q: float) -> tuple[Any, Any]:
        Rm = mp.mpf(R)
        return mp_circle(mp.mpf(d), 0, mp.mpf(q), Rm * mp.cos(phi), Rm * mp.sin(phi), mp.mpf(coupler), 1)

    def test_fourbar_rocker_dead_centres(self) -> None:
        """Crank-rocker (0.3, 0.9, 0.7 on ground 1.0): v_B changes sign at the collinear positions,
        with |v_B| = |dv_B/dphi| 1e-12 (mpmath), a_B finite and continuous."""
        d, R, coupler, q = 1.0, 0.3, 0.9, 0.7
        assert classify_fourbar(d, R, coupler, q) == 'crank-rocker'
        scan = np.linspace(0.0, TAU, 4001)
        it0, vb, _ = self.fourbar(scan, d, R, coupler, q)
        speed = (it0.x - d) * vb[1] - it0.y * vb[0]  # (B - O2) x v_B: the rocker's angular velocity * q^2
        flips = np.flatnonzero(np.sign(speed[:-1]) != np.sign(speed[1:]))
        assert len(flips) == 2
        with mp.workdps(40):

            def cross(x: Any) -> Any:  # (A - O1) x (B - A): 0 where O1, A, B are in line
                bx, by = self.mp_fourbar_B(x, d, R, coupler, q)
                ax, ay = R * mp.cos(x), R * mp.sin(x)
                return ax * (by - ay) - ay * (bx - ax)

            for i in flips:
                phi0 = float(mp.findroot(cross, mp.mpf(float(scan[i]))))

                def bx(x: Any) -> Any:
                    return self.mp_fourbar_B(x, d, R, coupler, q)[0]

                def by(x: Any) -> Any:
                    return self.mp_fourbar_B(x, d, R, coupler, q)[1]

                slope = math.hypot(mp_rate(bx, phi0, 2), mp_rate(by, phi0, 2))  # |dv_B/dphi| there, m/rad
                assert abs(mp_rate(bx, phi0)) < 1e-14 and abs(mp_rate(by, phi0)) < 1e-14
                phis = np.array([phi0 - 1e-12, phi0 + 1e-12])
                it, v, a = self.fourbar(phis, d, R, coupler, q)
                assert np.all(np.isfinite(v)) and np.all(np.isfinite(a)) and not it.toggle.any()
                ref = np.array([[mp_rate(bx, x) for x in phis], [mp_rate(by, x) for x in phis]])
                assert np.abs(v - ref).max() <= 1e-15
                assert np.allclose(np.hypot(*v), slope * 1e-12, rtol=1e-2, atol=0.0)
                assert np.all(np.sign(v[:, 0]) == -np.sign(v[:, 1]))  # each component reverses
                assert np.abs(a[:, 0] - a[:, 1]).max() <= 1e-9 * np.abs(a).max()

    def test_fourbar_toggle_limit_position(self) -> None:
        """Non-Grashof (0.8, 0.5, 0.6 on 1.0): the crank's limit where coupler and rocker line up.
        Just inside: finite, |v_B| ~ delta^-1/2 (mpmath); just past within the toggle tolerance: the
        tangent point, flagged; further: AssemblyError naming the crank angle."""
        d, R, coupler, q = 1.0, 0.8, 0.5, 0.6
        assert classify_fourbar(d, R, coupler, q) == 'non-Grashof'
        with mp.workdps(40):
            phi_l = mp.acos((d * d + R * R - (coupler + q) ** 2) / (2 * d * R))  # |A - O2| = coupler + q
        x_l = float(phi_l)
        speeds = {}
        for dl in (1e-12, 4e-12):
            phi = x_l - dl
            it, v, a = self.fourbar(np.array([phi]), d, R, coupler, q)
            assert np.all(np.isfinite(v)) and np.all(np.isfinite(a))
            with mp.workdps(40):
                ref = math.hypot(
                    mp_rate(lambda x: self.mp_fourbar_B(x, d, R, coupler, q)[0], phi),
                    mp_rate(lambda x: self.mp_fourbar_B(x, d, R, coupler, q)[1], phi),
                )
                true_dl = float(phi_l - mp.mpf(phi))
            speed = math.hypot(float(v[0, 0]), float(v[1, 0]))
            assert abs(speed - ref) <= 1e-3 * ref
            speeds[dl] = speed * math.sqrt(true_dl)
        assert speeds[1e-12] == pytest.approx(speeds[4e-12], rel=1e-3)  # |v| sqrt(delta) constant
        past = x_l + 1e-12  # position only: the velocity is unbounded at a toggle (documented)
        it = loop.circle_intersection(d, 0.0, q, R * math.cos(past), R * math.sin(past), coupler, 1, inputs=past)
        x, y = float(it.x), float(it.y)
        assert bool(it.toggle) and math.isfinite(x) and math.isfinite(y) and float(it.disc) < 0.0
        miss = abs(math.hypot(x - d, y) - q) + abs(math.hypot(x - R * math.cos(past), y - R * math.sin(past)) - coupler)
        assert miss <= 1e-11
        with pytest.raises(AssemblyError) as info:
            self.fourbar(np.array([x_l - 0.1, x_l + 1e-6]), d, R, coupler, q)
        assert info.value.phi == x_l + 1e-6 and 'four-bar' in str(info.value)

    # ---- Grashof classification and change points -------------------------------------------
    @settings(max_examples=60, deadline=None, derandomize=True)
    @given(
        links=st.lists(st.integers(1, 2**20), min_size=3, max_size=3),
        order=st.permutations(range(4)),
        rel=st.sampled_from([0.0, 1e-13, -1e-13, 1e-9, -1e-9]),
    )
    def test_change_point_geometries(self, links: list[int], order: list[int], rel: float) -> None:
        """s + l = p + q exactly (dyadic lengths, exact sums) is 'change-point' whichever link is ground
        or input, and so is 1e-13 off (inside GRASHOF_REL_TOL). 1e-9 off it is a proper class that
        agrees with the geometry (exact arithmetic): the input link turns fully iff 'crank-rocker' or
        'double-crank'; a longest link made longer is 'non-Grashof'."""
        a, b, c = sorted(links)
        four = [a * 2.0**-20, b * 2.0**-20, c * 2.0**-20, (b + c - a) * 2.0**-20]  # s + l = p + q
        four[3] *= 1.0 + rel
        g = [four[i] for i in order]
        kind = classify_fourbar(*g)
        if abs(rel) < 1e-12:
            assert kind == 'change-point'
            return
        assert kind != 'change-point'
        assert crank_turns_fully(*g) == (kind in ('crank-rocker', 'double-crank'))
        if rel > 0:
            assert kind == 'non-Grashof'

    def test_change_point_fourbar_is_never_nan(self) -> None:
        """A change-point four-bar (0.4, 0.9, 0.5 on 1.0) turns fully but lines up at phi = pi:
        around it the positions are finite, continuous and flagged as a toggle; LayupParams of a
        change-point loop 1 is rejected (tested above)."""
        d, R, coupler, q = 1.0, 0.4, 0.9, 0.5
        assert classify_fourbar(d, R, coupler, q) == 'change-point'
        phis = math.pi + np.array([-1e-6, -1e-12, 0.0, 1e-12, 1e-6])
        it = loop.circle_intersection(d, 0.0, q, R * np.cos(phis), R * np.sin(phis), coupler, 1, inputs=phis)
        assert np.isfinite(it.x).all() and np.isfinite(it.y).all() and np.isfinite(it.disc).all()
        assert it.toggle[1:4].all()
        assert np.abs(np.diff(it.x[1:4])).max() <= 1e-11 and np.abs(np.diff(it.y[1:4])).max() <= 1e-11
        # the normalised discriminant touches 0 quadratically: ~ c (phi - pi)^2
        assert abs(it.disc[0]) < 1e-11 and abs(it.disc[1]) < 1e-20

    # ---- delta3 = 90 deg ------------------------------------------------------------------
    def test_branch_tracking_across_delta3_90(self) -> None:
        """Where the paper switches root (delta3 = 90 deg) the loop closure has no choice to make:
        E is continuous to O(step) on every scale from 1e-3 down to 1e-12 rad."""
        model = LayupModel(LAYUP)

        def d3(phi: float) -> float:  # angle at C between C->O2 and C->E, deg
            pt = model.point(phi)
            ux, uy, vx, vy = -pt.xC, -pt.yC, pt.xE - pt.xC, pt.yE - pt.yC
            return math.degrees(math.atan2(abs(ux * vy - uy * vx), ux * vx + uy * vy))

        grid = np.linspace(0.0, TAU, 3601)
        vals = np.array([d3(x) for x in grid]) - 90.0
        sc = find_sign_changes(lambda x: d3(x) - 90.0, grid, values=vals, xtol=1e-15)
        assert len(sc) == 2
        vmax = float(np.abs(model.arrays(grid, accelerations=False).vE).max()) / LAYUP.omega  # |dE/dphi|, m/rad
        for phi_s in sc.x:
            for h in (1e-3, 1e-6, 1e-9, 1e-12):
                a, b = model.point(phi_s - h), model.point(phi_s + h)
                assert math.hypot(a.xE - b.xE, a.yE - b.yE) <= 2 * h * vmax * (1 + 1e-9) + 4 * EPS
                assert abs(a.omega5 - b.omega5) <= 2 * h * 10.0 + 1e-13  # |d omega5/dphi| < 10 rad/s per rad
            # and it is the mpmath loop closure's E (the one root of the unsquared equations)
            with mp.workdps(40):
                ref = mp_sixbar(LAYUP, mp.mpf(float(phi_s)))['E']
            pt = model.point(float(phi_s))
            assert abs(pt.xE - float(ref[0])) <= 1e-15 and abs(pt.yE - float(ref[1])) <= 1e-15


# =========================================================================== 2. delivery
def delivery(**over: Any) -> dlv.DeliveryParams:
    base = dataclasses.asdict(load_params('delivery'))
    base.update(over)
    return dlv.DeliveryParams(**base)


FRICTIONLESS = {key: 0.0 for key in ('f_Ap', 'f_Bp', 'f_A', 'f_B', 'f_O', 'r_A', 'r_B', 'r_O')}
STROKE = np.concatenate([np.linspace(0.0, 2.0, 4001), [1.0 - 1e-15, 1.0 + 1e-15, 2.0 - 1e-12]])


def all_finite(s: dlv.DeliverySamples) -> bool:
    return all(np.all(np.isfinite(getattr(s, f.name))) for f in dataclasses.fields(s))


def non_ok_zeroed(s: dlv.DeliverySamples) -> bool:
    bad = s.state != dlv.STATE_OK
    return all(
        np.all(getattr(s, n)[bad] == 0.0)
        for n in ('eta', 'eta_A', 'eta_B', 'p_AB', 'p_ch', 'm_1', 'p_AB_ideal', 'p_ch_ideal', 'm_1_ideal')
    )


class TestDeliveryLimits:
    """Bullet 2: alpha_m -> 90 deg, K_v -> 0, eta -> 0: states, never NaN/inf, no warnings."""

    @pytest.mark.parametrize('alpha_m', [89.9999, 90.0 - 1e-9, math.nextafter(90.0, 0.0)])
    @pytest.mark.parametrize('friction', [True, False])
    def test_alpha_m_to_90(self, alpha_m: float, friction: bool) -> None:
        """Near psi = 1 the rod stands almost across the guide: self_locking (geometric or by
        friction), everything finite; where the model still holds, 1/cos(alpha) matches mpmath
        (to the 1e-4 that the rounding of sin(alpha_m) next to 1 allows)."""
        p = delivery(alpha_m_deg=alpha_m, **({} if friction else FRICTIONLESS))
        for mode in dlv.RETURN_SECTIONS:
            s = dlv.evaluate_stroke(p, STROKE, return_section=mode)
            assert all_finite(s) and non_ok_zeroed(s)
            end = np.abs(s.u - 1.0) < 1e-12  # psi = 1: alpha = alpha_m
            assert np.all(s.state[end] == dlv.STATE_SELF_LOCKING) or not friction and alpha_m == 89.9999
            ok = s.state == dlv.STATE_OK
            assert ok.any()  # most of the stroke still works
            with mp.workdps(40):
                sa = mp.sin(mp.radians(mp.mpf(alpha_m)))
                cos_ref = np.array([float(mp.sqrt(1 - (mp.mpf(float(x)) * sa) ** 2)) for x in s.psi[ok]])
            assert np.allclose(s.p_AB_ideal[ok] * cos_ref, 1.0, rtol=1e-4, atol=0.0)
            for u in (1.0, 0.999999, 1.5):  # the scalar path agrees on the state
                assert dlv.evaluate_stroke_point(p, u, return_section=mode).state == int(
                    dlv.evaluate_stroke(p, [u], return_section=mode).state[0]
                )
        if not friction and alpha_m == 89.9999:  # cos(alpha_m) = 1.7e-6 > COS_ALPHA_TOL: ok, force ~ 5.7e5 P_k
            pt = dlv.evaluate_point(p, 1.0)
            assert pt.state == dlv.STATE_OK and pt.p_AB == pytest.approx(
                1.0 / math.cos(math.radians(alpha_m)), rel=1e-4
            )
        with pytest.raises(ParameterError, match='alpha_m_deg'):
            delivery(alpha_m_deg=90.0)

    @staticmethod
    def kv_touch() -> tuple[float, float, float]:
        """(alpha_m, Lambda*, xi*) with min K_v = 0 on the geometric return (mpmath): there
        tan(alpha) tan|beta| = 1, i.e. Lambda* = 1 / max_xi(tan(alpha) psi'(xi))."""
        alpha_m = 60.0
        with mp.workdps(40):
            sm = mp.sin(mp.radians(alpha_m))

            def g(xi: Any) -> Any:  # tan(alpha) psi' for the sinusoidal law
                psi = xi - mp.sin(2 * mp.pi * xi) / (2 * mp.pi)
                sa = psi * sm
                return sa / mp.sqrt(1 - sa * sa) * (1 - mp.cos(2 * mp.pi * xi))

            xi = mp.findroot(lambda x: mp.diff(g, x), mp.mpf('0.67'))  # the maximum, near 0.67
            return alpha_m, float(1 / g(xi)), float(xi)

    @pytest.mark.parametrize('rel', [0.0, 1e-12, -1e-12, 1e-6, -1e-6])
    def test_kv_to_zero(self, rel: float) -> None:
        """K_v touches 0 at Lambda*: kv_zero there (|K_v| < 1e-9), carriage_reversed past it,
        forces and efficiencies 0 in those states, all finite, no warnings."""
        alpha_m, lam, xi = self.kv_touch()
        p = delivery(alpha_m_deg=alpha_m, Lambda=lam * (1.0 + rel))
        u_star = 2.0 - xi  # on the return section
        pt = dlv.evaluate_stroke_point(p, u_star)
        # K_v(xi*) = cos(beta) (1 - tan(alpha) tan|beta|) ~ -rel cos(beta) near the touch
        assert abs(pt.K_v + rel * math.cos(pt.beta)) <= 1e-6 * abs(rel) + 1e-13
        if abs(pt.K_v) < dlv.KV_TOL:
            expect = dlv.STATE_KV_ZERO
        elif pt.K_v < 0.0:
            expect = dlv.STATE_CARRIAGE_REVERSED
        else:  # eq. (3): eta_B = 1 - f_Bp |tan a| - f_B r_B |sin b| / (K_v cos^2 a) <= 0 locks by friction
            ca = math.cos(pt.alpha)
            eta_b = 1.0 - p.f_Bp * math.tan(pt.alpha) - p.f_B * p.r_B * abs(math.sin(pt.beta)) / (pt.K_v * ca * ca)
            expect = dlv.STATE_SELF_LOCKING if eta_b <= 0.0 else dlv.STATE_OK
        assert pt.state == expect
        if rel == 0.0:
            assert pt.state == dlv.STATE_KV_ZERO
        u = np.concatenate([STROKE, u_star + np.linspace(-1e-4, 1e-4, 201)])
        s = dlv.evaluate_stroke(p, u)
        assert all_finite(s) and non_ok_zeroed(s)
        reversed_ = s.state == dlv.STATE_CARRIAGE_REVERSED
        assert reversed_.any() == (rel > 1e-9)
        assert np.all(s.K_v[reversed_] <= -dlv.KV_TOL)

    @pytest.mark.parametrize('margin', [1e-6, 1e-11, 1e-13, 0.0, -1e-6])
    def test_eta_to_zero(self, margin: float) -> None:
        """Only pair B's sliding friction: eta = 1 - f_Bp tan(alpha), 0 at psi = 1 for
        f_Bp = (1 - margin) / tan(alpha_m). eta <= ETA_TOL is self_locking; above, the forces
        grow like 1/eta but stay finite."""
        alpha_m = 60.0
        f_bp = (1.0 - margin) / math.tan(math.radians(alpha_m))
        p = delivery(alpha_m_deg=alpha_m, **{**FRICTIONLESS, 'f_Bp': f_bp})
        pt = dlv.evaluate_point(p, 1.0)
        with mp.workdps(40):
            eta_ref = float(1 - mp.mpf(f_bp) * mp.tan(mp.radians(mp.mpf(alpha_m))))
        if eta_ref > dlv.ETA_TOL * 2:
            assert pt.state == dlv.STATE_OK
            assert pt.eta == pytest.approx(eta_ref, rel=1e-15 / eta_ref + 1e-12)
            assert pt.p_AB == pytest.approx(
                1.0 / (math.cos(math.radians(alpha_m)) * eta_ref), rel=1e-15 / eta_ref + 1e-12
            )
        elif eta_ref < dlv.ETA_TOL / 2:
            assert pt.state == dlv.STATE_SELF_LOCKING and pt.eta == 0.0 and pt.p_AB == 0.0
        s = dlv.evaluate(p, np.linspace(0.0, 1.0, 2001))
        assert all_finite(s) and non_ok_zeroed(s)
        assert np.all((s.eta >= 0.0) & (s.eta <= 1.0))


# =========================================================================== 3. long runs
def exact_frac_turns(t: float, rev_per_s: Fraction) -> Fraction:
    """Fractional crank turn at the float time ``t`` (taken exactly), exact."""
    x = Fraction(t) * rev_per_s
    return x - math.floor(x)


def angle_diff(a: float, b: float) -> float:
    """|a - b| modulo 2 pi, rad."""
    return abs(math.remainder(a - b, TAU))


class TestLongRuns:
    """Bullet 3: 1e9 crank turns and line times of 1e7 s without drift (exact references)."""

    @settings(max_examples=60, deadline=None, derandomize=True)
    @given(
        num=st.integers(1, 10**6),
        den=st.integers(1, 10**4),
        turns=st.integers(0, 10**9),
        extra_ns=st.integers(0, 10**9),
        phase0=st.fractions(0, 1, max_denominator=10**6),
    )
    def test_shaft_clock_after_a_billion_turns_is_exact(
        self, num: int, den: int, turns: int, extra_ns: int, phase0: Fraction
    ) -> None:
        speed = Fraction(num, den)  # rev/s
        clock = ShaftClock(speed, phase0=phase0)
        t_ns = int(turns / speed * NS_PER_S) + extra_ns  # ~1e9 turns and beyond
        whole, frac = clock.turns(t_ns)
        exact = Fraction(t_ns, NS_PER_S) * speed + phase0 % 1
        assert whole == math.floor(exact)
        assert abs(Fraction(frac) - (exact - whole)) <= Fraction(1, 2**53)  # only the final float rounding
        # and the time of a turn at 1e9 turns is the nearest nanosecond
        t_back = clock.time_of_turn(turns, 0.25)
        assert abs(Fraction(t_back) - (turns + Fraction(0.25) - phase0 % 1) / speed * NS_PER_S) <= Fraction(1, 2)

    def test_knife_float_path_at_a_billion_turns(self) -> None:
        """knife.state_at_time computes phi = omega_k t afresh (no accumulation): at 1e9 turns
        (t = 7.2e7 s) its phase error is a few ulp of phi, i.e. ~1e-8 s, 1.5e-16 of t."""
        T = Fraction(3600) / Fraction(KNIFE.n_k)
        for t in (1e7 + 0.0123, 7.2e7 + 0.0123, float(10**9 * T + Fraction(1, 50))):
            st_ = knf.state_at_time(KNIFE, t)
            with mp.workdps(50):
                frac = exact_frac_turns(t, Fraction(KNIFE.n_k) / 3600)
                phi_ref = float(2 * mp.pi * mp.mpf(frac.numerator) / frac.denominator)
            dphi = angle_diff(float(st_.phi), phi_ref)
            assert dphi <= 8 * ulp(float(st_.phi))
            assert dphi / KNIFE.omega_k <= 1e-15 * t  # 6 orders inside 1e-9 relative
            slope = abs(st_.v) / KNIFE.omega_k  # |ds/dphi|, m/rad
            assert st_.s == pytest.approx(
                knf.position(KNIFE, phi_ref), abs=1.01 * slope * dphi + 0.05 * dphi**2 + 1e-15
            )

    def test_layup_line_at_ten_million_seconds(self) -> None:
        """LineModel to 1e7 + 100 s (leaves every 99991 s, crank at 31 rev/min so no exact cycle):
        leaf_enter and leaf_exit times equal the exact rational sums to a few ulp(t) (~ns), the
        exit speed is the model's at the exact crank phase, and joint samples near 1e7 s equal those
        at the equivalent time of the first crank turn."""
        over = {'sheets.interval': 99991.0, 'sheets.jitter': 0.0, 'sheets.phase': 0.123456789, 'layup.n_kr': 31.0}
        scene = load_scene('layup', over)
        horizon = 1e7 + 100.0
        model = LineModel(scene, horizon)
        ev = model.events
        rate = Fraction(31, 60)  # crank turns per s
        ent = ev[ev['kind'] == event_kind('leaf_enter')]
        ext = ev[ev['kind'] == event_kind('leaf_exit')]
        assert ent['t'].max() > 9.9e6 and ext['t'].max() > 9.9e6
        exact_in = {int(j): Fraction(0.123456789) + int(j) * Fraction(99991.0) for j in ent['sheet']}
        for row in ent:
            assert abs(Fraction(float(row['t'])) - exact_in[int(row['sheet'])]) <= 2 * ulp(row['t'])
        lp = scene.machine('layup')
        lm = LayupModel(lp)
        for row in ext[-6:]:
            j = int(row['sheet'])
            length = lp.l5 if j % 2 else lp.l3
            t_exact = exact_in[j] + Fraction(length) / Fraction(lp.v_tr)
            err = abs(Fraction(float(row['t'])) - t_exact)
            assert err <= 4 * ulp(row['t']) and err <= 1e-9 * row['t']
            frac = exact_frac_turns(float(row['t']), rate)
            pt = lm.point(float(TAU * frac))
            v_perp = pt.vE if j % 2 else pt.vC
            assert row['value'] == pytest.approx(math.hypot(v_perp, lp.v_tr), abs=1e-8)
        # joint samples at ~1e7 s against the equivalent time in the first crank turn
        t_big = np.array([1e7 + 0.25, 1e7 + 1.3, 9999999.99, 1e7 + 37.123])
        period = 1 / rate
        t_small = np.array([float(Fraction(t) - math.floor(Fraction(t) * rate) * period) for t in t_big])
        assert np.all(t_small < float(period))
        big, small = model.sample('drive', t_big), model.sample('drive', t_small)
        w_max = np.abs(big.velocity).max()
        for k in range(t_big.size):
            frac = exact_frac_turns(float(t_big[k]), rate)
            assert angle_diff(float(big.position[k, 0]), float(TAU * frac)) <= 1e-8
            for jnt in range(big.position.shape[1]):
                assert angle_diff(float(big.position[k, jnt]), float(small.position[k, jnt])) <= 1e-8 * w_max
                assert abs(big.velocity[k, jnt] - small.velocity[k, jnt]) <= 1e-7 * w_max
        with pytest.raises(ParameterError, match='horizon'):
            LineModel(scene, MAX_DURATION * 1.5)

    def test_folder_line_at_ten_million_seconds(self) -> None:
        """The folder (a 7 rev/h knife: T = 514 s, 19444 cycles in 1e7 s -- the 50000 rev/h knife
        would need 1.39e8 cycles of event arrays, see the report) at 1e7 s: knife, hand-over and
        at-stops times equal the exact rational kinematics (pi to 50 digits) to a few ns."""
        scene = load_scene('folder', {'knife.n_k': 7.0})
        model = LineModel(scene, 1e7 + 600.0)
        ev = model.events
        kp = scene.machine('knife')
        tm = cycle_timing(scene.machine('cyclogram'), kp)
        kw = knf.window(kp)
        T = Fraction(3600) / Fraction(kp.n_k)  # s per crank turn, exact
        to_time = T / (2 * PI_50)  # s per rad of crank angle
        t_in, t_out = Fraction(kw.phi_in) * to_time, Fraction(kw.phi_out) * to_time
        feed = Fraction(tm.L_feed) / Fraction(scene.machine('feed_transporter').V_tr)
        checks = {
            'knife_contact': lambda k: (k + 1) * T + t_in,
            'knife_exit': lambda k: (k + 1) * T + t_out,
            'sheet_handover': lambda k: k * T + t_out + Fraction(scene.sheets.phase),
            'at_stops': lambda k: k * T + t_out + Fraction(scene.sheets.phase) + feed,
        }
        for kind, exact in checks.items():
            rows = ev[ev['kind'] == event_kind(kind)][-5:]
            assert rows.size == 5 and rows['t'].min() > 9.99e6
            for row in rows:
                err = abs(Fraction(float(row['t'])) - exact(int(row['cycle'])))
                assert err <= 8e-9 and err <= 1e-9 * row['t'], (kind, float(err))
        t_big = np.array([1e7 + 0.5, 1e7 + 123.456])
        t_small = np.array([float(Fraction(t) - math.floor(Fraction(t) / T) * T) for t in t_big])
        big, small = model.sample('drive', t_big), model.sample('drive', t_small)
        for k in range(t_big.size):
            frac = exact_frac_turns(float(t_big[k]), 1 / T)
            assert angle_diff(float(big.position[k, 0]), float(2 * PI_50 * frac)) <= 1e-9
            assert angle_diff(float(big.position[k, 0]), float(small.position[k, 0])) <= 1e-9
            assert abs(big.position[k, 1] - small.position[k, 1]) <= 1e-11  # knife s, m
            assert abs(big.velocity[k, 1] - small.velocity[k, 1]) <= 1e-12

    def test_default_folder_restarted_after_a_hold_to_ten_million_seconds(self) -> None:
        """The 50000 rev/h folder held from t = 1 s to 1e7 - 5 s and restarted: the events after the
        restart sit where the exact piecewise-linear drive puts them, to a few ulp(1e7 s)."""
        scene = load_scene('folder')
        t_u = 1e7 - 5.0
        model = LineModel(scene, 1e7 + 10.0, [Command(1.0, 'hold'), Command(t_u, 'unhold')])
        kp = scene.machine('knife')
        kw = knf.window(kp)
        T = Fraction(3600) / Fraction(kp.n_k)
        t_in = Fraction(kw.phi_in) * T / (2 * PI_50)
        tb, tu = Fraction(scene.drive.t_brake), Fraction(scene.drive.t_restart)
        theta_held = 1 + tb / 2  # Theta when the hold has stopped the drive

        def time_of(theta: Fraction) -> Fraction:  # after the restart
            d = theta - theta_held
            assert d > tu / 2  # past the ramp: lambda = 1
            return Fraction(t_u) + tu + (d - tu / 2)

        rows = model.events[model.events['kind'] == event_kind('knife_contact')]
        late = rows[rows['t'] > t_u]
        assert late.size > 100
        for row in late[-20:]:
            err = abs(Fraction(float(row['t'])) - time_of((int(row['cycle']) + 1) * T + t_in))
            assert err <= 2 * ulp(1e7)


# =========================================================================== 4. motor
MOTOR: dict[str, Any] = {
    'J': 0.5,
    'T_0': 264.6,
    'omega_0': 157.08,
    'omega_nom': 152.4,
    'b': 0.03,
    'method': 'dopri5',
    'h': 0.01,
    'rtol': 1e-10,
    'atol': 1e-12,
    't_stop': 1e9,
    'T_brake': 0.0,
}
#: tau = J / (T_0 / omega_0) = 1e-4 s: a stiff start
STIFF: dict[str, Any] = {'J': 0.001, 'T_0': 1600.0, 'omega_0': 160.0, 'omega_nom': 152.4, 'b': 0.0}


def motor_scene(**over: Any) -> Any:
    """The layup machine (cheapest) with motor_dynamics only: no position-dependent load."""
    return parse_scene(
        {
            'name': 'motor',
            'machines': {'layup': dataclasses.asdict(LAYUP)},
            'sheets': {'interval': 0.0625, 'jitter': 0.0, 'phase': 0.0, 'thickness': 0.0005},
            'effects': {'motor_dynamics': {**MOTOR, **over}},
        }
    )


def closed_form(p: dict[str, Any], t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Theta(t), omega(t) of J w' = T_0 (1 - w/w_0) - b w from standstill."""
    c = p['T_0'] / p['omega_0'] + p['b']
    tau = p['J'] / c
    w_ss = p['T_0'] / c
    return w_ss / p['omega_nom'] * (t + tau * np.expm1(-t / tau)), -w_ss * np.expm1(-t / tau)


def rk4_factor(z: float) -> float:
    """RK4's amplification of the error on y' = -(1/tau) y per step, z = h / tau."""
    return 1 - z + z * z / 2 - z**3 / 6 + z**4 / 24


class TestMotor:
    """Bullet 4: stiff start from standstill; tiny and huge steps."""

    @pytest.mark.parametrize('z', [2.21, 2.2, 0.5])
    def test_rk4_stiff_start_up_to_the_step_limit(self, z: float) -> None:
        """tau = 1e-4 s, h = z tau with z up to the accepted limit 2.21: the step values are exactly
        w_ss (1 - R(z)^n) (RK4 on a linear ODE), so they rise monotonically to w_ss (R in (0, 1))
        and reach lambda_ss; never NaN, never beyond w_ss; the cubic Hermite dense output between
        the steps is monotone and >= 0. Beyond 2.21 (RK4 is stable to 2.785, but the dense output
        overshoots from z* = 2.2134: omega < 0 in the first step from z ~ 2.65) build_drive refuses h."""
        p = {**MOTOR, **STIFF}
        tau = p['J'] / (p['T_0'] / p['omega_0'])
        h = z * tau
        n = 400
        drive = md.build_drive(motor_scene(**STIFF, method='rk4', h=h), n * h, periodic=False)
        sol = drive.segments[0].solution
        w = sol.y[:, 1]
        w_ss = p['T_0'] / (p['T_0'] / p['omega_0'])
        R = rk4_factor(z)
        assert 0.0 < R < 1.0
        k = np.arange(w.size)
        assert np.allclose(w, w_ss * (1.0 - R**k), rtol=0.0, atol=64 * EPS * w_ss)
        assert np.all(np.diff(w) >= -4 * EPS * w_ss) and np.all(np.isfinite(sol.y))  # rounding at w_ss only
        assert drive.rate(np.array(n * h))[()] == pytest.approx(w_ss / p['omega_nom'], rel=1e-9)  # no stall
        t = np.linspace(0.0, n * h, 40001)
        dense = drive.omega(t)
        assert np.all(np.isfinite(dense)) and dense.max() <= w_ss * (1 + 1e-12)
        assert dense.min() >= 0.0 and np.all(np.diff(dense) >= -4 * EPS * w_ss)
        with pytest.raises(ParameterError, match='effects.motor_dynamics.h.*stalls and overshoots'):
            md.build_drive(motor_scene(**STIFF, method='rk4', h=2.25 * tau), 0.01)
        with pytest.raises(ParameterError, match='effects.motor_dynamics.h.*unstable here'):
            md.build_drive(motor_scene(**STIFF, method='rk4', h=2.8 * tau), 0.01)

    def test_dopri5_stiff_start(self) -> None:
        """DOPRI5 from standstill with tau = 1e-4 s: stability-limited steps (~h = 3.3 tau, neither
        blown up nor stalled), within 2e-7 of w_ss of the closed form, monotone up to its tolerance."""
        p = {**MOTOR, **STIFF, 'rtol': 1e-8, 'atol': 1e-10}
        duration = 0.5
        drive = md.build_drive(motor_scene(**STIFF, rtol=1e-8, atol=1e-10), duration, periodic=False)
        t = np.linspace(0.0, duration, 100001)
        th, w = closed_form(p, t)
        w_ss = w[-1]
        got = drive.omega(t)
        assert np.all(np.isfinite(got)) and np.all(np.isfinite(drive.theta(t)))
        assert np.abs(got - w).max() <= 2e-8 * w_ss
        assert np.abs(drive.theta(t) - th).max() <= 1e-9
        assert duration / (3.4 * 1e-4) < drive.steps < duration / (2.0 * 1e-4)
        assert (np.maximum.accumulate(got) - got).max() <= 10 * (p['rtol'] * w_ss + p['atol'])
        assert got[-1] / p['omega_nom'] == pytest.approx(w_ss / p['omega_nom'], rel=2e-8)

    def test_tiny_steps(self) -> None:
        """h = 1e-9 s: over 1e-5 s (1e4 steps) RK4 is exact to rounding; over 1 s the run needs 1e9
        steps and fails at once with the documented max-steps IntegrationError (not after minutes)."""
        drive = md.build_drive(motor_scene(method='rk4', h=1e-9), 1e-5, periodic=False)
        t = np.linspace(0.0, 1e-5, 101)
        th, w = closed_form(MOTOR, t)
        assert drive.steps == 10_000
        assert np.abs(drive.omega(t) - w).max() <= 1e-15 * MOTOR['omega_0']
        assert np.abs(drive.theta(t) - th).max() <= 1e-18
        with pytest.raises(IntegrationError) as info:
            md.build_drive(motor_scene(method='rk4', h=1e-9), 1.0, periodic=False)
        msg = str(info.value)
        assert f'more than max_steps={md.MAX_STEPS} steps' in msg and '1e+09 steps of h' in msg
        assert info.value.step == 0 and info.value.h == 1e-9
        with pytest.raises(IntegrationError, match='max_steps'):
            md.build_drive(motor_scene(method='dopri5', h=1e-9), 1.0, periodic=False)

    def test_huge_steps(self) -> None:
        """h = 1 s: RK4 is refused up front (ParameterError naming h) where h c/J > 2.21; on a
        gentle motor it is stable and equals the RK4 recurrence; DOPRI5 with max step 1 s matches
        the closed form to its tolerance."""
        with pytest.raises(ParameterError, match='effects.motor_dynamics.h') as info:
            md.build_drive(motor_scene(method='rk4', h=1.0), 10.0)
        assert 'unstable' in str(info.value) and info.value.value == 1.0
        gentle = {'J': 20.0}
        p = {**MOTOR, **gentle}
        c = p['T_0'] / p['omega_0'] + p['b']
        drive = md.build_drive(motor_scene(**gentle, method='rk4', h=1.0), 60.0, periodic=False)
        w = drive.segments[0].solution.y[:, 1]
        R = rk4_factor(c / p['J'])
        assert np.allclose(w, p['T_0'] / c * (1 - R ** np.arange(w.size)), rtol=0.0, atol=1e-11)
        drive = md.build_drive(motor_scene(method='dopri5', h=1.0), 20.0, periodic=False)
        t = np.linspace(0.0, 20.0, 4001)
        th, w = closed_form(MOTOR, t)
        assert np.diff(drive.segments[0].solution.t).max() <= 1.0
        assert np.abs(drive.omega(t) - w).max() <= 1e-7
        assert np.abs(drive.theta(t) - th).max() <= 1e-9


# =========================================================================== 5. grazing
GRID = np.linspace(0.0, 1.0, 101)


class TestGrazing:
    """Bullet 5: a touch of a threshold is reported once or not at all, never twice."""

    @settings(max_examples=150, deadline=None, derandomize=True)
    @given(
        i=st.integers(0, 100),
        where=st.sampled_from(['on', 'near', 'between']),
        frac=st.floats(-0.5, 0.5),
        c=st.sampled_from([0.0, -1e-15, -1e-300, 1e-30, 1e-26]),
        sign=st.sampled_from([1.0, -1.0]),
    )
    def test_sign_changes_of_a_touch(self, i: int, where: str, frac: float, c: float, sign: float) -> None:
        """f = sign (c - (t - t0)^2): a touch (c = 0), a near miss (c < 0), or two roots closer than
        the root tolerance (c = 1e-30: +-1e-15; 1e-26: +-1e-13) that rounding may split; t0 on a
        sample, within 1e-15 of one, or anywhere between; a touch at a grid end can leave one root
        inside the grid (then once), otherwise none."""
        step = GRID[1] - GRID[0]
        t0 = float(GRID[i]) + {'on': 0.0, 'near': 1e-15 * np.sign(frac), 'between': frac * step}[where]
        sc = find_sign_changes(lambda t: sign * (c - (t - t0) ** 2), GRID)
        inside_end = not (GRID[0] < t0 - 1e-12 and t0 + 1e-12 < GRID[-1])
        assert len(sc) == 0 or (len(sc) == 1 and inside_end)
        # a resolvable double crossing is kept (sanity of the same call): roots +-1e-3 around t0
        if 0.01 < t0 < 0.99:
            two = find_sign_changes(lambda t: sign * (1e-6 - (t - t0) ** 2), GRID)
            if len(two) == 2:  # both roots between samples (not split by a sample landing on one)
                assert np.allclose(two.x, [t0 - 1e-3, t0 + 1e-3], atol=1e-12)
                assert list(two.direction) == ([1, -1] if sign > 0 else [-1, 1])

    @settings(max_examples=100, deadline=None, derandomize=True)
    @given(i=st.integers(1, 99), rel=st.floats(-1e-8, 1e-8), scale=st.sampled_from([1.0, 1e3, 1e-3]))
    def test_a_noisy_touch_with_ftol_is_never_doubled(self, i: int, rel: float, scale: float) -> None:
        """(t - a)^2 evaluated expanded, t^2 - 2at + a^2, has rounding noise ~ eps a^2 around its
        touch, wider (sqrt(eps) a) than the root tolerance. With ftol at that noise level the touch
        is never reported (documented rule 1); without ftol a noise sign change is a real sign
        change of the float function and may come out as a pair (see rule 5 of roots.py)."""
        grid = GRID * scale
        a = float(grid[i]) * (1.0 + rel)

        def f(t: float) -> float:
            return -(t * t - 2.0 * a * t + a * a)

        noise = 4 * EPS * (a * a + 2 * abs(a) * scale + scale * scale)
        assert len(find_sign_changes(f, grid, ftol=noise)) == 0
        raw = find_sign_changes(f, grid)
        assert len(raw) % 2 == 0  # pairs only: both neighbours are below 0
        if len(raw):
            assert abs(raw.x[0] - a) < 1e-7 * scale and abs(raw.x[-1] - a) < 1e-7 * scale

    @settings(max_examples=40, deadline=None, derandomize=True)
    @given(k=st.integers(0, 5), split=st.integers(1, 99))
    def test_stepwise_scan_of_a_touch_on_a_step_boundary(self, k: int, split: int) -> None:
        """Scanning step by step with left_sign, a touch exactly on the shared boundary sample is
        reported in neither step."""
        t0 = float(GRID[split])

        def f(t: float) -> float:
            return -((t - t0) ** 2)

        first = find_sign_changes(f, GRID[: split + 1])
        left = int(np.sign(f(float(GRID[split - 1]))))
        second = find_sign_changes(f, GRID[split:], left_sign=left)
        assert len(first) + len(second) == 0

    @settings(max_examples=25, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
    @given(
        delta=st.one_of(st.sampled_from([0.0, 1e-15, -1e-15, 1e-12, -1e-12]), st.floats(-1e-6, 1e-6)),
        k=st.integers(4, 9),
    )
    def test_sheet_edge_touching_the_stops(self, delta: float, k: int) -> None:
        """The line's front-stop threshold: the supervisor holds the folder so that the drive comes to
        rest with sheet k's edge exactly at the stops (delta = 0: a touch at zero speed), a hair
        short of it (delta < 0: it arrives after the restart) or a hair past it (delta > 0: it
        arrived while braking). Every sheet has at most one at_stops (exactly one if it got there),
        at the drive phase of the stops, with the impact speed of the closed-form ramps; and at
        most one 'settled'."""
        scene = load_scene('folder')
        timing = cycle_timing(scene.machine('cyclogram'), scene.machine('knife'))
        v_tr = scene.machine('feed_transporter').V_tr
        theta_a = k * timing.T + timing.knife.t_out + scene.sheets.phase + timing.L_feed / v_tr
        tb, tu = scene.drive.t_brake, scene.drive.t_restart
        t_hold = theta_a - tb / 2 + delta  # braking covers tb/2 of Theta
        t_unhold = t_hold + tb + 0.25  # stands still for 0.25 s
        model = LineModel(scene, t_unhold + tu + 0.1, [Command(t_hold, 'hold'), Command(t_unhold, 'unhold')])
        ev = model.events
        stops = ev[ev['kind'] == event_kind('at_stops')]
        _, counts = np.unique(stops['sheet'], return_counts=True)
        assert counts.max() == 1
        handed = ev[ev['kind'] == event_kind('sheet_handover')]['sheet']
        assert set(stops['sheet']) <= set(handed)
        settled = ev[ev['kind'] == event_kind('settled')]
        assert np.unique(settled['sheet']).size == settled.size
        row = stops[stops['sheet'] == k]
        assert row.size == 1
        t_a = float(row['t'][0])
        assert float(model.drive.theta(np.array(t_a))) == pytest.approx(theta_a, abs=1e-14)
        lam = float(model.drive.rate(np.array(t_a)))
        assert row['value'][0] == pytest.approx(v_tr * lam, abs=1e-12)
        # closed forms of the ramps (gap = Theta_a - Theta where the drive rests; > 0: short of the stops):
        # reached while braking, lambda = sqrt(-2 gap / tb); after the restart, lambda = sqrt(2 gap / tu)
        gap = theta_a - (t_hold + tb / 2)
        if gap < -1e-13:
            assert t_hold <= t_a <= t_hold + tb
            assert lam == pytest.approx(math.sqrt(-2 * gap / tb), rel=1e-3)
        elif gap > 1e-13:
            assert t_a >= t_unhold
            assert lam == pytest.approx(math.sqrt(2 * gap / tu), rel=1e-3)
        assert 0.0 <= lam <= math.sqrt(2 * abs(gap) / min(tb, tu)) * (1 + 1e-3) + 1e-6


# =========================================================================== 6. random scenes
def _defaults() -> dict[str, dict[str, Any]]:
    out = {sec: dataclasses.asdict(load_params(sec)) for sec in ('layup', 'knife', 'cyclogram', 'delivery')}
    for sec in ('container', 'feed_transporter', 'delivery_chain'):
        out[sec] = read_yaml_mapping(config_dir() / f'{sec}.yaml', sec)
    return out


DEFAULTS = _defaults()
#: documented ranges of the bounded parameters (the dataclasses' validation); the unbounded positive
#: ones are drawn as a factor of the shipped default
FACTOR = st.floats(0.5, 2.0)


@st.composite
def scenes(draw: Callable[..., Any]) -> dict[str, Any]:
    """A scene mapping with every value inside its documented type and range (combinations may
    still be invalid: a non-Grashof loop, a knife level outside the stroke, a feed window < 0 ...)."""
    machines: dict[str, Any] = {}
    has_layup = draw(st.booleans())
    has_folder = draw(st.booleans()) or not has_layup
    effects: dict[str, Any] = {}
    if has_layup:
        lp = {k: v * draw(st.floats(0.7, 1.4)) for k, v in DEFAULTS['layup'].items()}
        lp['n_kr'] = draw(st.floats(5.0, 120.0))
        lp['v_tr'] = draw(st.floats(0.0, 8.0))
        machines['layup'] = lp
        machines['container'] = {
            'x_left': draw(st.floats(-2.0, -0.2)),
            'x_right': draw(st.floats(0.9, 3.0)),
            'y_floor': draw(st.floats(-3.0, -0.9)),
            'bins': draw(st.integers(2, 200)),
        }
        if draw(st.booleans()):
            effects['chute_belts'] = {'v_min': draw(st.floats(0.0, 5.0))}
        elif draw(st.booleans()):
            effects['guide_friction'] = {
                'mu': draw(st.floats(0.0, 2.0)),
                's0': draw(st.floats(0.0, 0.6)),
                'v0': draw(st.floats(0.0, 5.0)),
                'h': draw(st.floats(2e-3, 0.05)),
            }
        if draw(st.booleans()):
            effects['leaf_flight'] = {'drag': draw(st.floats(0.0, 10.0))}
        if draw(st.booleans()):
            effects['leaf_damage'] = {'v_damage': draw(st.floats(0.1, 10.0))}
    if has_folder:
        kd = DEFAULTS['knife']
        r_k = kd['r_k'] * draw(FACTOR)
        e = draw(st.floats(-0.05, 0.05))
        L_k = (r_k + abs(e)) * draw(st.floats(0.95, 6.0))  # may fail L_k > r_k + |e|
        lo = math.sqrt(max((L_k - r_k) ** 2 - e * e, 0.0))
        hi = math.sqrt(max((L_k + r_k) ** 2 - e * e, 0.0))
        machines['knife'] = {
            'r_k': r_k,
            'L_k': L_k,
            'e': e,
            'n_k': draw(st.floats(2e3, 2e5)),
            's_clear': lo + (hi - lo) * draw(st.floats(-0.05, 1.05)),
        }
        cy = {k: v * draw(FACTOR) for k, v in DEFAULTS['cyclogram'].items() if k not in ('reserve', 'dwell_frac')}
        cy['reserve'] = draw(st.floats(0.0, 0.99))
        cy['dwell_frac'] = draw(st.floats(0.0, 0.99))
        machines['cyclogram'] = cy
        machines['feed_transporter'] = {'V_tr': draw(st.floats(0.5, 40.0))}
        if draw(st.booleans()):
            dd = dict(DEFAULTS['delivery'])
            dd.update(
                {
                    'Lambda': draw(st.floats(0.05, 3.0)),
                    'alpha_m_deg': draw(st.floats(1.0, 89.999)),
                    'law': draw(st.sampled_from(dlv.law_names())),
                }
            )
            for key in ('f_Ap', 'f_Bp', 'f_A', 'f_B', 'f_O', 'r_A', 'r_B', 'r_O'):
                dd[key] = draw(st.floats(0.0, 0.4))
            machines['delivery'] = dd
            machines['delivery_chain'] = {
                'x_max': draw(st.floats(0.05, 1.0)),
                'pitch': draw(st.floats(0.2, 3.0)),
                'L_transfer': draw(st.floats(0.0, 2.0)),
            }
            if draw(st.booleans()):
                effects['chain_friction'] = {
                    'P_k': draw(st.floats(0.0, 100.0)),
                    'r': draw(st.floats(0.01, 0.5)),
                    'return_section': draw(st.sampled_from(dlv.RETURN_SECTIONS)),
                }
        if draw(st.booleans()):
            effects['stop_bounce'] = {
                'e': draw(st.floats(0.0, 0.95)),
                'a_f': draw(st.floats(10.0, 2000.0)),
                'tolerance': draw(st.floats(1e-4, 0.01)),
                'v_rest': draw(st.floats(0.01, 1.0)),
            }
        if draw(st.booleans()):
            effects['feed_slip'] = {
                'mu': draw(st.floats(0.05, 2.0)),
                'p': draw(st.floats(0.0, 100.0)),
                'm': draw(st.floats(0.005, 0.1)),
            }
    if draw(st.booleans()):
        effects['faults'] = {
            'p_missing': draw(st.floats(0.0, 1.0)),
            'p_double': draw(st.floats(0.0, 1.0)),
            'p_late': draw(st.floats(0.0, 1.0)),
            'late_delay': draw(st.floats(0.0, 0.05)),
            'p_slowdown': draw(st.floats(0.0, 1.0)),
            'slowdown_factor': draw(st.floats(0.05, 1.0)),
            'slowdown_duration': draw(st.floats(0.0, 0.2)),
        }
    if draw(st.integers(0, 3)) == 0:
        omega_nom = draw(st.floats(50.0, 200.0))
        effects['motor_dynamics'] = {
            'J': draw(st.floats(0.05, 5.0)),
            'T_0': draw(st.floats(20.0, 2000.0)),
            'omega_0': omega_nom * draw(st.floats(1.01, 1.5)),
            'omega_nom': omega_nom,
            'b': draw(st.floats(0.0, 0.1)),
            'method': draw(st.sampled_from(md.METHODS)),
            'h': draw(st.floats(1e-3, 0.05)),
            'rtol': draw(st.floats(1e-10, 1e-4)),
            'atol': draw(st.floats(1e-12, 1e-6)),
            't_stop': draw(st.sampled_from([1e9, 0.1, 0.0])),
            'T_brake': draw(st.floats(0.0, 50.0)),
        }
    profile = draw(st.sampled_from(['constant', 'ramp']))
    return {
        'name': 'random',
        'machines': machines,
        'effects': effects,
        'drive': {'profile': profile, 't_ramp': draw(st.floats(0.01, 1.0)), 't_brake': draw(st.floats(0.01, 1.0))},
        'sheets': {
            'interval': draw(st.floats(0.02, 0.5)),
            'jitter': draw(st.floats(0.0, 0.99)),
            'phase': draw(st.floats(0.0, 0.3)),
            'thickness': draw(st.floats(1e-5, 0.01)),
        },
        'seed': draw(st.integers(0, 2**62)),
        'sample_rate': draw(st.floats(0.0, 400.0)),
    }


def finite_tree(x: Any) -> bool:
    """Every number in a nested summary (dicts, lists) is finite (None allowed)."""
    if isinstance(x, dict):
        return all(finite_tree(v) for v in x.values())
    if isinstance(x, (list, tuple)):
        return all(finite_tree(v) for v in x)
    if isinstance(x, (bool, str)) or x is None:
        return True
    return bool(np.all(np.isfinite(x)))


class TestRandomScenes:
    """Bullet 6: random scenes within the documented ranges: finite outputs or a documented error."""

    @settings(
        max_examples=200,
        deadline=None,
        derandomize=True,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
    )
    @given(data=scenes(), commands=st.sampled_from([(), ((0.1, 'hold'), (0.2, 'unhold'))]))
    def test_random_scene_runs_finite_or_fails_documented(
        self, data: dict[str, Any], commands: tuple[tuple[float, str], ...]
    ) -> None:
        try:
            scene = parse_scene(data)
            res = simulate(scene, 0.3, commands=[Command(t, kind) for t, kind in commands])
        except ParameterError as exc:
            assert exc.key and str(exc).startswith(f'{exc.key}=')  # names the parameter
            return
        except AssemblyError as exc:
            assert exc.mechanism.startswith('layup loop') and math.isfinite(exc.phi)
            assert str(exc).startswith(exc.mechanism)  # names the loop and the angle
            return
        ev = res.events
        assert np.all(np.isfinite(ev['t'])) and np.all(np.isfinite(ev['value']))
        assert np.all((ev['t'] >= 0.0) & (ev['t'] <= 0.3))
        assert np.all(np.diff(ev['t']) >= 0.0)
        for js in res.samples.values():
            assert np.all(np.isfinite(js.position)) and np.all(np.isfinite(js.velocity))
            assert js.effort is None or np.all(np.isfinite(js.effort))
        for c in res.constraints:
            assert np.all(np.isfinite(c.margin))
        assert finite_tree(res.summary())
