"""Lockstep speed of the live line over real DDS, against the bare rclpy floor, in one run.

Run: ``.venv/bin/python bench/bench_nodes.py`` (``--quick``: shorter spans). Prints a
markdown table; docs/benchmarks.md quotes it with the machine it ran on.

What is measured
----------------
* **Line.** ``folder-line run`` (:func:`folder_line.ros.run.run_line`) of the ``folder`` scene
  at ``--rtf max`` (no ceiling: as fast as the slowest participant allows), recorded to
  a bag, at 200 Hz and at 1 kHz of sim time, in process (one ``EventsExecutor``) and one
  process per node. Reported: the real-time factor reached (sim s per wall s from the
  first tick answered by all), the CPU of the whole line per tick (this process and every
  process descended from it, read from ``/proc`` as the run passes 20 % and 90 % of its
  line time, so start-up, imports and discovery, and the end are left out) and the
  messages each tick sends (published, the acknowledgements included, from the bag's
  counts and the acknowledgements' own count).
* **Floors.** In the same run: a bare rclpy publish -> take of the same mix of messages
  (JointState, TimeReference, String, UInt64, Float64, Clock), with no work in the
  callbacks, from one publisher to ``k`` subscribers that each take every message, for
  every ``k`` the line has: *in process* (one publisher node and ``k`` subscriber nodes on
  one executor), and *across processes* (a publisher process and ``k`` subscriber
  processes: what the deliveries of one process per node cost at least). Per tick, each
  message counts as many times as it has subscribers in the line (read from the ROS
  graph of an in-process line, :func:`line_fanout`): a message the clock, the recorder and
  the supervisor all take is three takes. The ratio columns are the line's CPU per tick
  over each floor.

* **Network.** The same line distributed (``--net``, as root where network namespaces can be
  made): ``folder-line run --external-nodes`` (clock and recorder) on one host and each machine
  node on a host of its own, over UDPv4 through the test network's user-space switch
  (``test/net/netns.py``), clean, with 5 +- 2 ms of delay on every host's link, and with 5 %
  loss on every link. CPU per tick is every process's.

* **The key** (``--key``): what closing the line to strangers costs. The in-process line at
  200 Hz, in child processes that alternate: *closed* (the line's key: its partition and its
  signatures, the default) and *open* (no key and a profiles file of the user's own: no
  partition, nothing signed), three of each; medians of rtf and CPU per tick, and their ratios.

Under load: run it with two busy loops on both cores (``timeout 600 sh -c 'while :; do
:; done' &`` twice) to see sim time slow down while the recorded answer stays the same.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import platform
import re
import statistics
import subprocess
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
    from folder_line.ros.dds_profile import use_line_profile
    from folder_line.ros.line_key import ensure_key

    if '--key-role' not in sys.argv:  # (a run of --key takes the key, or none, from its parent)
        ensure_key(os.environ)  # one line key for this process and its children (the lines run here are closed)
    use_line_profile()  # the floors run with the line's Fast DDS profile, as the line does


def _qos() -> Any:
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def _mix() -> list[tuple[type, Any]]:
    """The floor's messages: one of each type the line publishes, of the line's sizes."""
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import JointState, TimeReference
    from std_msgs.msg import Float64, String, UInt64

    js = JointState(name=['a', 'b', 'c'], position=[1.0, 2.0, 3.0], velocity=[1.0, 2.0, 3.0])
    ack = TimeReference(source='messages=123456 events=1234 commands=0')
    return [
        (JointState, js),
        (TimeReference, ack),
        (String, String(data='EXECUTE')),
        (UInt64, UInt64(data=7)),
        (Float64, Float64(data=1.5)),
        (Clock, Clock()),
    ]


def floor_across_processes(n: int = 3000, fanout: int = 1) -> float:
    """CPU s per message of a bare publish -> take of the line's message mix from one publisher process
    to ``fanout`` subscriber processes (each taking every message; empty callbacks, EventsExecutor):
    the floor of a line with one process per node. The CPU is every process's, over the messages only
    (start-up, discovery and shutdown excluded: each process measures its own)."""
    import subprocess

    env = {**os.environ, 'ROS_DOMAIN_ID': str(150 + (os.getpid() + fanout) % 80)}
    me = [sys.executable, __file__, '--floor-role']
    subs = [subprocess.Popen([*me, 'sub', str(n)], env=env, stdout=subprocess.PIPE, text=True) for _ in range(fanout)]
    pub = subprocess.Popen([*me, 'pub', str(n), str(fanout)], env=env, stdout=subprocess.PIPE, text=True)
    cpu = 0.0
    for p in (pub, *subs):
        out, _ = p.communicate(timeout=300)
        if p.returncode != 0:
            raise SystemExit(f'the cross-process floor failed (exit {p.returncode}): {out[-300:]}')
        cpu += float(out.split()[-1])
    return cpu / n


def _floor_role(role: str, n: int, fanout: int) -> None:
    """One process of :func:`floor_across_processes`: prints its CPU s over the messages."""
    import rclpy
    from rclpy.experimental import EventsExecutor

    rclpy.init()
    node = rclpy.create_node(f'floor_{role}_{os.getpid()}')
    ex = EventsExecutor()
    ex.add_node(node)
    mix = _mix()
    if role == 'sub':
        got = [0]
        cpu0 = [0.0]

        def take(_: Any) -> None:
            if got[0] == 0:
                cpu0[0] = time.process_time()
            got[0] += 1

        for i, (cls, _) in enumerate(mix):
            node.create_subscription(cls, f'/floor/t{i}', take, _qos())
        while got[0] < n:
            ex.spin_once(timeout_sec=1.0)
        print(time.process_time() - cpu0[0], flush=True)
    else:
        pubs = [(node.create_publisher(cls, f'/floor/t{i}', _qos()), msg) for i, (cls, msg) in enumerate(mix)]
        while any(p.get_subscription_count() < fanout for p, _ in pubs):
            ex.spin_once(timeout_sec=0.05)
        time.sleep(1.0)  # the readers matched too
        c0 = time.process_time()
        sent = 0
        while sent < n:
            for p, m in pubs[: n - sent]:
                p.publish(m)
                sent += 1
            time.sleep(0.0005)  # no more than the readers take: a reliable 1000-deep history never overflows
        print(time.process_time() - c0, flush=True)
        time.sleep(2.0)  # the readers take the last ones before the writer goes
    ex.shutdown()
    node.destroy_node()
    rclpy.try_shutdown()


def floor_per_message(n: int = 3000, executor_kind: str = 'events', fanout: int = 1) -> float:
    """CPU s per message of a bare publish -> take of the line's message mix: one publisher node and
    ``fanout`` subscriber nodes, each taking every message, on one executor, with empty callbacks."""
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.experimental import EventsExecutor

    qos = _qos()
    ctx = Context()
    rclpy.init(context=ctx)
    ex = EventsExecutor(context=ctx) if executor_kind == 'events' else SingleThreadedExecutor(context=ctx)
    pub_node = rclpy.create_node('floor_pub', context=ctx)
    sub_nodes = [rclpy.create_node(f'floor_sub{k}', context=ctx) for k in range(fanout)]
    mix = _mix()
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


def line_fanout(rate: float) -> tuple[dict[str, int], dict[str, float]]:
    """Subscribers per topic of the in-process line (topic -> count), read from the ROS graph once every
    participant has subscribed to everything it takes (the acknowledgements after the announcement); and
    the lockstep's own messages per tick of that line at rtf max (topic -> count: ``tick_done`` of every
    tick, ``progress`` now and then, the grants), counted by the participants and the clock."""
    import rclpy
    from rclpy.parameter import Parameter

    from folder_line.config.run_config import RunConfig, clock_parameters
    from folder_line.interfaces import GRANT_TOPIC, KNOWN_PARTICIPANTS, progress_topic, tick_done_topic
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
    ticks = clock.ticks
    lockstep: dict[str, float] = {GRANT_TOPIC: clock.grants / ticks}
    for node in nodes:
        participant = getattr(node, 'lockstep', None)
        if participant is not None:
            lockstep[tick_done_topic(participant.name)] = participant.acknowledged / ticks
            lockstep[progress_topic(participant.name)] = participant.said / ticks
    topics = [*LINE_TOPICS, *lockstep]
    fanout = {t: clock.count_subscribers(t) for t in topics}
    executor.shutdown()
    for node in nodes:
        node.destroy_node()
    rclpy.try_shutdown(context=ctx)
    return fanout, lockstep


#: the CPU per tick is measured between these fractions of the run's line time: start-up and the end excluded
STEADY = (0.2, 0.9)
_PROGRESS = re.compile(r'\]\s+([0-9.]+) / ')


def tree_cpu() -> float:
    """CPU s (user + system) so far of this process and of every live process descended from it."""
    tick = os.sysconf('SC_CLK_TCK')
    parent: dict[int, int] = {}
    cpu: dict[int, float] = {}
    for entry in os.listdir('/proc'):
        if not entry.isdigit():
            continue
        try:
            with open(f'/proc/{entry}/stat') as f:
                fields = f.read().rsplit(')', 1)[1].split()
        except OSError:
            continue  # ended meanwhile
        parent[int(entry)] = int(fields[1])
        cpu[int(entry)] = (int(fields[11]) + int(fields[12])) / tick
    mine = {os.getpid()}
    grew = True
    while grew:
        kids = {p for p, pp in parent.items() if pp in mine and p not in mine}
        grew = bool(kids)
        mine |= kids
    return sum(cpu.get(p, 0.0) for p in mine)


class _Marks(io.StringIO):
    """The run's progress stream (one line per tenth of its line time): the CPU of the process tree at each."""

    def __init__(self) -> None:
        super().__init__()
        self.marks: list[tuple[float, float]] = []  # (line time s, tree CPU s)

    def write(self, text: str) -> int:
        for m in _PROGRESS.finditer(text):
            self.marks.append((float(m[1]), tree_cpu()))
        return len(text)


def _steady_cpu_per_tick(marks: list[tuple[float, float]], duration: float, rate: float) -> float:
    """CPU s per tick between the marks at :data:`STEADY` of ``duration``."""
    lo, hi = STEADY[0] * duration - 1e-9, STEADY[1] * duration + 1e-9
    inside = [(t, c) for t, c in marks if lo <= t <= hi]
    if len(inside) < 2 or inside[-1][0] <= inside[0][0]:
        raise SystemExit(f'too few progress marks to measure the steady CPU: {marks}')
    (t0, c0), (t1, c1) = inside[0], inside[-1]
    return (c1 - c0) / ((t1 - t0) * rate)


def _net_run(net: Any, duration: float, rate: float, impair: str, work: Path) -> tuple[float, float, dict]:
    """One distributed run at rtf max over the test network with ``impair`` ('clean', 'delay', 'loss'):
    (CPU s per tick of every process, rtf reached, summary)."""
    from net._line import HOSTS  # test/net: the harness of the network tests
    from net._line import run_line as run_distributed

    from folder_line.config.run_config import RunConfig

    net.clear()
    for host in HOSTS:
        if impair == 'delay':
            net.set(host, delay_ms=5.0, jitter_ms=2.0)
        elif impair == 'loss':
            net.set(host, loss=0.05)
    out = Path(tempfile.mkdtemp(prefix='run_', dir=work)) / 'out'
    cfg = RunConfig(scene='folder', duration=duration, rtf=0.0, rate=rate, out=out)
    marks = _Marks()

    def during(net: Any, nodes: Any, started: float) -> None:  # the run's log, read as it grows
        log = out.parent / 'logs' / 'run.log'
        seen = 0
        deadline = time.monotonic() + 600
        while time.monotonic() < deadline and not any(t >= STEADY[1] * duration for t, _ in marks.marks):
            text = log.read_text(errors='replace')
            marks.write(text[seen:])
            seen = len(text)
            time.sleep(0.02)

    result = run_distributed(net, cfg, during=during)
    if not result.summary.get('outcome', {}).get('ok'):
        raise SystemExit(f'the distributed line did not end as expected: {result.summary.get("outcome")}')
    return _steady_cpu_per_tick(marks.marks, duration, rate), result.rtf, result.summary


def _run(duration: float, rate: float, processes: bool) -> tuple[float, float, dict]:
    """One lockstep run at rtf max: (CPU s per tick of this process and its children, rtf reached, summary)."""
    from folder_line.config.run_config import RunConfig
    from folder_line.ros.run import run_line

    marks = _Marks()
    with tempfile.TemporaryDirectory(prefix='bench_nodes_') as tmp:
        cfg = RunConfig(scene='folder', duration=duration, rtf=0.0, rate=rate, out=Path(tmp), processes=processes)
        result = run_line(cfg, marks)
    s = result.summary
    if not s['outcome']['ok']:
        raise SystemExit(f'the line did not end as expected: {s["outcome"]["message"]}')
    return _steady_cpu_per_tick(marks.marks, duration, rate), s['rtf_achieved'], s


def line(
    duration: float, rate: float, processes: bool, lockstep: dict[str, float], net: Any = None, impair: str = ''
) -> dict[str, Any]:
    """One run of ``duration``: the CPU per tick of the whole process tree between :data:`STEADY` of its line
    time (start-up, imports and discovery, and the end excluded), the rtf reached, the messages per tick.
    ``lockstep``: the protocol's own messages per tick (:func:`line_fanout`; not recorded)."""
    if net is None:
        cpu, rtf, s = _run(duration, rate, processes)
    else:
        cpu, rtf, s = _net_run(net, duration, rate, impair, Path(net.workdir))
    ticks = round(duration * rate) + 1
    per_topic = {t: n / ticks for t, n in s['bag']['messages'].items()}
    per_topic.update(lockstep)
    return {'rtf': rtf, 'cpu_per_tick': cpu, 'per_topic': per_topic, 'ticks': ticks}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--quick', action='store_true', help='shorter spans')
    parser.add_argument('--net', action='store_true', help='also the line distributed over impaired links (root)')
    parser.add_argument('--key', action='store_true', help='only the line closed (its key) against open, side by side')
    parser.add_argument('--floor-role', nargs='+', help=argparse.SUPPRESS)  # a process of the cross-process floor
    parser.add_argument('--key-role', type=float, help=argparse.SUPPRESS)  # one run of --key, of this many sim s
    args = parser.parse_args()
    if args.floor_role:
        role, n, *fanout = args.floor_role
        _floor_role(role, int(n), int(fanout[0]) if fanout else 0)
        return 0
    if args.key_role:
        from folder_line.ros.signing import line_signer

        signer = line_signer()  # read once, now: without a key in the environment, this process signs nothing
        cpu, rtf, s = _run(args.key_role, 200.0, False)
        print(json.dumps({'cpu': cpu, 'rtf': rtf, 'partition': s.get('partition'), 'signed': signer.keyed}))
        return 0
    span = 2.0 if args.quick else 10.0
    if args.key:
        return key_cost(span)
    print(
        f'machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, '
        f'Python {platform.python_version()}; load average {os.getloadavg()[0]:.2f}'
    )
    fanout, lockstep = line_fanout(200.0)
    floors = {
        k: floor_per_message(executor_kind='events', fanout=k) for k in sorted({max(v, 1) for v in fanout.values()})
    }
    floor_single = floor_per_message(executor_kind='single')
    across = {k: floor_across_processes(fanout=k) for k in floors}
    print(
        'floor (bare publish -> take, same message mix), EventsExecutor: '
        + ', '.join(f'{floors[k] * 1e6:.1f} us/message with {k} subscriber{"s" if k > 1 else ""}' for k in floors)
        + f'; SingleThreadedExecutor {floor_single * 1e6:.1f} us/message with 1'
    )
    print(
        'floor across processes (one publisher process, each subscriber a process of its own): '
        + ', '.join(f'{across[k] * 1e6:.1f} us/message with {k}' for k in across)
    )
    print('subscribers per topic in the line: ' + ', '.join(f'{t} {k}' for t, k in fanout.items()))
    print('lockstep messages per tick (in process): ' + ', '.join(f'{t} {n:.2f}' for t, n in lockstep.items()) + '\n')
    print(
        '| setup | rate (Hz) | sim s | rtf reached | CPU per tick | messages per tick | deliveries per tick '
        '| floor per tick, in process | CPU / that | floor per tick, across processes | CPU / that |'
    )
    print('|---|---|---|---|---|---|---|---|---|---|---|')
    setups: list[tuple[str, float, Any]] = [
        (label, rate, processes)
        for label, processes in (('in process', False), ('one process per node', True))
        for rate in (200.0, 1000.0)
    ]
    with contextlib.ExitStack() as stack:
        net = stack.enter_context(_network()) if args.net else None
        if net is not None:
            setups += [(f'one host per node, {what}', 200.0, what) for what in ('clean', 'delay', 'loss')]
        for label, rate, how in setups:
            duration = span if rate == 200.0 else span / 5
            if isinstance(how, str):
                r = line(duration, rate, False, lockstep, net, how)
            else:
                r = line(duration, rate, how, lockstep)
            _row(label, rate, duration, r, fanout, floors, across)
    return 0


def key_cost(span: float, repeats: int = 3) -> int:
    """``--key``: the in-process line closed and open, alternating, each in a process of its own."""
    from folder_line.ros.dds_profile import PROFILE_FILE, PROFILES_FILE_VARIABLE
    from folder_line.ros.line_key import KEY_VARIABLE, new_key

    results: dict[str, list[dict[str, float]]] = {'closed': [], 'open': []}
    with tempfile.TemporaryDirectory(prefix='bench_key_') as tmp:
        own = Path(tmp) / 'my_profiles.xml'  # a profiles file of the user's own: the line stays open
        own.write_bytes(PROFILE_FILE.read_bytes())
        for _ in range(repeats):
            for how in ('closed', 'open'):
                env = dict(os.environ)
                env.setdefault(KEY_VARIABLE, new_key())
                if how == 'open':  # no partition, no signatures (run makes a key only after the signer is read)
                    env[PROFILES_FILE_VARIABLE] = str(own)
                    env.pop(KEY_VARIABLE)
                done = subprocess.run(
                    [sys.executable, __file__, '--key-role', str(span)],
                    env=env,
                    capture_output=True,
                    text=True,
                    check=True,
                )
                result = json.loads(done.stdout.strip().splitlines()[-1])
                assert result['signed'] == (how == 'closed') and bool(result['partition']) == (how == 'closed'), result
                results[how].append(result)
    med = {how: {k: statistics.median(r[k] for r in rs) for k in ('cpu', 'rtf')} for how, rs in results.items()}
    print(f'in process, 200 Hz, {span:g} s of line time, {repeats} runs of each, alternating; medians:')
    print('| line | rtf reached | CPU per tick |')
    print('|---|---|---|')
    for how in ('open', 'closed'):
        print(f'| {how} | {med[how]["rtf"]:.2f} | {med[how]["cpu"] * 1e3:.2f} ms |')
    print(
        f'closed / open: rtf {med["closed"]["rtf"] / med["open"]["rtf"]:.3f}, '
        f'CPU per tick {med["closed"]["cpu"] / med["open"]["cpu"]:.3f}'
    )
    return 0


def _network() -> Any:
    """The test network's hosts (control and one per machine node), in a directory of its own."""
    sys.path.insert(0, str(REPO / 'test'))
    from net._line import HOSTS
    from net.netns import Network, available, build_switch

    reason = available()
    if reason is not None:
        raise SystemExit(f'--net: {reason}')
    work = Path(tempfile.mkdtemp(prefix='bench_net_'))
    network = Network(list(HOSTS), work / 'net', switch=build_switch(work))
    network.workdir = work  # type: ignore[attr-defined]
    return network


def _row(
    label: str, rate: float, duration: float, r: dict[str, Any], fanout: dict[str, int], floors: dict, across: dict
) -> None:
    """One line of the table: both floors count every message as many times as the line has subscribers to it."""
    per_topic = r['per_topic']
    messages = sum(per_topic.values())
    deliveries = sum(n * fanout.get(t, 1) for t, n in per_topic.items())
    floor_in = sum(n * floors[max(fanout.get(t, 1), 1)] for t, n in per_topic.items())
    floor_across = sum(n * across[max(fanout.get(t, 1), 1)] for t, n in per_topic.items())
    cpu = r['cpu_per_tick']
    print(
        f'| {label} | {rate:g} | {duration:g} | '
        f'{r["rtf"]:.2f} | {cpu * 1e3:.2f} ms | {messages:.1f} | {deliveries:.1f} | '
        f'{floor_in * 1e3:.2f} ms | {cpu / floor_in:.1f} | {floor_across * 1e3:.2f} ms | {cpu / floor_across:.1f} |',
        flush=True,
    )


if __name__ == '__main__':
    sys.exit(main())
