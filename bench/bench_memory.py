"""Peak memory against line time: ``folder-line simulate`` and the live line's node processes.

Run: ``.venv/bin/python bench/bench_memory.py`` (about 25 minutes on two cores; ``--quick``:
1 h and 10 h of ``simulate`` only, and the nodes at 1 h, about three minutes).

1. ``folder-line simulate --scene S --duration D`` in a fresh process for D = 1 h, 10 h and
   100 h of ``line`` and of ``folder``; its peak resident set (``ru_maxrss`` of the child, from
   ``os.wait4``). The line is streamed window by window: the goal is at most 300 MB at any span,
   and no growth from 1 h to 100 h beyond noise.
2. The live line as ``ros2 launch`` starts it: the five machine nodes of ``line``, one process
   each from their executables with their default parameters, and ``line_clock``
   (lockstep, ``rtf 0``) started at ``start_time`` = 1 h and = a day, for 5 s of line time. Each
   node fast-forwards to the clock at batch speed keeping nothing, then publishes, and ends
   with the line. The peak resident set of each node process (``ru_maxrss``) is read when it
   is reaped; the goal is at most 200 MB per process at either start.

The ROS part runs on a private domain (``ROS_DOMAIN_ID`` 97 unless set, localhost discovery).
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
HOUR = 3600.0
DAY = 86400.0
SIMULATE_GOAL = 300e6  # bytes
NODE_GOAL = 200e6  # bytes
NODE_SPAN = 5.0  # line time each node run publishes, s


def simulate_peak(scene: str, duration: float) -> tuple[int, float]:
    """(peak RSS bytes, wall s) of ``folder-line simulate --scene scene --duration duration``."""
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [
            sys.executable,
            '-m',
            'folder_line.cli.main',
            'simulate',
            '--scene',
            scene,
            '--duration',
            f'{duration:g}',
        ]
        cmd += ['--json', str(Path(tmp) / 'summary.json')]
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        if proc.returncode != 0:
            assert proc.stderr is not None
            raise RuntimeError(f'simulate {scene} {duration:g} s failed: {proc.stderr.read().decode()}')
    return usage.ru_maxrss * 1024, wall


class _Nodes:
    """Node processes started for :func:`node_peaks`, each reaped with ``os.wait4`` (its ``ru_maxrss``)."""

    def __init__(self, start: float, env: dict[str, str], logs: Path) -> None:
        self.start, self.env, self.logs = start, env, logs
        self.procs: dict[str, subprocess.Popen[bytes]] = {}
        self.ended: dict[str, tuple[int, int]] = {}  # name -> (exit code, peak RSS bytes)

    def log_of(self, name: str) -> Path:
        return self.logs / f'{name}-{self.start:g}.log'

    def start_node(self, name: str, params: dict[str, str]) -> None:
        cmd = [sys.executable, '-m', f'folder_line.ros.nodes.{name}', '--ros-args']
        for key, value in params.items():
            cmd += ['-p', f'{key}:={value}']
        with open(self.log_of(name), 'wb') as log:
            self.procs[name] = subprocess.Popen(cmd, cwd=REPO, env=self.env, stdout=subprocess.DEVNULL, stderr=log)

    def reap(self, name: str, block: bool) -> bool:
        """Whether ``name`` has ended (reaped now or before); waits for it if ``block``."""
        if name not in self.ended:
            pid, status, usage = os.wait4(self.procs[name].pid, 0 if block else os.WNOHANG)
            if pid == 0:
                return False
            self.ended[name] = (os.waitstatus_to_exitcode(status), usage.ru_maxrss * 1024)
            self.procs[name].returncode = self.ended[name][0]  # reaped here: Popen must not wait for it again
        return True

    def wait_for(self, clock: str, others: Sequence[str]) -> None:
        """Until ``clock`` ends; ``RuntimeError`` if one of ``others`` ends first."""
        while not self.reap(clock, block=False):
            for name in others:
                if self.reap(name, block=False):
                    raise RuntimeError(f'{name} ended before the clock: see {self.log_of(name)}')
            time.sleep(0.2)

    def end(self, names: Sequence[str], within: float) -> None:
        """Let ``names`` end by themselves within ``within`` s; SIGINT those that do not, and reap them."""
        deadline = time.monotonic() + within
        while not all(self.reap(name, block=False) for name in names) and time.monotonic() < deadline:
            time.sleep(0.1)
        for name in names:
            if name not in self.ended:
                os.kill(self.procs[name].pid, signal.SIGINT)  # not Popen.send_signal: it would reap the process
                self.reap(name, block=True)

    def kill_rest(self) -> None:
        for name, proc in self.procs.items():
            if name not in self.ended:
                os.kill(proc.pid, signal.SIGKILL)
                self.reap(name, block=True)


def node_peaks(scene: str, start: float, env: dict[str, str], logs: Path) -> tuple[dict[str, int], float]:
    """({node: peak RSS bytes}, wall s) of the machine nodes of ``scene`` when the line is joined at ``start``.

    Each process is reaped with ``os.wait4`` (its ``ru_maxrss``): the nodes end with the line, or on SIGINT.
    """
    from folder_line.interfaces import LINE_CLOCK, MACHINE_NODES

    nodes = _Nodes(start, env, logs)
    t0 = time.perf_counter()
    try:
        for name in MACHINE_NODES:
            nodes.start_node(name, {'scene': scene})
        clock = {
            'rtf': '0.0',
            'start_time': f'{start:.1f}',
            'duration': f'{NODE_SPAN:.1f}',
            'participants': ','.join(MACHINE_NODES),
        }
        nodes.start_node(LINE_CLOCK, clock)
        nodes.wait_for(LINE_CLOCK, MACHINE_NODES)
        wall = time.perf_counter() - t0
        if nodes.ended[LINE_CLOCK][0] != 0:
            raise RuntimeError(f'line_clock exited {nodes.ended[LINE_CLOCK][0]}: see {nodes.log_of(LINE_CLOCK)}')
        nodes.end(MACHINE_NODES, 10.0)  # the nodes end with the line; SIGINT those that do not
        failed = [name for name in MACHINE_NODES if nodes.ended[name][0] != 0]
        if failed:
            raise RuntimeError(f'{", ".join(failed)} exited non-zero: see {logs}')
        return {name: nodes.ended[name][1] for name in MACHINE_NODES}, wall
    finally:
        nodes.kill_rest()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument('--quick', action='store_true', help='1 h and 10 h of simulate, the nodes at 1 h')
    args = ap.parse_args()
    spans = [HOUR, 10 * HOUR] if args.quick else [HOUR, 10 * HOUR, 100 * HOUR]
    ok = True

    print('folder-line simulate, peak resident set (goal <= 300 MB, flat in line time):\n')
    print('| scene | line time | peak RSS, MB | wall, s |')
    print('|---|---:|---:|---:|')
    for scene in ('folder', 'line'):
        peaks = []
        for span in spans:
            rss, wall = simulate_peak(scene, span)
            peaks.append(rss)
            print(f'| {scene} | {span / HOUR:g} h | {rss / 1e6:.0f} | {wall:.0f} |', flush=True)
        ok &= max(peaks) <= SIMULATE_GOAL
        print(f'| {scene} | {spans[-1] / HOUR:g} h / 1 h | {peaks[-1] / peaks[0]:.2f} | |', flush=True)

    env = dict(os.environ)
    env.setdefault('ROS_DOMAIN_ID', '97')
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    starts = [HOUR] if args.quick else [HOUR, DAY]
    print(f'\nthe machine nodes of line, one process each, joined at a start time for {NODE_SPAN:g} s')
    print('(lockstep, rtf 0), peak resident set per process (goal <= 200 MB):\n')
    with tempfile.TemporaryDirectory() as tmp:
        logs = Path(tmp)
        rows = {start: node_peaks('line', start, env, logs) for start in starts}
    from folder_line.interfaces import MACHINE_NODES

    print('| node | ' + ' | '.join(f'at {s / HOUR:g} h, MB' for s in starts) + ' |')
    print('|---|' + '---:|' * len(starts))
    for name in MACHINE_NODES:
        print(f'| {name} | ' + ' | '.join(f'{rows[s][0][name] / 1e6:.0f}' for s in starts) + ' |')
        ok &= all(rows[s][0][name] <= NODE_GOAL for s in starts)
    print('| wall, s | ' + ' | '.join(f'{rows[s][1]:.0f}' for s in starts) + ' |')
    if not ok:
        print('over a goal', file=sys.stderr)
    return 0 if ok else 1


if __name__ == '__main__':
    sys.exit(main())
