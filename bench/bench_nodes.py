"""Lockstep speed of the live line over real DDS, against the bare rclpy floor, in one run.

Run: ``.venv/bin/python bench/bench_nodes.py`` (``--quick``: shorter spans). Prints a
markdown table; the README quotes it with the machine it ran on.

What is measured
----------------
* **Line.** ``folder-line run`` (:func:`folder_line.run.run_line`) of the ``folder`` scene
  at ``--rtf max`` (no ceiling: as fast as the slowest participant allows), recorded to
  a bag, at 200 Hz and at 1 kHz of sim time, in process (one ``EventsExecutor``) and one
  process per node. Reported: the real-time factor reached (sim s per wall s from the
  first tick answered by all), the CPU of the whole line per tick (this process's CPU,
  plus the node processes' for ``--processes``: the difference between a run of ``d``
  and one of ``2 d`` over the extra ticks, so start-up cancels out) and the messages
  each tick sends (published, the acknowledgements included, from the bag's counts
  and the acknowledgements' own count).
* **Floor.** In the same run: a bare rclpy publish -> take of the same mix of messages
  (JointState, TimeReference, String, UInt64, Float64, Clock) between two nodes on the
  same executor, with no work in the callbacks: CPU per message, and per tick for the
  line's message count. The ratio column is line CPU per tick / floor per tick (the
  goal: <= 2).

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

REPO = Path(__file__).resolve().parents[1]
if __name__ == '__main__':
    sys.path.insert(0, str(REPO))
    # a domain of its own, discovery on this host only (before rclpy is imported)
    os.environ.setdefault('ROS_DOMAIN_ID', str(101 + os.getpid() % 100))
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    os.environ.pop('ROS_LOCALHOST_ONLY', None)


def floor_per_message(n: int = 3000, executor_kind: str = 'events') -> float:
    """CPU s per message of a bare publish -> take of the line's message mix (one publisher node, one
    subscriber node, one executor, empty callbacks)."""
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
    sub_node = rclpy.create_node('floor_sub', context=ctx)
    js = JointState(name=['a', 'b', 'c'], position=[1.0, 2.0, 3.0], velocity=[1.0, 2.0, 3.0])
    ack = TimeReference(source='messages=123456 events=1234 commands=0')
    mix = [(JointState, js), (TimeReference, ack), (String, String(data='EXECUTE')), (UInt64, UInt64(data=7)),
           (Float64, Float64(data=1.5)), (Clock, Clock())]
    got = [0]
    pubs = []
    for i, (cls, msg) in enumerate(mix):
        pubs.append((pub_node.create_publisher(cls, f'/floor/t{i}', qos), msg))
        sub_node.create_subscription(cls, f'/floor/t{i}', lambda m: got.__setitem__(0, got[0] + 1), qos)
    ex.add_node(pub_node)
    ex.add_node(sub_node)
    end = time.monotonic() + 1.0
    while time.monotonic() < end:
        ex.spin_once(timeout_sec=0.05)
    c0 = time.process_time()
    sent = 0
    while sent < n:
        for p, m in pubs:
            p.publish(m)
            sent += 1
        while got[0] < sent:
            ex.spin_once(timeout_sec=1.0)
    cpu = time.process_time() - c0
    ex.shutdown()
    pub_node.destroy_node()
    sub_node.destroy_node()
    rclpy.try_shutdown(context=ctx)
    return cpu / sent


def _run(duration: float, rate: float, processes: bool) -> tuple[float, float, dict]:
    """One lockstep run at rtf max: (CPU s of this process and its children, rtf reached, summary)."""
    from folder_line.run import RunConfig, run_line

    with tempfile.TemporaryDirectory(prefix='bench_nodes_') as tmp:
        cfg = RunConfig(scene='folder', duration=duration, rtf=0.0, rate=rate, out=Path(tmp), processes=processes)
        self0, kids0 = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
        with open(os.devnull, 'w') as quiet:
            result = run_line(cfg, quiet)
        self1, kids1 = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (self1.ru_utime + self1.ru_stime - self0.ru_utime - self0.ru_stime
           + kids1.ru_utime + kids1.ru_stime - kids0.ru_utime - kids0.ru_stime)
    s = result.summary
    if not s['outcome']['ok']:
        raise SystemExit(f'the line did not end as expected: {s["outcome"]["message"]}')
    return cpu, s['rtf_achieved'], s


def line(duration: float, rate: float, processes: bool) -> dict[str, float]:
    """Runs of ``duration`` and ``2 duration``: the CPU per tick is their difference over the extra ticks, so
    start-up (imports, models, discovery) cancels out; the rtf reached is the longer run's."""
    cpu1, _, _ = _run(duration, rate, processes)
    cpu2, rtf, s = _run(2 * duration, rate, processes)
    ticks = round(2 * duration * rate) + 1
    extra = round(duration * rate)
    recorded = sum(s['bag']['messages'].values())
    acks = 6 * ticks  # five machine nodes and the recorder acknowledge every tick
    return {'rtf': rtf, 'cpu_per_tick': (cpu2 - cpu1) / extra, 'messages_per_tick': (recorded + acks) / ticks,
            'ticks': ticks}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--quick', action='store_true', help='shorter spans')
    args = parser.parse_args()
    span = 1.0 if args.quick else 5.0
    print(f'machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, '
          f'Python {platform.python_version()}; load average {os.getloadavg()[0]:.2f}')
    floor_events = floor_per_message(executor_kind='events')
    floor_single = floor_per_message(executor_kind='single')
    print(f'floor (bare publish -> take, same message mix): EventsExecutor {floor_events * 1e6:.1f} us/message, '
          f'SingleThreadedExecutor {floor_single * 1e6:.1f} us/message\n')
    print('| setup | rate (Hz) | sim s | rtf reached | CPU per tick | messages per tick | floor per tick '
          '(EventsExecutor) | CPU / floor |')
    print('|---|---|---|---|---|---|---|---|')
    for processes in (False, True):
        for rate in (200.0, 1000.0):
            duration = span if rate == 200.0 else span / 5  # the longer run is twice this
            r = line(duration, rate, processes)
            floor = floor_events * r['messages_per_tick']
            print(f'| {"one process per node" if processes else "in process"} | {rate:g} | {2 * duration:g} | '
                  f'{r["rtf"]:.2f} | {r["cpu_per_tick"] * 1e3:.2f} ms | {r["messages_per_tick"]:.1f} | '
                  f'{floor * 1e3:.2f} ms | {r["cpu_per_tick"] / floor:.1f} |', flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
