"""Lockstep speed of the live line over real DDS, against the bare rclpy floor, in one run.

Run: ``.venv/bin/python bench/bench_nodes.py`` (``--quick``: shorter spans). Prints a
markdown table; the README quotes it with the machine it ran on.

What is measured
----------------
* **Line.** ``folder-line run`` (:func:`folder_line.ros.run.run_line`) of the ``folder`` scene
  at ``--rtf max`` (no ceiling: as fast as the slowest participant allows), recorded to
  a bag, at 200 Hz and at 1 kHz of sim time, in process (one ``EventsExecutor``) and one
  process per node. Reported: the real-time factor reached (sim s per wall s from the
  first tick answered by all), the CPU of the whole line per tick (this process's CPU,
  plus the node processes' for ``--processes``: the difference between a run of ``d``
  and one of ``2 d`` over the extra ticks, so start-up cancels out) and the messages
  each tick sends (published, the acknowledgements included, from the bag's counts
  and the acknowledgements' own count).
* **Floor.** In the same run: a bare rclpy publish -> take of the same mix of messages
  (JointState, TimeReference, String, UInt64, Float64, Clock) on the same executor, with
  no work in the callbacks, from one publisher node to ``k`` subscriber nodes that each
  take every message: CPU per message for every ``k`` the line has. Two floors per tick:
  the line's messages each taken once (``k = 1``), and each taken by as many subscribers
  as it has in the line (read from the ROS graph of an in-process line,
  :func:`line_fanout`): a message the clock, the recorder and the supervisor all take is
  three takes. The ratio columns are the line's CPU per tick over each (the goal: <= 2).

Under load: run it with two busy loops on both cores (``timeout 600 sh -c 'while :; do
:; done' &`` twice) to see sim time slow down while the recorded answer stays the same.
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
if __name__ == '__main__':
    sys.path.insert(0, str(REPO))
    # a domain of its own, discovery on this host only (before rclpy is imported)
    os.environ.setdefault('ROS_DOMAIN_ID', str(101 + os.getpid() % 100))
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    os.environ.pop('ROS_LOCALHOST_ONLY', None)


def floor_per_message(n: int = 3000, executor_kind: str = 'events', fanout: int = 1) -> float:
    """CPU s per message of a bare publish -> take of the line's message mix: one publisher node and
    ``fanout`` subscriber nodes, each taking every message, on one executor, with empty callbacks."""
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.experimental import EventsExecutor
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import JointState, TimeReference
    from std_msgs.msg import Float64, String, UInt64

    qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    ctx = Context()
    rclpy.init(context=ctx)
    ex = EventsExecutor(context=ctx) if executor_kind == 'events' else SingleThreadedExecutor(context=ctx)
    pub_node = rclpy.create_node('floor_pub', context=ctx)
    sub_nodes = [rclpy.create_node(f'floor_sub{k}', context=ctx) for k in range(fanout)]
    js = JointState(name=['a', 'b', 'c'], position=[1.0, 2.0, 3.0], velocity=[1.0, 2.0, 3.0])
    ack = TimeReference(source='messages=123456 events=1234 commands=0')
    mix = [
        (JointState, js),
        (TimeReference, ack),
        (String, String(data='EXECUTE')),
        (UInt64, UInt64(data=7)),
        (Float64, Float64(data=1.5)),
        (Clock, Clock()),
    ]
    got = [0]
    pubs = []
    for i, (cls, msg) in enumerate(mix):
        pubs.append((pub_node.create_publisher(cls, f'/floor/t{i}', qos), msg))
        for sub_node in sub_nodes:
            sub_node.create_subscription(cls, f'/floor/t{i}', lambda m: got.__setitem__(0, got[0] + 1), qos)
    for node in (pub_node, *sub_nodes):
        ex.add_node(node)
    end = time.monotonic() + 1.0
    while time.monotonic() < end:
        ex.spin_once(timeout_sec=0.05)
    c0 = time.process_time()
    sent = 0
    while sent < n:
        for p, m in pubs:
            p.publish(m)
            sent += 1
        while got[0] < sent * fanout:
            ex.spin_once(timeout_sec=1.0)
    cpu = time.process_time() - c0
    ex.shutdown()
    for node in (pub_node, *sub_nodes):
        node.destroy_node()
    rclpy.try_shutdown(context=ctx)
    return cpu / sent


def line_fanout(rate: float) -> dict[str, int]:
    """Subscribers per topic of the in-process line (topic -> count), read from the ROS graph once every
    participant has subscribed to everything it takes (the acknowledgements after the announcement)."""
    import rclpy
    from rclpy.parameter import Parameter

    from folder_line.config.run_config import RunConfig, clock_parameters
    from folder_line.interfaces import KNOWN_PARTICIPANTS, tick_done_topic
    from folder_line.ros.nodes.line_clock import LineClock
    from folder_line.ros.recorder import LINE_TOPICS, LineRecorder
    from folder_line.ros.run import add_machine_nodes
    from folder_line.ros.runtime import events_executor

    cfg = RunConfig(scene='folder', duration=1.0, rtf=0.0, rate=rate)
    ctx = rclpy.Context()
    rclpy.init(args=['--ros-args', '--log-level', 'WARN'], context=ctx)
    executor = events_executor(ctx)
    recorder = LineRecorder(context=ctx)
    executor.add_node(recorder)
    nodes = [recorder, *add_machine_nodes(cfg, ctx, executor)]
    params = clock_parameters(cfg, KNOWN_PARTICIPANTS)
    clock = LineClock(parameter_overrides=[Parameter(k, value=v) for k, v in params.items()], context=ctx)
    nodes.append(clock)
    executor.add_node(clock)
    while not clock.done.done():
        executor.spin_once(timeout_sec=0.05)
    topics = [*LINE_TOPICS, *(tick_done_topic(p) for p in KNOWN_PARTICIPANTS)]
    fanout = {t: clock.count_subscribers(t) for t in topics}
    executor.shutdown()
    for node in nodes:
        node.destroy_node()
    rclpy.try_shutdown(context=ctx)
    return fanout


def _run(duration: float, rate: float, processes: bool) -> tuple[float, float, dict]:
    """One lockstep run at rtf max: (CPU s of this process and its children, rtf reached, summary)."""
    from folder_line.config.run_config import RunConfig
    from folder_line.ros.run import run_line

    with tempfile.TemporaryDirectory(prefix='bench_nodes_') as tmp:
        cfg = RunConfig(scene='folder', duration=duration, rtf=0.0, rate=rate, out=Path(tmp), processes=processes)
        self0, kids0 = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
        with open(os.devnull, 'w') as quiet:
            result = run_line(cfg, quiet)
        self1, kids1 = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (
        self1.ru_utime
        + self1.ru_stime
        - self0.ru_utime
        - self0.ru_stime
        + kids1.ru_utime
        + kids1.ru_stime
        - kids0.ru_utime
        - kids0.ru_stime
    )
    s = result.summary
    if not s['outcome']['ok']:
        raise SystemExit(f'the line did not end as expected: {s["outcome"]["message"]}')
    return cpu, s['rtf_achieved'], s


def line(duration: float, rate: float, processes: bool) -> dict[str, Any]:
    """Runs of ``duration`` and ``2 duration``: the CPU per tick is their difference over the extra ticks, so
    start-up (imports, models, discovery) cancels out; the rtf reached is the longer run's."""
    from folder_line.interfaces import KNOWN_PARTICIPANTS, tick_done_topic

    cpu1, _, _ = _run(duration, rate, processes)
    cpu2, rtf, s = _run(2 * duration, rate, processes)
    ticks = round(2 * duration * rate) + 1
    extra = round(duration * rate)
    per_topic = {t: n / ticks for t, n in s['bag']['messages'].items()}
    # the five machine nodes and the recorder acknowledge every tick (the acknowledgements are not recorded)
    per_topic.update({tick_done_topic(p): 1.0 for p in KNOWN_PARTICIPANTS})
    return {'rtf': rtf, 'cpu_per_tick': (cpu2 - cpu1) / extra, 'per_topic': per_topic, 'ticks': ticks}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--quick', action='store_true', help='shorter spans')
    args = parser.parse_args()
    span = 1.0 if args.quick else 5.0
    print(
        f'machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, '
        f'Python {platform.python_version()}; load average {os.getloadavg()[0]:.2f}'
    )
    fanout = line_fanout(200.0)
    floors = {
        k: floor_per_message(executor_kind='events', fanout=k) for k in sorted({max(v, 1) for v in fanout.values()})
    }
    floor_single = floor_per_message(executor_kind='single')
    print(
        'floor (bare publish -> take, same message mix), EventsExecutor: '
        + ', '.join(f'{floors[k] * 1e6:.1f} us/message with {k} subscriber{"s" if k > 1 else ""}' for k in floors)
        + f'; SingleThreadedExecutor {floor_single * 1e6:.1f} us/message with 1'
    )
    print('subscribers per topic in the line: ' + ', '.join(f'{t} {k}' for t, k in fanout.items()) + '\n')
    print(
        '| setup | rate (Hz) | sim s | rtf reached | CPU per tick | messages per tick | deliveries per tick '
        "| floor per tick, 1 subscriber | CPU / that | floor per tick, the line's subscribers | CPU / that |"
    )
    print('|---|---|---|---|---|---|---|---|---|---|---|')
    for processes in (False, True):
        for rate in (200.0, 1000.0):
            duration = span if rate == 200.0 else span / 5  # the longer run is twice this
            r = line(duration, rate, processes)
            per_topic = r['per_topic']
            messages = sum(per_topic.values())
            deliveries = sum(n * fanout.get(t, 1) for t, n in per_topic.items())
            floor1 = floors[1] * messages
            floor_k = sum(n * floors[max(fanout.get(t, 1), 1)] for t, n in per_topic.items())
            cpu = r['cpu_per_tick']
            print(
                f'| {"one process per node" if processes else "in process"} | {rate:g} | {2 * duration:g} | '
                f'{r["rtf"]:.2f} | {cpu * 1e3:.2f} ms | {messages:.1f} | {deliveries:.1f} | '
                f'{floor1 * 1e3:.2f} ms | {cpu / floor1:.1f} | {floor_k * 1e3:.2f} ms | {cpu / floor_k:.1f} |',
                flush=True,
            )
    return 0


if __name__ == '__main__':
    sys.exit(main())
