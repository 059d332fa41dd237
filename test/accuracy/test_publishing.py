"""Study ``publishing``: the rebuilt knife position against theory, the reference against mpmath, the live cost.

The live-line tests run real DDS on the test process's own ROS domain, with discovery kept
on this host (``test/conftest.py``).
"""

from __future__ import annotations

import dataclasses
import re
from functools import cache, lru_cache

import mpmath as mp
import numpy as np
import pytest

from folder_line.accuracy import publishing as pub
from folder_line.config.scenes import load_scene
from folder_line.core.line.model import LineModel
from folder_line.core.mechanisms.knife import KnifeParams
from folder_line.errors import MeasurementError, ParameterError
from folder_line.interfaces import JOINT_NODES

DURATION = 2.0  # s of line time the errors are measured over
RESOLVED = tuple(r for r in pub.RATES if r >= 100.0)  # >= 7 samples per knife cycle: the asymptotic range


def _knife() -> KnifeParams:
    return load_scene(pub.SCENE).machines['knife']


@lru_cache(maxsize=1)
def _model() -> LineModel:
    return pub.knife_model(DURATION)


@cache
def _error(rate: float, method: str) -> float:
    return pub.reconstruction_error(rate, method, duration=DURATION, model=_model())


# --------------------------------------------------------------------------- the reference, in mpmath


def _mp_knife(t: float) -> tuple[mp.mpf, mp.mpf]:
    """Knife position (m) and velocity (m/s) at time ``t`` from the crank-slider's loop, in mpmath.

    The crank pin is at ``r (cos phi, sin phi)``, the knife edge at ``(s, e)`` on the
    stroke axis, the rod between them has length ``L``: ``(s - r cos phi)^2 +
    (e - r sin phi)^2 = L^2``, solved for ``s`` by the secant method from the rod
    stretched along the axis; ``ds/dt`` by differentiating the loop equation.
    """
    kp = _knife()
    r, L, e = mp.mpf(kp.r_k), mp.mpf(kp.L_k), mp.mpf(kp.e)
    w = 2 * mp.pi * mp.mpf(kp.n_k) / 3600
    phi = w * mp.mpf(t)
    cx, cy = r * mp.cos(phi), r * mp.sin(phi)
    s = mp.findroot(lambda x: (x - cx) ** 2 + (e - cy) ** 2 - L**2, cx + L, tol=mp.mpf(10) ** -50)
    # d/dt: (s - cx)(s' + r w sin phi) - (e - cy) r w cos phi = 0
    v = (e - cy) * w * cx / (s - cx) - w * cy
    return s, v


def _mp_max_derivative(order: int) -> float:
    """``max_t |d^order s / dt^order|`` of the knife, from mpmath (grid of 720 angles, then Newton on the next one)."""
    kp = _knife()
    r, L, e = mp.mpf(kp.r_k), mp.mpf(kp.L_k), mp.mpf(kp.e)
    w = 2 * mp.pi * mp.mpf(kp.n_k) / 3600

    def s(phi: mp.mpf) -> mp.mpf:
        return r * mp.cos(phi) + mp.sqrt(L**2 - (r * mp.sin(phi) - e) ** 2)

    n = 720
    grid = [2 * mp.pi * i / n for i in range(n)]
    values = [abs(mp.diff(s, phi, order)) for phi in grid]
    best = max(range(n), key=lambda i: values[i])
    phi_star = mp.findroot(lambda x: mp.diff(s, x, order + 1), grid[best])
    return float(max(values[best], abs(mp.diff(s, phi_star, order))) * w**order)


@lru_cache(maxsize=1)
def _a_max() -> float:
    with mp.workdps(30):
        return _mp_max_derivative(2)


@lru_cache(maxsize=1)
def _snap_max() -> float:
    with mp.workdps(30):
        return _mp_max_derivative(4)


def test_core_knife_agrees_with_an_independent_crank_slider_in_mpmath() -> None:
    rng = np.random.default_rng(7)
    kp = _knife()
    t_dead = np.arange(0, 40) * kp.period / 2  # both dead centres, where s'' is largest
    t = np.sort(np.concatenate([rng.uniform(0.0, DURATION, 300), t_dead[t_dead <= DURATION]]))
    js = _model().sample(pub.JOINT_UNIT, t)
    j = js.names.index(pub.JOINT)
    with mp.workdps(30):
        exact = [_mp_knife(float(x)) for x in t]
    s_err = max(abs(float(js.position[i, j] - ex[0])) for i, ex in enumerate(exact))
    v_err = max(abs(float(js.velocity[i, j] - ex[1])) for i, ex in enumerate(exact))
    assert s_err <= 1e-12
    assert v_err <= 1e-9  # |v| <= 4 m/s
    # the stream helper publishes the same values as the node's model at the tick grid
    t_k, p_k, v_k = pub.knife_stream(_model(), 500.0, 0.5)
    assert np.array_equal(t_k, np.arange(251) / 500.0)
    with mp.workdps(30):
        for i in (0, 37, 250):
            s_ex, v_ex = _mp_knife(float(t_k[i]))
            assert abs(float(p_k[i] - s_ex)) <= 1e-12 and abs(float(v_k[i] - v_ex)) <= 1e-9


# --------------------------------------------------------------------------- error against theory


def test_linear_error_is_within_the_acceleration_bound_and_tight() -> None:
    a_max = _a_max()
    kp = _knife()  # the central crank-slider's outer dead centre: omega^2 r (1 + r / L)
    assert a_max == pytest.approx(kp.omega_k**2 * kp.r_k * (1.0 + kp.r_k / kp.L_k), rel=1e-12)
    for rate in pub.RATES:
        bound = a_max / (8.0 * rate**2)
        err = _error(rate, 'linear interpolation')
        assert err <= bound * (1.0 + 1e-9), (rate, err, bound)
        if rate >= 200.0:  # samples straddle a dead centre within 2 s: the bound is attained to < 5 %
            assert err >= 0.95 * bound, (rate, err, bound)


def test_hermite_error_is_within_the_fourth_derivative_bound() -> None:
    snap = _snap_max()
    for rate in pub.RATES:
        bound = snap / (384.0 * rate**4)
        err = _error(rate, 'cubic Hermite')
        assert err <= bound * (1.0 + 1e-9), (rate, err, bound)
        if rate >= 200.0:
            assert err >= 0.95 * bound, (rate, err, bound)
        # and the velocities help: Hermite beats linear interpolation at every rate
        assert err < _error(rate, 'linear interpolation')


@pytest.mark.parametrize(('method', 'order'), [('linear interpolation', 2.0), ('cubic Hermite', 4.0)])
def test_error_falls_as_a_power_of_the_rate(method: str, order: float) -> None:
    rates = np.array(RESOLVED)
    errors = np.array([_error(r, method) for r in rates])
    slope = np.polyfit(np.log(rates), np.log(errors), 1)[0]
    assert -order - 0.05 <= slope <= -order + 0.05, slope
    # at 2000 Hz the error is still far above rounding (positions ~0.2 m, ulp ~3e-17 m)
    assert errors[-1] > 1e-12


def test_reconstruct_is_exact_for_its_degree() -> None:
    t_k = np.linspace(0.0, 1.0, 11)
    t = np.linspace(0.0, 1.0, 1001)
    lin = pub.reconstruct('linear interpolation', t_k, 3.0 * t_k - 1.0, np.full(11, 3.0), t)
    assert np.max(np.abs(lin - (3.0 * t - 1.0))) <= 1e-15
    cubic = pub.reconstruct('cubic Hermite', t_k, t_k**3 - 2.0 * t_k, 3.0 * t_k**2 - 2.0, t)
    assert np.max(np.abs(cubic - (t**3 - 2.0 * t))) <= 1e-14
    with pytest.raises(ParameterError, match='method'):
        pub.reconstruct('spline', t_k, t_k, t_k, t)


# --------------------------------------------------------------------------- cost in the live line


def test_published_check_threshold() -> None:
    def cost(n: int) -> pub.LiveCost:
        return pub.LiveCost(
            rate=100.0,
            rtf=2.0,
            clock_rate=200.0,
            t_start=1.0,
            t_end=2.0,
            cpu_s=0.3,
            wall_s=0.5,
            published={'crank_drive': 100, 'belt_conveyor': n, 'feed_transporter': 100},
        )

    pub.check_published(cost(90))  # 90 of 100 owed: enough
    assert cost(90).published_fraction == pytest.approx(0.9)
    with pytest.raises(MeasurementError, match=r'belt_conveyor published 89 of 100 ticks'):
        pub.check_published(cost(89))
    # a node's own span: it was 6 grid points ahead of the recorder at the start, so it owed 94
    ahead = dataclasses.replace(cost(94), owed={'crank_drive': 100, 'belt_conveyor': 94, 'feed_transporter': 100})
    assert ahead.published_fraction == 1.0
    with pytest.raises(MeasurementError, match=r'belt_conveyor published 84 of 94 ticks'):
        pub.check_published(dataclasses.replace(ahead, published={**ahead.published, 'belt_conveyor': 84}))


def test_live_cost_grows_with_the_rate() -> None:
    # measured_cost halves the rtf (at most four times) while a loaded machine keeps the line from its pace
    assert pub.default_rtf(100.0) == 2.0 and pub.default_rtf(1000.0) == 0.2
    low = pub.measured_cost(100.0, span_ticks=200, warmup_wall=0.4)
    high = pub.measured_cost(1000.0, span_ticks=200, warmup_wall=0.4)
    for c in (low, high):
        pub.check_published(c)  # >= 90 % of the ticks published: the cost is of a line that keeps up
        assert c.published_fraction >= pub.MIN_PUBLISHED
        assert set(c.published) == set(JOINT_NODES)  # sheet_counter too: the pile table
        assert max(c.published.values()) <= c.ticks_owed + 2  # never more than one message per tick
        assert any(c.rtf == pytest.approx(pub.default_rtf(c.rate) / k) for k in (1, 2, 4, 8, 16))
        assert c.span == pytest.approx(200.0 / c.rate, rel=0.05)
        assert c.wall_s == pytest.approx(c.span / c.rtf, rel=0.25)  # the clock kept its real-time factor
        assert c.supervisor_state  # the recorder heard the supervisor (EXECUTE unless it held: see measured_cost)
    # ten times the rate at the same ticks per wall second: several times the CPU per simulated second
    assert high.cpu_s_per_sim_s > 2.0 * low.cpu_s_per_sim_s, (low, high)


def test_a_slow_clock_no_longer_starves_the_nodes() -> None:
    # lockstep: a node publishes every point of its own grid up to each tick, so 50 ticks per sim s still
    # carry all 1000 joint states per sim s (before lockstep this published <= 30 % of them)
    cost = pub.live_cost(1000.0, rtf=0.2, clock_rate=50.0, span_ticks=100, warmup_wall=0.3)
    assert cost.published_fraction == 1.0
    pub.check_published(cost)


def test_run_quick_rows() -> None:
    rows = pub.run(quick=True)
    assert [(r.method, r.value) for r in rows] == [(m, rate) for rate in pub.RATES_QUICK for m in pub.METHODS]
    model = pub.knife_model(1.0)
    for r in rows:
        assert (r.study, r.knob, r.quantity, r.unit) == ('publishing', 'rate', 'knife position', 'm')
        assert r.error == pub.reconstruction_error(r.value, r.method, duration=1.0, model=model)
        published = re.search(r'([0-9.]+)% of ([0-9]+) ticks published', r.reference)
        assert published is not None and 'recorder' in r.reference, r.reference
        assert float(published[1]) >= 100.0 * pub.MIN_PUBLISHED and abs(int(published[2]) - 300) <= 2
    costs = [r.cpu_s_per_sim_s for r in rows]
    assert costs[0::2] == costs[1::2]  # both methods of a rate share the rate's live cost
    assert costs[0] < costs[2] < costs[4]  # 50 < 200 < 1000 Hz
    assert min(pub.RATES) == 50.0 and max(pub.RATES) == 2000.0 and len(pub.RATES) >= 4
