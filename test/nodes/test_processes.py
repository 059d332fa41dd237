"""The line as one process per node over real DDS, as a launch file would start it.

The five machine nodes and ``line_clock`` (with a duration) run from their module
executables in this test's ROS domain; an rclpy node in the test checks the graph,
the rates in sim time and the values against the line model, then every process is
stopped with SIGINT and must exit 0 without a traceback.
"""

from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import JointState, TimeReference
from std_msgs.msg import String, UInt64

from folder_line.core.events import EVENT_KINDS
from folder_line.core.line import LineModel
from folder_line.nodes.common import (
    CLOCK_TOPIC,
    EVENTS_TOPIC,
    NS_PER_S,
    SHEET_COUNT_TOPIC,
    SUPERVISOR_STATE_TOPIC,
    TOPICS,
    joint_states_topic,
    time_msg_to_ns,
)
from folder_line.nodes.machine import parse_event_source
from folder_line.nodes.supervisor import STATE_QOS
from folder_line.scenes import load_scene

if TYPE_CHECKING:
    from conftest import Ros

REPO = Path(__file__).resolve().parents[2]
RELIABLE = QoSProfile(depth=10000, reliability=ReliabilityPolicy.RELIABLE)
MACHINES = ('crank_drive', 'belt_conveyor', 'feed_transporter', 'sheet_counter', 'supervisor')
JOINT_NODES = ('crank_drive', 'belt_conveyor', 'feed_transporter')
DURATION = 3.0
#: the run's real-time factor: half speed gives each of the seven processes on two cores twice the wall
#: time before the supervisor's stale window (10 ticks, 50 ms of sim time) passes it: at rtf 1 a process
#: lagging at the start made the supervisor judge cycle 0 without its events and hold the line (CI, once)
RTF = 0.5
HORIZON = DURATION + 1.0
RATE = 200.0


def start(name: str, env: dict[str, str], tmp_path: Path, *params: str) -> tuple[subprocess.Popen[bytes], Path]:
    cmd = [sys.executable, '-m', f'folder_line.nodes.{name}', '--ros-args']
    for param in params:
        cmd += ['-p', param]
    err = tmp_path / f'{name}.err'
    with open(err, 'wb') as stderr:
        return subprocess.Popen(cmd, env=env, cwd=REPO, stdout=subprocess.DEVNULL, stderr=stderr), err


def test_one_process_per_node(ros: Ros, node_env: dict[str, str], tmp_path: Path) -> None:
    listener = ros.node('listener')
    received: dict[str, Any] = {}
    subs = {}
    for name in JOINT_NODES:
        received[name] = ros.subscribe(listener, JointState, joint_states_topic(name), RELIABLE)
        subs[name] = list(listener.subscriptions)[-1]
    events = ros.subscribe(listener, TimeReference, EVENTS_TOPIC, RELIABLE)
    events_sub = list(listener.subscriptions)[-1]
    counts = ros.subscribe(listener, UInt64, SHEET_COUNT_TOPIC, RELIABLE)
    states = ros.subscribe(listener, String, SUPERVISOR_STATE_TOPIC, STATE_QOS)
    clock = ros.subscribe(listener, ClockMsg, CLOCK_TOPIC, RELIABLE)

    procs: dict[str, tuple[subprocess.Popen[bytes], Path]] = {}
    try:
        for name in MACHINES:
            procs[name] = start(name, node_env, tmp_path, 'scene:=folder', f'horizon:={HORIZON}', f'rate:={RATE}')
        # the clock starts once every node's publishers are matched here, so nothing is missed
        assert ros.spin_until(lambda: all(s.get_publisher_count() == 1 for s in subs.values())
                              and events_sub.get_publisher_count() == len(MACHINES), timeout=60.0), \
            {n: e.read_text() for n, (_, e) in procs.items()}
        # Discovery between processes takes 0.1 s to a few s here, so the clock starts at the nodes'
        # first tick (one period) with sim time all but standing, and runs once every node has
        # published at that tick (so it hears the clock): as `folder-line run --processes` does. Two
        # clock messages per tick: after the rtf change the clock's phase is arbitrary (see run.py).
        t0 = 1.0 / RATE
        procs['line_clock'] = start('line_clock', node_env, tmp_path, f'start_time:={t0}',
                                    f'duration:={DURATION - t0}', 'rtf:=1e-06', 'publish_rate:=400.0')
        first_ns = round(t0 * NS_PER_S)
        assert ros.spin_until(lambda: all(len(received[n]) for n in JOINT_NODES) and len(counts) and len(states),
                              timeout=60.0), {n: e.read_text() for n, (_, e) in procs.items()}
        for name in JOINT_NODES:  # its first tick: at t0, or a few ns later if it missed the first message
            assert 0 <= time_msg_to_ns(received[name].messages[0].header.stamp) - first_ns < 100_000
        client = AsyncParameterClient(listener, 'line_clock')
        assert ros.spin_until(client.services_are_ready, timeout=30.0)
        future = client.set_parameters([Parameter('rtf', value=RTF)])
        assert ros.spin_until(future.done, timeout=30.0) and future.result().results[0].successful
        end_ns = round(DURATION * NS_PER_S)

        def last_stamp(name: str) -> int:
            msgs = received[name].messages
            return time_msg_to_ns(msgs[-1].header.stamp) if msgs else -1

        assert ros.spin_until(lambda: all(last_stamp(n) == end_ns for n in JOINT_NODES), timeout=60.0), \
            {n: last_stamp(n) for n in JOINT_NODES}
        assert procs['line_clock'][0].wait(timeout=30) == 0
        ros.spin_for(0.3)  # what is still under way

        # graph: names and types as documented, each publisher in its own process
        graph = dict(listener.get_topic_names_and_types())
        types = {t.name: t.type for t in TOPICS}
        for topic in (CLOCK_TOPIC, EVENTS_TOPIC, SHEET_COUNT_TOPIC, SUPERVISOR_STATE_TOPIC, '/diagnostics',
                      '/line/sheet_counter/rate', '/line/supervisor/commands'):
            assert graph.get(topic) == [types[topic]], topic
        for name in JOINT_NODES:
            assert graph.get(joint_states_topic(name)) == ['sensor_msgs/msg/JointState']
        nodes = set(listener.get_node_names())
        assert set(MACHINES) <= nodes

        model = LineModel(load_scene('folder'), HORIZON)
        for name in JOINT_NODES:
            msgs = received[name].messages
            stamps = np.array([time_msg_to_ns(m.header.stamp) for m in msgs])
            assert np.all(np.diff(stamps) > 0)
            # 200 Hz of sim time: one message per 5 ms tick; a tick lost to load costs one
            assert 0.75 * RATE * DURATION <= len(stamps) <= RATE * DURATION, (name, len(stamps))
            assert stamps[0] - first_ns < 100_000 and stamps[-1] == end_ns
            gaps = np.diff(stamps)
            assert np.median(gaps) == np.clip(np.median(gaps), 4_000_000, 6_000_000)
            expect = model.sample(name, stamps / NS_PER_S)
            np.testing.assert_allclose([m.position for m in msgs], expect.position, rtol=1e-9, atol=1e-9)
            np.testing.assert_allclose([m.velocity for m in msgs], expect.velocity, rtol=1e-9, atol=1e-9)
            np.testing.assert_allclose([m.effort for m in msgs], expect.effort, rtol=1e-9, atol=1e-9)
            assert all(tuple(m.name) == model.nodes[name] for m in msgs)

        # every event up to the end, exactly once, at its model time
        rows = sorted((EVENT_KINDS[r['kind']], int(r['sheet']), int(r['cycle']), round(float(r['t']) * NS_PER_S))
                      for r in model.events if r['t'] <= DURATION)
        got = sorted(parse_event_source(m.source)[:3] + (time_msg_to_ns(m.time_ref),) for m in events.messages)
        assert got == rows
        counted = model.events[model.events['kind'] == EVENT_KINDS.index('released_on_pile')]['t']
        assert counts.messages[-1].data == int(np.count_nonzero(counted <= DURATION)) > 0
        assert [m.data for m in counts.messages] == sorted(m.data for m in counts.messages)
        assert states.messages and all(m.data == 'EXECUTE' for m in states.messages)
        sim = np.array([time_msg_to_ns(m.clock) for m in clock.messages])
        assert sim[-1] == end_ns and np.all(np.diff(sim) > 0)
        running = sim[sim > first_ns + 100_000]  # after the start (before: the wait for every process)
        assert 0.6 * 400.0 * DURATION / RTF <= len(running) <= 400.0 * DURATION / RTF + 2  # 400 Hz of wall time

        for name in MACHINES:
            procs[name][0].send_signal(signal.SIGINT)
        codes = {name: proc.wait(timeout=30) for name, (proc, _) in procs.items()}
        assert codes == dict.fromkeys(procs, 0)
    finally:
        for proc, _ in procs.values():
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    for name, (_, err) in procs.items():
        text = err.read_text()
        assert 'Traceback' not in text and 'ERROR' not in text, (name, text)
        assert 'error' not in text.lower(), (name, text)
