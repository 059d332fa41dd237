"""evaluate_folder_constraints on hand-made event tables (as a live supervisor would feed it)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from numpy.testing import assert_allclose

from folder_line.config.params import config_dir, read_yaml_mapping
from folder_line.core.line.constraints import FOLDER_CONSTRAINTS, RELEASE_KV_TOL, evaluate_folder_constraints
from folder_line.core.line.delivery_plan import delivery_plan
from folder_line.core.line.scene import Scene, parse_scene
from folder_line.core.mechanisms.cyclogram import cycle_timing
from folder_line.core.mechanisms.drive import RampDrive
from folder_line.core.types.events import make_events, merge_events

BOUNCE = {'e': 0.1, 'a_f': 400.0, 'tolerance': 0.002, 'v_rest': 0.05}


def _scene(effects: dict[str, Any] | None = None, delivery: bool = False) -> Scene:
    sections = ['knife', 'cyclogram', 'feed_transporter'] + (['delivery', 'delivery_chain'] if delivery else [])
    machines = {s: read_yaml_mapping(config_dir() / f'{s}.yaml', s) for s in sections}
    return parse_scene(
        {
            'name': 'test',
            'machines': machines,
            'effects': effects or {},
            'sheets': read_yaml_mapping(config_dir() / 'sheets.yaml', 'sheets'),
        }
    )


def _by_name(series: list) -> dict[str, Any]:
    return {c.name: c for c in series}


def _table(timing: Any, arrivals: dict[int, list[float]], settle: float = 0.0, rebound: float = 0.0) -> np.ndarray:
    """Cycles 0..4: knife contacts, and per cycle the sheets' arrival delays after the window start."""
    T, t_out, t_in = timing.T, timing.knife.t_out, timing.knife.t_in
    k = np.arange(5)
    rows = [
        make_events('knife_contact', (k + 1) * T + t_in, cycle=k),
        make_events('knife_exit', (k + 1) * T + t_out, cycle=k),
    ]
    sid = 0
    for c, delays in arrivals.items():
        for d in delays:
            t0 = c * T + t_out
            rows.append(make_events('sheet_handover', [t0], sheet=sid, cycle=c))
            rows.append(make_events('at_stops', [t0 + d], sheet=sid, cycle=c, value=9.3))
            if settle:
                rows.append(make_events('settled', [t0 + d + settle], sheet=sid, cycle=c))
            if rebound:
                rows.append(make_events('bounce', [t0 + d], sheet=sid, cycle=c, value=rebound))
                rows.append(make_events('bounce', [t0 + d + 1e-4], sheet=sid, cycle=c, value=rebound / 100))
            sid += 1
    return merge_events(rows)


def test_margins_on_a_hand_made_table() -> None:
    scene = _scene({'stop_bounce': BOUNCE})
    tm = cycle_timing(scene.machines['cyclogram'], scene.machines['knife'])
    ta = tm.t_allowed
    # cycle 0 nominal, 1 late by 1 ms past the deadline, 2 missing, 3 double, 4 arrives after the knife
    late_knife = tm.T - tm.t_knife + 0.002
    arrivals = {0: [0.02], 1: [ta + 0.001], 3: [0.02, 0.021], 4: [late_knife]}
    ev = _table(tm, arrivals, settle=0.005, rebound=0.0015)
    got = _by_name(evaluate_folder_constraints(ev, tm, scene))
    assert list(got) == ['feed_window', 'settled_before_knife', 'one_per_cycle', 'rebound']
    fw = got['feed_window']
    assert fw.cycle.tolist() == [0, 1, 3, 4]
    assert_allclose(fw.margin, [ta - 0.02, -0.001, ta - 0.021, ta - late_knife], atol=1e-15)
    rest = tm.T - tm.t_knife  # window start to knife contact
    assert_allclose(
        got['settled_before_knife'].margin, [rest - 0.025, rest - ta - 0.006, rest - 0.026, -0.007], atol=1e-15
    )
    opc = got['one_per_cycle']
    assert opc.cycle.tolist() == [0, 1, 2, 3, 4]
    assert opc.margin.tolist() == [0.0, 0.0, -1.0, -1.0, -1.0]  # missing, double, after the knife
    assert not np.signbit(opc.margin[0])
    assert_allclose(got['rebound'].margin, [0.0005] * 4, atol=1e-15)
    assert all(np.all(np.isfinite(c.margin)) for c in got.values())


def test_without_stop_bounce_settled_is_at_stops_and_no_rebound() -> None:
    scene = _scene()
    tm = cycle_timing(scene.machines['cyclogram'], scene.machines['knife'])
    ev = _table(tm, {0: [0.02], 1: [0.03]})
    got = _by_name(evaluate_folder_constraints(ev, tm, scene))
    assert 'rebound' not in got and 'release_at_min_speed' not in got
    assert_allclose(
        got['settled_before_knife'].margin, [tm.T - tm.t_knife - 0.02, tm.T - tm.t_knife - 0.03], atol=1e-15
    )


def test_order_and_foreign_rows_do_not_matter() -> None:
    scene = _scene()
    tm = cycle_timing(scene.machines['cyclogram'], scene.machines['knife'])
    ev = _table(tm, {0: [0.02], 1: [0.021], 3: [0.019]})
    noise = make_events('leaf_landed', np.linspace(0, 0.5, 7), sheet=np.arange(7), value=0.3)
    shuffled = np.concatenate([ev, noise])[np.random.default_rng(3).permutation(ev.size + noise.size)]
    a = evaluate_folder_constraints(ev, tm, scene)
    b = evaluate_folder_constraints(shuffled, tm, scene)
    for x, y in zip(a, b, strict=True):
        assert x.name == y.name and np.array_equal(x.cycle, y.cycle) and np.array_equal(x.margin, y.margin)


def test_sheet_still_on_its_way_is_bounded_and_negative() -> None:
    scene = _scene({'stop_bounce': BOUNCE})
    tm = cycle_timing(scene.machines['cyclogram'], scene.machines['knife'])
    t0 = tm.knife.t_out
    t_c = tm.T + tm.knife.t_in
    ev = merge_events(
        [make_events('sheet_handover', [t0], sheet=0, cycle=0), make_events('knife_contact', [t_c], cycle=0)]
    )
    got = _by_name(evaluate_folder_constraints(ev, tm, scene))
    assert got['feed_window'].margin[0] < -(tm.t_dwell)
    assert got['settled_before_knife'].margin[0] < 0.0
    assert got['one_per_cycle'].margin.tolist() == [-1.0]
    assert got['rebound'].margin.size == 0  # nothing reached the stops


def test_cycles_without_knife_contact_are_not_judged() -> None:
    scene = _scene()
    tm = cycle_timing(scene.machines['cyclogram'], scene.machines['knife'])
    ev = make_events('sheet_handover', [0.02], sheet=0, cycle=0)
    got = evaluate_folder_constraints(ev, tm, scene)
    assert [c.name for c in got] == list(FOLDER_CONSTRAINTS[:3])
    assert all(c.margin.size == 0 for c in got)
    assert all(c.margin.size == 0 for c in evaluate_folder_constraints(make_events('at_stops', []), tm, scene))


def test_deadline_follows_the_drive() -> None:
    scene = _scene()
    tm = cycle_timing(scene.machines['cyclogram'], scene.machines['knife'])
    drive = RampDrive(1.0)
    th_c = tm.T + tm.knife.t_in
    t_c = float(drive.time_of(th_c))
    th_dead = tm.knife.t_out + tm.t_allowed
    t_dead = float(drive.time_of(th_dead))
    t_stop = t_dead - 0.003
    ev = merge_events(
        [
            make_events('sheet_handover', [float(drive.time_of(tm.knife.t_out))], sheet=0, cycle=0),
            make_events('at_stops', [t_stop], sheet=0, cycle=0),
            make_events('knife_contact', [t_c], cycle=0),
        ]
    )
    got = _by_name(evaluate_folder_constraints(ev, tm, scene, drive))
    assert got['feed_window'].margin[0] == pytest.approx(0.003, abs=1e-12)
    # without the drive the deadline would be placed at nominal speed: a different number
    assert _by_name(evaluate_folder_constraints(ev, tm, scene))['feed_window'].margin[0] != pytest.approx(0.003)


def test_release_at_min_speed() -> None:
    scene = _scene(delivery=True)
    tm = cycle_timing(scene.machines['cyclogram'], scene.machines['knife'])
    plan = delivery_plan(scene, tm)
    k = np.array([0, 1, 2])
    t_rel = plan.schedule.theta_pick0 + k * tm.T + plan.travel_rel / plan.v_A
    # cycle 2 lets go 5 mm of chain too early
    t_rel[2] -= 0.005 / plan.v_A
    ev = make_events('released_on_pile', t_rel, sheet=k, cycle=k)
    got = _by_name(evaluate_folder_constraints(ev, tm, scene, plan=plan))['release_at_min_speed']
    assert got.unit == '1' and got.cycle.tolist() == [0, 1, 2]
    assert got.margin[0] == pytest.approx(RELEASE_KV_TOL, abs=1e-9)
    assert got.margin[1] == pytest.approx(RELEASE_KV_TOL, abs=1e-9)
    assert got.margin[2] < 0.0
    # the same without a precomputed plan
    again = _by_name(evaluate_folder_constraints(ev, tm, scene))['release_at_min_speed']
    assert np.array_equal(again.margin, got.margin)
