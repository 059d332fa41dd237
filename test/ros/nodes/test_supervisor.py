"""The supervisor over real DDS: its services, PackML states, drive commands, diagnostics, its inputs.

The five machine nodes and ``line_clock`` run in this process in lockstep (the
``ros`` fixture); a :class:`FakeParticipant` (``line_recorder``) holds sim time at
the ticks the test chooses, so that every service is called at a known tick and
every effective time is known exactly: effective times are checked against
:class:`folder_line.core.line.model.LineModel` to the nanosecond, state changes on the
supervisor's check grid to the bit, the joint states against the model rebuilt
with the commands the supervisor published.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState, TimeReference
from std_msgs.msg import String
from std_srvs.srv import Trigger

from folder_line.config.scenes import load_scene
from folder_line.core.line.model import LineModel
from folder_line.core.mechanisms.drive import Command
from folder_line.core.supervision.settings import SPEED_REACHED
from folder_line.interfaces import (
    COMMANDS_TOPIC,
    DIAGNOSTICS_TOPIC,
    EVENT_KINDS,
    EVENTS_TOPIC,
    NS_PER_S,
    PARTICIPANTS_TOPIC,
    SUPERVISOR_STATE_TOPIC,
    UNIT_OF_NODE,
    progress_topic,
)
from folder_line.ros.lockstep import ACK_QOS, LINE_QOS, PARTICIPANTS_QOS
from folder_line.ros.nodes.belt_conveyor import BeltConveyor
from folder_line.ros.nodes.crank_drive import CrankDrive
from folder_line.ros.nodes.feed_transporter import FeedTransporter
from folder_line.ros.nodes.line_clock import LineClock
from folder_line.ros.nodes.machine import MachineNode
from folder_line.ros.nodes.sheet_counter import SheetCounter
from folder_line.ros.nodes.supervisor import SERVICES, STATE_QOS, Supervisor
from folder_line.ros.signing import sign_text, without_signature
from folder_line.ros.time_msg import ns_to_time_msg, time_msg_to_ns
from folder_line.ros.topics import COMMANDS_QOS, joint_states_topic

from .._signed import command_text, signed, time_reference
from .test_line_clock import FakeParticipant, grid

if TYPE_CHECKING:
    from ..conftest import Received, Ros

RELIABLE = QoSProfile(depth=10000, reliability=ReliabilityPolicy.RELIABLE)
MS = 1_000_000  # ns
STEP = 5 * MS  # ticks and grid at 200 Hz
H = 1.0 / 200.0  # the supervisor's check period, s (as the node computes it)
SPAN = 5.0
LEAD = 0.1  # the supervisor's default command_lead, s
MACHINES = (CrankDrive, BeltConveyor, FeedTransporter, SheetCounter)


def params(**values: Any) -> list[Parameter]:
    return [Parameter(name, value=value) for name, value in values.items()]


def subscribe(ros: Ros, node: Node, msg_type: type, topic: str, qos: QoSProfile = RELIABLE) -> tuple[Received, Any]:
    received = ros.subscribe(node, msg_type, topic, qos)
    return received, list(node.subscriptions)[-1]


def states_seen(received: Received) -> list[str]:
    """The states received, repeats collapsed."""
    out: list[str] = []
    for m in received.messages:
        if not out or out[-1] != m.data:
            out.append(m.data)
    return out


def tick_at_or_after(t: float) -> int:
    """The first tick (ns) at or after ``t`` s."""
    return math.ceil(round(t * NS_PER_S) / STEP) * STEP


def on_grid(t_from: float, ok: Callable[[float], bool], strictly_after: bool = False, h: float = H) -> float:
    """The first point ``n h`` of the supervisor's check grid at (or strictly after) ``t_from`` where ``ok``
    holds (``h = 1 / rate``, computed as the node does, so that the points are the logic's to the bit)."""
    n = math.floor(t_from / h) - 1
    while n * h < t_from or (strictly_after and n * h == t_from):
        n += 1
    while not ok(n * h):
        n += 1
    return n * h


class Line:
    """The folder line in this process: five nodes, ``line_clock``, a holding participant, a listener."""

    def __init__(self, ros: Ros, duration: float, **supervisor: Any) -> None:
        self.ros = ros
        common = {'scene': 'folder'}
        self.machines = {
            cls.NODE_NAME: ros.add(cls(context=ros.context, parameter_overrides=params(**common))) for cls in MACHINES
        }
        self.sup = ros.add(Supervisor(context=ros.context, parameter_overrides=params(**common, **supervisor)))
        self.nodes: dict[str, MachineNode] = {**self.machines, 'supervisor': self.sup}
        self.hold = ros.add(FakeParticipant(ros.context, hold_from=0))
        self.listener = ros.node('listener')
        self.state, state_sub = subscribe(ros, self.listener, String, SUPERVISOR_STATE_TOPIC, STATE_QOS)
        self.commands, commands_sub = subscribe(ros, self.listener, TimeReference, COMMANDS_TOPIC, COMMANDS_QOS)
        self.crank, crank_sub = subscribe(ros, self.listener, JointState, joint_states_topic('crank_drive'))
        self.clients = {name: self.listener.create_client(Trigger, f'/line/supervisor/{name}') for name in SERVICES}
        assert ros.spin_until(
            lambda: (
                all(c.service_is_ready() for c in self.clients.values())
                and state_sub.get_publisher_count() == crank_sub.get_publisher_count() == 1
                and commands_sub.get_publisher_count() == 1
            ),
            timeout=20.0,
        )
        self.end = round(duration * NS_PER_S)
        self.clock = ros.add(
            LineClock(
                context=ros.context,
                parameter_overrides=params(
                    duration=duration,
                    rtf=0.0,
                    lost_timeout=60.0,
                    window=0.0,  # a barrier per tick: the test holds the line at the ticks it names
                    participants=','.join([*self.nodes, 'line_recorder']),
                ),
            )
        )

    def pause_at(self, t: float) -> float:
        """Let sim time run to the first tick at or after ``t`` s and hold it there, every node's tick done;
        return that tick, s (the supervisor's watermark)."""
        stamp = tick_at_or_after(t)
        self.hold.run_to(stamp)
        assert self.ros.spin_until(
            lambda: (
                self.hold.held == stamp
                and self.sup.lockstep.last_done == stamp
                and len(self.state) == self.sup.published_state
                and len(self.commands) == self.sup.published_commands
                and len(self.crank) == self.machines['crank_drive'].published_joint_states
            ),
            timeout=30.0,
        )
        assert self.sup.logic.now == stamp / NS_PER_S
        return stamp / NS_PER_S

    def call(self, name: str, sign: bool = True) -> tuple[bool, str]:
        """Call the supervisor's service ``name``, its request first signed as ``folder-line`` does."""
        if sign:
            request = signed('supervisor', [Parameter('operator_command', value=name)])
            assert self.sup.set_parameters_atomically(request).successful
        future = self.clients[name].call_async(Trigger.Request())
        assert self.ros.spin_until(future.done, timeout=20.0)
        response = future.result()
        return response.success, response.message

    def run_to_end(self, rejected: dict[str, dict[str, int]] | None = None) -> None:
        """Let the line run to its end: every tick, no input rejected but the ``rejected`` counts (per node)."""
        self.hold.run_to(None)
        assert self.ros.spin_until(
            lambda: (
                self.clock.done.done()
                and all(n.done.done() for n in self.nodes.values())
                and len(self.crank) == self.machines['crank_drive'].published_joint_states
            ),
            timeout=60.0,
        )
        ticks = len(grid(0, self.end, STEP))
        assert self.clock.ticks == ticks and self.clock.lost == {}
        assert all(n.lockstep.ticks == ticks for n in self.nodes.values())
        assert {name: n.rejected for name, n in self.nodes.items() if n.rejected} == (rejected or {})


def effective_in_message(message: str) -> float:
    m = re.search(r'effective at (\d+\.\d{6}) s', message)
    assert m is not None, message
    return float(m[1])


# --------------------------------------------------------------------------- hold and unhold


def test_hold_at_the_next_cycle_boundary_then_unhold(ros: Ros) -> None:  # noqa: PLR0915
    """An operator's hold and unhold through the services, judged step by step against the model (long on
    purpose: each step reads the state the previous one left)."""
    scene = load_scene('folder')
    free = LineModel(scene, SPAN)
    line = Line(ros, duration=3.0)
    sup = line.sup
    services = dict(line.listener.get_service_names_and_types())
    for name in SERVICES:
        assert services.get(f'/line/supervisor/{name}') == ['std_srvs/srv/Trigger'], name

    t_request = line.pause_at(1.0)
    assert states_seen(line.state) == ['EXECUTE']
    # illegal: unhold while EXECUTE, refused with the reason, nothing published
    assert line.call('unhold') == (False, "'unhold' refused in state EXECUTE: legal only in HELD")
    assert len(line.commands) == 0 and sup.packml.state == 'EXECUTE'

    # without the line's key (as ros2 service call would): refused with the reason, nothing done
    ok, message = line.call('hold', sign=False)
    assert not ok and message.startswith('hold: refused: this line is keyed') and sup.packml.state == 'EXECUTE'
    # hold at the watermark: effective at the first cycle boundary at least command_lead later
    ok, message = line.call('hold')
    assert ok and message.startswith('hold: HOLDING, drive hold effective at') and 'next cycle boundary' in message
    assert ros.spin_until(lambda: len(line.commands) == 1, timeout=20.0)
    hold = line.commands.messages[0]
    assert command_text(hold) == 'hold' and hold.header.frame_id == 'supervisor'
    assert time_msg_to_ns(hold.header.stamp) == round(t_request * NS_PER_S)  # decided at the watermark
    boundary = free.next_cycle_boundary(t_request + LEAD)
    t_hold_ns = time_msg_to_ns(hold.time_ref)
    assert t_hold_ns == round(boundary * NS_PER_S)
    assert effective_in_message(message) == pytest.approx(boundary, abs=5e-7)
    cycle = free.part('folder').timing.T
    assert t_request + LEAD < boundary <= t_request + LEAD + cycle
    knife_exits = free.events[free.events['kind'] == EVENT_KINDS.index('knife_exit')]['t']  # boundaries
    assert boundary in knife_exits

    # HOLDING, then HELD at the first point of the check grid at standstill
    t_hold = t_hold_ns / NS_PER_S
    held = LineModel(scene, SPAN, [Command(t_hold, 'hold')])
    t_still = on_grid(t_hold, lambda g: held.drive.rate(np.array([g]))[0] <= 0.0)
    assert t_hold + scene.drive.t_brake <= t_still < t_hold + scene.drive.t_brake + H + 1e-9
    t_request2 = line.pause_at(t_still + 0.2)
    holding, done = sup.packml.history[-2:]
    assert (holding.source, holding.target, holding.cause, holding.t) == ('EXECUTE', 'HOLDING', 'hold', t_request)
    assert (done.source, done.target, done.cause, done.t) == ('HOLDING', 'HELD', 'drive at standstill', t_still)
    assert states_seen(line.state) == ['EXECUTE', 'HOLDING', 'HELD']

    # the crank stands still from then on, where the commanded model says
    assert line.machines['crank_drive'].commands == (Command(t_hold, 'hold'),)
    still = [m for m in line.crank.messages if time_msg_to_ns(m.header.stamp) >= t_still * NS_PER_S]
    assert len(still) == round((t_request2 - t_still) / H) + 1
    assert all(list(m.velocity) == [0.0, 0.0] and list(m.position) == list(still[0].position) for m in still)

    # unhold: effective command_lead after the request; UNHOLDING, then EXECUTE at speed
    ok, message = line.call('unhold')
    assert ok and message.startswith('unhold: UNHOLDING, drive unhold effective at')
    assert ros.spin_until(lambda: len(line.commands) == 2, timeout=20.0)
    unhold = line.commands.messages[1]
    assert command_text(unhold) == 'unhold' and time_msg_to_ns(unhold.header.stamp) == round(t_request2 * NS_PER_S)
    assert time_msg_to_ns(unhold.time_ref) == round((t_request2 + LEAD) * NS_PER_S)
    t_unhold = time_msg_to_ns(unhold.time_ref) / NS_PER_S
    cmds = [Command(t_hold, 'hold'), Command(t_unhold, 'unhold')]
    model = LineModel(scene, SPAN, cmds)
    t_speed = on_grid(t_unhold, lambda g: model.drive.rate(np.array([g]))[0] >= SPEED_REACHED)
    assert t_unhold + 0.99 * scene.drive.t_restart - 1e-9 <= t_speed < t_unhold + scene.drive.t_restart + 1e-9
    line.pause_at(t_speed + 0.2)
    assert states_seen(line.state) == ['EXECUTE', 'HOLDING', 'HELD', 'UNHOLDING', 'EXECUTE']
    back = sup.packml.history[-1]
    assert (back.source, back.target, back.cause, back.t) == ('UNHOLDING', 'EXECUTE', 'drive at speed', t_speed)

    # every crank joint state so far is the model with the commands the supervisor published, to the bit
    line.run_to_end(rejected={'supervisor': {'operator': 1}})  # the unsigned hold, counted
    assert [Command(time_msg_to_ns(m.time_ref) / NS_PER_S, command_text(m)) for m in line.commands.messages] == cmds
    stamps = np.array([time_msg_to_ns(m.header.stamp) for m in line.crank.messages])
    assert stamps.tolist() == grid(0, line.end, STEP)
    expect = model.sample(UNIT_OF_NODE['crank_drive'], stamps / NS_PER_S)
    np.testing.assert_array_equal([m.position for m in line.crank.messages], expect.position)
    np.testing.assert_array_equal([m.velocity for m in line.crank.messages], expect.velocity)
    moving = [m for m in line.crank.messages if time_msg_to_ns(m.header.stamp) > t_speed * NS_PER_S]
    assert moving and all(m.velocity[0] > 0.0 for m in moving)
    assert sup.logic.violations == [] and [b.state for b in sup.logic.balances] == ['HELD']


def test_stop_reset_start_abort_clear(ros: Ros) -> None:
    lead = 0.05
    scene = load_scene('folder')
    free = LineModel(scene, SPAN)
    line = Line(ros, duration=3.5, command_lead=lead)
    sup = line.sup

    def standstill(model: LineModel, t: float) -> float:
        return on_grid(t, lambda g: model.drive.rate(np.array([g]))[0] <= 0.0)

    t1 = line.pause_at(0.5)
    assert line.call('start') == (False, "'start' refused in state EXECUTE: legal only in IDLE")
    assert line.call('clear') == (False, "'clear' refused in state EXECUTE: legal only in ABORTED")
    ok, message = line.call('stop')
    assert ok and message.startswith('stop: STOPPING, drive stop effective at') and 'next cycle boundary' in message
    t_stop = round(free.next_cycle_boundary(t1 + lead) * NS_PER_S) / NS_PER_S
    cmds = [Command(t_stop, 'stop')]
    t_stopped = standstill(LineModel(scene, SPAN, cmds), t_stop)

    t2 = line.pause_at(t_stopped + 0.1)
    assert line.call('reset') == (True, 'reset: RESETTING')  # no drive command
    t_idle = on_grid(t2, lambda g: True, strictly_after=True)  # at the next grid point
    t3 = line.pause_at(t_idle + H)
    ok, message = line.call('start')
    assert ok and message.startswith('start: STARTING, drive start effective at')
    assert '0.05 s after the request' in message
    cmds.append(Command(round((t3 + lead) * NS_PER_S) / NS_PER_S, 'start'))
    model = LineModel(scene, SPAN, cmds)
    t_execute = on_grid(cmds[-1].t, lambda g: model.drive.rate(np.array([g]))[0] >= SPEED_REACHED)

    t4 = line.pause_at(t_execute + 0.1)
    ok, message = line.call('abort')
    assert ok and message.startswith('abort: ABORTING, drive stop effective at') and 'after the request' in message
    cmds.append(Command(round((t4 + lead) * NS_PER_S) / NS_PER_S, 'stop'))
    t_aborted = standstill(LineModel(scene, SPAN, cmds), cmds[-1].t)

    t5 = line.pause_at(t_aborted + 0.1)
    assert line.call('clear') == (True, 'clear: CLEARING')
    t_cleared = on_grid(t5, lambda g: True, strictly_after=True)
    line.run_to_end()

    assert states_seen(line.state) == [
        'EXECUTE',
        'STOPPING',
        'STOPPED',
        'RESETTING',
        'IDLE',
        'STARTING',
        'EXECUTE',
        'ABORTING',
        'ABORTED',
        'CLEARING',
        'STOPPED',
    ]
    assert [(t.target, t.t) for t in sup.packml.history] == [
        ('EXECUTE', 0.0),
        ('STOPPING', t1),
        ('STOPPED', t_stopped),
        ('RESETTING', t2),
        ('IDLE', t_idle),
        ('STARTING', t3),
        ('EXECUTE', t_execute),
        ('ABORTING', t4),
        ('ABORTED', t_aborted),
        ('CLEARING', t5),
        ('STOPPED', t_cleared),
    ]
    assert [
        (command_text(m), time_msg_to_ns(m.header.stamp), time_msg_to_ns(m.time_ref)) for m in line.commands.messages
    ] == [(c.kind, round(t * NS_PER_S), round(c.t * NS_PER_S)) for t, c in zip((t1, t3, t4), cmds, strict=True)]
    assert line.machines['crank_drive'].commands == tuple(cmds)
    assert [(b.state, b.ok) for b in sup.logic.balances] == [('STOPPED', True), ('ABORTED', True), ('STOPPED', True)]


# --------------------------------------------------------------------------- diagnostics

KEYS = {'margin', 'min_margin', 'unit', 'violations', 'evaluations', 'cycle'}


@pytest.mark.parametrize('overrides', ['', 'feed_transporter.V_tr=5.8333'])
def test_diagnostics_one_status_per_constraint_then_the_inputs(ros: Ros, overrides: str) -> None:
    extra = {'overrides': overrides} if overrides else {}
    sup = ros.add(Supervisor(context=ros.context, parameter_overrides=params(diag_rate=2.0, **extra)))
    scene = load_scene('folder', {'feed_transporter.V_tr': 5.8333} if overrides else None)
    model = LineModel(scene, 5.0)
    listener = ros.node('listener')
    diags, sub = subscribe(ros, listener, DiagnosticArray, DIAGNOSTICS_TOPIC)
    assert ros.spin_until(lambda: sub.get_publisher_count() == 1, timeout=20.0)
    clock = ros.add(
        LineClock(context=ros.context, parameter_overrides=params(participants='supervisor', rtf=0.0, duration=2.0))
    )
    names = [f'folder_line/{c.name}' for c in model.constraints]
    assert 'folder_line/feed_window' in names
    assert ros.spin_until(
        lambda: clock.done.done() and sup.done.done() and len(diags) == sup.published_diagnostics, timeout=30.0
    )
    arrays = [d for d in diags.messages if d.status and d.status[0].name in names]  # not the event statuses
    # 2 Hz of sim time, exactly
    assert [time_msg_to_ns(d.header.stamp) for d in arrays] == [0, 500 * MS, 1000 * MS, 1500 * MS, 2000 * MS]
    for arr in arrays:
        t = time_msg_to_ns(arr.header.stamp) / NS_PER_S
        assert [s.name for s in arr.status] == [*names, 'folder_line/supervisor/inputs']
        inputs = arr.status[-1]
        assert (inputs.level, inputs.message, list(inputs.values)) == (DiagnosticStatus.OK, 'no input rejected', [])
        # the last status (supervisor inputs) has no constraint: zip stops before it
        for status, c in zip(arr.status, model.constraints, strict=False):
            values = {kv.key: kv.value for kv in status.values}
            decided = c.decided_by(t)
            n = int(np.count_nonzero(decided))
            assert values['evaluations'] == str(n) and values['unit'] == c.unit
            if n == 0:
                assert status.level == DiagnosticStatus.OK and status.message == 'no cycle evaluated yet'
                continue
            assert set(values) == KEYS
            last = int(np.flatnonzero(decided)[-1])
            assert float(values['margin']) == float(c.margin[last])
            assert float(values['min_margin']) == float(c.margin[decided].min())
            violations = int(np.count_nonzero(c.margin[decided] < 0.0))
            assert values['violations'] == str(violations)
            level = (
                DiagnosticStatus.ERROR
                if c.margin[last] < 0.0
                else DiagnosticStatus.WARN
                if violations
                else DiagnosticStatus.OK
            )
            assert status.level == level
    last = {s.name: s for s in arrays[-1].status}
    feed = last['folder_line/feed_window']
    values = {kv.key: kv.value for kv in feed.values}
    assert int(values['evaluations']) > 10
    if overrides:  # V_tr = V_d: the sheet cannot be fed in the window, every cycle
        assert feed.level == DiagnosticStatus.ERROR and feed.message.startswith('violated in cycle')
        assert values['violations'] == values['evaluations'] and float(values['min_margin']) < 0.0
    else:
        assert all(s.level == DiagnosticStatus.OK for s in last.values())
        assert float(values['min_margin']) > 0.0 and values['violations'] == '0'


# --------------------------------------------------------------------------- the watermark


def test_the_watermark_waits_for_every_event_a_tick_acknowledged(ros: Ros) -> None:
    """The logic advances to tick t only once every machine participant's tick t is complete: its
    acknowledgement alone is not enough while an event it counts has not arrived; then exactly to t.
    An event published at tick t whose time rounds to the tick before (it came just after it) is
    still t's; an event of a node that takes no part is taken without waiting for it."""
    sup = ros.add(Supervisor(context=ros.context, parameter_overrides=params(lost_timeout=60.0)))
    s = 100 * MS
    belt = ros.add(FakeParticipant(ros.context, 'belt_conveyor', hold_from=s))  # publishes what the test says
    producer = ros.node('producer')
    events = producer.create_publisher(TimeReference, EVENTS_TOPIC, LINE_QOS)

    def event(frame: str, source: str, tick_ns: int, t_ns: int) -> TimeReference:
        msg = TimeReference(source=source)
        msg.header.frame_id = frame
        msg.header.stamp = ns_to_time_msg(tick_ns)
        msg.time_ref = ns_to_time_msg(t_ns)
        return msg

    clock = ros.add(
        LineClock(
            context=ros.context,
            parameter_overrides=params(
                participants='belt_conveyor,supervisor', rtf=0.0, duration=0.2, lost_timeout=60.0, window=0.0
            ),
        )
    )
    assert ros.spin_until(lambda: belt.held == s and list(sup.lockstep.pending) == [s], timeout=30.0)
    assert sup.lockstep.last_done == s - STEP and sup.logic.now == (s - STEP) / NS_PER_S
    # crank_drive is no participant here: its knife_exit (judged by no constraint, at 0: late) is not waited for
    events.publish(event('crank_drive', 'knife_exit sheet=0 cycle=0 value=0.0', 0, 0))
    # the belt acknowledges tick s with two events that are not there yet
    belt.counts.update(messages=2, events=2)
    belt.run_to(s + STEP)
    assert ros.spin_until(lambda: sup.lockstep.ledger.last_ack('belt_conveyor') == s, timeout=20.0)
    ros.spin_for(0.2)  # nothing may happen: the supervisor waits for the events
    assert list(sup.lockstep.pending) == [s] and sup.logic.now == (s - STEP) / NS_PER_S
    assert sup.lockstep.ledger.missing('belt_conveyor') == {'events': 2} and clock.current == s
    # they arrive (belt slow-downs: judged by no constraint), one of them at the previous tick's ns
    events.publish(event('belt_conveyor', 'belt_slowdown_start sheet=0 cycle=0 value=0.5', s, s - 2 * MS))
    events.publish(event('belt_conveyor', 'belt_slowdown_end sheet=0 cycle=0 value=0.5', s, s - STEP))
    assert ros.spin_until(lambda: sup.lockstep.last_done == s, timeout=20.0)
    assert sup.logic.now == s / NS_PER_S  # exactly to the tick
    assert sup.logic.late == 2  # the knife_exit at 0 and the slow-down end at the tick before: decided at once
    belt.run_to(None)
    assert ros.spin_until(lambda: clock.done.done() and sup.done.done(), timeout=30.0)
    assert sup.lockstep.ticks == 41 and sup.logic.now == 0.2 and sup.rejected == {}
    assert sup.logic.lost_nodes == [] and clock.lost == {}


# --------------------------------------------------------------------------- hostile inputs


def test_hostile_inputs_are_rejected_counted_and_the_line_runs_on(ros: Ros) -> None:
    line = Line(ros, duration=2.0, diag_rate=1.0)  # held at its first tick
    diags, _ = subscribe(ros, line.listener, DiagnosticArray, DIAGNOSTICS_TOPIC)
    hostile = ros.node('intruder')

    def publish(msg_type: type, topic: str, qos: QoSProfile, *messages: Any, readers: int = 0) -> None:
        pub = hostile.create_publisher(msg_type, topic, qos)
        # acknowledgements are read best-effort and volatile: only readers matched already get them
        assert ros.spin_until(lambda: pub.get_subscription_count() >= readers, timeout=20.0)
        for m in messages:
            pub.publish(m)

    def ref(frame: str, source: str, t_ns: int = 0, kind: str = 'progress') -> TimeReference:
        return time_reference(frame, t_ns, source, kind)  # signed: the intruder is an insider that errs

    counts = 'messages=0 events=0 commands=0'
    publish(
        TimeReference,
        COMMANDS_TOPIC,
        COMMANDS_QOS,
        ref('intruder', 'hold', NS_PER_S, 'command'),
        ref('supervisor', 'jump', NS_PER_S, 'command'),
    )  # to every machine node
    publish(
        TimeReference,
        progress_topic('supervisor'),
        ACK_QOS,
        ref('supervisor', 'garbage'),
        ref('intruder', counts),
        readers=5,
    )  # to the machine nodes and the clock
    publish(
        TimeReference, progress_topic('crank_drive'), ACK_QOS, ref('crank_drive', 'messages=1'), readers=2
    )  # to the supervisor and the clock
    publish(
        String,
        PARTICIPANTS_TOPIC,
        PARTICIPANTS_QOS,
        String(data=sign_text('clock=banana end=none participants=crank_drive', 'announcement')),
    )  # to every participant
    publish(
        TimeReference,
        EVENTS_TOPIC,
        LINE_QOS,
        ref('belt_conveyor', 'knife_contact sheet=1 cycle=1 value=0.0'),
        ref('crank_drive', 'nonsense'),
    )  # to the supervisor: a kind from another node, and unparsable
    machine = {'command': 2, 'tick_done': 2, 'announcement': 1}
    supervisor = {'command': 2, 'tick_done': 1, 'announcement': 1, 'event': 2}

    def all_in() -> bool:
        return (
            all(n.rejected == machine for n in line.machines.values())
            and line.sup.rejected == supervisor
            and line.clock.rejected == 3
        )

    assert ros.spin_until(all_in, timeout=20.0), ({n: m.rejected for n, m in line.nodes.items()}, line.clock.rejected)
    assert line.hold.held == 0  # all of it while the line waited at its first tick
    line.hold.run_to(None)
    assert ros.spin_until(
        lambda: (
            line.clock.done.done()
            and all(n.done.done() for n in line.nodes.values())
            and len(diags) == line.sup.published_diagnostics + line.clock.published_statuses
        ),
        timeout=60.0,
    )
    assert all_in()  # counted once each, and the line ran every tick to the end
    # named by the clock, which looks at the graph every 2 s (an insider here: the test process has the key)
    assert ros.spin_until(lambda: '/intruder' in line.clock.strangers, timeout=20.0)
    assert line.clock.ticks == 401 and line.clock.lost == {}
    assert all(n.lockstep.ticks == 401 for n in line.nodes.values())
    assert line.sup.packml.state == 'EXECUTE' and line.sup.logic.violations == []
    assert line.sup.published_commands == 0
    assert [without_signature(m.source) for m in line.commands.messages] == ['hold', 'jump']
    assert all(n.commands == () for n in line.nodes.values())  # the intruder's hold changed nothing
    inputs = [
        d.status[-1]
        for d in diags.messages
        if d.status[-1].name == 'folder_line/supervisor/inputs' and time_msg_to_ns(d.header.stamp) > 0
    ]
    assert len(inputs) == 2  # at 1 s and 2 s of sim time
    for status in inputs:
        assert (status.level, status.message) == (DiagnosticStatus.WARN, '6 inputs rejected')
        assert [(kv.key, kv.value) for kv in status.values] == [
            ('announcement', '1'),
            ('command', '2'),
            ('event', '2'),
            ('tick_done', '1'),
        ]
