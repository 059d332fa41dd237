"""Determinism over real DDS: what the line published is the batch model under the recorded commands.

The whole line (the five machine nodes and ``line_clock``) runs in this process on
one executor, as ``folder-line run`` runs it; mid-run the supervisor is asked to hold
the line and later to unhold it through its services. Every joint state and every
event received is then compared with a :class:`folder_line.core.line.LineModel` (and
:func:`folder_line.core.line.simulate`) rebuilt offline from nothing but the scene
and the drive commands recorded on ``/line/supervisor/commands``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import JointState, TimeReference
from std_msgs.msg import UInt64
from std_srvs.srv import Trigger

from folder_line.core.drive import Command
from folder_line.core.events import EVENT_KINDS
from folder_line.core.line import LineModel, sample_times, simulate
from folder_line.nodes.belt_conveyor import BeltConveyor
from folder_line.nodes.common import (
    CLOCK_TOPIC,
    COMMANDS_QOS,
    COMMANDS_TOPIC,
    EVENTS_TOPIC,
    NS_PER_S,
    SHEET_COUNT_TOPIC,
    joint_states_topic,
    time_msg_to_ns,
)
from folder_line.nodes.crank_drive import CrankDrive
from folder_line.nodes.feed_transporter import FeedTransporter
from folder_line.nodes.line_clock import LineClock
from folder_line.nodes.machine import parse_event_source
from folder_line.nodes.sheet_counter import SheetCounter
from folder_line.nodes.supervisor import Supervisor
from folder_line.scenes import load_scene

if TYPE_CHECKING:
    from conftest import Ros

RELIABLE = QoSProfile(depth=10000, reliability=ReliabilityPolicy.RELIABLE)
JOINT_NODES = ('crank_drive', 'belt_conveyor', 'feed_transporter')
DURATION = 4.0
HORIZON = DURATION + 1.0
RTF = 1.0  # 200 Hz at rtf 2 is the in-process limit (bench_nodes): a loaded CI box skips ticks there


def test_recorded_run_with_hold_and_unhold_is_the_model_under_the_recorded_commands(ros: Ros) -> None:
    scene = load_scene('folder')
    common = [Parameter('scene', value='folder'), Parameter('horizon', value=HORIZON)]
    machines = [ros.add(cls(context=ros.context, parameter_overrides=common))
                for cls in (CrankDrive, BeltConveyor, FeedTransporter, SheetCounter)]
    # only the operator's commands here: automatic enforcement would add its own (and is tested elsewhere)
    supervisor = ros.add(Supervisor(context=ros.context,
                                    parameter_overrides=common + [Parameter('enforce', value=False)]))
    nodes = machines + [supervisor]
    listener = ros.node('listener')
    joints = {n: ros.subscribe(listener, JointState, joint_states_topic(n), RELIABLE) for n in JOINT_NODES}
    events = ros.subscribe(listener, TimeReference, EVENTS_TOPIC, RELIABLE)
    commands = ros.subscribe(listener, TimeReference, COMMANDS_TOPIC, COMMANDS_QOS)
    counts = ros.subscribe(listener, UInt64, SHEET_COUNT_TOPIC, RELIABLE)
    clock_msgs = ros.subscribe(listener, ClockMsg, CLOCK_TOPIC, RELIABLE)
    subs = list(listener.subscriptions)
    hold = listener.create_client(Trigger, '/line/supervisor/hold')
    unhold = listener.create_client(Trigger, '/line/supervisor/unhold')
    assert ros.spin_until(lambda: all(s.get_publisher_count() >= 1 for s in subs[:4] + subs[5:6])
                          and hold.service_is_ready() and unhold.service_is_ready(), timeout=20.0)
    clock = ros.add(LineClock(context=ros.context, parameter_overrides=[
        Parameter('duration', value=DURATION), Parameter('rtf', value=RTF),
        Parameter('publish_rate', value=200.0 * RTF)]))

    def sim_time() -> float:
        return time_msg_to_ns(clock_msgs.messages[-1].clock) / NS_PER_S if clock_msgs.messages else 0.0

    def call(client: Any) -> tuple[bool, str]:
        future = client.call_async(Trigger.Request())
        assert ros.spin_until(future.done, timeout=20.0)
        return future.result().success, future.result().message

    assert ros.spin_until(lambda: sim_time() >= 1.0, timeout=20.0)
    ok, message = call(hold)
    assert ok, message
    assert ros.spin_until(lambda: supervisor.packml.state == 'HELD', timeout=20.0)
    t_held = sim_time()
    assert ros.spin_until(lambda: sim_time() >= t_held + 0.25, timeout=20.0)
    ok, message = call(unhold)
    assert ok, message
    end_ns = round(DURATION * NS_PER_S)

    def complete() -> bool:
        return (clock.done.done() and all(n._last_ns == end_ns for n in nodes)
                and all(len(joints[n.NODE_NAME]) == n.published_joint_states for n in machines[:3])
                and len(events) == sum(n.published_events for n in machines))

    assert ros.spin_until(complete, timeout=30.0)
    assert supervisor.packml.state == 'EXECUTE'

    # the model, offline, from the scene and the recorded commands alone
    recorded = [Command(t=time_msg_to_ns(m.time_ref) / NS_PER_S, kind=m.source) for m in commands.messages]
    assert [c.kind for c in recorded] == ['hold', 'unhold']
    assert 1.0 < recorded[0].t < recorded[1].t < DURATION
    model = LineModel(scene, HORIZON, recorded)
    free = LineModel(scene, HORIZON)

    differs = 0
    for name, received in joints.items():
        msgs = received.messages
        stamps = [time_msg_to_ns(m.header.stamp) for m in msgs]
        assert len(msgs) >= 0.75 * DURATION * 200.0 and np.all(np.diff(stamps) > 0) and stamps[-1] == end_ns
        for m, stamp in zip(msgs, stamps):
            expect = model.sample(name, [stamp / NS_PER_S])
            np.testing.assert_allclose(m.position, expect.position[0], rtol=1e-9, atol=1e-9)
            np.testing.assert_allclose(m.velocity, expect.velocity[0], rtol=1e-9, atol=1e-9)
            np.testing.assert_allclose(m.effort, expect.effort[0], rtol=1e-9, atol=1e-9)
        t = np.array(stamps) / NS_PER_S
        differs += int(np.count_nonzero(np.abs(np.array([m.position for m in msgs])
                                               - free.sample(name, t).position).max(axis=1) > 1e-3))
    assert differs > 100  # the commands changed what was published: the comparison above could fail

    # the held line stood still between standstill and the unhold's effective time
    still = LineModel(scene, HORIZON, recorded[:1]).drive
    t_still = recorded[0].t + scene.drive.t_brake
    assert still.rate(np.array([t_still]))[0] == 0.0
    held = [m for m in joints['crank_drive'].messages
            if t_still * NS_PER_S <= time_msg_to_ns(m.header.stamp) <= recorded[1].t * NS_PER_S]
    assert len(held) > 20 and all(list(m.velocity) == [0.0, 0.0] for m in held)

    # events: every one up to the end, once, with the model's time (nearest ns) and value
    got = sorted(parse_event_source(m.source)[:3] + (time_msg_to_ns(m.time_ref), parse_event_source(m.source)[3])
                 for m in events.messages)
    table = model.events[model.events['t'] <= DURATION]
    expect_rows = sorted((EVENT_KINDS[r['kind']], int(r['sheet']), int(r['cycle']), round(float(r['t']) * NS_PER_S),
                          float(r['value'])) for r in table)
    assert got == expect_rows
    assert len(got) > 200
    shifted = free.events[free.events['t'] <= DURATION]
    assert len(shifted) != len(table) or not np.array_equal(shifted['t'], table['t'])

    # the batch simulation with the same commands says the same
    result = simulate(scene, DURATION, commands=recorded)
    assert np.array_equal(result.events, table)
    grid = sample_times(DURATION, scene.sample_rate)
    for name in JOINT_NODES:
        batch = result.samples[name]
        np.testing.assert_array_equal(batch.t, grid)
        np.testing.assert_allclose(batch.position, model.sample(name, grid).position, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(batch.velocity, model.sample(name, grid).velocity, rtol=1e-9, atol=1e-9)
    assert result.summary()['sheets_counted'] == counts.messages[-1].data > 0
    assert counts.messages[-1].data < free.result(DURATION, 0.0).summary()['sheets_counted']
