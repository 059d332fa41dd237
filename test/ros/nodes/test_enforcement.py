"""The supervisor enforces over real DDS: the fault scene holds, starves, loses a node, is cleared.

The machine nodes, the supervisor and ``line_clock`` run in this process in lockstep
(the ``ros`` fixture) on the ``folder_faults`` scene; a :class:`FakeParticipant`
(``line_recorder``) holds sim time where the test acts (an operator command, a node
that hangs), and a plain node listens to everything the supervisor hears. Expected
times come from the line model (the batch simulation); at the end the recorded
stream is replayed through the supervisor's logic offline
(:func:`folder_line.core.supervision.offline.replay`) and must give the same decisions.

Wall time matters only where a node hangs: the supervisor declares it lost after its
``lost_timeout`` and ``line_clock`` after its own. While sim time is held nobody but
``line_clock`` waits, so the test does its work there (or after the end) and never
keeps a waiting node from its input.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState, TimeReference
from std_msgs.msg import String
from std_srvs.srv import Trigger

from folder_line.config.scenes import load_scene
from folder_line.core.line.model import LineModel
from folder_line.core.mechanisms.cyclogram import cycle_timing
from folder_line.core.mechanisms.drive import Command
from folder_line.core.supervision.offline import replay
from folder_line.core.supervision.settings import SPEED_REACHED
from folder_line.core.types.events import EVENT_DTYPE, event_kind
from folder_line.interfaces import (
    COMMANDS_TOPIC,
    DIAGNOSTICS_TOPIC,
    EVENT_KINDS,
    EVENTS_TOPIC,
    NS_PER_S,
    SUPERVISOR_STATE_TOPIC,
    UNIT_OF_NODE,
    parse_event_source,
)
from folder_line.ros.nodes.belt_conveyor import BeltConveyor
from folder_line.ros.nodes.crank_drive import CrankDrive
from folder_line.ros.nodes.feed_transporter import FeedTransporter
from folder_line.ros.nodes.line_clock import LineClock
from folder_line.ros.nodes.sheet_counter import SheetCounter
from folder_line.ros.nodes.supervisor import STATE_QOS, Supervisor
from folder_line.ros.time_msg import time_msg_to_ns
from folder_line.ros.topics import COMMANDS_QOS, joint_states_topic

from .._signed import command_text, signed
from .test_line_clock import FakeParticipant, grid
from .test_supervisor import on_grid

if TYPE_CHECKING:
    from ..conftest import Received, Ros

SCENE = 'folder_faults'
SPAN = 10.0
DURATION = 7.0  # s of sim time the clock runs
RATE = 100.0  # Hz of sim time: the clock, every node, the supervisor's check grid
PERIOD = 1.0 / RATE
PERIOD_NS = 10_000_000
LEAD = 0.1  # command_lead (default), s
SUPERVISOR_LOST = 1.0  # wall s the supervisor waits for a machine node's tick before it is lost
CLOCK_LOST = 3.0  # wall s line_clock waits for an answer (the holds here last a few ms)
RELIABLE = QoSProfile(depth=10000, reliability=ReliabilityPolicy.RELIABLE)
JOINT_NODES = ('crank_drive', 'belt_conveyor', 'feed_transporter')


def params(**values: Any) -> list[Parameter]:
    return [Parameter(name, value=value) for name, value in values.items()]


def states_seen(received: Received) -> list[str]:
    out: list[str] = []
    for m in received.messages:
        if not out or out[-1] != m.data:
            out.append(m.data)
    return out


def statuses(diags: Received, name: str) -> list[DiagnosticStatus]:
    return [s for arr in diags.messages for s in arr.status if s.name == name]


def values(status: DiagnosticStatus) -> dict[str, str]:
    return {kv.key: kv.value for kv in status.values}


def call(ros: Ros, sup: Supervisor, client: Any) -> tuple[bool, str]:
    """Call an operator service of ``sup``, its request signed first as ``folder-line`` does."""
    name = client.srv_name.rsplit('/', 1)[-1]
    assert sup.set_parameters_atomically(signed('supervisor', [Parameter('operator_command', value=name)])).successful
    future = client.call_async(Trigger.Request())
    assert ros.spin_until(future.done, timeout=20.0)
    return future.result().success, future.result().message


def test_the_fault_scene_is_held_suspended_aborted_for_a_lost_node_and_cleared(ros: Ros) -> None:  # noqa: PLR0915
    """One run of the fault scene, judged section by section against the model (long on purpose: each
    section reads the state the previous one left, as the run does; split, it would carry a dozen
    values from helper to helper)."""
    scene = load_scene(SCENE)
    free = LineModel(scene, SPAN)
    T = cycle_timing(scene.machines['cyclogram'], scene.machines['knife']).T
    common = {'scene': SCENE, 'rate': RATE}
    nodes = {
        cls.NODE_NAME: ros.add(cls(context=ros.context, parameter_overrides=params(**common)))
        for cls in (CrankDrive, BeltConveyor, FeedTransporter, SheetCounter)
    }
    sup = ros.add(Supervisor(context=ros.context, parameter_overrides=params(**common, lost_timeout=SUPERVISOR_LOST)))
    hold = ros.add(FakeParticipant(ros.context))
    listener = ros.node('listener')
    state = ros.subscribe(listener, String, SUPERVISOR_STATE_TOPIC, STATE_QOS)
    commands = ros.subscribe(listener, TimeReference, COMMANDS_TOPIC, COMMANDS_QOS)
    diags = ros.subscribe(listener, DiagnosticArray, DIAGNOSTICS_TOPIC, RELIABLE)
    events = ros.subscribe(listener, TimeReference, EVENTS_TOPIC, RELIABLE)
    events_sub = list(listener.subscriptions)[-1]
    joints = {name: ros.subscribe(listener, JointState, joint_states_topic(name), RELIABLE) for name in JOINT_NODES}
    clients = {name: listener.create_client(Trigger, f'/line/supervisor/{name}') for name in ('unhold', 'clear')}
    assert ros.spin_until(
        lambda: (
            events_sub.get_publisher_count() == 5
            and all(s.get_publisher_count() >= 1 for s in listener.subscriptions)
            and all(c.service_is_ready() for c in clients.values())
        ),
        timeout=20.0,
    )
    clock = ros.add(
        LineClock(
            context=ros.context,
            parameter_overrides=params(
                rate=RATE,
                rtf=0.0,
                duration=DURATION,
                lost_timeout=CLOCK_LOST,
                window=0.0,  # a barrier per tick: the test holds the line at a tick of its choosing
                participants=','.join([*nodes, 'supervisor', 'line_recorder']),
            ),
        )
    )
    logic = sup.logic

    def pause_when(condition: Callable[[], bool]) -> float:
        """Run until the first tick at whose arrival ``condition()`` holds; hold it, every node's tick done."""
        hold.run_to(None, when=lambda stamp: condition())
        assert ros.spin_until(lambda: hold.held is not None and sup.lockstep.last_done == hold.held, timeout=30.0), (
            states_seen(state)
        )
        return hold.held / NS_PER_S

    # ---- the late sheet of cycle 13: a timing fault -> HOLDING at its knife contact, HELD at standstill
    t1 = pause_when(lambda: sup.packml.state == 'HELD')
    ok, message = call(ros, sup, clients['unhold'])
    assert ok and message.startswith('unhold: UNHOLDING, drive unhold effective at'), message
    # ---- then the missing sheet of cycle 45: starvation -> SUSPENDED
    t2 = pause_when(lambda: sup.packml.state == 'SUSPENDED')
    # ---- the belt's process dies (its node leaves the graph): lost for the supervisor and the clock -> ABORTED
    belt = nodes['belt_conveyor']
    assert belt.lockstep.last_done == round(t2 * NS_PER_S)
    ros.remove(belt)
    t3 = pause_when(lambda: sup.packml.state == 'ABORTED')
    # ---- only clear leaves ABORTED
    assert call(ros, sup, clients['unhold']) == (False, "'unhold' refused in state ABORTED: legal only in HELD")
    assert call(ros, sup, clients['clear']) == (True, 'clear: CLEARING')
    hold.run_to(None)
    end = round(DURATION * NS_PER_S)
    live = [n for n in (*nodes.values(), sup) if n is not belt]
    assert ros.spin_until(
        lambda: (
            clock.done.done()
            and all(n.done.done() for n in live)
            and len(state) == sup.published_state
            and len(commands) == sup.published_commands
            and len(diags) == sup.published_diagnostics + 1  # the clock's lost diagnostic
            and len(events) == sum(n.published_events for n in (*nodes.values(), sup))
            and all(len(joints[n]) == nodes[n].published_joint_states for n in JOINT_NODES)
        ),
        timeout=60.0,
    ), states_seen(state)

    # ---- lockstep: every live node ran every tick; the belt up to the tick it hung at, then it was lost
    ticks = grid(0, end, PERIOD_NS)
    assert clock.ticks == len(ticks) and all(n.lockstep.ticks == len(ticks) for n in live)
    assert belt.lockstep.ticks == ticks.index(round(t2 * NS_PER_S)) + 1
    assert clock.lost == {'belt_conveyor': (round(t2 * NS_PER_S) + PERIOD_NS) / NS_PER_S}
    assert logic.lost_nodes == ['belt_conveyor'] and all(n.rejected == {} for n in live)
    assert states_seen(state) == [
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
    ]
    assert [(tr.source, tr.target) for tr in logic.transitions] == [
        ('STARTING', 'EXECUTE'),
        ('EXECUTE', 'HOLDING'),
        ('HOLDING', 'HELD'),
        ('HELD', 'UNHOLDING'),
        ('UNHOLDING', 'EXECUTE'),
        ('EXECUTE', 'SUSPENDING'),
        ('SUSPENDING', 'SUSPENDED'),
        ('SUSPENDED', 'ABORTING'),
        ('ABORTING', 'ABORTED'),
        ('ABORTED', 'CLEARING'),
        ('CLEARING', 'STOPPED'),
    ]
    published = [Command(time_msg_to_ns(m.time_ref) / NS_PER_S, command_text(m)) for m in commands.messages]
    assert [c.kind for c in published] == ['hold', 'unhold', 'hold', 'stop'] and published == list(logic.commands)
    assert nodes['crank_drive'].commands == tuple(published)

    # ---- the hold: decided at the violating cycle's knife contact, effective at the next cycle boundary
    c_fw = next(c for c in free.constraints if c.name == 'feed_window')
    first = int(np.flatnonzero(c_fw.margin < 0.0)[0])
    t_violation, cycle = float(c_fw.t[first]), int(c_fw.cycle[first])
    assert cycle == 13
    holding = logic.transitions[1]
    assert abs(holding.t - t_violation) < 1e-9  # the event's ns time
    exits = free.events[free.events['kind'] == event_kind('knife_exit')]
    start = float(exits['t'][exits['cycle'] == cycle - 1][0])
    assert start <= holding.t < start + T  # within the violating cycle
    v = logic.violations[0]
    assert (v.cycle, v.constraint, v.action, v.state) == (cycle, 'feed_window', 'hold', 'EXECUTE')
    assert abs(v.margin - float(c_fw.margin[first])) < 2e-9
    hold_cmd = commands.messages[0]
    assert time_msg_to_ns(hold_cmd.time_ref) == round(free.next_cycle_boundary(holding.t + LEAD) * NS_PER_S)
    (viol,) = [values(s) for s in statuses(diags, 'folder_line/supervisor/violation') if values(s)['cycle'] == '13']
    assert (viol['constraint'], viol['action']) == ('feed_window', 'hold') and float(viol['margin']) == v.margin
    # HELD at the first check-grid point at standstill; the crank ramped down and stood still, as the model says
    t_hold = published[0].t
    held_model = LineModel(scene, SPAN, published[:1])
    t_held = on_grid(t_hold, lambda g: held_model.drive.rate(np.array([g]))[0] <= 0.0, h=PERIOD)
    assert logic.transitions[2].t == t_held and t_hold + scene.drive.t_brake <= t_held
    model = LineModel(scene, SPAN, published)
    crank = joints['crank_drive'].messages
    stamps = np.array([time_msg_to_ns(m.header.stamp) for m in crank])
    assert stamps.tolist() == ticks
    np.testing.assert_array_equal(
        [m.velocity for m in crank], model.sample(UNIT_OF_NODE['crank_drive'], stamps / NS_PER_S).velocity
    )
    speed = np.array([m.velocity[0] for m in crank])
    ramp = (stamps >= t_hold * NS_PER_S) & (stamps < (t_hold + scene.drive.t_brake) * NS_PER_S)
    assert ramp.sum() >= 49 and np.all(np.diff(speed[ramp]) < 0.0)  # down along the brake ramp
    assert np.all(speed[(stamps >= t_held * NS_PER_S) & (stamps <= t1 * NS_PER_S)] == 0.0)

    # ---- the unhold, at the tick held in HELD: effective command_lead later, EXECUTE at speed
    assert t1 > t_held and published[1] == Command(round((t1 + LEAD) * NS_PER_S) / NS_PER_S, 'unhold')
    t_speed = on_grid(published[1].t, lambda g: model.drive.rate(np.array([g]))[0] >= SPEED_REACHED, h=PERIOD)
    assert logic.transitions[4].t == t_speed

    # ---- the suspension: at the knife contact of cycle 45 (missing sheet), within that cycle
    suspending = logic.transitions[5]
    assert suspending.cause.startswith('missing sheet') and 'cycle 45' in suspending.cause
    contact = model.events[(model.events['kind'] == event_kind('knife_contact')) & (model.events['cycle'] == 45)]
    assert abs(suspending.t - float(contact['t'][0])) < 1e-9
    exits = model.events[model.events['kind'] == event_kind('knife_exit')]
    start = float(exits['t'][exits['cycle'] == 44][0])
    assert start <= suspending.t < start + T
    assert published[2].t == round(model.next_cycle_boundary(suspending.t + LEAD) * NS_PER_S) / NS_PER_S
    assert [b.state for b in logic.balances][:2] == ['HELD', 'SUSPENDED']
    assert t2 > logic.transitions[6].t

    # ---- the lost belt: decided at the supervisor's last complete tick, the one it hung at
    aborting = logic.transitions[7]
    assert (aborting.t, aborting.source) == (t2, 'SUSPENDED') and 'participant belt_conveyor lost' in aborting.cause
    lost = logic.violations[-1]
    assert (lost.t, lost.constraint, lost.action, lost.unit, lost.state) == (
        t2,
        'lost:belt_conveyor',
        'abort',
        'wall s',
        'SUSPENDED',
    )
    assert lost.margin < -SUPERVISOR_LOST  # minus the wall seconds it was waited for
    assert time_msg_to_ns(joints['belt_conveyor'].messages[-1].header.stamp) == round(t2 * NS_PER_S)
    assert published[3] == Command(round((t2 + LEAD) * NS_PER_S) / NS_PER_S, 'stop')  # abort: stop lead later
    t_aborted = on_grid(published[3].t, lambda g: model.drive.rate(np.array([g]))[0] <= 0.0, h=PERIOD)
    assert logic.transitions[8].t == t_aborted and t3 > t_aborted
    cleared = logic.transitions[10]
    assert (cleared.t, cleared.cause) == (on_grid(t3, lambda g: True, h=PERIOD, strictly_after=True), 'done')
    assert sup.packml.state == 'STOPPED' and sum(tr.target == 'ABORTING' for tr in logic.transitions) == 1
    (clock_lost,) = statuses(diags, 'folder_line/line_clock/lost')
    assert clock_lost.level == DiagnosticStatus.ERROR and values(clock_lost)['node'] == 'belt_conveyor'
    inputs = [
        (time_msg_to_ns(arr.header.stamp), s)
        for arr in diags.messages
        for s in arr.status
        if s.name == 'folder_line/supervisor/inputs'
    ]
    assert [stamp for stamp, _ in inputs] == list(range(0, end + 1, NS_PER_S))  # 1 Hz of sim time
    for stamp, s in inputs:  # the lost node from the first one after the tick it hung at
        if stamp > t2 * NS_PER_S:
            assert (s.level, s.message) == (
                DiagnosticStatus.ERROR,
                'no input rejected; participants lost: belt_conveyor',
            )
            assert values(s) == {'lost': 'belt_conveyor'}
        else:
            assert (s.level, s.message, values(s)) == (DiagnosticStatus.OK, 'no input rejected', {})
    # after the loss the belt's events are missing: those balances are not judged, they say why
    not_received = f'events of belt_conveyor not received after {logic.blind_from:.6f} s'
    assert [(b.state, b.ok, b.missing) for b in logic.balances] == [
        ('HELD', True, ''),
        ('SUSPENDED', True, ''),
        ('ABORTED', False, not_received),
        ('STOPPED', False, not_received),
    ]

    # ---- replay: the recorded stream through the same logic offline gives the same decisions
    rows = []
    for m in events.messages:
        kind, sheet, cyc, value = parse_event_source(m.source)
        rows.append((time_msg_to_ns(m.time_ref) / NS_PER_S, EVENT_KINDS.index(kind), sheet, cyc, value))
    again = replay(
        scene,
        np.array(rows, dtype=EVENT_DTYPE),
        operator=[(t, c) for t, c, _ in logic.operator_log],
        lost=[(lost.t, 'belt_conveyor', -lost.margin)],
        until=logic.now,
        lead=LEAD,
        check_period=PERIOD,
        t_start=logic.t_start,
    )
    assert again.transitions == logic.transitions
    assert again.commands == logic.commands
    assert again.violations == logic.violations and again.balances == logic.balances
    # no input came after its tick, except events just after a tick, whose time rounds to its stamp
    assert logic.late == sum(
        time_msg_to_ns(m.time_ref) == time_msg_to_ns(m.header.stamp) - PERIOD_NS for m in events.messages
    )
