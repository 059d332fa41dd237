"""The supervisor's logic (core.supervision) on the line model's exact event streams.

The live loop is reproduced offline by :func:`run_closed_loop`: the events of the
line model are fed step by step and the supervisor's drive commands rebuild the
model, as the nodes do. Expected times come from the batch simulation (the model
without commands), from closed forms of the drive, or from an independent count.
"""

from __future__ import annotations

import itertools
import math
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from folder_line.config.scenes import load_scene
from folder_line.core.line.constraints import evaluate_layup_constraints, folder_evaluation
from folder_line.core.line.model import LineModel
from folder_line.core.line.stream import LineStream
from folder_line.core.mechanisms.cyclogram import cycle_timing
from folder_line.core.mechanisms.drive import Command
from folder_line.core.supervision.commands import DRIVE_COMMANDS, STOP_STATES
from folder_line.core.supervision.offline import ReplayInputs, replay, run_closed_loop
from folder_line.core.supervision.packml import ACTING, COMMANDS
from folder_line.core.supervision.supervisor import SHEET_UNIT, TIMING_CONSTRAINTS, Supervisor
from folder_line.core.types.events import EVENT_DTYPE, event_kind
from folder_line.errors import ParameterError
from folder_line.interfaces import NODE_OF_UNIT

H = 8.0  # model horizon, s
P = 0.005  # node period and check grid, s
NODES = {'crank_drive': P, 'belt_conveyor': P, 'feed_transporter': P}
KW: dict[str, Any] = {
    'periods': NODES,
    'stale_periods': 5.0,
    'lead': 0.01,
    'check_period': P,
    'sheet_source': NODE_OF_UNIT[SHEET_UNIT],
}
SCENE = load_scene('folder_faults')
T = cycle_timing(SCENE.machines['cyclogram'], SCENE.machines['knife']).T
NOT_LATE = {'faults.p_late': 0.0}


def _ns(t: float) -> float:
    return round(t * 1e9) / 1e9


def _rows(model: LineModel, kind: str) -> np.ndarray:
    return model.events[model.events['kind'] == event_kind(kind)]


def _exit_of(model: LineModel, cycle: int) -> float:
    ex = _rows(model, 'knife_exit')
    return float(ex['t'][ex['cycle'] == cycle][0])


def _cycle_start(model: LineModel, cycle: int) -> float:
    """Cycle k starts at the knife exit that ends cycle k - 1."""
    return _exit_of(model, cycle - 1) if cycle > 0 else 0.0


def _first_violation(model: LineModel) -> tuple[float, int, str, float]:
    """The earliest violated evaluation of the batch constraints: (decision time, cycle, name, margin)."""
    out = []
    for c in model.constraints:
        bad = np.flatnonzero(c.margin < 0.0)
        out += [(float(c.t[i]), int(c.cycle[i]), c.name, float(c.margin[i])) for i in bad]
    return min(out)


def _path(sup: Supervisor) -> list[tuple[str, str]]:
    return [(tr.source, tr.target) for tr in sup.transitions]


@pytest.fixture(scope='module')
def free() -> LineModel:
    return LineModel(SCENE, H)


@pytest.fixture(scope='module')
def hold_run() -> tuple[Supervisor, LineStream, ReplayInputs]:
    return run_closed_loop(SCENE, 3.0, **KW)


# --------------------------------------------------------------------------- timing fault -> HELD


def test_first_timing_violation_holds_at_the_next_cycle_boundary(free: LineModel, hold_run: Any) -> None:
    sup, _, _ = hold_run
    t0, cycle, name, margin = _first_violation(free)
    assert (cycle, name) == (13, 'feed_window') and margin < -0.004  # the scene's late sheet
    v = sup.violations[0]
    assert (v.t, v.cycle, v.constraint, v.margin, v.action, v.state) == (t0, cycle, name, margin, 'hold', 'EXECUTE')
    assert _path(sup) == [('STARTING', 'EXECUTE'), ('EXECUTE', 'HOLDING'), ('HOLDING', 'HELD')]
    holding = sup.transitions[1]
    assert holding.t == t0 and 'feed_window' in holding.cause and 'cycle 13' in holding.cause
    # decided within the violating cycle: after its start, less than one cycle later
    assert _cycle_start(free, cycle) <= holding.t < _cycle_start(free, cycle) + T
    # the hold is effective at the next cycle boundary: the knife exit that ends the violating cycle
    (hold,) = sup.commands
    assert hold.kind == 'hold'
    assert hold.t == _ns(_exit_of(free, cycle)) == _ns(free.next_cycle_boundary(t0 + KW['lead']))
    assert t0 < hold.t < t0 + T
    # HELD at the first check-grid point of standstill: the brake ramp of t_brake from the hold
    held = sup.transitions[2]
    assert held.cause == 'drive at standstill'
    t_still = hold.t + SCENE.drive.t_brake
    assert t_still <= held.t < t_still + P + 1e-12
    assert held.t == pytest.approx(round(held.t / P) * P, abs=1e-12)


def test_the_model_rebuilt_with_the_hold_stands_still_and_keeps_every_sheet(free: LineModel, hold_run: Any) -> None:
    sup, model, fed = hold_run
    rebuilt = LineModel(SCENE, H, sup.commands)
    assert model.commands == rebuilt.commands == sup.commands
    # what was fed live is exactly the rebuilt model's stream (a command changes nothing before its time)
    stream = rebuilt.events_between(-math.inf, 3.0)
    assert np.sort(fed.events, order=['t', 'kind', 'sheet']).tobytes() == stream.tobytes()
    # and before the hold it is the free model's
    t_hold = sup.commands[0].t
    before = free.events_between(-math.inf, t_hold)
    assert stream[stream['t'] < t_hold].tobytes() == before[before['t'] < t_hold].tobytes()
    # replaying the rebuilt model's events gives the same transitions, commands and balances
    again = replay(SCENE, stream, heard=fed.heard, until=3.0, **KW)
    assert again.transitions == sup.transitions and again.commands == sup.commands
    assert again.balances == sup.balances and again.violations == sup.violations
    # fed and ticked in windows of any length (a multiple of the check period), or at once: the same
    for window in (0.05, 0.75, 1e9):
        other = replay(SCENE, stream, heard=fed.heard, until=3.0, window=window, **KW)
        assert other.transitions == sup.transitions and other.commands == sup.commands, window
        assert other.balances == sup.balances and other.violations == sup.violations, window
    with pytest.raises(ParameterError, match='window'):
        replay(SCENE, stream, heard=fed.heard, until=3.0, window=0.0, **KW)
    # the drive stands still from HELD on: no rate, no phase, no machine event
    t_held = sup.transitions[-1].t
    t = np.linspace(t_held, 3.0, 200)
    assert np.all(rebuilt.drive.rate(t) == 0.0)
    assert np.all(rebuilt.drive.theta(t) == rebuilt.drive.theta(t_held))
    later = stream[stream['t'] > t_held]
    for kind in ('sheet_handover', 'at_stops', 'knife_contact', 'knife_exit', 'released_on_pile'):
        assert not np.any(later['kind'] == event_kind(kind)), kind
    # sheets balance at the stop, and agree with the batch simulation's own count
    (b,) = sup.balances
    assert b.state == 'HELD' and b.t == t_held and b.ok
    summary = LineModel(SCENE, 3.0, sup.commands).parts['folder']
    assert (b.fed, b.delivered, b.in_machine) == (
        summary.sheets_fed,
        summary.sheets_counted,
        summary.sheets_in_machine,
    )
    assert b.fed == b.delivered + b.in_machine and b.in_machine > 0
    assert b.detail['jammed'] == 0 and b.detail['folded'] == summary.sheets_folded


# --------------------------------------------------------------------------- starvation -> SUSPENDED


def test_a_missing_sheet_suspends_within_its_cycle() -> None:
    scene = load_scene('folder_faults', NOT_LATE)
    free = LineModel(scene, H)
    t0, cycle, name, margin = _first_violation(free)
    assert (cycle, name, margin) == (45, 'one_per_cycle', -1.0)
    missing = _rows(free, 'fault_missing')
    assert missing['cycle'][0] == cycle  # the scene's missing sheet, not a late one
    sup, model, _ = run_closed_loop(scene, 4.5, **KW)
    assert _path(sup) == [('STARTING', 'EXECUTE'), ('EXECUTE', 'SUSPENDING'), ('SUSPENDING', 'SUSPENDED')]
    susp = sup.transitions[1]
    assert susp.t == t0 and susp.cause.startswith('missing sheet')
    assert _cycle_start(free, cycle) <= susp.t < _cycle_start(free, cycle) + T
    (cmd,) = sup.commands
    assert cmd == Command(_ns(_exit_of(free, cycle)), 'hold')  # the drive goes down like for a hold
    assert sup.violations[0].action == 'suspend'
    (b,) = sup.balances
    assert b.state == 'SUSPENDED' and b.ok and b.fed == b.delivered + b.in_machine
    assert np.all(model.drive.rate(np.linspace(b.t, 4.5, 50)) == 0.0)


def test_unhold_then_the_missing_sheet_suspends() -> None:
    sup, _, _ = run_closed_loop(SCENE, 5.5, operator=[(2.0, 'unhold')], **KW)
    assert _path(sup) == [
        ('STARTING', 'EXECUTE'),
        ('EXECUTE', 'HOLDING'),
        ('HOLDING', 'HELD'),
        ('HELD', 'UNHOLDING'),
        ('UNHOLDING', 'EXECUTE'),
        ('EXECUTE', 'SUSPENDING'),
        ('SUSPENDING', 'SUSPENDED'),
    ]
    assert [c.kind for c in sup.commands] == ['hold', 'unhold', 'hold']
    assert sup.commands[1].t == _ns(2.0 + KW['lead'])
    assert [v.cycle for v in sup.violations] == [13, 45]
    assert all(b.ok for b in sup.balances) and [b.state for b in sup.balances] == ['HELD', 'SUSPENDED']


# --------------------------------------------------------------------------- double sheet


@pytest.mark.parametrize('policy, path', [('hold', ['HOLDING', 'HELD']), ('abort', ['ABORTING', 'ABORTED'])])
def test_a_double_sheet_is_a_fault_of_the_process_by_default(policy: str, path: list[str]) -> None:
    scene = load_scene('folder_faults', {'faults.p_late': 0.0, 'faults.p_missing': 0.0, 'faults.p_double': 0.1})
    free = LineModel(scene, 4.0)
    double = _rows(free, 'fault_double')
    assert double.size
    t0, cycle, name, margin = _first_violation(free)
    assert (cycle, name, margin) == (int(double['cycle'][0]), 'one_per_cycle', -1.0)
    sup, _, _ = run_closed_loop(scene, min(t0 + 1.0, 4.0), double=policy, **KW)
    assert [tr.target for tr in sup.transitions[1:]] == path
    assert sup.transitions[1].t == t0 and sup.transitions[1].cause.startswith('double sheet')
    assert sup.balances[0].ok


# --------------------------------------------------------------------------- interlocks -> ABORTED


def test_a_stale_node_aborts_within_one_cycle_and_only_clear_leaves_aborted() -> None:
    ops = [
        (1.2, 'reset'),
        (1.25, 'start'),
        (1.3, 'unhold'),
        (1.35, 'hold'),
        (1.375, 'stop'),
        (1.4, 'clear'),
        (1.6, 'reset'),
    ]
    sup, model, _ = run_closed_loop(SCENE, 2.0, silent={'belt_conveyor': 0.5}, operator=ops, **KW)
    assert [tr.target for tr in sup.transitions] == [
        'EXECUTE',
        'ABORTING',
        'ABORTED',
        'CLEARING',
        'STOPPED',
        'RESETTING',
        'IDLE',
    ]
    aborting = sup.transitions[1]
    last = 0.495  # the belt's last tick before it died at 0.5 s
    k_p = KW['stale_periods'] * P
    assert aborting.t == pytest.approx(last + k_p + P, abs=1e-12)  # first grid point with no tick for k periods
    assert aborting.t - 0.5 < T  # within one cycle of the node's death
    v = sup.violations[0]
    assert v.constraint == 'liveness:belt_conveyor' and v.action == 'abort'
    assert v.margin == pytest.approx(k_p - (aborting.t - last), abs=1e-12) and v.margin < 0.0
    (stop,) = sup.commands
    assert stop == Command(_ns(aborting.t + KW['lead']), 'stop')
    aborted = sup.transitions[2]
    t_still = stop.t + SCENE.drive.t_brake  # the brake ramp's closed form
    assert t_still - 1e-9 <= aborted.t < t_still + P + 1e-9
    before = (round(aborted.t / P) - 1) * P  # the grid point before
    assert model.drive.rate(np.array([aborted.t]))[0] == 0.0 < model.drive.rate(np.array([before]))[0]
    # in ABORTED every command but clear is refused; the belt is still silent: no second abort
    assert [(round(t, 9), c, ok) for t, c, ok in sup.operator_log] == [
        (1.2, 'reset', False),
        (1.25, 'start', False),
        (1.3, 'unhold', False),
        (1.35, 'hold', False),
        (1.375, 'stop', False),
        (1.4, 'clear', True),
        (1.6, 'reset', True),
    ]
    assert sup.stale_nodes() == ['belt_conveyor']
    assert all(b.ok for b in sup.balances) and [b.state for b in sup.balances] == ['ABORTED', 'STOPPED']


def test_a_node_heard_again_can_go_stale_again() -> None:
    sup = Supervisor(SCENE, **KW)
    for node in NODES:
        sup.heard(node, np.arange(0, 61) * P)  # up to 0.3 s
    sup.feed(LineModel(SCENE, H).events_between(-math.inf, 0.3))
    sup.tick(0.3)
    assert sup.state == 'EXECUTE'
    sup.heard('crank_drive', np.arange(80, 91) * P)  # silent 0.3 .. 0.4: stale at 0.33
    sup.heard('belt_conveyor', np.arange(61, 100) * P)
    sup.heard('feed_transporter', np.arange(61, 100) * P)
    sup.tick(0.45)
    assert [tr.target for tr in sup.transitions] == ['EXECUTE', 'ABORTING']
    assert sup.transitions[1].t == pytest.approx(0.33, abs=1e-12)
    assert sup.stale_nodes() == []  # heard again at 0.4
    assert sup.command('clear').ok is False  # still ABORTING (the drive is braking)


def test_nan_in_a_message_or_in_an_event_aborts_at_its_stamp(free: LineModel) -> None:
    sup, _, _ = run_closed_loop(SCENE, 0.9, bad_values=[(0.3, '/line/crank_drive/joint_states', 2)], **KW)
    assert [tr.target for tr in sup.transitions] == ['EXECUTE', 'ABORTING', 'ABORTED']
    assert sup.transitions[1].t == 0.3 and 'non-finite' in sup.transitions[1].cause
    v = sup.violations[0]
    assert (v.constraint, v.margin, v.unit, v.action) == (
        'finite:/line/crank_drive/joint_states',
        -2.0,
        'values',
        'abort',
    )
    # a NaN value in the event stream
    sup = Supervisor(SCENE, **KW)
    ev = free.events_between(-math.inf, 0.5).copy()
    i = int(np.flatnonzero(ev['kind'] == event_kind('at_stops'))[3])
    ev['value'][i] = np.nan
    sup.feed(ev)
    sup.tick(0.5)
    assert [tr.target for tr in sup.transitions] == ['EXECUTE', 'ABORTING']
    assert sup.transitions[1].t == ev['t'][i] and sup.violations[0].constraint == 'finite:/line/events'


# --------------------------------------------------------------------------- replay equality


@pytest.fixture(scope='module')
def rich_run() -> tuple[Supervisor, ReplayInputs]:
    """Hold, unhold, starvation, a dead node, clear, a NaN: everything in one run."""
    ops = [(2.0, 'unhold'), (5.8, 'clear'), (5.85, 'start'), (5.9, 'reset')]
    sup, _, fed = run_closed_loop(
        SCENE,
        6.5,
        operator=ops,
        silent={'feed_transporter': 5.5},
        bad_values=[(6.2, '/line/sheet_counter/rate', 1)],
        **KW,
    )
    assert [tr.target for tr in sup.transitions] == [
        'EXECUTE',
        'HOLDING',
        'HELD',
        'UNHOLDING',
        'EXECUTE',
        'SUSPENDING',
        'SUSPENDED',
        'ABORTING',
        'ABORTED',
        'CLEARING',
        'STOPPED',
        'RESETTING',
        'IDLE',
        'ABORTING',
        'ABORTED',
    ]
    assert sup.late == 0
    return sup, fed


def _same(a: Supervisor, b: Supervisor) -> None:
    assert a.transitions == b.transitions
    assert a.commands == b.commands
    assert a.violations == b.violations
    assert a.balances == b.balances
    assert a.operator_log == b.operator_log


def test_replay_reproduces_the_live_run(rich_run: Any) -> None:
    sup, fed = rich_run
    again = replay(
        SCENE,
        fed.events,
        heard=fed.heard,
        bad_values=fed.bad_values,
        operator=fed.operator,
        until=fed.until,
        **KW,
    )
    _same(again, sup)
    assert again.late == 0


@settings(max_examples=25, deadline=None, suppress_health_check=list(HealthCheck))
@given(seed=st.integers(0, 2**32 - 1), n_ticks=st.integers(1, 400), ahead=st.floats(0.0, 0.5))
def test_any_batching_gives_the_same_decisions(rich_run: Any, seed: int, n_ticks: int, ahead: float) -> None:
    """Events fed in random chunks, shuffled, partly ahead of the watermark; ticks at random times."""
    sup, fed = rich_run
    rng = np.random.default_rng(seed)
    until = fed.until
    ops = list(fed.operator)
    ticks = sorted(set(np.round(rng.uniform(0.0, until, n_ticks), 4).tolist()) | {t for t, _ in ops} | {until})
    ev = fed.events[rng.permutation(fed.events.size)]
    heard = {n: np.asarray(v) for n, v in fed.heard.items()}
    bad = list(fed.bad_values)
    done_ev = np.zeros(ev.size, dtype=bool)
    done_h = {n: np.zeros(v.size, dtype=bool) for n, v in heard.items()}
    other = Supervisor(SCENE, **KW)
    for w in ticks:
        reach = w + float(rng.uniform(0.0, ahead))
        take = ~done_ev & (ev['t'] <= reach)
        idx = np.flatnonzero(take)
        for part in np.array_split(idx, int(rng.integers(1, 4))):
            other.feed(ev[part])
        done_ev |= take
        for n, v in heard.items():
            take = ~done_h[n] & (v <= reach)
            other.heard(n, v[take])
            done_h[n] |= take
        while bad and bad[0][0] <= reach:
            t_b, topic, count = bad.pop(0)
            other.bad_value(topic, t_b, count)
        other.tick(w)
        for t_op, name in ops:
            if t_op == w:
                other.command(name, w)
    _same(other, sup)
    assert other.late == 0


def test_a_late_input_is_counted() -> None:
    sup = Supervisor(SCENE, **KW)
    sup.tick(0.2)
    sup.heard('crank_drive', 0.1)
    ev = np.zeros(1, dtype=EVENT_DTYPE)
    ev['t'] = 0.15
    sup.feed(ev)
    assert sup.late == 2
    with pytest.raises(ParameterError, match='watermark'):
        sup.command('hold', 0.1)


# --------------------------------------------------------------------------- every decision within its cycle


def test_report_only_records_every_batch_violation_within_its_cycle(free: LineModel) -> None:
    """enforce=False: the line runs on; the violations decided live are the batch ones, at their cycles."""
    duration = 30.0
    sup, model, _ = run_closed_loop(SCENE, duration, enforce=False, **KW)
    assert _path(sup) == [('STARTING', 'EXECUTE')] and sup.commands == () == model.commands
    batch = LineModel(SCENE, duration + 1.0)
    expect = sorted(
        (float(c.t[i]), int(c.cycle[i]), c.name, float(c.margin[i]))
        for c in batch.constraints
        for i in np.flatnonzero((c.margin < 0.0) & (c.t <= duration))
    )
    got = sorted((v.t, v.cycle, v.constraint, v.margin) for v in sup.violations)
    assert got == expect  # exactly: the late sheets reach the stops before their knife, so causal = batch
    assert {v.constraint for v in sup.violations} == {'feed_window', 'one_per_cycle'}
    assert all(v.action == 'none' for v in sup.violations)
    for v in sup.violations:
        assert _cycle_start(batch, v.cycle) <= v.t < _cycle_start(batch, v.cycle) + T
    # the running figures are the batch's over the decided cycles
    for c in batch.constraints:
        decided = c.t <= duration
        s = sup.stats[c.name]
        assert s.evaluations == int(np.count_nonzero(decided))
        assert s.min_margin == float(c.margin[decided].min())


# --------------------------------------------------------------------------- causal evaluation


@pytest.mark.parametrize('delay', [0.005, 0.03, 0.06])
def test_causal_evaluation_is_per_cycle_and_agrees_in_sign_with_the_batch(delay: float) -> None:
    scene = load_scene('folder_faults', {'faults.late_delay': delay, 'faults.p_late': 0.1})
    model = LineModel(scene, 6.0)
    tm = cycle_timing(scene.machines['cyclogram'], scene.machines['knife'])
    ev = model.events
    whole = folder_evaluation(ev, tm, scene, model.drive, causal=True)
    batch = folder_evaluation(ev, tm, scene, model.drive)
    assert np.array_equal(whole.cycle, batch.cycle) and np.array_equal(whole.signatures, batch.signatures)
    # cycle by cycle, on the events up to each knife contact only: the same as one call
    for k in range(0, int(whole.cycle.max()) + 1, 7):
        t_k = whole.t[k]
        one = folder_evaluation(ev[(ev['t'] <= t_k) & (ev['cycle'] == k)], tm, scene, model.drive, causal=True)
        assert one.cycle.tolist() == [k] and one.signatures.tolist() == [whole.signatures[k]]
        for a, b in zip(one.constraints, whole.constraints, strict=True):
            if b.name != 'release_at_min_speed':
                assert a.margin.tolist() == b.margin[b.cycle == k].tolist(), (b.name, k)
    late = set(_rows(model, 'fault_late')['cycle'].tolist())
    for a, b in zip(whole.constraints, batch.constraints, strict=True):
        assert a.name == b.name and np.array_equal(a.t, a.t)
        # a cycle is dropped only where its sheet was not at the stops (or not handed over) by the knife
        assert set(a.cycle.tolist()) <= set(b.cycle.tolist())
        assert set(b.cycle.tolist()) - set(a.cycle.tolist()) <= late
        keep = np.isin(b.cycle, a.cycle)
        assert np.array_equal(a.cycle, b.cycle[keep]) and np.array_equal(a.t, b.t[keep])
        assert np.array_equal(a.margin < 0.0, b.margin[keep] < 0.0), a.name
        if delay == 0.005:
            assert a.margin.tobytes() == b.margin.tobytes()
    if delay == 0.06:  # handed over after its knife: no feed_window judgement, a starvation at the decision
        fw = next(c for c in whole.constraints if c.name == 'feed_window')
        assert late and not late & set(fw.cycle.tolist())


# --------------------------------------------------------------------------- layup and motor


def test_chute_speed_is_the_layup_simulations_own_code() -> None:
    model = LineModel(load_scene('line'), 10.0)
    (live,) = evaluate_layup_constraints(model.events, model.scene)
    sim = next(c for c in model.constraints if c.name == 'chute_speed')
    a = np.lexsort((live.cycle, live.t))
    b = np.lexsort((sim.cycle, sim.t))
    assert live.cycle[a].tolist() == sim.cycle[b].tolist()
    assert live.margin[a].tobytes() == sim.margin[b].tobytes() and live.t[a].tobytes() == sim.t[b].tobytes()


def test_a_chute_speed_violation_holds_the_layup_at_its_next_crank_turn() -> None:
    scene = load_scene('layup', {'chute_belts.v_min': 3.2})
    free = LineModel(scene, 6.0)
    t0, leaf, name, margin = _first_violation(free)
    assert name == 'chute_speed' and margin < 0.0
    turn = 60.0 / scene.machine('layup').n_kr
    sup, model, _ = run_closed_loop(scene, turn + 1.0, lead=0.01, check_period=P)
    assert t0 < turn - 0.01
    assert _path(sup)[:3] == [('STARTING', 'EXECUTE'), ('EXECUTE', 'HOLDING'), ('HOLDING', 'HELD')]
    t_held = sup.transitions[2].t
    assert np.all(model.drive.rate(np.linspace(t_held, turn + 1.0, 50)) == 0.0)
    assert sup.transitions[1].t == t0 and sup.violations[0].cycle == leaf  # the leaf id
    # later leaves violate too while the line is holding: recorded, nothing more to command
    assert all(v.action == 'none' and v.state in ('HOLDING', 'HELD') for v in sup.violations[1:])
    hold = sup.commands[0]
    assert hold.t == _ns(free.next_cycle_boundary(t0 + 0.01))
    assert hold.t == pytest.approx(math.floor((t0 + 0.01) / turn + 1.0) * turn, abs=1e-9)  # a crank turn
    assert sup.balances[0].ok and sup.balances[0].detail['on_chutes'] >= 0


def test_with_motor_dynamics_held_when_the_motor_has_braked_to_rest() -> None:
    scene = load_scene('line')
    sup, model, _ = run_closed_loop(scene, 8.0, operator=[(3.0, 'hold')], lead=0.01, check_period=P)
    assert [tr.target for tr in sup.transitions] == ['EXECUTE', 'HOLDING', 'HELD']
    assert sup.transitions[0].t > 1.0  # the motor spins up along its curve first
    t_rest = model.drive.t_rest
    assert math.isfinite(t_rest) and t_rest > sup.commands[0].t + 1.0  # braked along the motor's curve
    assert t_rest <= sup.transitions[2].t < t_rest + P + 1e-12
    assert sup.balances[0].ok


# --------------------------------------------------------------------------- PackML legality


@settings(max_examples=20, deadline=None, suppress_health_check=list(HealthCheck))
@given(st.lists(st.tuples(st.integers(1, 300), st.sampled_from([*sorted(COMMANDS), 'warp'])), max_size=12))
@example(seq=[(1, 'stop'), (104, 'stop'), (104, 'reset')])  # a refusal and an acceptance at the same time
def test_operator_command_sequences_follow_the_packml_table(seq: list[tuple[int, str]]) -> None:
    scene = load_scene('folder')
    ops = sorted(((n * P, c) for n, c in seq), key=lambda x: x[0])
    sup, model, _ = run_closed_loop(scene, 1.6, operator=ops, lead=0.01, check_period=P)
    log = list(sup.operator_log)
    assert [(t, c) for t, c, _ in log] == [(t, c) for t, c in ops if t <= 1.6]
    hist = sup.transitions
    assert all(a.target == b.source for a, b in itertools.pairwise(hist))
    ends = {'drive at speed', 'drive at standstill', 'done'}
    by_operator = [tr for tr in hist if tr.cause not in ends]
    accepted = [(t, c) for t, c, ok in log if ok]
    assert [(tr.t, tr.cause) for tr in by_operator] == accepted
    for tr in hist:
        if tr.cause in ends:
            assert tr.target == ACTING[tr.source]
            if tr.cause == 'drive at standstill':
                assert float(model.drive.rate(np.array([tr.t]))[0]) == 0.0
        else:
            legal, target = COMMANDS[tr.cause]
            assert tr.source in legal and tr.target == target
    # refused: unknown or not legal in the state at that moment (walk log and history in
    # processing order: commands at the same time are applied one after the other); it changed nothing
    i, state = 0, 'STARTING'
    for t, c, ok in log:
        while i < len(hist) and (hist[i].t < t or (hist[i].t == t and hist[i].cause in ends)):
            state = hist[i].target
            i += 1
        if ok:
            assert (hist[i].t, hist[i].cause) == (t, c)
            state = hist[i].target
            i += 1
        else:
            assert c not in COMMANDS or state not in COMMANDS[c][0], (t, c, state)
    kinds = [DRIVE_COMMANDS[c][0] for _, c in accepted if DRIVE_COMMANDS[c][0] is not None]
    assert sorted(c.kind for c in sup.commands) == sorted(kinds)
    assert all(tr.target != 'ABORTED' or tr.source == 'ABORTING' for tr in hist)
    assert {b.state for b in sup.balances} <= set(STOP_STATES) and all(b.ok for b in sup.balances)


def test_constants_and_parameters() -> None:
    assert set(DRIVE_COMMANDS) == set(COMMANDS)
    assert set(TIMING_CONSTRAINTS) >= {
        'feed_window',
        'settled_before_knife',
        'rebound',
        'chute_speed',
        'release_at_min_speed',
    }
    for bad in (
        {'stale_periods': 0.0},
        {'lead': -1.0},
        {'lead': math.nan},
        {'check_period': 0.0},
        {'double': 'ignore'},
        {'speed_reached': 1.5},
        {'expected': ['nobody']},
    ):
        with pytest.raises(ParameterError):
            Supervisor(SCENE, **{**KW, **bad})
    with pytest.raises(ParameterError, match='t_start'):
        replay(SCENE, np.zeros(0, dtype=EVENT_DTYPE), t_start=None)


def test_with_clock_ticks_a_coarse_clock_does_not_make_nodes_stale() -> None:
    """A clock stepping 4 periods at a time, one step lost in a burst: k periods pass, k clock ticks do not."""
    clock = np.round(np.arange(0, 41) * 4 * P, 12)  # 0 .. 0.8 s, every 20 ms
    ticks = np.delete(clock, [10])  # the nodes miss the clock tick at 0.2 s
    out = {}
    for with_clock in (False, True):
        sup = Supervisor(SCENE, **{**KW, 'clock_ticks': with_clock})
        sup.clock(clock)
        for node in NODES:
            sup.heard(node, ticks if node != 'crank_drive' else ticks[ticks < 0.5])  # the crank dies at 0.5 s
        sup.tick(0.8)
        out[with_clock] = [(tr.target, tr.cause) for tr in sup.transitions]
        if with_clock:
            assert [tr.target for tr in sup.transitions] == ['EXECUTE', 'ABORTING']  # braking until 1.09 s
            # the crank's last tick 0.48 s; the fifth clock tick after it at 0.58 s
            assert sup.transitions[1].t == pytest.approx(0.58, abs=1e-12)
            assert 'crank_drive' in sup.transitions[1].cause
        else:  # the 40 ms gap at 0.2 s is more than 5 periods: a false alarm
            assert sup.transitions[1].t == pytest.approx(0.18 + 5 * P + P, abs=1e-12)
    # replay needs the clock stamps
    sup, _, fed = run_closed_loop(SCENE, 1.0, silent={'feed_transporter': 0.5}, **{**KW, 'clock_ticks': True})
    again = replay(
        SCENE,
        fed.events,
        heard=fed.heard,
        clock=fed.clock,
        until=fed.until,
        **{**KW, 'clock_ticks': True},
    )
    _same(again, sup)
    assert sup.transitions[1].target == 'ABORTING'


def test_a_command_leaves_the_supervisors_drive_unchanged_before_its_time() -> None:
    """The supervisor's drive is updated when it issues a command: before the command's effective
    time it is the free drive, bit for bit (the nodes may learn of the command late)."""
    free = LineModel(SCENE, H)
    sup = Supervisor(SCENE, **{**KW, 'lead': 0.05})
    sup.feed(free.events_between(-math.inf, 1.0))
    for node in NODES:
        sup.heard(node, np.arange(0, 401) * P)
    new = sup.tick(1.0)
    assert len(new) == 1 and new[0].kind == 'hold'
    t = np.linspace(0.0, new[0].t, 2001)
    assert sup.drive.theta(t).tobytes() == free.drive.theta(t).tobytes()
    after = np.linspace(new[0].t + 0.6, H, 50)  # a brake ramp of 0.5 s: at rest after
    assert np.all(sup.drive.rate(after) == 0.0) and np.all(free.drive.rate(after) == 1.0)


# --------------------------------------------------------------------------- lost participants (lockstep)


def _lockstep_supervisor() -> tuple[Any, LineModel, Supervisor]:
    """The fault scene, its free model, and a supervisor as the lockstep node builds it (no staleness)."""
    scene = load_scene('folder_faults')
    return scene, LineModel(scene, H), Supervisor(scene, periods={}, lead=0.01, check_period=P, t_start=0.0)


def test_a_lost_participant_aborts_naming_it_and_nothing_is_judged_after() -> None:
    """``lost`` at 0.4 s: abort at once with cause lost:<node>; a late sheet after 0.4 s is not judged."""
    scene, free, sup = _lockstep_supervisor()
    sup.feed(free.events_between(-math.inf, 0.4))
    sup.tick(0.4)
    assert sup.state == 'EXECUTE'
    sup.lost('feed_transporter', 0.4, 3.25)
    sup.feed(free.events_between(0.4, 3.0))  # what the others still sent (the feed's are missing)
    sup.tick(3.0)
    assert [tr.target for tr in sup.transitions] == ['EXECUTE', 'ABORTING', 'ABORTED']
    aborting = sup.transitions[1]
    assert aborting.t == 0.4 and 'participant feed_transporter lost' in aborting.cause
    (v,) = sup.violations  # folder_faults has a late sheet in cycle 13 (about 0.9 s): not judged
    assert (v.t, v.constraint, v.margin, v.unit, v.action) == (0.4, 'lost:feed_transporter', -3.25, 'wall s', 'abort')
    assert sup.lost_nodes == ['feed_transporter'] and sup.blind_from == 0.4
    assert all(st.last_t < 0.4 for st in sup.stats.values() if st.name != 'lost:feed_transporter')
    again = replay(
        scene,
        free.events_between(-math.inf, 3.0),
        lost=[(0.4, 'feed_transporter', 3.25)],
        until=3.0,
        periods={},
        lead=0.01,
        check_period=P,
        t_start=0.0,
    )
    _same(again, sup)


def test_without_a_lost_participant_the_late_sheet_holds_the_line() -> None:
    """The control of the test above: the same stream, nobody lost, holds in cycle 13."""
    _, free, sup = _lockstep_supervisor()
    sup.feed(free.events_between(-math.inf, 3.0))
    sup.tick(3.0)
    assert 'HOLDING' in [tr.target for tr in sup.transitions]
    assert any(v.constraint == 'feed_window' and v.cycle == 13 for v in sup.violations)


def test_the_balance_after_a_lost_participant_reads_not_judged() -> None:
    """The feed is lost at 0.4 s: its hand-overs stop there while the others' events go on, so the balance at
    ABORTED is not a number to judge: it says which events were not received."""
    _, free, sup = _lockstep_supervisor()
    sup.feed(free.events_between(-math.inf, 0.4))
    sup.tick(0.4)
    sup.lost('feed_transporter', 0.4, 1.5)
    rest = free.events_between(0.4, 3.0)
    sup.feed(rest[np.isin(rest['kind'], [event_kind(k) for k in ('knife_contact', 'knife_exit', 'released_on_pile')])])
    sup.tick(3.0)
    (b,) = sup.balances
    assert b.state == 'ABORTED' and not b.ok
    assert b.missing == 'events of feed_transporter not received after 0.400000 s'


@pytest.mark.parametrize('name', ['folder_faults', 'folder_jitter', 'line'])
def test_cycles_evaluated_ahead_are_judged_as_when_due(name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """``Supervisor.preview`` of each second's events, then the events fed tick by tick (5 ms): the same
    evaluations (margins and all), violations and transitions as without it, while most cycles are taken
    from the preview. Not enforcing, folder_faults runs on through its missing, late and double
    signatures (a cycle with two releases is evaluated when due, not ahead)."""
    from folder_line.core.line.stream import LineStream
    from folder_line.core.supervision import evaluation

    scene = load_scene(name)
    stream = LineStream(scene)
    windows = [stream.advance(float(s)).events for s in range(1, 41)]
    calls: list[int] = []
    taken: list[Any] = []  # every evaluation judged, in order
    real_evaluation, real_taken = evaluation.folder_evaluation, evaluation.CycleEvaluation.taken

    def counted(*args: Any, **kwargs: Any) -> Any:
        calls.append(1)
        return real_evaluation(*args, **kwargs)

    def recorded(self: Any, it: Any) -> None:
        taken.append(it)
        real_taken(self, it)

    monkeypatch.setattr(evaluation, 'folder_evaluation', counted)
    monkeypatch.setattr(evaluation.CycleEvaluation, 'taken', recorded)
    runs = []
    for ahead in (True, False):
        sup = Supervisor(scene, enforce=False, lead=0.01)
        calls.clear()
        taken.clear()
        t0 = 0.0
        for second, rows in enumerate(windows, start=1):
            if ahead:
                sup.preview(rows)
            for k in range(1, 201):
                t = second - 1 + k * 0.005
                sup.feed(rows[(rows['t'] > t0) & (rows['t'] <= t)])
                sup.tick(t)
                t0 = t
        runs.append((sup, list(taken), len(calls)))
    (a, taken_a, n_ahead), (b, taken_b, n_plain) = runs
    assert len(taken_a) > 500 and taken_a == taken_b
    assert a.violations == b.violations and a.transitions == b.transitions and a.stats == b.stats
    if scene.has_folder:
        assert n_ahead < n_plain / 4, (n_ahead, n_plain)
    if name == 'folder_faults':
        assert a.violations  # the faults are judged
        releases = np.concatenate(windows)
        released = releases['cycle'][releases['kind'] == event_kind('released_on_pile')]
        assert np.unique(released, return_counts=True)[1].max() == 2  # a cycle with a double sheet
