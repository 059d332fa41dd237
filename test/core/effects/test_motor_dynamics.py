"""Effect motor_dynamics: the master drive from the motor ODE (closed forms, brake, load, inverse)."""

from __future__ import annotations

import dataclasses
import math
from itertools import pairwise
from typing import Any

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from folder_line.config.params import load_params
from folder_line.core.effects import chain_friction as cf
from folder_line.core.effects import motor_dynamics as md
from folder_line.core.line.drives import make_drive
from folder_line.core.line.model import simulate
from folder_line.core.line.scene import Scene, parse_scene
from folder_line.core.mechanisms.drive import Drive
from folder_line.errors import ParameterError
from folder_line.interfaces import EVENT_KINDS

from .._reference import EPS
from .._scenes import folder_scene

#: the suggested scene values (report): lambda_steady ~ 1 with the default chain load
MOTOR: dict[str, Any] = dict(
    J=0.5,
    T_0=264.6,
    omega_0=157.08,
    omega_nom=152.4,
    b=0.03,
    method='dopri5',
    h=0.01,
    rtol=1e-10,
    atol=1e-12,
    t_stop=1e9,
    T_brake=0.0,
)
CHAIN: dict[str, Any] = {'P_k': 50.0, 'r': 0.1, 'return_section': 'geometric'}


def make_scene(
    motor: dict[str, Any] | None = None,
    *,
    chain: bool = True,
    chain_params: dict[str, Any] | None = None,
    delivery: dict[str, Any] | None = None,
) -> Scene:
    effects: dict[str, Any] = {'motor_dynamics': {**MOTOR, **(motor or {})}}
    if chain:
        effects['chain_friction'] = {**CHAIN, **(chain_params or {})}
    return folder_scene('motor', effects, delivery=delivery)


def closed_form(p: dict[str, Any], t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Θ(t), ω(t) of the linear ODE from standstill (no position-dependent load)."""
    c = p['T_0'] / p['omega_0'] + p['b']
    tau = p['J'] / c
    w_ss = p['T_0'] / c
    omega = -w_ss * np.expm1(-t / tau)
    theta = w_ss / p['omega_nom'] * (t + tau * np.expm1(-t / tau))
    return theta, omega


def brake_closed_form(p: dict[str, Any]) -> tuple[float, float]:
    """Braking time ``t_rest - t_stop`` (s) and the phase at rest Θ_r (nominal s), no chain load.

    ``J dω/dt = -b ω - T_brake`` from the closed-form speed at ``t_stop``.
    """
    th_s, w_s = (float(v) for v in closed_form(p, np.array(p['t_stop'])))
    Tb, J, b = p['T_brake'], p['J'], p['b']
    if b > 0:
        dt = J / b * math.log1p(b * w_s / Tb)
        th_r = th_s + ((w_s + Tb / b) * J / b * (-math.expm1(-b * dt / J)) - Tb / b * dt) / p['omega_nom']
    else:
        dt = J * w_s / Tb
        th_r = th_s + 0.5 * w_s * dt / p['omega_nom']
    return dt, th_r


# ------------------------------------------------------------------ parameters


@pytest.mark.parametrize(
    'key, value',
    [
        ('J', 0.0),
        ('T_0', -1.0),
        ('omega_0', math.inf),
        ('b', -0.1),
        ('method', 'euler'),
        ('h', 0.0),
        ('rtol', 1e-17),
        ('rtol', 1.0),
        ('atol', 0.0),
        ('t_stop', -1.0),
        ('T_brake', -2.0),
    ],
)
def test_bad_params_name_the_key(key: str, value: Any) -> None:
    with pytest.raises(ParameterError) as info:
        md.Params(**{**MOTOR, key: value})
    assert info.value.key == f'effects.motor_dynamics.{key}'


def test_nominal_speed_must_be_below_no_load_speed() -> None:
    with pytest.raises(ParameterError, match='omega_0') as info:
        md.Params(**{**MOTOR, 'omega_nom': 157.08})
    assert info.value.key == 'effects.motor_dynamics.omega_nom'


def test_steady_state_helpers() -> None:
    p = md.Params(**MOTOR)
    T0 = md.stall_torque_for(p.omega_0, p.omega_nom, p.b, mean_load=3.3)
    q = dataclasses.replace(p, T_0=T0)
    assert md.steady_speed(q, 3.3) == pytest.approx(p.omega_nom, rel=1e-14)
    assert q.omega_free > q.omega_nom
    with pytest.raises(ParameterError):
        md.stall_torque_for(100.0, 150.0, 0.0)


def test_scene_errors() -> None:
    sc = make_scene()
    bare = parse_scene({**dict(sc.source), 'effects': {}})
    with pytest.raises(ParameterError, match='motor_dynamics'):
        md.build_drive(bare, 1.0)
    with pytest.raises(ParameterError) as info:
        md.build_drive(make_scene({'T_0': 5.0}), 1.0)  # peak chain load is 6.49 N m
    assert info.value.key == 'effects.motor_dynamics.T_0'
    with pytest.raises(ParameterError) as info:
        md.build_drive(make_scene(delivery={'alpha_m_deg': 89.999}), 1.0)
    assert info.value.key == 'delivery.alpha_m_deg' and 'self-locks' in str(info.value)
    with pytest.raises(ParameterError) as info:
        md.build_drive(make_scene({'method': 'rk4', 'h': 1.0}), 1.0)
    assert info.value.key == 'effects.motor_dynamics.h' and 'unstable' in str(info.value)
    with pytest.raises(ParameterError):
        md.build_drive(sc, 0.0)


# ------------------------------------------------------------------ closed forms


@pytest.mark.parametrize('periodic', [False, True])
def test_rk4_matches_the_closed_form_with_fourth_order(periodic: bool) -> None:
    t = np.linspace(0.0, 3.0, 3001)
    errs = []
    for h in (0.04, 0.02, 0.01):
        p = {**MOTOR, 'method': 'rk4', 'h': h}
        d = md.build_drive(make_scene(p, chain=False), 3.0, periodic=periodic)
        th, w = closed_form(p, t)
        errs.append(max(np.abs(d.theta(t) - th).max(), np.abs(d.omega(t) - w).max() / p['omega_nom']))
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert errs[-1] < 1e-7
    assert np.all((orders > 3.5) & (orders < 4.5)), (errs, orders)


def test_dopri5_matches_the_closed_form_and_improves_with_rtol() -> None:
    t = np.linspace(0.0, 3.0, 3001)
    errs = []
    for rtol in (1e-4, 1e-6, 1e-8, 1e-10):
        p = {**MOTOR, 'rtol': rtol, 'atol': rtol * 1e-2, 'h': 1.0}
        d = md.build_drive(make_scene(p, chain=False), 3.0, periodic=False)
        th, w = closed_form(p, t)
        errs.append(max(np.abs(d.theta(t) - th).max(), np.abs(d.omega(t) - w).max() / p['omega_nom']))
        assert errs[-1] < 100 * rtol
    assert all(a > 10 * b for a, b in pairwise(errs)), errs
    assert errs[-1] < 1e-9


def test_closed_form_over_a_long_run_with_the_periodic_shortcut() -> None:
    p = {**MOTOR}
    d = md.build_drive(make_scene(p, chain=False), 600.0)
    assert d.tail is not None and d.tail.t_b < 30.0  # ~30 time constants, then the period repeats
    t = np.linspace(0.0, 600.0, 60001)
    th, w = closed_form(p, t)
    np.testing.assert_allclose(d.theta(t), th, rtol=1e-11, atol=1e-11)
    np.testing.assert_allclose(d.omega(t), w, rtol=1e-11, atol=1e-9)
    assert d.steps < 5000


# ------------------------------------------------------------------ brake


@pytest.mark.parametrize('method, h', [('dopri5', 0.01), ('rk4', 1e-3)])
@pytest.mark.parametrize('b', [0.03, 0.0])
def test_brake_stops_at_the_closed_form_time_and_holds(method: str, h: float, b: float) -> None:
    p = {**MOTOR, 'method': method, 'h': h, 'b': b, 't_stop': 5.0, 'T_brake': 50.0}
    d = md.build_drive(make_scene(p, chain=False), 12.0)
    dt, th_r = brake_closed_form(p)
    Tb, J = p['T_brake'], p['J']
    assert d.t_stop == 5.0
    assert d.t_rest == pytest.approx(5.0 + dt, abs=1e-10)
    after = np.linspace(d.t_rest, 12.0, 101)
    assert np.all(d.omega(after) == 0.0) and np.all(d.rate_dot(after) == 0.0)
    np.testing.assert_allclose(d.theta(after), th_r, rtol=1e-10)
    assert np.all(np.diff(d.theta(after)) == 0.0)
    during = np.linspace(5.0, d.t_rest, 1001)[:-1]
    assert np.all(d.omega(during) > 0.0)
    np.testing.assert_allclose(d.rate_dot(during[1:]) * p['omega_nom'], (-b * d.omega(during[1:]) - Tb) / J, rtol=1e-12)
    # the plateau: the earliest time with that phase is the standstill
    assert float(d.time_of(th_r)) == pytest.approx(d.t_rest, abs=1e-6)


@pytest.mark.parametrize('method, h', [('dopri5', 0.01), ('rk4', 1e-3)])
@pytest.mark.parametrize('periodic', [True, False])
def test_brake_without_chain_friction_through_the_line(
    monkeypatch: pytest.MonkeyPatch, method: str, h: float, periodic: bool
) -> None:
    """Regression: the brake segment without ``chain_friction`` (no load, no breaks) stops at the closed form."""
    for name in ('master_load', 'master_load_torque', 'sprocket_torque', 'MasterLoad'):
        monkeypatch.setattr(cf, name, _raiser(name))
    p = {**MOTOR, 'method': method, 'h': h, 't_stop': 2.5, 'T_brake': 40.0}
    scene = make_scene(p, chain=False)
    assert not scene.has('chain_friction')
    dt, th_r = brake_closed_form(p)
    d = md.build_drive(scene, 6.0, periodic=periodic)
    assert d.load is None and d.t_stop == 2.5
    assert d.t_rest == pytest.approx(2.5 + dt, abs=1e-9)
    assert float(d.theta(6.0)) == pytest.approx(th_r, rel=1e-10)
    # the same drive from the line orchestrator, and a folder run on it that ends with the shaft
    streamed = make_drive(scene)
    streamed.extend(6.0)
    assert streamed.t_rest == pytest.approx(d.t_rest, abs=1e-9)
    res = simulate(scene, 6.0, sample_rate=100.0)
    exits = res.events[res.events['kind'] == EVENT_KINDS.index('knife_exit')]
    assert exits.size > 0 and exits['t'].max() <= d.t_rest
    assert all(js.effort is None for js in res.samples.values())


def _raiser(name: str) -> Any:
    def boom(*_a: Any, **_k: Any) -> Any:
        raise AssertionError(f'chain_friction.{name} called although the scene does not list it')

    return boom


def test_brake_with_chain_load_and_a_periodic_tail() -> None:
    p = {**MOTOR, 'rtol': 1e-9, 'atol': 1e-11, 't_stop': 40.0, 'T_brake': 20.0}
    d = md.build_drive(make_scene(p), 45.0)
    assert d.tail is not None and d.tail.t_b < 40.0 and d.tail.t_end == 40.0
    assert 40.0 < d.t_rest < 45.0
    t = np.linspace(0.0, 45.0, 45001)
    w = d.omega(t)
    assert np.all(w >= 0.0) and np.all(w[t >= d.t_rest] == 0.0)
    assert np.all(np.diff(d.theta(t)) >= 0.0)
    # continuity across the seams: tail start, motor off, standstill
    for ts in (d.tail.t_b, 40.0, d.t_rest):
        a, b_ = d.theta([ts - 1e-9, ts + 1e-9])
        assert abs(b_ - a) < 1e-8
        wa, wb = d.omega([ts - 1e-9, ts + 1e-9])
        assert abs(wb - wa) < 1e-5
    # against a full integration of the same run
    full = md.build_drive(make_scene(p), 45.0, periodic=False)
    assert full.t_rest == pytest.approx(d.t_rest, abs=1e-6)
    np.testing.assert_allclose(d.theta(t), full.theta(t), rtol=0, atol=2e-7)


def test_never_started_and_coasting() -> None:
    d = md.build_drive(make_scene({'t_stop': 0.0}), 2.0)
    assert d.t_rest == 0.0
    assert np.all(d.theta([0.0, 1.0, 2.0]) == 0.0) and np.all(d.time_of([0.0, 3.0]) == 0.0)
    coast = md.build_drive(make_scene({'t_stop': 2.0, 'b': 0.0}, chain=False), 4.0)
    assert coast.t_rest == math.inf
    np.testing.assert_allclose(coast.omega([2.0, 3.0, 4.0]), coast.omega(2.0), rtol=1e-14)


# ------------------------------------------------------------------ chain load


def test_chain_load_lowers_the_mean_speed_to_the_estimate() -> None:
    with_load = md.build_drive(make_scene(), 60.0)
    without = md.build_drive(make_scene(chain=False), 60.0)
    lam_load = with_load.mean_rate(50.0, 60.0)
    lam_free = without.mean_rate(50.0, 60.0)
    p = md.Params(**MOTOR)
    assert lam_free == pytest.approx(p.omega_free / p.omega_nom, rel=1e-12)
    assert lam_load < lam_free - 0.01
    load = cf.master_load(make_scene())
    assert lam_load == pytest.approx(md.steady_speed(p, load.mean) / p.omega_nom, rel=1e-4)
    # the suggested defaults give a steady lambda of 1 within 1e-4
    assert lam_load == pytest.approx(1.0, abs=1e-4)
    s = with_load.summary()
    P = with_load.tail.period  # type: ignore[union-attr]
    assert s.lambda_steady == pytest.approx(with_load.mean_rate(50.0, 50.0 + 100 * P), rel=1e-12)
    # the ripple: the speed dips while a carriage is on the stroke
    t = np.linspace(50.0, 50.5, 5001)
    lam = with_load.rate(t)
    assert 1e-4 < lam.max() - lam.min() < 1e-2


def test_chain_load_against_scipy_solve_ivp() -> None:
    p = {**MOTOR, 'rtol': 1e-11, 'atol': 1e-12}
    sc = make_scene(p)
    d = md.build_drive(sc, 2.0, periodic=False)
    P = md.Params(**MOTOR)

    def rhs(t: float, y: np.ndarray) -> np.ndarray:
        load = float(cf.master_load_torque(sc, y[0]))
        return np.array([y[1] / P.omega_nom, (P.T_0 * (1 - y[1] / P.omega_0) - P.b * y[1] - load) / P.J])

    ref = solve_ivp(rhs, (0.0, 2.0), [0.0, 0.0], method='DOP853', rtol=1e-12, atol=1e-12, dense_output=True)
    t = np.linspace(0.0, 2.0, 401)
    np.testing.assert_allclose(d.theta(t), ref.sol(t)[0], rtol=0, atol=1e-8)
    np.testing.assert_allclose(d.omega(t), ref.sol(t)[1], rtol=0, atol=1e-6)
    # RK4 with a fixed step converges to the same solution, 4th order thanks to the breaks
    errs = []
    for h in (4e-3, 2e-3, 1e-3):
        r = md.build_drive(make_scene({**p, 'method': 'rk4', 'h': h}), 2.0, periodic=False)
        errs.append(abs(float(r.theta(2.0)) - float(d.theta(2.0))))
    assert errs[-1] < 1e-9 and errs[0] / errs[-1] > 100, errs


def test_periodic_shortcut_matches_full_integration() -> None:
    p = {**MOTOR, 'rtol': 1e-10}
    short = md.build_drive(make_scene(p), 25.0)
    full = md.build_drive(make_scene(p), 25.0, periodic=False)
    assert short.tail is not None and full.tail is None
    assert short.nfev < 0.7 * full.nfev
    t = np.linspace(0.0, 25.0, 25001)
    np.testing.assert_allclose(short.theta(t), full.theta(t), rtol=0, atol=1e-9)
    np.testing.assert_allclose(short.omega(t), full.omega(t), rtol=0, atol=1e-7)
    th = np.linspace(0.0, short.theta_end, 10001)
    np.testing.assert_allclose(short.time_of(th), full.time_of(th), rtol=0, atol=1e-9)


def test_stiff_start() -> None:
    # tau = J / (T_0/omega_0) = 1e-4 s: a stiff start from standstill
    stiff = {'J': 0.001, 'T_0': 1600.0, 'omega_0': 160.0, 'omega_nom': 152.4, 'b': 0.0, 'rtol': 1e-8, 'atol': 1e-10}
    d = md.build_drive(make_scene(stiff, chain=False), 5.0, periodic=False)
    t = np.linspace(0.0, 5.0, 50001)
    th, w = closed_form({**MOTOR, **stiff}, t)
    np.testing.assert_allclose(d.omega(t), w, rtol=0, atol=1e-5)
    np.testing.assert_allclose(d.theta(t), th, rtol=0, atol=1e-8)
    assert d.steps < 30_000  # stability-limited (~3.3/1e4 s per step), neither blown up nor stalled
    with pytest.raises(ParameterError, match='unstable'):
        md.build_drive(make_scene({**stiff, 'method': 'rk4', 'h': 1e-3}, chain=False), 1.0)
    tt = np.linspace(0.0, 0.05, 5001)
    errs = []
    for h in (2e-5, 1e-5):  # h lambda = 0.2, 0.1: stable and accurate
        r = md.build_drive(make_scene({**stiff, 'method': 'rk4', 'h': h}, chain=False), 0.05)
        errs.append(np.abs(r.omega(tt) - closed_form({**MOTOR, **stiff}, tt)[1]).max())
    assert errs[0] < 1e-5 * 160.0 and errs[1] < errs[0] / 10
    loaded = md.build_drive(make_scene({**stiff, 'T_0': 1600.0}), 3.0)
    assert np.all(np.isfinite(loaded.theta(t[:30001]))) and loaded.tail is not None


# ------------------------------------------------------------------ the Drive protocol


@pytest.fixture(scope='module')
def drive() -> md.MotorDrive:
    return md.build_drive(make_scene({'rtol': 1e-9, 'atol': 1e-11, 't_stop': 50.0, 'T_brake': 10.0}), 60.0)


def test_is_a_drive(drive: md.MotorDrive) -> None:
    assert isinstance(drive, Drive)

    assert isinstance(make_drive(make_scene()), md.MotorDrive)


def test_time_of_inverts_theta(drive: md.MotorDrive) -> None:
    th = np.linspace(0.0, drive.theta_end, 400_001)
    t = drive.time_of(th)
    assert np.all(np.isfinite(t)) and np.all(np.diff(t) >= 0.0)
    np.testing.assert_allclose(drive.theta(t), th, rtol=1e-12, atol=1e-12)
    ts = np.linspace(1e-3, drive.t_rest - 1e-3, 200_001)
    np.testing.assert_allclose(drive.time_of(drive.theta(ts)), ts, rtol=0, atol=1e-9)
    # clipping, never NaN
    assert drive.time_of(-5.0) == 0.0 and drive.time_of(drive.theta_end + 100.0) == drive.t_rest
    assert drive.theta(-1.0) == 0.0 and drive.theta(1e6) == drive.theta_end
    with pytest.raises(ParameterError):
        drive.time_of(np.nan)


def test_rate_and_rate_dot_are_derivatives(drive: md.MotorDrive) -> None:
    t = np.linspace(0.01, 59.9, 20011)
    h = 1e-5
    np.testing.assert_allclose((drive.theta(t + h) - drive.theta(t - h)) / (2 * h), drive.rate(t), rtol=0, atol=2e-6)
    fd = (drive.rate(t + h) - drive.rate(t - h)) / (2 * h)
    rd = drive.rate_dot(t)
    # away from the load's jumps and kinks and the brake onset the finite difference agrees
    # (to its own truncation and the dense output's rounding, ~1e-4 of |rate_dot| ~ 0.5)
    agree = np.abs(fd - rd) <= 2e-4
    assert agree.mean() > 0.995, agree.mean()
    assert np.abs(rd).max() > 0.1
    assert np.all(np.isfinite(drive.rate_dot(np.array([-1.0, 0.0, 50.0, 1e9]))))
    assert drive.rate(0.0) == 0.0 and drive.rate_dot(0.0) > 0.0


def test_determinism() -> None:
    sc = make_scene({'rtol': 1e-8})
    a, b = md.build_drive(sc, 20.0), md.build_drive(sc, 20.0)
    t = np.linspace(0.0, 20.0, 1001)
    assert a.theta(t).tobytes() == b.theta(t).tobytes()
    assert a.solution.coef.tobytes() == b.solution.coef.tobytes()
    assert a.time_of(t).tobytes() == b.time_of(t).tobytes()


# --------------------------------------------------------------------------- stiff start, tiny and huge steps
#: tau = J / (T_0 / omega_0) = 1e-4 s: a stiff start
STIFF: dict[str, Any] = {'J': 0.001, 'T_0': 1600.0, 'omega_0': 160.0, 'omega_nom': 152.4, 'b': 0.0}


def motor_scene(**over: Any) -> Any:
    """The layup machine (cheapest) with motor_dynamics only: no position-dependent load."""
    return parse_scene(
        {
            'name': 'motor',
            'machines': {'layup': dataclasses.asdict(load_params('layup'))},
            'sheets': {'interval': 0.0625, 'jitter': 0.0, 'phase': 0.0, 'thickness': 0.0005},
            'effects': {'motor_dynamics': {**MOTOR, **over}},
        }
    )


def rk4_factor(z: float) -> float:
    """RK4's amplification of the error on y' = -(1/tau) y per step, z = h / tau."""
    return 1 - z + z * z / 2 - z**3 / 6 + z**4 / 24


class TestStiffStartAndStepSizes:
    """Stiff start from standstill; tiny and huge steps (closed forms, the RK4 recurrence)."""

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
        with pytest.raises(ParameterError, match=r'effects.motor_dynamics.h.*stalls and overshoots'):
            md.build_drive(motor_scene(**STIFF, method='rk4', h=2.25 * tau), 0.01)
        with pytest.raises(ParameterError, match=r'effects.motor_dynamics.h.*unstable here'):
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
        steps and is refused at once, naming h (not after minutes); streamed (no end), the drive must still
        settle over 5 time constants, and is refused the same way."""
        drive = md.build_drive(motor_scene(method='rk4', h=1e-9), 1e-5, periodic=False)
        t = np.linspace(0.0, 1e-5, 101)
        th, w = closed_form(MOTOR, t)
        assert drive.steps == 10_000
        assert np.abs(drive.omega(t) - w).max() <= 1e-15 * MOTOR['omega_0']
        assert np.abs(drive.theta(t) - th).max() <= 1e-18
        for method in ('rk4', 'dopri5'):
            with pytest.raises(ParameterError) as info:
                md.build_drive(motor_scene(method=method, h=1e-9), 1.0, periodic=False)
            assert info.value.key == 'effects.motor_dynamics.h' and info.value.value == 1e-9
            span = min(1.0, md.SETTLE_TAUS * md.motor_params(motor_scene()).tau)
            assert f'asks for ~{span / 1e-9:.3g} steps' in str(info.value)
            assert f'at most max_steps={md.MAX_STEPS}' in str(info.value)
            with pytest.raises(ParameterError, match=r'effects.motor_dynamics.h'):
                md.stream_drive(motor_scene(method=method, h=1e-9))
        # the least h refused and the largest taken are one step apart in the steps they ask for
        tau = md.motor_params(motor_scene()).tau
        h_ok = md.SETTLE_TAUS * tau / md.MAX_STEPS
        md.stream_drive(motor_scene(method='dopri5', h=h_ok * 1.0001))
        with pytest.raises(ParameterError, match=r'effects.motor_dynamics.h'):
            md.stream_drive(motor_scene(method='dopri5', h=h_ok * 0.999))

    def test_huge_steps(self) -> None:
        """h = 1 s: RK4 is refused up front (ParameterError naming h) where h c/J > 2.21; on a
        gentle motor it is stable and equals the RK4 recurrence; DOPRI5 with max step 1 s matches
        the closed form to its tolerance."""
        with pytest.raises(ParameterError, match=r'effects.motor_dynamics.h') as info:
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
