"""Loop-closure primitives: circle-circle intersection, branches, toggles, derivatives."""

from __future__ import annotations

import math
from typing import Any

import mpmath as mp
import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose, assert_array_equal

from folder_line.core.mechanisms.layup_angles import TAU, classify_fourbar
from folder_line.core.numerics.loop import (
    TOGGLE_TOL,
    Intersection,
    circle_intersection,
    circle_intersection_scalar,
    circle_point_acceleration,
    circle_point_velocity,
    normalised_discriminant,
    solve2x2,
    tracked_intersection,
)
from folder_line.errors import AssemblyError

from .._reference import mp_circle, mp_rate

coord = st.floats(-10.0, 10.0, allow_nan=False)
radius = st.floats(0.05, 5.0, allow_nan=False)


def _cross(ux: float, uy: float, vx: float, vy: float) -> float:
    return ux * vy - uy * vx


# --------------------------------------------------------------------------- closed forms
def test_three_four_five_both_branches() -> None:
    # circles of radius 5 about (0, 0) and (8, 0) meet at (4, ±3)
    up = circle_intersection(0.0, 0.0, 5.0, 8.0, 0.0, 5.0, 1, inputs=0.0)
    down = circle_intersection(0.0, 0.0, 5.0, 8.0, 0.0, 5.0, -1, inputs=0.0)
    assert_allclose([up.x, up.y], [4.0, 3.0], rtol=0, atol=1e-15)
    assert_allclose([down.x, down.y], [4.0, -3.0], rtol=0, atol=1e-15)
    # sin of the angle between the radii at (4, 3): |(4,3) x (-4,3)| / 25 = 24/25
    assert_allclose(up.disc, (24.0 / 25.0) ** 2, rtol=1e-15)
    assert not up.toggle


def test_swapping_the_centres_flips_the_branch() -> None:
    a = circle_intersection(0.3, -0.2, 0.7, 1.1, 0.4, 0.9, 1, inputs=0.0)
    b = circle_intersection(1.1, 0.4, 0.9, 0.3, -0.2, 0.7, -1, inputs=0.0)
    assert_allclose([a.x, a.y], [b.x, b.y], rtol=0, atol=1e-15)


@settings(max_examples=300, deadline=None)
@given(
    x0=coord,
    y0=coord,
    r0=radius,
    ang=st.floats(-math.pi, math.pi),
    r1=radius,
    frac=st.floats(0.02, 0.98),
    branch=st.sampled_from([1, -1]),
)
def test_point_lies_on_both_circles_on_the_requested_side(
    x0: float, y0: float, r0: float, ang: float, r1: float, frac: float, branch: int
) -> None:
    # place c1 so that the circles properly intersect: |r0 - r1| < d < r0 + r1
    d = abs(r0 - r1) + frac * (r0 + r1 - abs(r0 - r1))
    x1, y1 = x0 + d * math.cos(ang), y0 + d * math.sin(ang)
    res = circle_intersection(x0, y0, r0, x1, y1, r1, branch, inputs=0.0)
    x, y = float(res.x), float(res.y)
    scale = r0 + r1 + abs(x0) + abs(y0)
    assert abs(math.hypot(x - x0, y - y0) - r0) < 1e-12 * scale / max(math.sqrt(max(float(res.disc), 0)), 1e-3)
    assert abs(math.hypot(x - x1, y - y1) - r1) < 1e-12 * scale / max(math.sqrt(max(float(res.disc), 0)), 1e-3)
    side = _cross(x1 - x0, y1 - y0, x - x0, y - y0)
    if float(res.disc) > 1e-8:
        assert math.copysign(1.0, side) == branch
        # independent: the angle between the radii at the joint
        ang_joint = math.atan2(_cross(x0 - x, y0 - y, x1 - x, y1 - y), (x0 - x) * (x1 - x) + (y0 - y) * (y1 - y))
        assert_allclose(float(res.disc), math.sin(ang_joint) ** 2, rtol=1e-9, atol=1e-12)
    # scalar path agrees
    xs, ys, ds = circle_intersection_scalar(x0, y0, r0, x1, y1, r1, branch, inputs=0.0)
    assert_allclose([xs, ys, ds], [x, y, float(res.disc)], rtol=1e-14, atol=1e-14 * scale)


@given(
    x0=coord,
    y0=coord,
    r0=radius,
    ang=st.floats(-math.pi, math.pi),
    r1=radius,
    frac=st.floats(0.05, 0.95),
    theta=st.floats(-math.pi, math.pi),
    tx=coord,
    ty=coord,
)
@settings(max_examples=200, deadline=None)
def test_rigid_motion_covariance(
    x0: float, y0: float, r0: float, ang: float, r1: float, frac: float, theta: float, tx: float, ty: float
) -> None:
    d = abs(r0 - r1) + frac * (r0 + r1 - abs(r0 - r1))
    assume(d > 1e-3)
    x1, y1 = x0 + d * math.cos(ang), y0 + d * math.sin(ang)
    disc = float(normalised_discriminant(d * d, r0, r1))
    c, s = math.cos(theta), math.sin(theta)

    def move(x: float, y: float) -> tuple[float, float]:
        return c * x - s * y + tx, s * x + c * y + ty

    p = circle_intersection(x0, y0, r0, x1, y1, r1, 1, inputs=0.0)
    q = circle_intersection(*move(x0, y0), r0, *move(x1, y1), r1, 1, inputs=0.0)
    assert_allclose([float(q.x), float(q.y)], move(float(p.x), float(p.y)), rtol=0, atol=1e-11 / math.sqrt(disc))


def test_vectorised_broadcasting_matches_elementwise() -> None:
    rng = np.random.default_rng(1)
    x1 = rng.uniform(0.5, 1.5, (3, 5))
    y1 = rng.uniform(-0.5, 0.5, (3, 5))
    branch = np.where(rng.uniform(size=(3, 5)) > 0.5, 1, -1)
    res = circle_intersection(0.0, 0.0, 1.0, x1, y1, 0.8, branch, inputs=np.zeros((3, 5)))
    assert res.x.shape == (3, 5)
    for idx in np.ndindex(3, 5):
        xs, ys, ds = circle_intersection_scalar(
            0.0, 0.0, 1.0, float(x1[idx]), float(y1[idx]), 0.8, int(branch[idx]), inputs=0.0
        )
        assert_allclose([res.x[idx], res.y[idx], res.disc[idx]], [xs, ys, ds], rtol=1e-15, atol=1e-15)


# --------------------------------------------------------------------------- toggles
@pytest.mark.parametrize(
    'x1, r1, expect',
    [
        (0.75, 0.5, (0.25, 0.0)),  # external tangency: d = r0 + r1
        (0.25, 0.5, (-0.25, 0.0)),  # internal tangency: d = r1 - r0
    ],
)
def test_exact_tangency_is_a_toggle_at_the_tangent_point(x1: float, r1: float, expect: tuple[float, float]) -> None:
    for branch in (1, -1):
        res = circle_intersection(0.0, 0.0, 0.25, x1, 0.0, r1, branch, inputs=0.0)
        assert bool(res.toggle)
        assert float(res.disc) == 0.0
        assert_allclose([res.x, res.y], expect, rtol=0, atol=1e-16)
        assert float(res.margin) == 0.0


@pytest.mark.parametrize('delta', [1e-12, -1e-12, 3e-13, -3e-13])
@pytest.mark.parametrize('internal', [False, True])
def test_tangent_plus_minus_1e12_is_flagged_finite_and_closes(delta: float, internal: bool) -> None:
    r0 = 0.25
    r1 = 0.5
    d = (r1 - r0 if internal else r0 + r1) + delta
    # a sweep of inputs around the tangency, vectorised and scalar
    res = circle_intersection(0.0, 0.0, r0, d, 0.0, r1, 1, inputs=0.0)
    xs, ys, ds = circle_intersection_scalar(0.0, 0.0, r0, d, 0.0, r1, 1, inputs=0.0)
    assert bool(res.toggle)
    assert abs(float(res.disc)) <= TOGGLE_TOL
    assert np.isfinite([res.x, res.y, res.disc]).all()
    # clamped: misses the circles by at most |D| r0 r1 max(r0, r1) / (2 d²) (the documented bound);
    # overlapping: meets them to rounding
    bound = abs(float(res.disc)) * r0 * r1 * max(r0, r1) / (2 * d * d) * 1.001 + 1e-16
    assert bound < 3e-12
    assert abs(math.hypot(float(res.x), float(res.y)) - r0) <= bound
    assert abs(math.hypot(float(res.x) - d, float(res.y)) - r1) <= bound
    assert_allclose([xs, ys, ds], [float(res.x), float(res.y), float(res.disc)], rtol=1e-12, atol=1e-15)
    # inside the overlap the point is a true intersection on the requested side
    overlapping = (delta < 0) != internal
    if overlapping:
        assert float(res.disc) > 0.0
        assert float(res.y) > 0.0


def test_unassemblable_names_the_first_failing_input() -> None:
    phis = np.array([0.1, 0.2, 0.3, 0.4, 0.5])
    d = np.array([0.5, 0.7, 0.75 + 1e-6, 0.9, 0.6])  # fails at 0.3 and 0.4 (> r0 + r1 = 0.75)
    with pytest.raises(AssemblyError) as err:
        circle_intersection(0.0, 0.0, 0.25, d, 0.0, 0.5, 1, inputs=phis, mechanism='test dyad')
    assert err.value.phi == 0.3
    assert err.value.mechanism == 'test dyad'
    assert 'apart' in err.value.reason
    with pytest.raises(AssemblyError) as err:
        circle_intersection_scalar(0.0, 0.0, 0.25, 0.1, 0.0, 0.5, 1, inputs=1.25)
    assert err.value.phi == 1.25
    assert 'inside' in err.value.reason


def test_concentric_and_nonfinite_are_unassemblable() -> None:
    with pytest.raises(AssemblyError, match='concentric'):
        circle_intersection(0.0, 0.0, 0.5, 0.0, 0.0, 0.5, 1, inputs=np.array([2.0]))
    with pytest.raises(AssemblyError, match='concentric'):
        circle_intersection_scalar(1.0, 1.0, 0.5, 1.0, 1.0, 0.5, 1, inputs=2.0)
    with pytest.raises(AssemblyError, match='non-finite'):
        circle_intersection_scalar(0.0, 0.0, 0.5, math.nan, 0.0, 0.5, 1, inputs=2.0)


def test_normalised_discriminant_signs_and_heron() -> None:
    # 3-4-5 triangle: radii 3 and 4, centres 5 apart -> right angle at the joint
    assert_allclose(normalised_discriminant(25.0, 3.0, 4.0), 1.0, rtol=1e-15)
    assert float(normalised_discriminant(49.0, 3.0, 4.0)) == 0.0
    assert float(normalised_discriminant(1.0, 3.0, 4.0)) == 0.0
    assert float(normalised_discriminant(50.0, 3.0, 4.0)) < 0.0
    assert float(normalised_discriminant(0.5, 3.0, 4.0)) < 0.0
    arr = normalised_discriminant(np.array([25.0, 50.0]), 3.0, 4.0)
    assert arr.shape == (2,)


# --------------------------------------------------------------------------- tracked mode
def _loop_path(n: int = 2001) -> tuple[np.ndarray, np.ndarray]:
    """c1 runs round an ellipse; c0 = origin, r0 = 1, r1 = 0.9: no toggle on the way."""
    t = np.linspace(0.0, 2.0 * np.pi, n)
    return 1.2 + 0.3 * np.cos(t), 0.4 * np.sin(t)


def test_tracked_mode_never_flips_and_ignores_centre_order() -> None:
    x1, y1 = _loop_path()
    exp = circle_intersection(0.0, 0.0, 1.0, x1, y1, 0.9, 1, inputs=0.0)
    other = circle_intersection(0.0, 0.0, 1.0, x1, y1, 0.9, -1, inputs=0.0)
    assert np.min(exp.disc) > 0.1
    for start, ref, expect_branch in ((exp, exp, 1), (other, other, -1)):
        px, py = float(start.x[0]), float(start.y[0])
        xs, ys = [], []
        for i in range(x1.size):
            # tracked with the centres given in the opposite order: a fixed branch sign would flip
            px, py, br = tracked_intersection(float(x1[i]), float(y1[i]), 0.9, 0.0, 0.0, 1.0, px, py, inputs=0.0)
            assert br == -expect_branch  # branch is relative to the order given
            xs.append(px)
            ys.append(py)
        assert_allclose(xs, ref.x, rtol=0, atol=1e-14)
        assert_allclose(ys, ref.y, rtol=0, atol=1e-14)


def test_tracked_mode_raises_when_unassemblable() -> None:
    with pytest.raises(AssemblyError) as err:
        tracked_intersection(0.0, 0.0, 1.0, 3.0, 0.0, 1.0, 1.0, 0.0, inputs=0.7)
    assert err.value.phi == 0.7


# --------------------------------------------------------------------------- derivatives
@settings(max_examples=100, deadline=None)
@given(
    a11=st.floats(-5, 5),
    a12=st.floats(-5, 5),
    a21=st.floats(-5, 5),
    a22=st.floats(-5, 5),
    b1=st.floats(-5, 5),
    b2=st.floats(-5, 5),
)
def test_solve2x2_matches_linalg(a11: float, a12: float, a21: float, a22: float, b1: float, b2: float) -> None:
    m = np.array([[a11, a12], [a21, a22]])
    # the filter only: LU-based det/cond divide by a zero pivot on singular inputs with subnormal entries
    # (hypothesis found a21 = 2.2e-311), which warns; the closed-form determinant does not
    with np.errstate(divide='ignore', invalid='ignore', over='ignore'):
        well_posed = abs(a11 * a22 - a12 * a21) > 1e-3 and np.linalg.cond(m) < 1e6
    assume(well_posed)
    x1, x2 = solve2x2(a11, a12, a21, a22, b1, b2)
    assert_allclose([x1, x2], np.linalg.solve(m, [b1, b2]), rtol=1e-9, atol=1e-9)


def _dyad_path(t: np.ndarray) -> tuple[np.ndarray, ...]:
    """Two moving centres (closed forms of their velocities and accelerations)."""
    x0, y0 = 0.1 * np.cos(t), 0.2 * np.sin(t)
    vx0, vy0 = -0.1 * np.sin(t), 0.2 * np.cos(t)
    ax0, ay0 = -0.1 * np.cos(t), -0.2 * np.sin(t)
    x1, y1 = 1.3 + 0.2 * np.sin(2 * t), 0.1 * t
    vx1, vy1 = 0.4 * np.cos(2 * t), 0.1 + 0 * t
    ax1, ay1 = -0.8 * np.sin(2 * t), 0 * t
    return x0, y0, vx0, vy0, ax0, ay0, x1, y1, vx1, vy1, ax1, ay1


def test_velocity_and_acceleration_match_finite_differences() -> None:
    t = np.linspace(0.0, 3.0, 41)
    h = 1e-4

    def pos(tt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        x0, y0, _, _, _, _, x1, y1, *_ = _dyad_path(tt)
        r = circle_intersection(x0, y0, 1.0, x1, y1, 0.7, -1, inputs=tt)
        return r.x, r.y

    x0, y0, vx0, vy0, ax0, ay0, x1, y1, vx1, vy1, ax1, ay1 = _dyad_path(t)
    x, y = pos(t)
    vx, vy = circle_point_velocity(x, y, x0, y0, vx0, vy0, x1, y1, vx1, vy1)
    ax, ay = circle_point_acceleration(x, y, vx, vy, x0, y0, vx0, vy0, ax0, ay0, x1, y1, vx1, vy1, ax1, ay1)
    # fourth-order central differences
    xp2, yp2 = pos(t + 2 * h)
    xp1, yp1 = pos(t + h)
    xm1, ym1 = pos(t - h)
    xm2, ym2 = pos(t - 2 * h)
    fdv = [(-xp2 + 8 * xp1 - 8 * xm1 + xm2) / (12 * h), (-yp2 + 8 * yp1 - 8 * ym1 + ym2) / (12 * h)]
    fda = [
        (-xp2 + 16 * xp1 - 30 * x + 16 * xm1 - xm2) / (12 * h * h),
        (-yp2 + 16 * yp1 - 30 * y + 16 * ym1 - ym2) / (12 * h * h),
    ]
    assert_allclose([vx, vy], fdv, rtol=0, atol=1e-9)
    assert_allclose([ax, ay], fda, rtol=0, atol=1e-5)
    # and the velocity is tangent to both circles relative to their centres
    assert_allclose((x - x0) * (vx - vx0) + (y - y0) * (vy - vy0), 0.0, atol=1e-14)
    assert_allclose((x - x1) * (vx - vx1) + (y - y1) * (vy - vy1), 0.0, atol=1e-14)


def test_scalar_inputs_give_scalars() -> None:
    vx, vy = circle_point_velocity(4.0, 3.0, 0.0, 0.0, 0.0, 0.0, 8.0, 0.0, 1.0, 0.0)
    # c1 slides right at 1 m/s with c0 fixed: X turns about c0, and (X - c1)·(V - v1) = 0
    assert_allclose((4.0 * vx + 3.0 * vy, (-4.0) * (vx - 1.0) + 3.0 * vy), (0.0, 0.0), atol=1e-15)
    assert_allclose([vx, vy], [0.5, -2.0 / 3.0], rtol=1e-15)
    assert_array_equal(np.shape(vx), ())


# --------------------------------------------------------------------------- a four-bar at its dead centres and toggles


class TestFourBarDeadCentresAndToggles:
    """The four-bar of circle_intersection at +-1e-12 rad of its rocker dead centres, at its toggle
    limit and at a change point: against the mpmath loop closure of :mod:`_reference`."""

    @staticmethod
    def fourbar(
        phi: np.ndarray, d: float, R: float, coupler: float, q: float, w: float = 1.0, tol: float = TOGGLE_TOL
    ) -> tuple[Intersection, np.ndarray, np.ndarray]:
        """Crank O1 = 0 (radius R, speed w), rocker pivot O2 = (d, 0) (radius q), coupler of length ``coupler``:
        B = circle(O2, q) x circle(A, coupler) on branch +1; velocity and acceleration of B."""
        ax, ay = R * np.cos(phi), R * np.sin(phi)
        vx, vy = -w * ay, w * ax
        accx, accy = -w * w * ax, -w * w * ay
        it = circle_intersection(d, 0.0, q, ax, ay, coupler, 1, inputs=phi, tol=tol, mechanism='four-bar')
        zero = np.zeros_like(phi)
        vb = np.array(circle_point_velocity(it.x, it.y, ax, ay, vx, vy, d, 0.0, zero, zero))
        ab = np.array(
            circle_point_acceleration(
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
        it = circle_intersection(d, 0.0, q, R * math.cos(past), R * math.sin(past), coupler, 1, inputs=past)
        x, y = float(it.x), float(it.y)
        assert bool(it.toggle) and math.isfinite(x) and math.isfinite(y) and float(it.disc) < 0.0
        miss = abs(math.hypot(x - d, y) - q) + abs(math.hypot(x - R * math.cos(past), y - R * math.sin(past)) - coupler)
        assert miss <= 1e-11
        with pytest.raises(AssemblyError) as info:
            self.fourbar(np.array([x_l - 0.1, x_l + 1e-6]), d, R, coupler, q)
        assert info.value.phi == x_l + 1e-6 and 'four-bar' in str(info.value)

    def test_change_point_fourbar_is_never_nan(self) -> None:
        """A change-point four-bar (0.4, 0.9, 0.5 on 1.0) turns fully but lines up at phi = pi:
        around it the positions are finite, continuous and flagged as a toggle; LayupParams of a
        change-point loop 1 is rejected (tested above)."""
        d, R, coupler, q = 1.0, 0.4, 0.9, 0.5
        assert classify_fourbar(d, R, coupler, q) == 'change-point'
        phis = math.pi + np.array([-1e-6, -1e-12, 0.0, 1e-12, 1e-6])
        it = circle_intersection(d, 0.0, q, R * np.cos(phis), R * np.sin(phis), coupler, 1, inputs=phis)
        assert np.isfinite(it.x).all() and np.isfinite(it.y).all() and np.isfinite(it.disc).all()
        assert it.toggle[1:4].all()
        assert np.abs(np.diff(it.x[1:4])).max() <= 1e-11 and np.abs(np.diff(it.y[1:4])).max() <= 1e-11
        # the normalised discriminant touches 0 quadratically: ~ c (phi - pi)^2
        assert abs(it.disc[0]) < 1e-11 and abs(it.disc[1]) < 1e-20
