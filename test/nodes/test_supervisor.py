"""The supervisor over real DDS: its services, PackML states, drive commands and diagnostics.

The supervisor and ``crank_drive`` run in this process with ``line_clock`` (the
``ros`` fixture); a plain node calls the ``std_srvs/Trigger`` services and listens.
Effective times are checked against :class:`folder_line.core.line.LineModel`
to the nanosecond, the joint states against the model rebuilt with the commands
the supervisor published.
"""

from __future__ import annotations

import re
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

from folder_line.core.drive import Command
from folder_line.core.events import EVENT_KINDS
from folder_line.core.line import LineModel
from folder_line.nodes.common import (
    COMMANDS_QOS,
    COMMANDS_TOPIC,
    DIAGNOSTICS_TOPIC,
    NS_PER_S,
    SUPERVISOR_STATE_TOPIC,
    joint_states_topic,
    time_msg_to_ns,
)
from folder_line.nodes.crank_drive import CrankDrive
from folder_line.nodes.line_clock import LineClock
from folder_line.nodes.supervisor import SERVICES, STATE_QOS, Supervisor
from folder_line.scenes import load_scene

if TYPE_CHECKING:
    from conftest import Received, Ros

RELIABLE = QoSProfile(depth=10000, reliability=ReliabilityPolicy.RELIABLE)
HORIZON = 30.0
LEAD = 0.1  # the supervisor's default command_lead, s


def params(**values: Any) -> list[Parameter]:
    return [Parameter(name, value=value) for name, value in values.items()]


def subscribe(ros: Ros, node: Node, msg_type: type, topic: str, qos: QoSProfile = RELIABLE) -> tuple[Received, Any]:
    received = ros.subscribe(node, msg_type, topic, qos)
    return received, list(node.subscriptions)[-1]


def start_clock(ros: Ros, rtf: float, duration: float = 0.0) -> LineClock:
    return ros.add(LineClock(context=ros.context, parameter_overrides=params(
        rtf=rtf, duration=duration, publish_rate=min(1000.0, 200.0 * rtf))))


def states_seen(received: Received) -> list[str]:
    """The states received, repeats collapsed."""
    out: list[str] = []
    for m in received.messages:
        if not out or out[-1] != m.data:
            out.append(m.data)
    return out


class Caller:
    """Calls the supervisor's Trigger services from a plain node."""

    def __init__(self, ros: Ros, node: Node) -> None:
        self.ros = ros
        self.clients = {name: node.create_client(Trigger, f'/line/supervisor/{name}') for name in SERVICES}
        assert ros.spin_until(lambda: all(c.service_is_ready() for c in self.clients.values()), timeout=20.0)

    def __call__(self, name: str) -> tuple[bool, str]:
        future = self.clients[name].call_async(Trigger.Request())
        assert self.ros.spin_until(future.done, timeout=20.0)
        response = future.result()
        return response.success, response.message


def effective_in_message(message: str) -> float:
    m = re.search(r'effective at (\d+\.\d{6}) s', message)
    assert m is not None, message
    return float(m[1])


# --------------------------------------------------------------------------- hold and unhold

def test_hold_at_the_next_cycle_boundary_then_unhold(ros: Ros) -> None:
    scene = load_scene('folder')
    free = LineModel(scene, HORIZON)
    sup = ros.add(Supervisor(context=ros.context, parameter_overrides=params(horizon=HORIZON)))
    crank = ros.add(CrankDrive(context=ros.context, parameter_overrides=params(horizon=HORIZON)))
    listener = ros.node('listener')
    state, state_sub = subscribe(ros, listener, String, SUPERVISOR_STATE_TOPIC, STATE_QOS)
    commands, commands_sub = subscribe(ros, listener, TimeReference, COMMANDS_TOPIC, COMMANDS_QOS)
    joints, joints_sub = subscribe(ros, listener, JointState, joint_states_topic('crank_drive'))
    call = Caller(ros, listener)
    assert ros.spin_until(lambda: state_sub.get_publisher_count() == 1 and joints_sub.get_publisher_count() == 1
                          and commands_sub.get_publisher_count() == 1, timeout=20.0)

    # every service, under its name and type
    services = dict(listener.get_service_names_and_types())
    for name in ('start', 'stop', 'hold', 'unhold', 'reset', 'clear', 'abort'):
        assert services.get(f'/line/supervisor/{name}') == ['std_srvs/srv/Trigger'], name

    start_clock(ros, rtf=2.0)
    assert ros.spin_until(lambda: 'EXECUTE' in states_seen(state), timeout=20.0)

    # illegal: unhold while EXECUTE, refused with the reason, nothing published
    ok, reason = call('unhold')
    assert not ok and reason == "'unhold' refused in state EXECUTE: legal only in HELD"
    assert len(commands) == 0 and sup.packml.state == 'EXECUTE'

    # hold: effective at the first cycle boundary at least command_lead after the request
    ok, message = call('hold')
    assert ok and message.startswith('hold: HOLDING, drive hold effective at') and 'next cycle boundary' in message
    assert ros.spin_until(lambda: len(commands) == 1, timeout=20.0)
    hold = commands.messages[0]
    assert hold.source == 'hold' and hold.header.frame_id == 'supervisor'
    t_request = time_msg_to_ns(hold.header.stamp) / NS_PER_S
    t_hold_ns = time_msg_to_ns(hold.time_ref)
    boundary = free.next_cycle_boundary(t_request + LEAD)
    assert t_hold_ns == round(boundary * NS_PER_S)
    assert effective_in_message(message) == pytest.approx(boundary, abs=5e-7)
    cycle = free._parts['folder'].timing.T
    assert t_request + LEAD < boundary <= t_request + LEAD + cycle
    knife_exits = free.events[free.events['kind'] == EVENT_KINDS.index('knife_exit')]['t']  # boundaries
    assert boundary in knife_exits

    # HOLDING, then HELD once the drive stands still
    held = LineModel(scene, HORIZON, [Command(t_hold_ns / NS_PER_S, 'hold')])
    t_still = t_hold_ns / NS_PER_S + scene.drive.t_brake
    assert held.drive.rate(np.array([t_still]))[0] == 0.0
    assert held.drive.rate(np.array([t_still - 1e-3]))[0] > 0.0
    assert ros.spin_until(lambda: states_seen(state)[-1] == 'HELD', timeout=20.0)
    holding, done = sup.packml.history[-2:]
    assert (holding.source, holding.target, holding.cause) == ('EXECUTE', 'HOLDING', 'hold')
    assert (done.source, done.target, done.cause) == ('HOLDING', 'HELD', 'drive at standstill')
    assert t_still <= done.t < t_still + 0.05  # at the first tick at standstill

    # the crank stands still from then on, where the commanded model says
    assert ros.spin_until(lambda: len(joints) and time_msg_to_ns(joints.messages[-1].header.stamp)
                          > (t_still + 0.3) * NS_PER_S, timeout=20.0)
    assert crank.commands == (Command(t_hold_ns / NS_PER_S, 'hold'),)
    still = [m for m in joints.messages if time_msg_to_ns(m.header.stamp) >= t_still * NS_PER_S]
    assert len(still) > 20
    assert all(list(m.velocity) == [0.0, 0.0] for m in still)
    assert all(list(m.position) == list(still[0].position) for m in still)

    # unhold: effective command_lead after the request; UNHOLDING, then EXECUTE at speed
    ok, message = call('unhold')
    assert ok and message.startswith('unhold: UNHOLDING, drive unhold effective at')
    assert ros.spin_until(lambda: len(commands) == 2, timeout=20.0)
    unhold = commands.messages[1]
    t_request2 = time_msg_to_ns(unhold.header.stamp) / NS_PER_S
    assert unhold.source == 'unhold'
    assert time_msg_to_ns(unhold.time_ref) == round((t_request2 + LEAD) * NS_PER_S)
    assert ros.spin_until(lambda: states_seen(state)[-1] == 'EXECUTE' and len(states_seen(state)) > 2, timeout=20.0)
    assert states_seen(state)[-5:] == ['EXECUTE', 'HOLDING', 'HELD', 'UNHOLDING', 'EXECUTE']
    back = sup.packml.history[-1]
    assert (back.source, back.target, back.cause) == ('UNHOLDING', 'EXECUTE', 'drive at speed')
    t_unhold = time_msg_to_ns(unhold.time_ref) / NS_PER_S
    t_speed = t_unhold + 0.99 * scene.drive.t_restart
    assert t_speed - 1e-9 <= back.t < t_speed + 0.05

    # every joint state so far is the model with the commands the supervisor published
    assert ros.spin_until(lambda: time_msg_to_ns(joints.messages[-1].header.stamp) > (t_speed + 0.1) * NS_PER_S,
                          timeout=20.0)
    cmds = [Command(time_msg_to_ns(m.time_ref) / NS_PER_S, m.source) for m in commands.messages]
    model = LineModel(scene, HORIZON, cmds)
    stamps = np.array([time_msg_to_ns(m.header.stamp) for m in joints.messages]) / NS_PER_S
    expect = model.sample('crank_drive', stamps)
    np.testing.assert_allclose([m.position for m in joints.messages], expect.position, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose([m.velocity for m in joints.messages], expect.velocity, rtol=1e-9, atol=1e-9)
    moving = [m for m in joints.messages if time_msg_to_ns(m.header.stamp) > t_speed * NS_PER_S]
    assert moving and all(m.velocity[0] > 0.0 for m in moving)


def test_stop_reset_start_abort_clear(ros: Ros) -> None:
    scene = load_scene('folder')
    free = LineModel(scene, HORIZON)
    sup = ros.add(Supervisor(context=ros.context, parameter_overrides=params(horizon=HORIZON, command_lead=0.05)))
    listener = ros.node('listener')
    state, state_sub = subscribe(ros, listener, String, SUPERVISOR_STATE_TOPIC, STATE_QOS)
    commands, _ = subscribe(ros, listener, TimeReference, COMMANDS_TOPIC, COMMANDS_QOS)
    call = Caller(ros, listener)
    assert ros.spin_until(lambda: state_sub.get_publisher_count() == 1, timeout=20.0)
    start_clock(ros, rtf=4.0)
    assert ros.spin_until(lambda: states_seen(state)[-1:] == ['EXECUTE'], timeout=20.0)

    assert call('start') == (False, "'start' refused in state EXECUTE: legal only in IDLE")
    assert call('clear') == (False, "'clear' refused in state EXECUTE: legal only in ABORTED")
    ok, message = call('stop')
    assert ok and 'next cycle boundary' in message
    assert ros.spin_until(lambda: states_seen(state)[-1] == 'STOPPED', timeout=20.0)
    stop = commands.messages[-1]
    t_request = time_msg_to_ns(stop.header.stamp) / NS_PER_S
    assert stop.source == 'stop'
    assert time_msg_to_ns(stop.time_ref) == round(free.next_cycle_boundary(t_request + 0.05) * NS_PER_S)
    assert call('reset') == (True, 'reset: RESETTING')  # no drive command
    assert ros.spin_until(lambda: states_seen(state)[-1] == 'IDLE', timeout=20.0)
    ok, message = call('start')
    assert ok and '0.05 s after the request' in message
    assert ros.spin_until(lambda: states_seen(state)[-1] == 'EXECUTE' and 'IDLE' in states_seen(state),
                          timeout=20.0)
    ok, message = call('abort')
    assert ok and 'drive stop' in message
    assert ros.spin_until(lambda: states_seen(state)[-1] == 'ABORTED', timeout=20.0)
    assert call('clear') == (True, 'clear: CLEARING')
    assert ros.spin_until(lambda: states_seen(state)[-1] == 'STOPPED' and 'CLEARING' in states_seen(state),
                          timeout=20.0)
    assert states_seen(state) == ['EXECUTE', 'STOPPING', 'STOPPED', 'RESETTING', 'IDLE', 'STARTING',
                                  'EXECUTE', 'ABORTING', 'ABORTED', 'CLEARING', 'STOPPED']
    assert [m.source for m in commands.messages] == ['stop', 'start', 'stop']
    assert [t.target for t in sup.packml.history] == ['EXECUTE', 'STOPPING', 'STOPPED', 'RESETTING', 'IDLE',
                                                      'STARTING', 'EXECUTE', 'ABORTING', 'ABORTED', 'CLEARING',
                                                      'STOPPED']


# --------------------------------------------------------------------------- diagnostics

KEYS = {'margin', 'min_margin', 'unit', 'violations', 'evaluations', 'cycle'}


@pytest.mark.parametrize('overrides', ['', 'feed_transporter.V_tr=5.8333'])
def test_diagnostics_one_status_per_constraint(ros: Ros, overrides: str) -> None:
    extra = {'overrides': overrides} if overrides else {}
    ros.add(Supervisor(context=ros.context, parameter_overrides=params(horizon=5.0, diag_rate=2.0, **extra)))
    scene = load_scene('folder', {'feed_transporter.V_tr': 5.8333} if overrides else None)
    model = LineModel(scene, 5.0)
    listener = ros.node('listener')
    diags, sub = subscribe(ros, listener, DiagnosticArray, DIAGNOSTICS_TOPIC)
    assert ros.spin_until(lambda: sub.get_publisher_count() == 1, timeout=20.0)
    clock = start_clock(ros, rtf=4.0, duration=2.0)
    names = [f'folder_line/{c.name}' for c in model.constraints]
    assert 'folder_line/feed_window' in names

    def constraint_arrays() -> list[DiagnosticArray]:  # not the supervisor's own event statuses
        return [d for d in diags.messages if d.status and d.status[0].name in names]

    assert ros.spin_until(lambda: clock.done.done() and len(constraint_arrays()) >= 4, timeout=20.0)
    arrays = constraint_arrays()
    stamps = [time_msg_to_ns(d.header.stamp) for d in arrays]
    assert np.all(np.diff(stamps) >= 0.5 * NS_PER_S - 10_000_000)  # 2 Hz of sim time
    for arr in arrays:
        t = time_msg_to_ns(arr.header.stamp) / NS_PER_S
        assert [s.name for s in arr.status] == names
        for status, c in zip(arr.status, model.constraints):
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
            level = (DiagnosticStatus.ERROR if c.margin[last] < 0.0 else
                     DiagnosticStatus.WARN if violations else DiagnosticStatus.OK)
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


def test_watermark_waits_for_the_previous_tick_of_the_slowest_node_and_not_for_the_clock(ros: Ros) -> None:
    """The decision watermark (rate 200 Hz, stale_periods 10, event_latency 0.03 s): at most the tick
    before the latest heard from the slowest node; a whole-process stall (every node silent) holds it
    however far the clock runs; a dead node is passed stale_periods ticks behind the freshest."""
    from folder_line.nodes.common import ns_to_time_msg

    sup = ros.add(Supervisor(context=ros.context, parameter_overrides=params(horizon=HORIZON)))
    nodes = ('crank_drive', 'belt_conveyor', 'feed_transporter')
    assert set(sup.model.nodes) == set(nodes)
    callbacks = {n: sup._on_joints(n) for n in nodes}

    def hear(node: str, t: float) -> None:
        msg = JointState()
        msg.header.stamp = ns_to_time_msg(round(t * 1e9))
        callbacks[node](msg)

    def watermark(clock: float) -> float:
        return sup._watermark(round(clock * 1e9))

    period, window, latency = 0.005, 10 * 0.005, 0.03
    assert watermark(1.0) == pytest.approx(1.0 - latency - window)  # nothing heard: the stale window
    # a node's first tick at 0.0744 carries every event before it: not a tick to wait past yet
    for n in nodes:
        hear(n, 0.0744)
    assert watermark(0.08) == pytest.approx(min(0.08 - latency, 0.0744 - period) - window)  # the floor only
    for n in nodes:
        hear(n, 0.0844)  # the tick at 0.0794 was skipped
    assert watermark(0.2) == pytest.approx(0.0744)  # the previous tick heard, not 0.0844 - period
    hear('crank_drive', 0.0894)
    hear('belt_conveyor', 0.0894)
    assert watermark(0.2) == pytest.approx(0.0744)  # feed_transporter's previous tick is still 0.0744
    # a stall of the whole process: the clock runs on, nobody is heard, the watermark waits
    assert watermark(50.0) == pytest.approx(0.0744)
    # the feed dies, the others run on: passed stale_periods ticks behind the freshest
    for k in range(1, 40):
        hear('crank_drive', 0.0894 + k * period)
        hear('belt_conveyor', 0.0894 + k * period)
    freshest = 0.0894 + 39 * period
    assert watermark(freshest + 0.001) == pytest.approx(min(freshest + 0.001 - latency, freshest - period) - window)
    # and never ahead of event_latency behind the clock
    hear('feed_transporter', freshest)
    hear('feed_transporter', freshest + period)
    assert watermark(freshest) == pytest.approx(freshest - latency)
