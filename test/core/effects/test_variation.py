"""The variation effects: arrival_jitter, length_scatter, speed_ripple, property_scatter.

Each against a closed form: the feed travel ``L_feed + δ_k - ΔL_k`` shifts a signature's
arrival by exactly its extra travel over V_tr; the ripple's phase map integrates in
closed form; a scattered restitution or friction gives each signature the rebound and
the slip of its own value. Draws are per sheet: a longer run agrees with a shorter one.
"""

from __future__ import annotations

import copy
import dataclasses
import math
from typing import Any

import numpy as np
import pytest
from numpy.testing import assert_allclose

from folder_line.config.scenes import scene_mapping
from folder_line.core.effects import arrival_jitter, feed_slip, length_scatter, property_scatter, speed_ripple
from folder_line.core.line.drives import make_drive
from folder_line.core.line.model import LineResult, simulate
from folder_line.core.line.scene import Scene, parse_scene
from folder_line.core.mechanisms.cyclogram import cycle_timing
from folder_line.core.mechanisms.drive import Command
from folder_line.errors import ParameterError

V_TR = 9.3


def _scene(effects: dict[str, Any], **top: Any) -> Scene:
    """The shipped folder scene with ``effects`` added (and top-level keys replaced)."""
    data = copy.deepcopy(scene_mapping('folder'))
    data['effects'].update(effects)
    data.update(top)
    return parse_scene(data)


def _by_sheet(result: LineResult, kind: str) -> dict[int, float]:
    rows = result.events_of(kind)
    return dict(zip(rows['sheet'].tolist(), rows['t'].tolist(), strict=True))


@pytest.fixture(scope='module')
def nominal() -> LineResult:
    return simulate(_scene({}), 8.0)


# --------------------------------------------------------------------------- arrival_jitter, length_scatter


@pytest.mark.parametrize('distribution', ['normal', 'uniform'])
def test_jitter_shifts_each_feed_margin_by_its_offset_over_V_tr(nominal: LineResult, distribution: str) -> None:
    scene = _scene({'arrival_jitter': {'distribution': distribution, 'sigma': 1.0}})
    got = simulate(scene, 8.0).constraint('feed_window')
    base = nominal.constraint('feed_window')
    assert np.array_equal(got.cycle, base.cycle) and got.cycle.size > 50
    n = got.cycle.size  # one signature per cycle, sheet k in cycle k
    delta = arrival_jitter.draw_offsets(scene.effect_params('arrival_jitter'), scene.seed, n)
    assert np.ptp(delta) > 1e-3  # a spread of millimetres
    assert_allclose(got.margin, base.margin - delta / V_TR, rtol=0.0, atol=1e-15)
    if distribution == 'uniform':
        assert np.max(np.abs(delta)) <= math.sqrt(3.0) * 1e-3


def test_length_scatter_moves_the_leading_edge_and_adds_to_jitter(nominal: LineResult) -> None:
    scene = _scene(
        {'arrival_jitter': {'distribution': 'normal', 'sigma': 0.5}, 'length_scatter': {'sigma': 2.0}}, seed=9
    )
    got = simulate(scene, 8.0).constraint('feed_window')
    base = nominal.constraint('feed_window')
    n = got.cycle.size
    delta = arrival_jitter.draw_offsets(scene.effect_params('arrival_jitter'), 9, n)
    excess = length_scatter.draw_excess(scene.effect_params('length_scatter'), 9, n)
    assert np.std(excess) > 1e-3  # visible: σ 2 mm
    # a longer signature (excess > 0) has its leading edge further on: earlier at the stops
    assert_allclose(got.margin, base.margin - (delta - excess) / V_TR, rtol=0.0, atol=1e-15)


def test_zero_sigma_is_the_nominal_run_bit_for_bit(nominal: LineResult) -> None:
    scene = _scene({'arrival_jitter': {'distribution': 'normal', 'sigma': 0.0}, 'length_scatter': {'sigma': 0.0}})
    got = simulate(scene, 8.0)
    assert got.events.tobytes() == nominal.events.tobytes()


def test_a_jitter_as_long_as_the_feed_is_refused() -> None:
    with pytest.raises(ParameterError, match=r'effects.arrival_jitter.sigma'):
        simulate(_scene({'arrival_jitter': {'distribution': 'normal', 'sigma': 40.0}}), 1.0)  # 6σ = 240 mm > 230
    with pytest.raises(ParameterError, match=r'effects.arrival_jitter.distribution'):
        _scene({'arrival_jitter': {'distribution': 'cauchy', 'sigma': 1.0}})


def test_draws_are_per_sheet_a_longer_run_agrees_on_the_shared_sheets() -> None:
    effects = {
        'arrival_jitter': {'distribution': 'uniform', 'sigma': 0.7},
        'length_scatter': {'sigma': 0.4},
        'speed_ripple': {'amplitude': 0.002, 'frequency': 3.0},
        'property_scatter': {'e_sigma': 0.2, 'mu_sigma': 0.1},
        'feed_slip': {'mu': 0.5, 'p': 40.0, 'm': 0.02},
    }
    data = copy.deepcopy(scene_mapping('folder'))
    data['effects'].update(effects)
    data['machines']['feed_transporter']['V_tr'] = 9.8  # with slip, in time
    scene = parse_scene(data)
    short, long_ = simulate(scene, 3.0), simulate(scene, 7.0)
    for kind in ('at_stops', 'settled', 'sheet_handover'):
        a, b = _by_sheet(short, kind), _by_sheet(long_, kind)
        assert a and all(b[k] == v for k, v in a.items())
    ra, rb = short.events_of('bounce'), long_.events_of('bounce')
    assert np.array_equal(ra, rb[: ra.size])


# --------------------------------------------------------------------------- speed_ripple


def test_ripple_phase_is_a_closed_form_and_time_of_its_exact_inverse() -> None:
    p = speed_ripple.Params(amplitude=0.05, frequency=7.0)
    scene = _scene({'speed_ripple': {'amplitude': 0.05, 'frequency': 7.0}}, seed=4)
    drive = make_drive(scene)
    psi = speed_ripple.draw_phase(4)
    w = 2.0 * math.pi * 7.0
    t = np.linspace(0.0, 10.0, 10_001)
    assert_allclose(drive.theta(t), t + (0.05 / w) * (np.sin(w * t + psi) - math.sin(psi)), rtol=0, atol=1e-14)
    assert_allclose(drive.rate(t), 1.0 + 0.05 * np.cos(w * t + psi), rtol=0, atol=1e-15)
    assert_allclose(drive.rate_dot(t), -0.05 * w * np.sin(w * t + psi), rtol=0, atol=1e-12)
    assert_allclose(drive.time_of(drive.theta(t)), t, rtol=0, atol=4e-15 * 10.0)
    assert_allclose(speed_ripple.phase_inverse(p, psi, speed_ripple.phase_map(p, psi, t)[0]), t, rtol=0, atol=4e-14)


def test_ripple_moves_the_knife_to_its_phase() -> None:
    scene = _scene({'speed_ripple': {'amplitude': 0.05, 'frequency': 2.0}}, seed=4)
    result = simulate(scene, 5.0)
    timing = cycle_timing(scene.machine('cyclogram'), scene.machine('knife'))
    contact = result.events_of('knife_contact')
    drive = make_drive(scene)
    expected = (contact['cycle'] + 1) * timing.T + timing.knife.t_in
    assert_allclose(drive.theta(contact['t']), expected, rtol=0, atol=1e-13)
    nominal = expected  # on the constant drive Θ = t: the ripple moves the events
    assert np.max(np.abs(contact['t'] - nominal)) > 1e-3


def test_ripple_composes_with_the_supervisors_commands() -> None:
    scene = _scene({'speed_ripple': {'amplitude': 0.1, 'frequency': 3.0}}, seed=2)
    plain = make_drive(scene)
    held = make_drive(scene, [Command(2.0, 'hold'), Command(5.0, 'unhold')])
    before = np.linspace(0.0, 2.0, 401)
    assert held.theta(before).tobytes() == plain.theta(before).tobytes()  # causal: nothing changes before
    stand = np.linspace(2.6, 5.0, 50)  # t_brake 0.5 s: standing from 2.5 s until the unhold
    assert np.all(held.rate(stand) == 0.0) and np.ptp(held.theta(stand)) == 0.0
    t = np.linspace(0.0, 10.0, 2001)
    th = held.theta(t)
    assert np.all(np.diff(th) >= 0.0)
    moving = np.diff(th) > 0.0
    assert_allclose(held.time_of(th)[1:][moving], t[1:][moving], rtol=0, atol=1e-12)


def test_ripple_amplitude_is_bounded() -> None:
    with pytest.raises(ParameterError, match=r'effects.speed_ripple.amplitude'):
        _scene({'speed_ripple': {'amplitude': 0.9, 'frequency': 1.0}})


# --------------------------------------------------------------------------- property_scatter


def test_restitution_scatter_gives_each_sheet_its_own_rebound() -> None:
    scene = _scene({'property_scatter': {'e_sigma': 0.3, 'mu_sigma': 0.0}}, seed=5)
    result = simulate(scene, 5.0)
    bounce = result.events_of('bounce')
    first = {}
    for row in bounce:  # rows sorted by time: a sheet's first bounce comes first
        first.setdefault(int(row['sheet']), float(row['value']))
    bp = scene.effect_params('stop_bounce')
    n = int(result.events_of('sheet_handover').size)
    e = property_scatter.restitution(scene.effect_params('property_scatter'), bp.e, 5, n)
    assert np.ptp(e) > 0.03 and np.all(e < 1.0)
    for k, rebound in first.items():  # impact at V_tr on a constant drive
        assert rebound == pytest.approx((e[k] * V_TR) ** 2 / (2.0 * bp.a_f), rel=1e-12)


def test_friction_scatter_gives_each_sheet_its_own_slip() -> None:
    slip = {'mu': 0.5, 'p': 40.0, 'm': 0.02}
    data = copy.deepcopy(scene_mapping('folder'))
    data['effects'].update({'feed_slip': slip, 'property_scatter': {'e_sigma': 0.0, 'mu_sigma': 0.3}})
    data['machines']['feed_transporter']['V_tr'] = 9.8
    data['seed'] = 6
    scene = parse_scene(data)
    result = simulate(scene, 5.0)
    hand, stops = _by_sheet(result, 'sheet_handover'), _by_sheet(result, 'at_stops')
    params = scene.effect_params('feed_slip')
    mu = property_scatter.friction(scene.effect_params('property_scatter'), 0.5, 6, len(hand))
    timing = cycle_timing(scene.machine('cyclogram'), scene.machine('knife'))
    for k, t_a in stops.items():  # each sheet against the scalar closed form at its own mu
        own = dataclasses.replace(params, mu=float(mu[k]))
        t = float(feed_slip.arrival(own, timing.V_d, 9.8, timing.L_feed).t)
        assert t_a - hand[k] == pytest.approx(t, rel=1e-12)
    assert np.ptp([stops[k] - hand[k] for k in stops]) > 1e-5


def test_a_scatter_of_an_unlisted_effect_is_refused() -> None:
    with pytest.raises(ParameterError, match=r'effects.property_scatter.mu_sigma=0.1: scatters feed_slip'):
        simulate(_scene({'property_scatter': {'e_sigma': 0.0, 'mu_sigma': 0.1}}), 1.0)
