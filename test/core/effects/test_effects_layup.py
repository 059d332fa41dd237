"""L effects: chute_belts, leaf_flight, guide_friction, leaf_damage — closed forms and cross-checks."""

from __future__ import annotations

import dataclasses
import math

import mpmath
import numpy as np
import pytest
import scipy.optimize
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose
from scipy.integrate import quad, solve_ivp

from folder_line.config.params import load_params
from folder_line.core.effects import chute_belts as cb
from folder_line.core.effects import guide_friction as gf
from folder_line.core.effects import leaf_damage as ld
from folder_line.core.effects import leaf_flight as lf
from folder_line.core.effects import parse_effect_params
from folder_line.core.line.layup_kinematics import LayupKinematics
from folder_line.core.mechanisms.drive import ConstantDrive, RampDrive
from folder_line.core.numerics.roots import brentq
from folder_line.errors import ParameterError

G = 9.80665
P = load_params('layup')
KIN = LayupKinematics(P, ConstantDrive())


def kin_vec(t: np.ndarray, ch: np.ndarray) -> gf.ChuteState:
    q = KIN.chute(t, ch)
    return gf.ChuteState(q['sin'], q['cos'], q['omega'], q['eps'])


def kin_one(t: float, ch: int) -> gf.ChuteState:
    return gf.ChuteState(*KIN.chute_scalar(t, ch))


# ---------------------------------------------------------------------------- parameters


@pytest.mark.parametrize(
    ('name', 'values', 'key'),
    [
        ('leaf_damage', {'v_damage': 0.0}, 'effects.leaf_damage.v_damage'),
        ('leaf_damage', {'v_damage': float('nan')}, 'effects.leaf_damage.v_damage'),
        ('chute_belts', {'v_min': -0.1}, 'effects.chute_belts.v_min'),
        ('leaf_flight', {'drag': -1.0}, 'effects.leaf_flight.drag'),
        ('leaf_flight', {'drag': True}, 'effects.leaf_flight.drag'),
        ('guide_friction', {'mu': -0.1, 's0': 0.0, 'v0': 1.0, 'h': 0.002}, 'effects.guide_friction.mu'),
        ('guide_friction', {'mu': 0.5, 's0': -0.1, 'v0': 1.0, 'h': 0.002}, 'effects.guide_friction.s0'),
        ('guide_friction', {'mu': 0.5, 's0': 0.0, 'v0': -1.0, 'h': 0.002}, 'effects.guide_friction.v0'),
        ('guide_friction', {'mu': 0.5, 's0': 0.0, 'v0': 1.0, 'h': 0.0}, 'effects.guide_friction.h'),
        ('guide_friction', {'mu': 0.5, 's0': 0.0, 'v0': 1.0, 'h': 0.1}, 'effects.guide_friction.h'),
        ('guide_friction', {'mu': 0.5, 's0': 0.0, 'v0': 1.0}, 'effects.guide_friction.h'),
    ],
)
def test_bad_effect_parameters_are_named(name: str, values: dict, key: str) -> None:
    with pytest.raises(ParameterError) as exc:
        parse_effect_params(name, values)
    assert exc.value.key == key


def test_params_have_no_defaults() -> None:
    for mod in (cb, lf, gf, ld):
        assert all(f.default is dataclasses.MISSING for f in dataclasses.fields(mod.Params))


# ---------------------------------------------------------------------------- leaf_damage


def test_damage_threshold_is_inclusive_and_the_margin_exclusive() -> None:
    p = ld.Params(v_damage=5.6)
    below = np.nextafter(5.6, 0.0)
    speeds = np.array([2.8, below, 5.6, 6.0])
    assert ld.damaged(p, speeds).tolist() == [False, False, True, True]
    m = ld.upper_margin(p, speeds)
    assert m[1] == 0.0 and m[0] > 0.0  # the largest admissible float has margin 0, not violated
    assert m[2] < 0.0 and m[3] < 0.0  # exactly v_damage is violated
    assert -m[2] == 5.6 - below  # by one ulp


def test_paper_speeds_with_a_damage_speed_between() -> None:
    """2.8 m/s belts: no leaf damaged; 5.6 m/s: every leaf (eq. 25 over a whole turn)."""
    p = ld.Params(v_damage=4.5)
    st_ = KIN.model.arrays(np.linspace(0.0, 2 * math.pi, 2001), accelerations=False)
    v_perp = np.concatenate([st_.vC, st_.vE])
    assert not ld.damaged(p, cb.absolute_speed(v_perp, 2.8)).any()
    assert ld.damaged(p, cb.absolute_speed(v_perp, 5.6)).all()


# ---------------------------------------------------------------------------- chute_belts


def test_belt_exit_time_constant_drive_is_closed_form() -> None:
    prof = cb.belt_profile(2.8, ConstantDrive(), 100.0)
    t_in = np.array([0.0, 1.3, 50.25])
    t_x, ok = cb.exit_times(prof, ConstantDrive(), np.array([1.0, 0.95, 1.0]), t_in, 100.0)
    assert ok.all()
    assert_allclose(t_x, t_in + np.array([1.0, 0.95, 1.0]) / 2.8, rtol=0, atol=1e-14)


def test_belt_exit_time_beyond_the_run_is_not_reached() -> None:
    prof = cb.belt_profile(2.8, ConstantDrive(), 10.0)
    t_x, ok = cb.exit_times(prof, ConstantDrive(), 1.0, np.array([9.0, 9.7]), 10.0)
    assert ok.tolist() == [True, False]
    assert np.isfinite(t_x).all()


def test_belt_exit_time_with_a_ramp_drive_moves_the_belt_exactly_l() -> None:
    drive = RampDrive(3.0)
    prof = cb.belt_profile(2.8, drive, 20.0)
    t_in = np.array([0.0, 0.5, 2.0, 2.9, 5.0])
    t_x, ok = cb.exit_times(prof, drive, 1.0, t_in, float(drive.theta(20.0)))
    assert ok.all()
    for a, b in zip(t_in, t_x, strict=True):
        travel = quad(lambda t: 2.8 * float(drive.rate(t)), a, b, points=[3.0], epsabs=1e-13, epsrel=1e-13)[0]
        assert travel == pytest.approx(1.0, abs=1e-11)


def test_belt_exit_time_across_slowdowns_is_exact() -> None:
    drive = RampDrive(1.0)
    prof = cb.belt_profile(2.8, drive, 30.0, [2.0, 2.5, 10.0], [2.3, 2.6, 40.0], [0.5, 0.25, 0.8])
    t_in = np.linspace(0.0, 12.0, 97)
    t_x, ok = cb.exit_times(prof, drive, 1.0, t_in, float(drive.theta(30.0)))
    assert ok.all()

    def speed(t: float) -> float:
        return float(cb.belt_speed(prof, drive, np.array([t]))[0])

    brk = [1.0, 2.0, 2.3, 2.5, 2.6, 10.0]
    for a, b in zip(t_in, t_x, strict=True):
        pts = [x for x in brk if a < x < b]
        travel = quad(speed, a, b, points=pts or None, epsabs=1e-13, epsrel=1e-13, limit=200)[0]
        assert travel == pytest.approx(1.0, abs=1e-10)
    # belt_position is the integral of belt_speed
    pos = cb.belt_position(prof, drive, t_x) - cb.belt_position(prof, drive, t_in)
    assert_allclose(pos, 1.0, atol=1e-12)


def test_belt_speed_must_be_positive() -> None:
    with pytest.raises(ParameterError) as exc:
        cb.check_belt_speed(0.0)
    assert exc.value.key == 'layup.v_tr'


def test_speed_margin_takes_the_smaller_bound() -> None:
    p = cb.Params(v_min=2.0)
    d = ld.Params(v_damage=3.0)
    v = np.array([1.5, 2.0, 2.5, 3.0])
    assert cb.speed_margin(p, v).tolist() == [-0.5, 0.0, 0.5, 1.0]
    m = cb.speed_margin(p, v, ld.upper_margin(d, v))
    assert m[0] == -0.5 and m[1] == 0.0 and m[2] > 0.0 and m[3] < 0.0


# ---------------------------------------------------------------------------- leaf_flight


def test_phi_functions_against_mpmath() -> None:
    z = np.concatenate([[0.0, 1e-300, 1e-12, 1e-6], np.geomspace(1e-4, 50.0, 200), [0.4999999, 0.5, 700.0]])
    for zi, a, b in zip(z, lf.phi1(z), lf.phi2(z), strict=True):
        if zi == 0.0:
            assert a == 1.0 and b == 0.5
            continue
        with mpmath.workdps(700):  # enough digits for the cancellation at z = 1e-300
            x = mpmath.mpf(float(zi))
            e1 = float(-mpmath.expm1(-x) / x)
            e2 = float((x + mpmath.expm1(-x)) / x**2)
        assert a == pytest.approx(e1, rel=4e-16)
        assert b == pytest.approx(e2, rel=2e-15)


def test_no_drag_landing_time_is_the_stable_quadratic_root() -> None:
    p = lf.Params(drag=0.0)
    y0 = np.array([0.0, 0.0, 0.0, 0.0, -1.0])
    vy = np.array([3.0, -3.0, 0.0, -1e8, 1e-9])
    t = lf.landing_time(p, y0, vy, -1.25)
    for ti, a, b in zip(t, y0, vy, strict=True):
        h = a + 1.25
        with mpmath.workdps(60):
            ref = float((mpmath.mpf(b) + mpmath.sqrt(mpmath.mpf(b) ** 2 + 2 * G * mpmath.mpf(h))) / G)
        assert ti == pytest.approx(ref, rel=4e-16)
    # the root is exact: y(t) = floor
    _, y, _, _ = lf.state(p, 0.0, y0, 0.0, vy, t)
    assert (np.abs(y + 1.25) <= 1e-15 * np.maximum(1.0, np.abs(vy) * t)).all()


def test_horizontal_range_closed_form() -> None:
    p = lf.Params(drag=0.0)
    vx = np.array([0.5, 2.8, -1.0])
    t, x = lf.landing(p, np.zeros(3), np.full(3, 1.0), vx, np.zeros(3), 0.0)
    assert_allclose(t, math.sqrt(2.0 / G), rtol=1e-15)
    assert_allclose(x, vx * math.sqrt(2.0 / G), rtol=1e-15)
    # with drag: x = vx (1 - exp(-k t))/k at the landing time
    pd = lf.Params(drag=2.0)
    t2, x2 = lf.landing(pd, np.zeros(3), np.full(3, 1.0), vx, np.zeros(3), 0.0)
    assert_allclose(x2, vx * (1.0 - np.exp(-2.0 * t2)) / 2.0, rtol=1e-14)


@pytest.mark.parametrize('drag', [0.0, 0.5, 3.0, 40.0])
def test_landing_against_solve_ivp_with_an_event(drag: float) -> None:
    p = lf.Params(drag=drag)
    rng = np.random.default_rng(7)
    x0 = rng.uniform(-0.3, 0.9, 12)
    y0 = rng.uniform(-0.95, -0.85, 12)
    vx = rng.uniform(-3.0, 3.0, 12)
    vy = rng.uniform(-3.0, 2.0, 12)
    t, x = lf.landing(p, x0, y0, vx, vy, -1.25)
    for i in range(12):

        def rhs(_t: float, y: np.ndarray) -> list[float]:
            return [y[2], y[3], -drag * y[2], -G - drag * y[3]]

        def floor(_t: float, y: np.ndarray) -> float:
            return y[1] + 1.25

        floor.terminal = True
        floor.direction = -1
        sol = solve_ivp(
            rhs, (0.0, 100.0), [x0[i], y0[i], vx[i], vy[i]], events=floor, rtol=1e-12, atol=1e-14, method='DOP853'
        )
        assert t[i] == pytest.approx(sol.t_events[0][0], abs=1e-10)
        assert x[i] == pytest.approx(sol.y_events[0][0][0], abs=1e-10)


@pytest.mark.parametrize('drag', [0.3, 3.0, 300.0])
def test_drag_landing_time_against_brent(drag: float) -> None:
    p = lf.Params(drag=drag)
    y0, vy = np.array([-0.9, -0.9, -0.9]), np.array([2.0, 0.0, -2.0 * G / drag])
    t = lf.landing_time(p, y0, vy, -1.25)
    for ti, a, b in zip(t, y0, vy, strict=True):

        def f(x: float, a: float = a, b: float = b) -> float:
            return float(lf.state(p, 0.0, a, 0.0, b, x)[1]) + 1.25

        hi = (drag * (a + 1.25) + max(b + G / drag, 0.0)) / G  # the documented analytic bracket
        assert f(hi) <= 0.0 < f(0.0)
        assert ti == pytest.approx(brentq(f, 0.0, hi, xtol=1e-15), abs=2e-15)
        assert ti == pytest.approx(scipy.optimize.brentq(f, 0.0, hi, xtol=1e-15), abs=2e-15)


def test_drag_to_zero_limit_matches_no_drag() -> None:
    y0, vy, vx = np.array([-0.9, -0.9]), np.array([1.5, -2.5]), np.array([2.0, -1.0])
    t0, x0 = lf.landing(lf.Params(0.0), 0.0, y0, vx, vy, -1.25)
    prev = None
    for k in (1e-2, 1e-4, 1e-6, 1e-9, 1e-14):
        t, x = lf.landing(lf.Params(k), 0.0, y0, vx, vy, -1.25)
        err = max(np.abs(t - t0).max(), np.abs(x - x0).max())
        assert err <= 2.0 * k + 1e-15  # O(k)
        if prev is not None:
            assert err <= prev
        prev = err
    assert prev <= 1e-14  # a few ulp


@settings(max_examples=200, deadline=None)
@given(st.floats(0.0, 50.0), st.floats(1e-3, 5.0), st.floats(-20.0, 20.0), st.floats(-5.0, 5.0))
def test_landing_lands_on_the_floor(drag: float, height: float, vy: float, vx: float) -> None:
    p = lf.Params(drag)
    t, x = lf.landing(p, 0.0, np.array([height]), np.array([vx]), np.array([vy]), 0.0)
    assert np.isfinite(t).all() and np.isfinite(x).all() and t[0] > 0.0
    _, y, _, vyt = lf.state(p, 0.0, height, vx, vy, t)
    assert abs(y[0]) <= 1e-13 * max(1.0, height, abs(vy) * t[0])
    assert vyt[0] < 0.0  # falling when it lands


def test_landing_start_below_the_floor_is_rejected() -> None:
    with pytest.raises(ParameterError) as exc:
        lf.landing_time(lf.Params(0.0), np.array([-1.0, -1.3]), np.zeros(2), -1.25)
    assert exc.value.key == 'container.y_floor'


def test_histogram_and_cv() -> None:
    h = lf.histogram([0.05, 0.15, 0.15, 0.95, 1.0], 0.0, 1.0, 10)
    assert h.counts.tolist() == [1, 2, 0, 0, 0, 0, 0, 0, 0, 2]
    assert h.cv == pytest.approx(np.std(h.counts) / np.mean(h.counts))
    assert lf.histogram(np.full(50, 0.5), 0.0, 1.0, 2).cv == pytest.approx(1.0)
    assert lf.histogram(np.arange(10) / 10 + 0.05, 0.0, 1.0, 10).cv == 0.0
    assert lf.histogram([], 0.0, 1.0, 10).cv is None


# ---------------------------------------------------------------------------- guide_friction: the equation


def test_equation_signs_from_an_inertial_frame_check() -> None:
    """r = s t̂(θ'): the computed N and s̈ satisfy Newton's law in x, y (finite differences of r(t))."""
    mu = 0.4
    p = gf.Params(mu, 0.0, 1.0, 0.002)

    def theta(t: float) -> float:
        return 0.3 * math.sin(2.1 * t) + 0.1

    for t0, s0, v0 in [(0.1, 0.4, 1.2), (0.7, 0.8, 0.3), (1.9, 0.2, 2.5)]:
        th, w = theta(t0), 0.3 * 2.1 * math.cos(2.1 * t0)
        eps = -0.3 * 2.1**2 * math.sin(2.1 * t0)
        k = gf.ChuteState(np.array(math.sin(th)), np.array(math.cos(th)), np.array(w), np.array(eps))
        a = float(gf.acceleration(p, s0, v0, k))

        def r(
            t: float, t0: float = t0, s0: float = s0, v0: float = v0, a: float = a
        ) -> np.ndarray:  # s(t) = s0 + v0 τ + a τ²/2 has the right s, ṡ, s̈ at t0
            tau = t - t0
            s = s0 + v0 * tau + 0.5 * a * tau * tau
            return s * np.array([math.sin(theta(t)), -math.cos(theta(t))])

        d = 1e-4
        acc = (r(t0 + d) - 2 * r(t0) + r(t0 - d)) / d**2
        tt = np.array([math.sin(th), -math.cos(th)])
        nn = np.array([math.cos(th), math.sin(th)])
        n_wall = float(gf.normal(s0, v0, k))
        force = np.array([0.0, -G]) + n_wall * nn - mu * abs(n_wall) * tt  # per unit mass, ṡ > 0
        assert_allclose(acc, force, atol=2e-6)


def test_check_geometry() -> None:
    p = gf.Params(0.5, 0.96, 1.0, 0.002)
    with pytest.raises(ParameterError) as exc:
        gf.check_geometry(p, 0.95, 0.9)
    assert exc.value.key == 'effects.guide_friction.s0'
    with pytest.raises(ParameterError) as exc:
        gf.check_geometry(gf.Params(0.5, 0.0, 1.0, 0.002), 0.95, -0.01)
    assert exc.value.key == 'effects.guide_friction'
    gf.check_geometry(gf.Params(0.5, 0.0, 1.0, 0.002), 0.95, 0.9)


def test_scalar_and_vector_chute_kinematics_agree() -> None:
    t = np.linspace(0.0, 4.0, 157)
    for ch in (0, 1):
        q = kin_vec(t, np.full(t.size, ch))
        one = np.array([kin_one(float(x), ch) for x in t])
        assert_allclose(one[:, 0], q.sin, atol=1e-14)
        assert_allclose(one[:, 1], q.cos, atol=1e-14)
        assert_allclose(one[:, 2], q.omega, atol=1e-13)
        assert_allclose(one[:, 3], q.eps, atol=1e-12)
        # ε is the derivative of ω
        dt = 1e-6
        dw = (kin_vec(t + dt, np.full(t.size, ch)).omega - kin_vec(t - dt, np.full(t.size, ch)).omega) / (2 * dt)
        assert_allclose(q.eps, dw, atol=1e-7)


# ---------------------------------------------------------------------------- guide_friction: integration


def _leaves(n: int, span: float = 2.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t_in = np.linspace(0.0, span, n, endpoint=False)
    ch = np.arange(n) % 2
    return t_in, ch, np.where(ch == 1, P.l5, P.l3)


def _ivp_slide(
    mu: float, t0: float, s0: float, v0: float, ch: int, length: float, stop: bool = False
) -> tuple[float, float, float, bool]:
    """Reference: solve_ivp of the sliding equation until exit (or ṡ = 0): (t, s, ṡ, stopped)."""

    def rhs(t: float, y: np.ndarray) -> list[float]:
        s_, c_, w_, e_ = KIN.chute_scalar(t, ch)
        n_ = e_ * y[0] + 2 * w_ * y[1] + G * s_
        return [y[1], G * c_ + w_ * w_ * y[0] - mu * abs(n_)]

    def out(_t: float, y: np.ndarray) -> float:
        return y[0] - length

    def halt(_t: float, y: np.ndarray) -> float:
        return y[1]

    out.terminal = halt.terminal = True
    halt.direction = -1
    sol = solve_ivp(
        rhs, (t0, t0 + 10.0), [s0, v0], events=[out, halt] if stop else [out], rtol=1e-12, atol=1e-13, method='DOP853'
    )
    if sol.t_events[0].size:
        return float(sol.t_events[0][0]), length, float(sol.y_events[0][0][1]), False
    return float(sol.t_events[1][0]), float(sol.y_events[1][0][0]), 0.0, True


def test_slide_matches_solve_ivp() -> None:
    p = gf.Params(0.5, 0.0, 1.0, 0.002)
    t_in, ch, length = _leaves(24)
    r = gf.slide(p, kin_vec, kin_one, t_in, ch, length, 50.0)
    assert r.exited.all() and r.stick_t.size == 0
    for i in range(24):
        t_x, _, v_x, _ = _ivp_slide(0.5, t_in[i], 0.0, 1.0, int(ch[i]), length[i])
        assert r.t_exit[i] == pytest.approx(t_x, abs=1e-10)
        assert r.v_exit[i] == pytest.approx(v_x, abs=1e-9)


def test_slide_is_fourth_order_across_the_kinks_of_the_normal_force() -> None:
    t_in, ch, length = _leaves(16)
    runs = {
        h: gf.slide(gf.Params(2.5, 0.3, 0.2, h), kin_vec, kin_one, t_in, ch, length, 50.0)
        for h in (0.004, 0.002, 0.001, 0.00025)
    }
    ref = runs[0.00025]
    e = [np.abs(runs[h].v_exit - ref.v_exit).max() for h in (0.004, 0.002, 0.001)]
    assert e[0] / e[1] > 8.0 and e[1] / e[2] > 8.0  # 16 for fourth order; 4 would be second


def test_frictionless_leaf_matches_solve_ivp() -> None:
    p = gf.Params(0.0, 0.1, 0.5, 0.002)
    t_in, ch, length = _leaves(8)
    r = gf.slide(p, kin_vec, kin_one, t_in, ch, length, 50.0)
    for i in range(8):
        t_x, _, v_x, _ = _ivp_slide(0.0, t_in[i], 0.1, 0.5, int(ch[i]), length[i])
        assert r.t_exit[i] == pytest.approx(t_x, abs=1e-11)
        assert r.v_exit[i] == pytest.approx(v_x, abs=1e-10)


def test_entry_at_rest_sticks_where_the_wall_holds_it_and_slips_at_the_closed_form_angle() -> None:
    """s = 0, ṡ = 0: σ = g (cos θ' − μ |sin θ'|), so the leaf holds while |tan θ'| >= 1/μ."""
    mu = 4.0
    p = gf.Params(mu, 0.0, 0.0, 0.002)
    t_in, ch, length = _leaves(40)
    r = gf.slide(p, kin_vec, kin_one, t_in, ch, length, 50.0)
    assert r.exited.all()
    q = kin_vec(t_in, ch)
    held = np.abs(q.sin) * mu >= q.cos
    assert held.any() and not held.all()
    first_stick = {}
    for i, t in zip(r.stick_leaf.tolist(), r.stick_t.tolist(), strict=True):
        first_stick.setdefault(i, t)
    assert sorted(i for i in first_stick if first_stick[i] == t_in[i]) == np.flatnonzero(held).tolist()
    slip = {}
    for i, t in zip(r.slip_leaf.tolist(), r.slip_t.tolist(), strict=True):
        slip.setdefault(i, t)
    for i in np.flatnonzero(held):
        ts = slip[i]
        c = kin_one(ts, int(ch[i]))
        assert abs(c.sin) * mu == pytest.approx(c.cos, abs=1e-9)  # tan|θ'| = 1/μ at the slip
        grid = np.linspace(t_in[i], ts, 400)[:-1]
        k = kin_vec(grid, np.full(grid.size, ch[i]))
        assert (gf.switching(p, 0.0, k) <= 1e-9).all()  # held all the way (brute force)


def test_stick_and_slip_mid_slide_match_a_piecewise_reference() -> None:
    """μ = 4, entry at 0.5 m/s: leaves near the extremes stop, stick, slip and slide out."""
    mu = 4.0
    p = gf.Params(mu, 0.0, 0.5, 0.001)
    t_in, ch, length = _leaves(48)
    r = gf.slide(p, kin_vec, kin_one, t_in, ch, length, 50.0)
    assert r.stick_t.size >= 10 and r.slip_t.size == r.stick_t.size
    checked = 0
    for i in np.unique(r.stick_leaf)[:8]:
        i = int(i)
        c = int(ch[i])
        t_st, s_st, _, stopped = _ivp_slide(mu, t_in[i], 0.0, 0.5, c, length[i], stop=True)
        assert stopped
        assert r.stick_t[r.stick_leaf == i][0] == pytest.approx(t_st, abs=1e-9)

        def sigma(t: float, s_: float = s_st, c_: int = c) -> float:
            return float(gf.switching(p, s_, kin_one(t, c_)))

        assert sigma(t_st) <= 0.0
        grid = t_st + np.arange(1, 4000) * 1e-4
        vals = np.array([sigma(x) for x in grid])
        k = int(np.argmax(vals > 0.0))
        t_sl = scipy.optimize.brentq(sigma, grid[k - 1] if k else t_st, grid[k], xtol=1e-14)
        assert r.slip_t[r.slip_leaf == i][0] == pytest.approx(t_sl, abs=1e-9)
        if (r.stick_leaf == i).sum() == 1:
            t_x, _, v_x, st2 = _ivp_slide(mu, t_sl, s_st, 0.0, c, length[i], stop=True)
            assert not st2
            assert r.t_exit[i] == pytest.approx(t_x, abs=1e-8)
            assert r.v_exit[i] == pytest.approx(v_x, abs=1e-7)
            checked += 1
    assert checked >= 3


def test_slide_stops_at_the_end_of_the_run() -> None:
    p = gf.Params(0.5, 0.0, 1.0, 0.002)
    r = gf.slide(p, kin_vec, kin_one, np.array([0.0, 0.9, 0.99]), np.array([0, 1, 0]), np.array([1.0, 0.95, 1.0]), 1.0)
    assert r.exited.tolist() == [True, False, False]
    assert r.t_exit[0] <= 1.0
    assert np.isfinite(r.t_exit).all() and np.isfinite(r.v_exit).all()


def test_a_leaf_held_to_the_end_never_slips() -> None:
    p = gf.Params(50.0, 0.0, 0.0, 0.002)  # |tan θ'| >= 1/50 nearly everywhere
    t_in = np.array([0.0])
    r = gf.slide(p, kin_vec, kin_one, t_in, np.array([0]), np.array([1.0]), 3.0)
    assert r.stick_t.size >= 1 and not r.exited.any()
