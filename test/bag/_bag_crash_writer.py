"""Writes a bag with a fake line clock until it is killed: the subject of test_bag_crash.py.

``python test/bag/_bag_crash_writer.py DIR --dt-ns N --chunk-size B [--max-bag-duration S] [--flush-s F]
[--block-after STEPS]``

Step ``i`` (from 0) writes ``/clock`` at ``t_i = i * dt``, then a ``JointState`` on
``/line/crank_drive/joint_states`` with ``position = [i]`` stamped ``t_i``, and on every
fifth step a ``TimeReference`` on ``/line/events`` with ``source = 'step i'``.

With ``--block-after STEPS`` it writes that many steps, prints ``blocked STEPS`` and
waits on stdin (so the test kills it at a known point). Without it, it
writes forever, printing ``step i`` every 50 steps, pacing itself at ~0.3 ms per step.
"""

from __future__ import annotations

import argparse
import sys
import time

from builtin_interfaces.msg import Time
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState, TimeReference

from folder_line.bag.writer import BagWriter
from folder_line.ros.recorder import LINE_TOPICS

JOINTS = '/line/crank_drive/joint_states'
EVENTS = '/line/events'


def stamp(t_ns: int) -> Time:
    return Time(sec=t_ns // 1_000_000_000, nanosec=t_ns % 1_000_000_000)


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument('dir')
    parser.add_argument('--dt-ns', type=int, required=True)
    parser.add_argument('--max-bag-duration', type=float, default=0.0)  # 0: one file, as by default
    parser.add_argument('--chunk-size', type=int, required=True)
    parser.add_argument('--flush-s', type=float, default=0.1)
    parser.add_argument('--block-after', type=int, default=0)
    args = parser.parse_args()
    writer = BagWriter(
        args.dir,
        scene_source='name: crash\n',
        effects=['faults'],
        scene_name='crash',
        max_duration_s=args.max_bag_duration,
        topics=LINE_TOPICS,
        chunk_size=args.chunk_size,
        flush_s=args.flush_s,
    )
    i = 0
    while True:
        t_ns = i * args.dt_ns
        writer.write('/clock', Clock(clock=stamp(t_ns)))
        js = JointState(name=['crank'], position=[float(i)], velocity=[0.5], effort=[])
        js.header.stamp = stamp(t_ns)
        writer.write(JOINTS, js)
        if i % 5 == 0:
            ref = TimeReference(time_ref=stamp(t_ns), source=f'step {i}')
            ref.header.stamp = stamp(t_ns)
            writer.write(EVENTS, ref)
        i += 1
        if args.block_after and i == args.block_after:
            print(f'blocked {i}', flush=True)
            sys.stdin.read()  # until killed
            return 1
        if not args.block_after:
            if i % 50 == 0:
                print(f'step {i - 1}', flush=True)
            time.sleep(0.0003)


if __name__ == '__main__':
    sys.exit(main())
