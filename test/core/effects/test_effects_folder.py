"""feed_slip and stop_bounce: closed forms against independent integrations and brute force."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from folder_line.core.effects import feed_slip, parse_effect_params, stop_bounce
from folder_line.errors import ParameterError

V_D = 5.833326692478048
L_FEED = 0.230
T_ALLOWED = 0.0248311759646518


# --------------------------------------------------------------------------- feed_slip


def test_accel_is_mu_g_plus_p_over_m() -> None:
    p = feed_slip.Params(mu=0.5, p=40.0, m=0.02)
    assert p.accel == pytest.approx(0.5 * (9.80665 + 2000.0), rel=1e-15)
    assert feed_slip.Params(mu=0.3, p=0.0, m=1.0).accel == pytest.approx(0.3 * 9.80665)


@pytest.mark.parametrize(
    ('key', 'value'),
    [('mu', 0.0), ('mu', -0.1), ('mu', math.nan), ('p', -1.0), ('m', 0.0), ('m', math.inf), ('mu', True)],
)
def test_feed_slip_rejects_bad_values(key: str, value: float) -> None:
    values = {'mu': 0.5, 'p': 40.0, 'm': 0.02, key: value}
    with pytest.raises(ParameterError, match=f'effects.feed_slip.{key}'):
        parse_effect_params('feed_slip', values)


def test_feed_slip_params_have_no_defaults() -> None:
    with pytest.raises(ParameterError, match=r'effects.feed_slip.m'):
        parse_effect_params('feed_slip', {'mu': 0.5, 'p': 40.0})


def _ivp_arrival(a: float, V0: float, V1: float, L: float) -> tuple[float, float]:
    """Integrate x'' = a sign(V1 - x') until the speeds match, then ride at V1 (scipy, independent)."""
    sgn = math.copysign(1.0, V1 - V0) if V1 != V0 else 0.0

    def f(_t: float, y: np.ndarray) -> list[float]:
        return [y[1], sgn * a]

    def match(_t: float, y: np.ndarray) -> float:
        return y[1] - V1

    def stops(_t: float, y: np.ndarray) -> float:
        return y[0] - L

    match.terminal = True  # type: ignore[attr-defined]
    stops.terminal = True  # type: ignore[attr-defined]
    if sgn == 0.0:
        return L / V1, V1
    sol = solve_ivp(f, (0.0, 10.0), [0.0, V0], events=[match, stops], rtol=1e-12, atol=1e-14, method='DOP853')
    if sol.t_events[1].size:
        return float(sol.t_events[1][0]), float(sol.y_events[1][0][1])
    t1, x1 = float(sol.t_events[0][0]), float(sol.y_events[0][0][0])
    return t1 + (L - x1) / V1, V1


@pytest.mark.parametrize(
    ('V0', 'V1', 'mu', 'p', 'm'),
    [
        (V_D, 9.3, 0.5, 40.0, 0.02),  # reaches belt speed early
        (V_D, 9.3, 0.3, 0.0, 0.05),  # friction of the weight alone: slides all the way
        (V_D, 9.3, 0.5, 1.4, 0.02),  # reaches belt speed just before the stops
        (9.3, V_D, 0.5, 40.0, 0.02),  # belt slower than the hand-over: decelerates
        (9.3, 2.0, 0.2, 0.0, 0.02),  # decelerates all the way
        (V_D, V_D, 0.5, 40.0, 0.02),  # no slip at all
        (0.0, 9.3, 0.5, 40.0, 0.02),  # from standstill
    ],
)
def test_arrival_matches_ode_integration(V0: float, V1: float, mu: float, p: float, m: float) -> None:
    params = feed_slip.Params(mu=mu, p=p, m=m)
    got = feed_slip.arrival(params, V0, V1, L_FEED)
    t_ref, v_ref = _ivp_arrival(params.accel, V0, V1, L_FEED)
    assert float(got.t) == pytest.approx(t_ref, rel=1e-10, abs=1e-13)
    assert float(got.v_impact) == pytest.approx(v_ref, rel=1e-9, abs=1e-12)


def test_arrival_closed_forms_of_the_brief() -> None:
    params = feed_slip.Params(mu=0.5, p=40.0, m=0.02)
    a = params.accel
    got = feed_slip.arrival(params, V_D, 9.3, L_FEED)
    t1 = (9.3 - V_D) / a
    d1 = (9.3**2 - V_D**2) / (2 * a)
    assert bool(got.reached)
    assert float(got.t) == pytest.approx(t1 + (L_FEED - d1) / 9.3, rel=1e-14)
    assert float(feed_slip.slip_cost(params, V_D, 9.3, L_FEED)) == pytest.approx(
        (9.3 - V_D) ** 2 / (2 * a * 9.3), rel=1e-10
    )
    weak = feed_slip.Params(mu=0.1, p=0.0, m=0.02)
    got = feed_slip.arrival(weak, V_D, 9.3, L_FEED)
    aw = weak.accel
    assert not bool(got.reached)
    t_root = brentq(lambda t: V_D * t + aw * t * t / 2 - L_FEED, 0.0, 1.0, xtol=1e-16, rtol=1e-15)
    assert float(got.t) == pytest.approx(t_root, rel=1e-13)
    assert float(got.v_impact) == pytest.approx(V_D + aw * t_root, rel=1e-12)


@settings(max_examples=300, deadline=None)
@given(
    V0=st.floats(0.0, 20.0),
    V1=st.floats(0.1, 20.0),
    L=st.floats(1e-3, 2.0),
    mu=st.floats(0.01, 2.0),
    p=st.floats(0.0, 200.0),
    m=st.floats(0.005, 1.0),
)
def test_arrival_is_consistent(V0: float, V1: float, L: float, mu: float, p: float, m: float) -> None:
    params = feed_slip.Params(mu=mu, p=p, m=m)
    a = params.accel
    r = feed_slip.arrival(params, V0, V1, L)
    t, v = float(r.t), float(r.v_impact)
    assert math.isfinite(t) and t > 0.0 and math.isfinite(v) and v >= 0.0
    # position at t from the piecewise motion equals L
    s = math.copysign(1.0, V1 - V0)
    t1 = abs(V1 - V0) / a
    if t <= t1:
        x = V0 * t + s * a * t * t / 2
        assert v == pytest.approx(V0 + s * a * t, rel=1e-9, abs=1e-9)
    else:
        x = (V0 + V1) / 2 * t1 + V1 * (t - t1)
        assert v == V1
    assert x == pytest.approx(L, rel=1e-9)
    # arrival lies between the ride at the slower and at the faster of the two speeds
    assert L / max(V0, V1) * (1 - 1e-12) <= t
    if V0 > 0:
        assert t <= L / min(V0, V1) * (1 + 1e-12)


def test_arrival_is_vectorised_and_rejects_bad_speeds() -> None:
    params = feed_slip.Params(mu=0.5, p=40.0, m=0.02)
    V1 = np.array([5.0, 9.3, 12.0])
    r = feed_slip.arrival(params, V_D, V1, L_FEED)
    assert r.t.shape == (3,)
    for i, v in enumerate(V1):
        assert r.t[i] == float(feed_slip.arrival(params, V_D, v, L_FEED).t)
    with pytest.raises(ParameterError, match='V1'):
        feed_slip.arrival(params, V_D, 0.0, L_FEED)
    with pytest.raises(ParameterError, match='V0'):
        feed_slip.arrival(params, -1.0, 9.3, L_FEED)


def test_min_belt_speed_gives_zero_margin() -> None:
    params = feed_slip.Params(mu=0.5, p=40.0, m=0.02)
    v = feed_slip.min_belt_speed(params, V_D, L_FEED, T_ALLOWED)
    assert float(feed_slip.arrival(params, V_D, v, L_FEED).t) == pytest.approx(T_ALLOWED, rel=1e-12)
    assert float(feed_slip.arrival(params, V_D, v * (1 - 1e-6), L_FEED).t) > T_ALLOWED
    # independent: scipy root of the feed time
    ref = brentq(lambda V: float(feed_slip.arrival(params, V_D, V, L_FEED).t) - T_ALLOWED, V_D, 30.0, xtol=1e-14)
    assert v == pytest.approx(ref, rel=1e-11)
    # no speed-up needed / no speed fast enough
    assert feed_slip.min_belt_speed(params, V_D, 0.1, T_ALLOWED) == V_D
    with pytest.raises(ParameterError, match='no belt speed'):
        feed_slip.min_belt_speed(feed_slip.Params(mu=0.4, p=20.0, m=0.03), V_D, L_FEED, T_ALLOWED)


# --------------------------------------------------------------------------- stop_bounce


def _brute_bounces(e: float, a_f: float, v_rest: float, V: float) -> tuple[int, float, list[float]]:
    n, t, rebounds, v = 0, 0.0, [], V
    while e > 0.0 and v >= v_rest:
        v = e * v
        n += 1
        rebounds.append(v * v / (2 * a_f))
        t += 2 * v / a_f
    return n, t, rebounds


@pytest.mark.parametrize(
    ('key', 'value'), [('e', 1.0), ('e', -0.1), ('a_f', 0.0), ('tolerance', 0.0), ('v_rest', 0.0), ('v_rest', math.nan)]
)
def test_stop_bounce_rejects_bad_values(key: str, value: float) -> None:
    values = {'e': 0.1, 'a_f': 400.0, 'tolerance': 0.002, 'v_rest': 0.05, key: value}
    with pytest.raises(ParameterError, match=f'effects.stop_bounce.{key}'):
        parse_effect_params('stop_bounce', values)


def test_bounce_reference_numbers() -> None:
    p = stop_bounce.Params(e=0.1, a_f=400.0, tolerance=0.002, v_rest=0.05)
    # impacts 9.3, 0.93, 0.093 >= 0.05 bounce; 0.0093 does not
    assert int(stop_bounce.bounce_count(p, 9.3)) == 3
    assert float(stop_bounce.first_rebound(p, 9.3)) == pytest.approx(0.93**2 / 800.0, rel=1e-14)
    assert float(stop_bounce.settle_time(p, 9.3)) == pytest.approx(2 * (0.93 + 0.093 + 0.0093) / 400.0, rel=1e-13)


def test_bounce_edge_cases() -> None:
    p0 = stop_bounce.Params(e=0.0, a_f=400.0, tolerance=0.002, v_rest=0.05)
    assert int(stop_bounce.bounce_count(p0, 9.3)) == 0
    assert float(stop_bounce.settle_time(p0, 9.3)) == 0.0 and float(stop_bounce.first_rebound(p0, 9.3)) == 0.0
    p = stop_bounce.Params(e=0.5, a_f=400.0, tolerance=0.002, v_rest=1.0)
    assert int(stop_bounce.bounce_count(p, 0.999)) == 0  # v_rest >= V
    assert int(stop_bounce.bounce_count(p, 0.0)) == 0
    assert int(stop_bounce.bounce_count(p, 1.0)) == 1  # exactly at v_rest: bounces once
    assert int(stop_bounce.bounce_count(p, 2.0)) == 2  # 2 -> 1 (= v_rest, bounces) -> 0.5
    assert int(stop_bounce.bounce_count(p, 4.0)) == 3
    assert int(stop_bounce.bounce_count(p, np.nextafter(4.0, 0.0))) == 2
    with pytest.raises(ParameterError):
        stop_bounce.bounce_count(p, -1.0)


@settings(max_examples=400, deadline=None)
@given(e=st.floats(0.0, 0.95), a_f=st.floats(1.0, 1e4), v_rest=st.floats(1e-4, 5.0), V=st.floats(0.0, 30.0))
def test_bounces_match_brute_force(e: float, a_f: float, v_rest: float, V: float) -> None:
    p = stop_bounce.Params(e=e, a_f=a_f, tolerance=0.002, v_rest=v_rest)
    n, t, rebounds = _brute_bounces(e, a_f, v_rest, V)
    assert int(stop_bounce.bounce_count(p, V)) == n
    assert float(stop_bounce.settle_time(p, V)) == pytest.approx(t, rel=1e-12, abs=1e-300)
    sched = stop_bounce.bounce_schedule(p, np.array([V]), max_events=10_000)
    assert sched.n.tolist() == list(range(1, n + 1))
    assert_allclose(sched.rebound, rebounds, rtol=1e-12, atol=0.0)
    starts = np.concatenate(([0.0], np.cumsum(2 * e ** np.arange(1, n) * V / a_f)))[:n] if n else np.zeros(0)
    assert_allclose(sched.dt, starts, rtol=1e-12, atol=1e-18)


def test_schedule_caps_the_event_rows_not_the_physics() -> None:
    p = stop_bounce.Params(e=0.9, a_f=100.0, tolerance=0.002, v_rest=1e-3)
    V = np.array([9.3, 0.5, 1e-4])
    sched = stop_bounce.bounce_schedule(p, V)
    n = stop_bounce.bounce_count(p, V)
    assert n[0] > stop_bounce.MAX_BOUNCE_EVENTS and n[2] == 0
    assert np.bincount(sched.index, minlength=3).tolist() == [
        stop_bounce.MAX_BOUNCE_EVENTS,
        min(int(n[1]), stop_bounce.MAX_BOUNCE_EVENTS),
        0,
    ]
    assert_allclose(sched.settle, stop_bounce.settle_time(p, V), rtol=1e-15)
