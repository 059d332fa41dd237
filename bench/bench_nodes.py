"""Real-time behaviour of the line's ROS 2 nodes over real DDS: late ticks, highest rate, highest rtf.

Run: ``.venv/bin/python bench/bench_nodes.py`` (``--quick`` for a short run; about 2.5 min
in full). It prints markdown tables.

What is measured
----------------
Every node is instrumented in its own process (a subclass that notes, for each tick it
publishes, the tick's stamp and the wall time, ``CLOCK_MONOTONIC``, just after
publishing); ``line_clock`` notes the wall time of each ``/clock`` message it publishes.
A node of rate ``R`` owes one tick per grid point ``g_k = k / R`` of sim time (its
timer runs on sim time). Grid point ``k`` is **late** if the node published no tick
stamped in ``[g_k, g_k+1)`` (a skipped tick), or published it more than one period of
wall time (``1 / (R rtf)``) after ``line_clock`` first published a sim time
``>= g_k``. The late fraction is late grid points / grid points, over the whole run
(the target is <= 1 %); the latency column is the 99th percentile of that delay for
the ticks that were published.

Setups: (1) the six nodes (``line_clock`` and the five machine nodes, ``folder`` scene)
on one single-threaded executor in one process, as ``folder-line run`` runs them
(also with the run's recorder subscribed to every topic, without its bag), and one
process per node (started as ``folder-line run --processes`` does: the clock waits
until every process hears it); (2) the same in one process at 200, 400, 800 and 1600
Hz; (3) at 200 Hz with the clock at rtf 2, 4, 8 and 16. ``line_clock`` publishes
``rate x rtf`` messages per wall second (two per tick for the processes), at most
1000: above that the nodes cannot tick at every grid point, whatever the CPU, and the
table says "clock-limited".
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
if __name__ == '__main__':
    sys.path.insert(0, str(REPO))
    # a domain of its own, discovery on this host only (before rclpy is imported)
    os.environ.setdefault('ROS_DOMAIN_ID', str(101 + os.getpid() % 100))
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    os.environ.pop('ROS_LOCALHOST_ONLY', None)

import numpy as np

MACHINES = ('crank_drive', 'belt_conveyor', 'feed_transporter', 'sheet_counter', 'supervisor')
NS = 1_000_000_000
MAX_CLOCK_RATE = 1000.0  # line_clock's publish_rate bound
HOLD_RTF = 1e-6


# --------------------------------------------------------------------------- instrumented nodes

def node_classes() -> dict[str, type]:
    from folder_line.nodes.belt_conveyor import BeltConveyor
    from folder_line.nodes.crank_drive import CrankDrive
    from folder_line.nodes.feed_transporter import FeedTransporter
    from folder_line.nodes.line_clock import LineClock
    from folder_line.nodes.sheet_counter import SheetCounter
    from folder_line.nodes.supervisor import Supervisor

    def timed(cls: type) -> type:
        class Timed(cls):  # type: ignore[valid-type, misc]
            def __init__(self, **kwargs: Any) -> None:
                self.log: list[tuple[int, int]] = []  # (sim stamp ns, wall ns) per tick
                super().__init__(**kwargs)

            def publish_at(self, stamp_ns: int) -> None:
                super().publish_at(stamp_ns)
                self.log.append((stamp_ns, time.monotonic_ns()))

        Timed.__name__ = cls.__name__
        return Timed

    class TimedClock(LineClock):
        def __init__(self, **kwargs: Any) -> None:
            self.log: list[tuple[int, int]] = []  # (sim ns, wall ns) per /clock message
            super().__init__(**kwargs)

        def _tick(self) -> None:
            before = self._last
            super()._tick()
            if self._last != before:
                self.log.append((self._last, time.monotonic_ns()))

    classes = {name: timed(cls) for name, cls in zip(MACHINES, (CrankDrive, BeltConveyor, FeedTransporter,
                                                               SheetCounter, Supervisor))}
    classes['line_clock'] = TimedClock
    return classes


def as_node(name: str, out: str, ros_args: list[str]) -> int:
    """Body of a node process of the benchmark: run the instrumented node, then write its log."""
    from folder_line.nodes.common import run_node

    cls = node_classes()[name]
    built: list[Any] = []

    def factory() -> Any:
        built.append(cls())
        return built[-1]

    code = run_node(factory, ros_args)
    Path(out).write_text(json.dumps(built[0].log if built else []))
    return code


# --------------------------------------------------------------------------- analysis

@dataclass
class NodeStats:
    node: str
    expected: int
    published: int
    skipped: int
    late: int
    p99_ms: float

    @property
    def late_fraction(self) -> float:
        return (self.skipped + self.late) / self.expected if self.expected else 0.0


def analyse(node: str, ticks: list[tuple[int, int]], clock: list[tuple[int, int]], rate: float, rtf: float,
            k_first: int, end_ns: int) -> NodeStats:
    """Late grid points of one node (module docstring) over grid points ``k_first .. end/P``."""
    period = int(1.0 / rate * NS)  # as rclpy's timer rounds it
    k = np.arange(k_first, end_ns // period + 1)
    grid = k * period
    c_sim = np.array([c[0] for c in clock], dtype=np.int64)
    c_wall = np.array([c[1] for c in clock], dtype=np.int64)
    reached = c_wall[np.minimum(np.searchsorted(c_sim, grid, side='left'), c_sim.size - 1)]
    t = np.array(ticks, dtype=np.int64).reshape(-1, 2)
    kt = t[:, 0] // period
    first = np.unique(kt, return_index=True)[1]
    kt, wall = kt[first], t[first, 1]
    pos = np.searchsorted(kt, k)
    present = (pos < kt.size) & (kt[np.minimum(pos, kt.size - 1)] == k)
    delay = wall[np.minimum(pos, kt.size - 1)] - reached
    limit = period / rtf
    late = int(np.count_nonzero(present & (delay > limit)))
    p99 = float(np.percentile(delay[present], 99)) / 1e6 if present.any() else float('nan')
    return NodeStats(node, int(k.size), int(t.shape[0]), int(np.count_nonzero(~present)), late, p99)


@dataclass
class RunStats:
    nodes: list[NodeStats]
    rtf_achieved: float
    clock_rate: float
    wall: float

    @property
    def worst(self) -> NodeStats:
        return max(self.nodes, key=lambda s: s.late_fraction)


def clock_rtf(clock: list[tuple[int, int]], sim_from: int) -> float:
    c = np.array([x for x in clock if x[0] >= sim_from], dtype=np.int64).reshape(-1, 2)
    if c.shape[0] < 2:
        return float('nan')
    return float((c[-1, 0] - c[0, 0]) / (c[-1, 1] - c[0, 1]))


# --------------------------------------------------------------------------- runs

def run_in_process(duration: float, rate: float = 200.0, rtf: float = 1.0, recorder: bool = False) -> RunStats:
    """The six nodes on one executor in this process (as ``folder-line run``)."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    classes = node_classes()
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    executor = SingleThreadedExecutor(context=ctx)
    nodes: list[Any] = []
    try:
        if recorder:
            from folder_line.recorder import LineRecorder

            nodes.append(LineRecorder(context=ctx))
        common = [Parameter('horizon', value=duration + 1.0), Parameter('rate', value=float(rate))]
        machines = [classes[name](context=ctx, parameter_overrides=common) for name in MACHINES]
        nodes += machines
        clock_rate = min(MAX_CLOCK_RATE, rate * rtf)
        clock = classes['line_clock'](context=ctx, parameter_overrides=[
            Parameter('duration', value=float(duration)), Parameter('rtf', value=float(rtf)),
            Parameter('publish_rate', value=clock_rate)])
        nodes.append(clock)
        for node in nodes:
            executor.add_node(node)
        t0 = time.perf_counter()
        while not clock.done.done():
            executor.spin_once(timeout_sec=0.05)
        wall = time.perf_counter() - t0
        end = round(duration * NS)
        deadline = time.monotonic() + 2.0
        while time.monotonic() < deadline and not all(n._last_ns == end for n in machines):
            executor.spin_once(timeout_sec=0.05)
        stats = [analyse(n.NODE_NAME, n.log, clock.log, rate, rtf, 1, end) for n in machines]
        return RunStats(stats, clock_rtf(clock.log, 0), clock_rate, wall)
    finally:
        executor.shutdown()
        for node in nodes:
            node.destroy_node()
        ctx.try_shutdown()


def run_processes(duration: float, tmp: Path, rate: float = 200.0, rtf: float = 1.0) -> RunStats:
    """One process per node, started like ``folder-line run --processes``."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter
    from rclpy.parameter_client import AsyncParameterClient
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState
    from std_msgs.msg import UInt64

    from folder_line.nodes.common import SHEET_COUNT_TOPIC, joint_states_topic

    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join(p for p in (str(REPO), env.get('PYTHONPATH', '')) if p)
    procs: dict[str, subprocess.Popen[bytes]] = {}
    logs = {name: tmp / f'{name}.json' for name in (*MACHINES, 'line_clock')}

    def start(name: str, *params: str) -> None:
        cmd = [sys.executable, str(Path(__file__).resolve()), '--as-node', name, str(logs[name]), '--ros-args']
        for p in params:
            cmd += ['-p', p]
        with open(tmp / f'{name}.stderr', 'wb') as err:
            procs[name] = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=err)

    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    executor = SingleThreadedExecutor(context=ctx)
    watcher = rclpy.create_node('bench_watcher', context=ctx)
    executor.add_node(watcher)
    heard: dict[str, int] = {}
    qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    for topic, cls in [(joint_states_topic(n), JointState) for n in MACHINES[:3]] + [(SHEET_COUNT_TOPIC, UInt64)]:
        heard[topic] = 0
        watcher.create_subscription(cls, topic, lambda m, t=topic: heard.__setitem__(t, heard[t] + 1), qos)
    try:
        for name in MACHINES:
            start(name, f'horizon:={duration + 1.0!r}', f'rate:={float(rate)!r}')
        deadline = time.monotonic() + 60.0
        while time.monotonic() < deadline and not all(watcher.count_publishers(t) for t in heard):
            executor.spin_once(timeout_sec=0.05)
        t0 = 1.0 / rate
        clock_rate = min(MAX_CLOCK_RATE, 2.0 * rate * rtf)
        start('line_clock', f'start_time:={t0!r}', f'duration:={duration - t0!r}', f'rtf:={HOLD_RTF!r}',
              f'publish_rate:={clock_rate!r}')
        client = AsyncParameterClient(watcher, 'line_clock')
        while time.monotonic() < deadline and not (client.services_are_ready() and all(heard.values())):
            executor.spin_once(timeout_sec=0.05)
        future = client.set_parameters([Parameter('rtf', value=float(rtf))])
        while not future.done():
            executor.spin_once(timeout_sec=0.05)
        wall0 = time.perf_counter()
        procs['line_clock'].wait(timeout=duration / rtf + 60.0)
        wall = time.perf_counter() - wall0
        time.sleep(0.5)  # the nodes' last ticks (their logs are written at exit anyway)
        for name in MACHINES:
            procs[name].send_signal(signal.SIGINT)
        for proc in procs.values():
            proc.wait(timeout=30)
    finally:
        for proc in procs.values():
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        executor.shutdown()
        watcher.destroy_node()
        ctx.try_shutdown()
    clock = [tuple(x) for x in json.loads(logs['line_clock'].read_text())]
    end = round(duration * NS)
    k_first = 2  # grid point 1 is the start (the clock holds there until every process hears it)
    stats = [analyse(name, [tuple(x) for x in json.loads(logs[name].read_text())], clock, rate, rtf, k_first, end)
             for name in MACHINES]
    return RunStats(stats, clock_rtf(clock, round(2 * NS / rate)), clock_rate, wall)


# --------------------------------------------------------------------------- report

def machine_info() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path('/proc/cpuinfo').read_text().splitlines():
            if line.startswith('model name'):
                cpu = line.split(':', 1)[1].strip()
                break
    except OSError:
        pass
    import rclpy  # noqa: F401  (the RMW in use)
    from rclpy.utilities import get_rmw_implementation_identifier

    load = os.getloadavg()
    return (f'{platform.system()} {platform.release()}, {cpu}, {os.cpu_count()} cores, '
            f'load {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} at start; python {platform.python_version()}, '
            f'numpy {np.__version__}, {get_rmw_implementation_identifier()}, '
            f'ROS_DOMAIN_ID {os.environ.get("ROS_DOMAIN_ID")}, '
            f'discovery {os.environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE")}')


def pct(x: float) -> str:
    return f'{100.0 * x:.2f} %'


def node_table(title: str, run: RunStats) -> None:
    print(f'\n{title} (achieved rtf {run.rtf_achieved:.3f}, /clock {run.clock_rate:g} msg/s)\n')
    print('| node | grid ticks | published | skipped | late > 1 period | late fraction | p99 delay, ms |')
    print('|---|---:|---:|---:|---:|---:|---:|')
    for s in run.nodes:
        print(f'| {s.node} | {s.expected} | {s.published} | {s.skipped} | {s.late} | {pct(s.late_fraction)} '
              f'| {s.p99_ms:.2f} |')


def main() -> int:
    if len(sys.argv) > 1 and sys.argv[1] == '--as-node':
        return as_node(sys.argv[2], sys.argv[3], sys.argv[4:])
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--quick', action='store_true', help='short runs (about 1 min)')
    args = ap.parse_args()
    q = args.quick
    import tempfile

    print(machine_info())
    t_start = time.perf_counter()

    base = 4.0 if q else 10.0
    one = run_in_process(base)
    node_table(f'(1) six nodes, one process, 200 Hz, rtf 1, {base:g} s of line time', one)
    rec = run_in_process(base / 2, recorder=True)
    node_table(f'(1) the same with the run\'s recorder subscribed to every topic (no bag), {base / 2:g} s', rec)
    with tempfile.TemporaryDirectory() as tmp:
        procs = run_processes(base, Path(tmp))
    node_table(f'(1) one process per node, 200 Hz, rtf 1, {base:g} s of line time', procs)

    print('\n(2) highest rate, one process, rtf 1\n')
    print('| rate, Hz | /clock msg/s | achieved rtf | worst node | its late fraction | of which skipped '
          '| p99 delay, ms | |')
    print('|---:|---:|---:|---|---:|---:|---:|---|')
    sustained, failed = None, False
    for rate in (200.0, 400.0, 800.0, 1600.0):
        r = run_in_process(2.0 if q else 5.0, rate=rate)
        w = r.worst
        ok = w.late_fraction <= 0.01
        note = 'clock-limited' if rate > MAX_CLOCK_RATE else ('ok' if ok else '> 1 % late')
        if ok and not failed:
            sustained = rate
        failed |= not ok
        print(f'| {rate:g} | {r.clock_rate:g} | {r.rtf_achieved:.3f} | {w.node} | {pct(w.late_fraction)} '
              f'| {pct(w.skipped / w.expected)} | {w.p99_ms:.2f} | {note} |')
    print(f'\nhighest rate with <= 1 % late ticks: {sustained:g} Hz' if sustained else
          '\nno rate with <= 1 % late ticks')

    print('\n(3) highest real-time factor, one process, 200 Hz\n')
    print('| rtf | /clock msg/s | achieved rtf | line time, s | worst node | its late fraction | of which skipped '
          '| p99 delay, ms | |')
    print('|---:|---:|---:|---:|---|---:|---:|---:|---|')
    best, failed = None, False
    for rtf in (2.0, 4.0, 8.0, 16.0):
        d = (1.5 if q else 4.0) * rtf  # the same wall time for each
        r = run_in_process(d, rtf=rtf)
        w = r.worst
        ok = w.late_fraction <= 0.01
        note = 'clock-limited' if 200.0 * rtf > MAX_CLOCK_RATE else ('ok' if ok else '> 1 % late')
        if ok and not failed:
            best = rtf
        failed |= not ok
        print(f'| {rtf:g} | {r.clock_rate:g} | {r.rtf_achieved:.3f} | {d:g} | {w.node} | {pct(w.late_fraction)} '
              f'| {pct(w.skipped / w.expected)} | {w.p99_ms:.2f} | {note} |')
    print(f'\nhighest rtf with <= 1 % late ticks at 200 Hz: {best:g}' if best else
          '\nno tested rtf (>= 2) keeps late ticks <= 1 % at 200 Hz')
    print(f'\ntotal {time.perf_counter() - t_start:.0f} s')
    return 0


if __name__ == '__main__':
    sys.exit(main())
