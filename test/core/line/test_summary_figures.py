"""The design figures of the folder's summary: knife window, feed speed, the delivery's efficiency and torque.

Each is checked against an independent computation: the knife kinematics sampled on a grid, the
efficiency and the torque sampled densely along the stroke and over a cycle, and the closed form of
a frictionless delivery (power balance).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from folder_line.config.scenes import load_scene
from folder_line.core.effects import chain_friction
from folder_line.core.line.line_summary import LineSummary
from folder_line.core.line.metric_units import metric_unit
from folder_line.core.line.metrics import flatten_metrics, resolve_metric
from folder_line.core.line.model import simulate
from folder_line.core.line.scene import parse_scene
from folder_line.core.mechanisms import knife as knf
from folder_line.core.mechanisms.chain import chain_path, schedule
from folder_line.core.mechanisms.delivery import evaluate_stroke

_FRICTION = ('f_Ap', 'f_Bp', 'f_A', 'f_B', 'f_O', 'r_A', 'r_B', 'r_O')


def _folder(overrides: dict[str, Any] | None = None) -> LineSummary:
    return simulate(load_scene('folder', overrides or {}), 0.5, sample_rate=0.0).summary()


def test_knife_window_is_the_time_the_knife_occupies_the_table() -> None:
    scene = load_scene('folder')
    kp = scene.machine('knife')
    folder = _folder().folder
    # the occupied share of a crank turn, sampled on a fine grid of crank angles
    phi = np.linspace(-math.pi, math.pi, 2_000_001)
    share = float(np.mean(np.asarray(knf.state(kp, phi).occupies)))
    # the grid resolves the share to a sample at each end: 2 / 2e6 of a turn
    assert folder.knife_window_deg == pytest.approx(360.0 * share, abs=360.0 * 2e-6)
    assert folder.knife_window_s == pytest.approx(share * kp.period, abs=kp.period * 2e-6)
    assert folder.knife_window_s == pytest.approx(0.03, rel=5e-4)  # the paper's 0.03 s
    # the window's ends in crank degrees and in time are the same span
    span = math.radians(folder.knife_out_deg - folder.knife_in_deg)
    assert span / kp.omega_k == pytest.approx(folder.knife_window_s, rel=1e-12)


def test_the_knife_window_shrinks_with_the_press_speed() -> None:
    slow, fast = _folder().folder, _folder({'press.n_c': 30000}).folder
    assert fast.knife_window_deg == pytest.approx(slow.knife_window_deg, rel=1e-12)  # kinematics
    assert fast.knife_window_s == pytest.approx(slow.knife_window_s * 25000 / 30000, rel=1e-12)
    assert fast.V_tr_min == pytest.approx(slow.V_tr_min * 30000 / 25000, rel=1e-12)
    assert fast.V_tr_min_over_V_d == pytest.approx(slow.V_tr_min_over_V_d, rel=1e-12)


def test_efficiency_minimum_is_the_smallest_efficiency_along_the_stroke() -> None:
    scene = load_scene('folder')
    dl = _folder().folder.delivery
    state = chain_friction.stroke_state(
        scene.effect_params('chain_friction'), scene.machine('delivery'), np.linspace(0.0, 2.0, 400_001)
    )
    i = int(np.argmin(state.eta))
    assert dl.eta_min <= float(state.eta[i]) + 1e-12
    assert dl.eta_min == pytest.approx(float(state.eta[i]), abs=1e-8)
    assert dl.eta_min_u == pytest.approx(float(state.u[i]), abs=1e-4)
    assert dl.eta_min_travel_m == pytest.approx(float(chain_path(scene).arc(state.u[i])), abs=1e-4)


def test_delivery_friction_now_shows_in_the_summary() -> None:
    """The issue: ``--set delivery.f_*`` changed nothing visible."""
    base = _folder().folder.delivery
    rough = _folder({f'delivery.{k}': 1.5 * v for k, v in (('f_Ap', 0.1), ('f_A', 0.15), ('f_O', 0.15))})
    more = rough.folder.delivery
    assert more.eta_min < base.eta_min
    assert more.sprocket_torque_peak_Nm > base.sprocket_torque_peak_Nm


def test_sprocket_torque_peak_and_mean_over_a_cycle() -> None:
    scene = load_scene('folder')
    dl = _folder().folder.delivery
    sch = schedule(scene)
    theta = sch.theta_enter0 + np.linspace(0.0, sch.T, 400_001)
    m1 = chain_friction.sprocket_torque(scene, theta)
    assert float(m1.max()) <= dl.sprocket_torque_peak_Nm * (1 + 1e-9)
    assert float(m1.max()) == pytest.approx(dl.sprocket_torque_peak_Nm, rel=1e-4)
    assert float(np.mean(m1[:-1])) == pytest.approx(dl.sprocket_torque_mean_Nm, rel=1e-3)


def test_a_frictionless_delivery_obeys_the_power_balance() -> None:
    """Without friction eta = 1 and M_1 omega = P_k v_k, so M_1 = P_k r K_v: the mean torque is P_k r (carriage
    travel per cycle) / (chain travel per cycle) = P_k r 2 x_max / pitch, the peak P_k r max K_v."""
    over: dict[str, Any] = {f'delivery.{k}': 0.0 for k in _FRICTION}
    scene = load_scene('folder', over)
    dl = _folder(over).folder.delivery
    cf, ch = scene.effect_params('chain_friction'), scene.machine('delivery_chain')
    sch = schedule(scene)
    assert sch.pitch > sch.S  # one carriage on the stroke at a time
    assert dl.eta_min == pytest.approx(1.0, abs=1e-12)
    k_v = evaluate_stroke(scene.machine('delivery'), np.linspace(0.0, 2.0, 400_001)).K_v
    assert dl.sprocket_torque_peak_Nm == pytest.approx(cf.P_k * cf.r * float(k_v.max()), rel=1e-7)
    assert dl.sprocket_torque_mean_Nm == pytest.approx(cf.P_k * cf.r * 2 * ch.x_max / ch.pitch, rel=1e-6)


def test_no_delivery_figures_without_chain_friction() -> None:
    scene = load_scene('folder')
    data = dict(scene.source)
    data['effects'] = {k: v for k, v in data['effects'].items() if k != 'chain_friction'}
    folder = simulate(parse_scene(data), 0.5, sample_rate=0.0).summary().folder
    assert folder.delivery is None and 'knife_window_s' in folder.as_json()


def test_the_new_figures_are_metrics_with_units() -> None:
    summary = _folder().as_json()
    paths = flatten_metrics(summary)
    for name, unit in (
        ('knife_window_s', 's'),
        ('knife_window_deg', 'deg'),
        ('V_tr_min', 'm/s'),
        ('eta_min', ''),
        ('eta_min_travel_m', 'm'),
        ('sprocket_torque_peak_Nm', 'N m'),
        ('min_margin_s.feed_window', 's'),
        ('min_margin.rebound.margin', 'm'),
    ):
        path = resolve_metric(name, paths, '--metric')
        assert metric_unit(path, summary) == unit, (name, path)
