"""LineModel: built once, sampled anywhere; supervisor commands; the past never changes."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from folder_line.config.scenes import load_scene
from folder_line.core.effects import chain_friction
from folder_line.core.line.events import event_kind
from folder_line.core.line.folder_sim import FolderLine
from folder_line.core.line.model import NODES, LineModel, LineResult, sample_times, simulate
from folder_line.core.line.scene import Scene, parse_scene
from folder_line.core.mechanisms.drive import Command
from folder_line.interfaces import EVENT_KINDS

DURATION = {'folder': 12.0, 'layup': 12.0, 'line': 12.0}


@pytest.fixture(scope='module')
def runs() -> dict[str, tuple[LineModel, LineResult]]:
    out = {}
    for name, dur in DURATION.items():
        scene = load_scene(name)
        out[name] = (LineModel(scene, dur), simulate(scene, dur, sample_rate=250.0))
    return out


def _same(a: Any, b: Any) -> bool:
    return (
        a.names == b.names
        and a.position.tobytes() == b.position.tobytes()
        and a.velocity.tobytes() == b.velocity.tobytes()
        and (a.effort is None) == (b.effort is None)
        and (a.effort is None or a.effort.tobytes() == b.effort.tobytes())
    )


def _rows(js: Any, i: Any) -> Any:
    from folder_line.core.line.events import JointSamples

    return JointSamples(
        js.machine, js.names, js.t[i], js.position[i], js.velocity[i], None if js.effort is None else js.effort[i]
    )


# ------------------------------------------------------------------ sampling


@pytest.mark.parametrize('name', sorted(DURATION))
def test_nodes_and_joint_names_are_simulates(runs: dict[str, Any], name: str) -> None:
    model, res = runs[name]
    assert model.nodes == {node: js.names for node, js in res.samples.items()}
    assert list(model.nodes) == [n for n in NODES if n in res.samples]
    assert model.nodes['sheet_counter'] == (('container_floor',) if name == 'layup' else ('pile_table',))
    with pytest.raises(KeyError, match='nodes'):
        model.sample('supervisor', np.array([1.0]))
    if name == 'layup':
        with pytest.raises(KeyError, match='feed_transporter'):
            model.sample('feed_transporter', np.array([1.0]))


@settings(max_examples=300, deadline=None)
@given(name=st.sampled_from(sorted(DURATION)), u=st.floats(0.0, 1.0))
def test_one_tick_is_simulates_row_bit_for_bit(runs: dict[str, Any], name: str, u: float) -> None:
    model, res = runs[name]
    t_grid = sample_times(DURATION[name], 250.0)
    i = int(u * (t_grid.size - 1))
    for node, js in res.samples.items():
        one = model.sample(node, np.array([t_grid[i]]))
        assert one.position.shape == (1, len(js.names))
        assert _same(one, _rows(js, slice(i, i + 1))), node


@pytest.mark.parametrize('name', sorted(DURATION))
def test_order_and_chunking_do_not_change_values(runs: dict[str, Any], name: str) -> None:
    model, res = runs[name]
    t = res.samples['crank_drive'].t
    perm = np.random.default_rng(3).permutation(t.size)
    for node, js in res.samples.items():
        assert _same(model.sample(node, t), js)
        assert _same(model.sample(node, t[perm]), _rows(js, perm))
        parts = [model.sample(node, t[k : k + 97]) for k in range(0, t.size, 97)]
        assert np.vstack([p.position for p in parts]).tobytes() == js.position.tobytes()
    assert all(_same(a, res.samples[n]) for n, a in model.sample_all(t).items())


@pytest.mark.parametrize('name, short, long', [('folder', 8.0, 20.0), ('layup', 8.0, 20.0), ('line', 11.0, 30.0)])
def test_a_longer_horizon_agrees_on_the_shorter_one(name: str, short: float, long: float) -> None:
    """What a node publishes does not depend on the horizon it was built for (the motor's
    periodic steady state is reached by 10.5 s in the line scene: see core.line's docstring)."""
    scene = load_scene(name)
    a, b = LineModel(scene, short), LineModel(scene, long)
    assert a.events.tobytes() == b.events_between(-math.inf, short).tobytes()
    t = np.linspace(0.0, short, 1001)
    for node in a.nodes:
        assert _same(a.sample(node, t), b.sample(node, t)), node


def test_fast_torque_is_chain_frictions_bit_for_bit() -> None:
    """The one-tick path of feed_transporter reuses the carriage's stroke evaluation for the torque."""
    scene = load_scene('folder')
    line = LineModel(scene, 5.0)._parts['folder']
    assert isinstance(line, FolderLine)
    t = np.random.default_rng(5).uniform(0.0, 5.0, 3000)
    ref = chain_friction.sprocket_torque(scene, line.drive.theta(t))
    got = np.array([line.sample_node('feed_transporter', np.array([x])).effort[0, 1] for x in t])
    assert got.tobytes() == ref.tobytes()
    assert np.count_nonzero(got) > 1000 and np.count_nonzero(got == 0.0) > 500


def test_result_is_simulate(runs: dict[str, Any]) -> None:
    model, res = runs['folder']
    again = model.result(DURATION['folder'], 250.0)
    assert again.events.tobytes() == res.events.tobytes() and again.parts == res.parts
    assert all(_same(again.samples[n], res.samples[n]) for n in res.samples)
    shorter = model.result(3.0, 0.0)
    plain = simulate(model.scene, 3.0, sample_rate=0.0)
    assert shorter.duration == 3.0 and shorter.samples == {}
    assert shorter.events.tobytes() == plain.events.tobytes() and shorter.summary() == plain.summary()


# ------------------------------------------------------------------ events and cycles


@settings(max_examples=100, deadline=None)
@given(name=st.sampled_from(sorted(DURATION)), ticks=st.lists(st.floats(0.0, 12.0), min_size=1, max_size=40))
def test_events_between_partitions_the_table(runs: dict[str, Any], name: str, ticks: list[float]) -> None:
    model, _ = runs[name]
    stamps = sorted(set(ticks)) + [DURATION[name]]
    prev = -math.inf
    got = []
    for s in stamps:
        ev = model.events_between(prev, s)
        assert np.all(ev['t'] > prev) and np.all(ev['t'] <= s)
        got.append(ev)
        prev = s
    assert np.concatenate(got).tobytes() == model.events.tobytes()
    assert model.events_between(5.0, 4.0).size == 0


@settings(max_examples=200, deadline=None, suppress_health_check=list(HealthCheck))
@given(t=st.floats(0.0, 11.5))
def test_next_cycle_boundary_is_the_next_knife_exit(runs: dict[str, Any], t: float) -> None:
    for name in ('folder', 'line'):
        model, _ = runs[name]
        exits = model.events[model.events['kind'] == event_kind('knife_exit')]
        b = model.next_cycle_boundary(t)
        if b > DURATION[name]:
            assert b == math.inf
            continue
        assert b > t
        if model.cycle_index(t) == -1:  # cycle 0 starts where the first feed window opens, not at an exit
            assert b == float(model.drive.time_of(model._parts['folder'].timing.knife.t_out))
            continue
        k = np.flatnonzero(exits['t'] > t)[0]
        assert exits['t'][k] == b  # bit for bit: the supervisor can put a hold exactly on the event
        # the knife exit that ends cycle c starts cycle c + 1
        assert model.cycle_index(b) == exits['cycle'][k] + 1 == model.cycle_index(t) + 1
        assert model.cycle_index(np.nextafter(b, 0.0)) == model.cycle_index(t)


def test_first_cycle_and_layup_crank_turns(runs: dict[str, Any]) -> None:
    folder, _ = runs['folder']
    assert folder.cycle_index(0.0) == -1  # the first feed window opens at the knife exit phase t_out
    t_out = folder._parts['folder'].timing.knife.t_out
    assert folder.next_cycle_boundary(0.0) == pytest.approx(t_out, abs=1e-15)
    assert folder.cycle_index(t_out) == 0
    layup, _ = runs['layup']
    period = 60.0 / layup.scene.machine('layup').n_kr  # the default constant drive: Θ = t
    assert layup.cycle_index(0.0) == 0 and layup.next_cycle_boundary(0.0) == period
    assert layup.next_cycle_boundary(2.5 * period) == 3 * period and layup.cycle_index(3 * period) == 3
    assert layup.next_cycle_boundary(11.9) == 12.0 and layup.next_cycle_boundary(12.0) == math.inf  # horizon 12


# ------------------------------------------------------------------ supervisor commands


def _folder_faults() -> Scene:
    data = dict(load_scene('folder').source)
    data['effects'] = {
        **data['effects'],
        'feed_slip': {'mu': 0.5, 'p': 40.0, 'm': 0.02},
        'faults': {
            'p_missing': 0.05,
            'p_double': 0.02,
            'p_late': 0.05,
            'late_delay': 0.002,
            'p_slowdown': 0.05,
            'slowdown_factor': 0.8,
            'slowdown_duration': 0.2,
        },
    }
    data['machines'] = {**data['machines'], 'feed_transporter': {'V_tr': 9.7}}
    return parse_scene(data)


@pytest.mark.parametrize(
    'name, t_c', [('folder', 4.3), ('folder_faults', 4.3), ('layup', 5.1), ('line', 6.2), ('line', 13.7)]
)
def test_events_before_a_command_are_unchanged(name: str, t_c: float) -> None:
    scene = _folder_faults() if name == 'folder_faults' else load_scene(name)
    plain = LineModel(scene, 18.0)
    held = LineModel(scene, 18.0, [Command(t_c, 'hold'), Command(t_c + 2.0, 'unhold')])
    assert (
        plain.events_between(-math.inf, np.nextafter(t_c, 0.0)).tobytes()
        == held.events_between(-math.inf, np.nextafter(t_c, 0.0)).tobytes()
    )
    assert held.events.tobytes() != plain.events.tobytes()  # and the command does change the future
    t = np.linspace(0.0, t_c, 501)[:-1]
    for node in plain.nodes:
        assert _same(plain.sample(node, t), held.sample(node, t)), node
    for node in held.nodes:
        js = held.sample(node, np.linspace(0.0, 18.0, 3601))
        assert np.all(np.isfinite(js.position)) and np.all(np.isfinite(js.velocity))
    for c in held.constraints:
        assert np.all(np.isfinite(c.margin))


def _of(events: np.ndarray, kind: str) -> np.ndarray:
    return events[events['kind'] == event_kind(kind)]


@pytest.fixture(scope='module')
def hold_run() -> dict[str, Any]:
    scene = load_scene('folder')
    plain = LineModel(scene, 30.0)
    t_hold = plain.next_cycle_boundary(6.0)
    t_unhold = 14.0
    cmds = (Command(t_hold, 'hold'), Command(t_unhold, 'unhold'))
    return {
        'scene': scene,
        'plain': plain,
        'model': LineModel(scene, 30.0, cmds),
        'cmds': cmds,
        't_hold': t_hold,
        't_unhold': t_unhold,
    }


def test_hold_at_the_cycle_boundary_stops_the_folder_with_no_sheet_lost(hold_run: dict[str, Any]) -> None:
    m, t_hold = hold_run['model'], hold_run['t_hold']
    scene = hold_run['scene']
    t_b = scene.drive.t_brake
    t_still = t_hold + t_b  # λ reaches 0 after the brake ramp
    theta = m.drive.theta(np.linspace(t_still, hold_run['t_unhold'], 1001))
    assert np.all(theta == theta[0]) and np.all(m.drive.rate(np.linspace(t_still, 14.0, 11)) == 0.0)
    # the ramp down advances the line half a brake time: Θ(t_hold) + t_brake/2
    assert theta[0] == pytest.approx(float(m.drive.theta(t_hold)) + t_b / 2, abs=1e-12)
    # nothing kinematic happens while the line stands (bounce/settle are line-time; they end sooner)
    quiet = m.events_between(t_still + 0.01, hold_run['t_unhold'])
    assert quiet.size == 0
    # at the standstill, every sheet fed is delivered or still in the machine, none jammed
    stop = LineModel(scene, t_still + 1.0, hold_run['cmds'][:1])
    s = stop.parts['folder']
    assert s['sheets_balance_ok'] and s['sheets_jammed'] == 0
    assert s['sheets_fed'] == s['sheets_counted'] + s['sheets_in_machine']
    assert 0 < s['sheets_in_machine'] <= 4  # at the stops / on the chain, waiting
    assert all(int(np.count_nonzero(c.violated)) == 0 for c in stop.constraints)
    # the sheet stream stops with the line: no handover after the standstill phase
    hand = _of(stop.events, 'sheet_handover')
    assert hand['t'].max() < t_still


def test_unhold_resumes_and_every_held_sheet_is_delivered(hold_run: dict[str, Any]) -> None:
    m, plain = hold_run['model'], hold_run['plain']
    t_u = hold_run['t_unhold']
    # up to and including the command's time (a knife exit) the run is the one without it
    assert (
        m.events_between(-math.inf, hold_run['t_hold']).tobytes()
        == plain.events_between(-math.inf, hold_run['t_hold']).tobytes()
    )
    assert _of(m.events_between(-math.inf, hold_run['t_hold']), 'knife_exit')['t'][-1] == hold_run['t_hold']
    up = hold_run['scene'].drive.t_restart
    assert float(m.drive.rate(t_u + up)) == 1.0
    exits = _of(m.events, 'knife_exit')
    after = exits[exits['t'] > t_u + up]
    T = m._parts['folder'].timing.T
    np.testing.assert_allclose(np.diff(after['t']), T, rtol=0, atol=1e-12)
    assert np.all(np.diff(exits['cycle']) == 1)  # no cycle skipped or repeated across the hold
    s = m.parts['folder']
    assert s['sheets_balance_ok'] and s['sheets_jammed'] == 0
    assert all(int(np.count_nonzero(c.violated)) == 0 for c in m.constraints)
    # every sheet handed over before the hold reaches the pile once the line runs again
    hand = _of(m.events, 'sheet_handover')
    early = hand['sheet'][hand['t'] < hold_run['t_hold'] + 1.0]
    released = _of(m.events, 'released_on_pile')['sheet']
    assert np.all(np.isin(early, released))
    assert np.array_equal(np.sort(released), np.arange(released.size))
    # the hold costs the line (t_unhold - t_hold) minus what the ramps give back, in cycles
    lost = plain.parts['folder']['cycles'] - s['cycles']
    dt = t_u - hold_run['t_hold'] - 0.5 * hold_run['scene'].drive.t_brake + 0.5 * up
    assert abs(lost - dt / T) <= 1.0


def test_layup_hold_stops_crank_and_belts(runs: dict[str, Any]) -> None:
    scene = load_scene('layup')
    m = LineModel(scene, 15.0, [Command(4.0, 'hold'), Command(9.0, 'unhold')])
    t = np.linspace(4.6, 9.0, 441)[:-1]
    crank = m.sample('crank_drive', t)
    belt = m.sample('belt_conveyor', t)
    assert np.all(crank.position == crank.position[0]) and np.all(crank.velocity == 0.0)
    assert np.all(belt.position == belt.position[0]) and np.all(belt.velocity == 0.0)
    # no leaf leaves a standing chute (the leaf stream itself is upstream, in line time)
    assert _of(m.events_between(4.6, 9.0), 'leaf_exit').size == 0
    assert _of(m.events_between(4.6, 9.0), 'leaf_enter').size > 0
    assert m.next_cycle_boundary(5.0) > 9.0  # no crank turn starts while held
    assert m.cycle_index(8.0) == m.cycle_index(4.6)


def test_commands_reach_simulate(hold_run: dict[str, Any]) -> None:
    res = simulate(hold_run['scene'], 30.0, sample_rate=0.0, commands=hold_run['cmds'])
    assert res.events.tobytes() == hold_run['model'].events.tobytes()
    assert res.summary()['folder']['sheets_balance_ok']
    with pytest.raises(Exception, match='sorted'):
        LineModel(hold_run['scene'], 10.0, hold_run['cmds'][::-1])
    assert set(EVENT_KINDS) >= {'knife_exit', 'released_on_pile'}


@pytest.mark.parametrize(
    'name, what, period, per',
    [('folder', 'knife cycles', 3600.0 / 50000.0, 'BYTES_PER_CYCLE'), ('layup', 'leaves', None, 'BYTES_PER_LEAF')],
)
def test_a_span_too_long_for_memory_is_refused_before_any_work(
    name: str, what: str, period: float | None, per: str
) -> None:
    """Every event up to the horizon is held in memory: 1e7 s of the folder is 1.4e8 knife cycles
    (~270 GB at the measured peak per cycle). The model refuses it at once, naming the span and the
    memory it would need, instead of exhausting the machine."""
    import time

    from folder_line.core.line import model as line_mod
    from folder_line.errors import ParameterError

    scene = load_scene(name, {})
    period = scene.sheets.interval if period is None else period
    per_event = getattr(line_mod, per)
    # the longest span: the machine's budget over the measured bytes per event, or MAX_CYCLES events
    limit = min(line_mod.MAX_CYCLES, line_mod.memory_budget() / per_event) * period
    t0 = time.process_time()
    with pytest.raises(ParameterError, match=f'horizon=.*{what}') as info:
        LineModel(scene, 1e7)
    assert info.value.key == 'horizon' and info.value.value == 1e7
    with pytest.raises(ParameterError) as info:
        simulate(scene, 1.01 * limit, sample_rate=0.0)
    assert info.value.key == 'duration' and info.value.value == 1.01 * limit
    assert f'at most {limit:.4g} s of this scene' in info.value.reason
    assert time.process_time() - t0 < 1.0  # refused up front, not after building events
    # just below the limit the check lets it through (checked without building: it is the same test)
    line_mod.check_size(scene, 0.99 * limit, 0.99 * limit)
    with pytest.raises(ParameterError, match=r'span=.*this machine allows .* GB \(75% of its memory\): at most'):
        line_mod.check_size(scene, 1.01 * limit, 1.01 * limit, 'span')


def test_the_refusal_states_the_memory_the_model_would_need(monkeypatch: pytest.MonkeyPatch) -> None:
    from folder_line.core.line import model as line_mod
    from folder_line.errors import ParameterError

    monkeypatch.setattr(line_mod, 'memory_budget', lambda: 10**9)  # a machine that allows 1 GB
    scene = load_scene('line', {})
    span = 36000.0
    cycles = span / float(scene.machines['knife'].period)
    leaves = span / float(scene.sheets.interval)
    need = cycles * line_mod.BYTES_PER_CYCLE + leaves * line_mod.BYTES_PER_LEAF
    with pytest.raises(ParameterError) as info:
        line_mod.check_size(scene, span, span, 'duration')
    reason = info.value.reason
    assert f'about {need / 1e9:.3g} GB of memory' in reason, reason
    assert f'{cycles:.3g} knife cycles x {line_mod.BYTES_PER_CYCLE} B' in reason
    assert f'{leaves:.3g} leaves x {line_mod.BYTES_PER_LEAF} B' in reason
    assert f'at most {span * 1e9 / need:.4g} s of this scene' in reason
    line_mod.check_size(scene, span * 0.99e9 / need, span * 0.99e9 / need)  # what it says fits, fits
