"""motor_dynamics under supervisor commands: motor off (brake) and on again at switching times."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from folder_line.config.scenes import load_scene
from folder_line.core.effects import chain_friction as cf
from folder_line.core.effects import motor_dynamics as md
from folder_line.core.line.scene import Scene, parse_scene
from folder_line.core.mechanisms.drive import Command
from folder_line.errors import ParameterError


def motor_scene(chain: bool = True, **motor: float) -> Scene:
    """The shipped ``line`` scene's motor (and chain load), with overrides of its parameters."""
    data = dict(load_scene('line').source)
    effects = dict(data['effects'])
    effects['motor_dynamics'] = {**effects['motor_dynamics'], **motor}
    if not chain:
        effects.pop('chain_friction')
    data['effects'] = effects
    return parse_scene(data)


def closed_on(p: md.Params, s: np.ndarray, theta0: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Θ, ω a time s after switching the motor on at standstill, no chain load."""
    c = p.T_0 / p.omega_0 + p.b
    tau, w_ss = p.J / c, p.T_0 / c
    return theta0 + w_ss / p.omega_nom * (s + tau * np.expm1(-s / tau)), -w_ss * np.expm1(-s / tau)


def closed_brake(p: md.Params, w_s: float) -> tuple[float, float]:
    """Time to standstill and Θ advance while braking from ω_s (no chain load, b > 0)."""
    tb, k = p.J / p.b, p.T_brake / p.b
    s = tb * math.log((w_s + k) / k)
    return s, (tb * (w_s + k) * -math.expm1(-s / tb) - k * s) / p.omega_nom


@pytest.fixture(scope='module')
def loaded() -> Scene:
    return motor_scene(rtol=1e-10, atol=1e-12)


def test_a_command_leaves_the_drive_before_it_unchanged_bit_for_bit(loaded: Scene) -> None:
    plain = md.build_drive(loaded, 30.0)
    held = md.build_drive(loaded, 30.0, commands=[Command(12.0, 'hold'), Command(20.0, 'unhold')])
    more = md.build_drive(
        loaded, 30.0, commands=[Command(12.0, 'hold'), Command(20.0, 'unhold'), Command(25.0, 'stop')]
    )
    t = np.linspace(0.0, 12.0, 60001)[:-1]
    assert plain.theta(t).tobytes() == held.theta(t).tobytes()
    assert plain.rate(t).tobytes() == held.rate(t).tobytes()
    th = plain.theta(t)
    assert plain.time_of(th).tobytes() == held.time_of(th).tobytes()
    t2 = np.linspace(12.0, 25.0, 30001)[:-1]
    assert held.theta(t2).tobytes() == more.theta(t2).tobytes()
    assert held.switches == [(12.0, False), (20.0, True)] and more.switches[-1] == (25.0, False)
    assert held.t_stop == 12.0 and 12.0 < held.t_rest < 20.0
    # held: standing still, with the brake holding; the plateau maps to its first instant
    rest = np.linspace(held.t_rest, 20.0, 101)[:-1]
    assert np.all(held.theta(rest) == held.theta(held.t_rest)) and np.all(held.rate(rest) == 0.0)
    assert np.all(held.rate_dot(rest) == 0.0)
    assert float(held.time_of(held.theta(19.0))) == pytest.approx(held.t_rest, abs=1e-6)
    # running again: the same periodic steady speed as before the hold
    assert held.mean_rate(28.0, 30.0) == pytest.approx(plain.mean_rate(28.0, 30.0), rel=1e-6)


def test_stop_command_matches_the_scene_stop_time() -> None:
    p = dict(rtol=1e-10, atol=1e-12, T_brake=40.0, b=0.03)
    by_scene = md.build_drive(motor_scene(chain=False, t_stop=5.0, **p), 12.0)
    by_command = md.build_drive(motor_scene(chain=False, **p), 12.0, commands=[Command(5.0, 'stop')])
    assert by_command.t_stop == by_scene.t_stop == 5.0
    assert by_command.t_rest == pytest.approx(by_scene.t_rest, abs=1e-9)
    t = np.linspace(0.0, 12.0, 12001)
    np.testing.assert_allclose(by_command.theta(t), by_scene.theta(t), rtol=0, atol=1e-9)
    params = motor_scene(chain=False, **p).effect('motor_dynamics')
    th5, w5 = (float(v) for v in closed_on(params, np.array(5.0)))
    s, dth = closed_brake(params, w5)
    assert by_command.t_rest == pytest.approx(5.0 + s, abs=1e-8)
    assert float(by_command.theta(12.0)) == pytest.approx(th5 + dth, abs=1e-8)


@pytest.mark.parametrize('method, h', [('dopri5', 0.01), ('rk4', 1e-3)])
def test_restart_from_standstill_is_the_closed_form_start(method: str, h: float) -> None:
    kw: dict[str, Any] = dict(method=method, h=h, rtol=1e-10, atol=1e-12, T_brake=40.0)
    sc = motor_scene(chain=False, **kw)
    d = md.build_drive(sc, 20.0, commands=[Command(3.0, 'hold'), Command(9.0, 'unhold')])
    p = sc.effect('motor_dynamics')
    assert d.t_rest < 9.0
    theta_r = float(d.theta(9.0))
    s = np.linspace(0.0, 11.0, 5501)
    th, w = closed_on(p, s, theta_r)
    np.testing.assert_allclose(d.theta(9.0 + s), th, rtol=0, atol=1e-8)
    np.testing.assert_allclose(d.omega(9.0 + s), w, rtol=0, atol=1e-6)
    assert [seg.on for seg in d.segments] == [True, False, True]


def test_unhold_while_coasting_down_against_solve_ivp(loaded: Scene) -> None:
    """Motor off at 2 s, on again at 2.5 s (still turning): the switched ODE, integrated independently."""
    d = md.build_drive(loaded, 4.0, commands=[Command(2.0, 'stop'), Command(2.5, 'start')], periodic=False)
    p = loaded.effect('motor_dynamics')
    assert float(d.omega(2.5)) > 0.3 * p.omega_nom  # not at rest: the restart continues from the coasting state

    def rhs(t: float, y: np.ndarray) -> np.ndarray:
        load = float(cf.master_load_torque(loaded, y[0]))
        drive = p.T_0 * (1 - y[1] / p.omega_0) if not 2.0 <= t < 2.5 else -p.T_brake
        return np.array([y[1] / p.omega_nom, (drive - p.b * y[1] - load) / p.J])

    y = np.zeros(2)
    for span in ((0.0, 2.0), (2.0, 2.5), (2.5, 4.0)):
        ref = solve_ivp(rhs, span, y, method='DOP853', rtol=1e-11, atol=1e-12, dense_output=True)
        t = np.linspace(*span, 301)
        np.testing.assert_allclose(d.theta(t), ref.sol(t)[0], rtol=0, atol=2e-8)
        np.testing.assert_allclose(d.omega(t), ref.sol(t)[1], rtol=0, atol=2e-6)
        y = ref.y[:, -1]


def test_redundant_and_late_commands_change_nothing(loaded: Scene) -> None:
    a = md.build_drive(loaded, 10.0, commands=[Command(5.0, 'hold')])
    b = md.build_drive(
        loaded,
        10.0,
        commands=[Command(1.0, 'start'), Command(5.0, 'hold'), Command(6.0, 'stop'), Command(11.0, 'unhold')],
    )
    t = np.linspace(0.0, 10.0, 20001)
    assert a.theta(t).tobytes() == b.theta(t).tobytes()
    assert b.switches == [(5.0, False)]
    with pytest.raises(ParameterError, match='sorted'):
        md.build_drive(loaded, 10.0, commands=[Command(5.0, 'hold'), Command(1.0, 'unhold')])
    s = b.summary()
    assert s.switches == [(5.0, False)] and md.build_drive(loaded, 1.0).summary().switches is None


@pytest.fixture(scope='module')
def switched(loaded: Scene) -> md.MotorDrive:
    return md.build_drive(
        loaded,
        40.0,
        commands=[Command(15.0, 'hold'), Command(16.0, 'unhold'), Command(30.0, 'stop'), Command(35.0, 'start')],
    )


@settings(max_examples=200, deadline=None)
@given(t=st.floats(-1.0, 41.0))
def test_theta_rate_is_theta_and_rate_bit_for_bit(switched: md.MotorDrive, t: float) -> None:
    th, lam = switched.theta_rate(np.array([t]))
    assert th.tobytes() == switched.theta(np.array([t])).tobytes()
    assert lam.tobytes() == switched.rate(np.array([t])).tobytes()
    big = np.array([t, 2.0, 20.0, 33.0])
    a, b = switched.theta_rate(big)
    assert a.tobytes() == switched.theta(big).tobytes() and b.tobytes() == switched.rate(big).tobytes()


def test_switched_drive_is_a_monotone_invertible_drive(switched: md.MotorDrive) -> None:
    t = np.linspace(0.0, 40.0, 200001)
    th = switched.theta(t)
    assert np.all(np.isfinite(th)) and np.all(np.diff(th) >= 0.0)
    assert np.all(switched.rate(t) >= 0.0) and np.all(np.isfinite(switched.rate_dot(t)))
    phases = np.linspace(0.0, switched.theta_end, 100001)
    back = switched.time_of(phases)
    assert np.all(np.diff(back) >= 0.0)
    np.testing.assert_allclose(switched.theta(back), phases, rtol=1e-12, atol=1e-12)
    # continuity at every switch
    for ts, _ in switched.switches:
        a, b = switched.theta([ts - 1e-9, ts + 1e-9])
        assert abs(b - a) < 1e-7
        wa, wb = switched.omega([ts - 1e-9, ts + 1e-9])
        assert abs(wb - wa) < 1e-4
