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

* **Network.** The same line distributed (``--net``, as root where network namespaces can be
  made): ``folder-line run --external-nodes`` (clock and recorder) on one host and each machine
  node on a host of its own, over UDPv4 through the test network's user-space switch
  (``test/net/netns.py``), clean, with 5 +- 2 ms of delay on every host's link, and with 5 %
  loss on every link. CPU per tick is every process's.

Under load: run it with two busy loops on both cores (``timeout 600 sh -c 'while :; do
:; done' &`` twice) to see sim time slow down while the recorded answer stays the same.
"""

from __future__ import annotations

import argparse
import contextlib
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


def _net_run(net: Any, duration: float, rate: float, impair: str, work: Path) -> tuple[float, float, dict]:
    """One distributed run at rtf max over the test network with ``impair`` ('clean', 'delay', 'loss')."""
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
    kids0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    result = run_distributed(net, cfg)
    kids1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if not result.summary.get('outcome', {}).get('ok'):
        raise SystemExit(f'the distributed line did not end as expected: {result.summary.get("outcome")}')
    cpu = kids1.ru_utime + kids1.ru_stime - kids0.ru_utime - kids0.ru_stime
    return cpu, result.rtf, result.summary


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


def line(
    duration: float, rate: float, processes: bool, lockstep: dict[str, float], net: Any = None, impair: str = ''
) -> dict[str, Any]:
    """Runs of ``duration`` and ``2 duration``: the CPU per tick is their difference over the extra ticks, so
    start-up (imports, models, discovery) cancels out; the rtf reached is the longer run's. ``lockstep``: the
    protocol's own messages per tick (:func:`line_fanout`; not recorded)."""
    if net is None:
        cpu1, _, _ = _run(duration, rate, processes)
        cpu2, rtf, s = _run(2 * duration, rate, processes)
    else:
        cpu1, _, _ = _net_run(net, duration, rate, impair, Path(net.workdir))
        cpu2, rtf, s = _net_run(net, 2 * duration, rate, impair, Path(net.workdir))
    ticks = round(2 * duration * rate) + 1
    extra = round(duration * rate)
    per_topic = {t: n / ticks for t, n in s['bag']['messages'].items()}
    per_topic.update(lockstep)
    return {'rtf': rtf, 'cpu_per_tick': (cpu2 - cpu1) / extra, 'per_topic': per_topic, 'ticks': ticks}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--quick', action='store_true', help='shorter spans')
    parser.add_argument('--net', action='store_true', help='also the line distributed over impaired links (root)')
    args = parser.parse_args()
    span = 1.0 if args.quick else 5.0
    print(
        f'machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, '
        f'Python {platform.python_version()}; load average {os.getloadavg()[0]:.2f}'
    )
    fanout, lockstep = line_fanout(200.0)
    floors = {
        k: floor_per_message(executor_kind='events', fanout=k) for k in sorted({max(v, 1) for v in fanout.values()})
    }
    floor_single = floor_per_message(executor_kind='single')
    print(
        'floor (bare publish -> take, same message mix), EventsExecutor: '
        + ', '.join(f'{floors[k] * 1e6:.1f} us/message with {k} subscriber{"s" if k > 1 else ""}' for k in floors)
        + f'; SingleThreadedExecutor {floor_single * 1e6:.1f} us/message with 1'
    )
    print('subscribers per topic in the line: ' + ', '.join(f'{t} {k}' for t, k in fanout.items()))
    print('lockstep messages per tick (in process): ' + ', '.join(f'{t} {n:.2f}' for t, n in lockstep.items()) + '\n')
    print(
        '| setup | rate (Hz) | sim s | rtf reached | CPU per tick | messages per tick | deliveries per tick '
        "| floor per tick, 1 subscriber | CPU / that | floor per tick, the line's subscribers | CPU / that |"
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
            duration = span if rate == 200.0 else span / 5  # the longer run is twice this
            if isinstance(how, str):
                r = line(duration, rate, False, lockstep, net, how)
            else:
                r = line(duration, rate, how, lockstep)
            _row(label, rate, duration, r, fanout, floors)
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


def _row(label: str, rate: float, duration: float, r: dict[str, Any], fanout: dict[str, int], floors: dict) -> None:
    """One line of the table."""
    per_topic = r['per_topic']
    messages = sum(per_topic.values())
    deliveries = sum(n * fanout.get(t, 1) for t, n in per_topic.items())
    floor1 = floors[1] * messages
    floor_k = sum(n * floors[max(fanout.get(t, 1), 1)] for t, n in per_topic.items())
    cpu = r['cpu_per_tick']
    print(
        f'| {label} | {rate:g} | {2 * duration:g} | '
        f'{r["rtf"]:.2f} | {cpu * 1e3:.2f} ms | {messages:.1f} | {deliveries:.1f} | '
        f'{floor1 * 1e3:.2f} ms | {cpu / floor1:.1f} | {floor_k * 1e3:.2f} ms | {cpu / floor_k:.1f} |',
        flush=True,
    )


if __name__ == '__main__':
    sys.exit(main())
