"""``folder-line run``: start the line's nodes, let it run, stop cleanly, report.

In-process (default): ``line_clock`` and the five machine nodes in one process on
one executor in a private context, as a component container would run them.
With ``processes=True``: one process per node, started from the node executables
as a launch file would, and stopped with SIGINT. Either way a recorder in this
process subscribes to every line topic, counts what arrives and compares it with
what the batch simulation (``simulate``) of the same scene says.

The recorder hands every message to a :class:`folder_line.bag.BagWriter`: the run's
bag is ``<out>/bag/`` (rosbag2, MCAP, one file per second of line time, the complete
scene and its effects in the metadata). Loss accounting: in-process, every node
counts what it publishes (``published_counts()``), read at the end of the run, so
``run.json`` has ``published`` and ``lost`` (= published - recorded) per topic. With
``processes=True`` the publishers live in other processes and their counts are not
collected: ``published`` and ``lost`` are ``null`` there, and ``loss_accounting`` says so.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any, Callable

from folder_line.atomic import write_json_atomic

__all__ = ['BAG_DIR', 'LINE_NODES', 'RunConfig', 'RunResult', 'add_machine_nodes', 'print_run_summary', 'run_line',
           'wait_until_matched']

#: the nodes of the line, in start order (the clock last, so nobody misses t = 0)
LINE_NODES: tuple[str, ...] = ('crank_drive', 'belt_conveyor', 'feed_transporter', 'sheet_counter', 'supervisor')

#: the run's bag, under ``cfg.out``
BAG_DIR = 'bag'

_PROCESSES_LOSS = ('unavailable with --processes: the publishers run in other processes and their '
                   'counts are not collected')


@dataclass(frozen=True)
class RunConfig:
    """What to run.

    Attributes
    ----------
    scene : str
        Scene name or file.
    duration : float
        Line time, s.
    overrides : tuple of str
        ``MACHINE.KEY=VALUE`` items.
    rtf : float
        Real-time factor of ``line_clock``.
    rate : float
        Publishing rate of the machine nodes, Hz of sim time.
    out : Path
        Output directory.
    processes : bool
        One process per node instead of one executor.
    """

    scene: str = 'folder'
    duration: float = 20.0
    overrides: tuple[str, ...] = ()
    rtf: float = 1.0
    rate: float = 200.0
    out: Path = Path('out')
    processes: bool = False


@dataclass
class RunResult:
    """What a run produced: per-topic message counts and the summary written to ``run.json``."""

    counts: dict[str, int] = field(default_factory=dict)
    summary: dict[str, Any] = field(default_factory=dict)
    exit_codes: dict[str, int] = field(default_factory=dict)


def _clock_publish_rate(cfg: RunConfig, per_tick: int = 1) -> float:
    """``/clock`` messages per wall second: ``per_tick`` per node tick (``rate`` Hz of sim time at ``rtf``).

    A node's timer runs on sim time and fires at most once per ``/clock`` message, so
    fewer messages than ``rate * rtf`` per wall second would lower the nodes' rate in sim
    time (``line_clock`` allows at most 1000 per second). One per tick suffices when the
    clock starts with the line (its messages then fall just after the ticks' grid
    points); a clock whose ``rtf`` is changed on the way has an arbitrary phase, and with
    one message per tick a message just before a grid point, jittered across it, skips a
    tick: two per tick put one in every grid interval.
    """
    return min(1000.0, max(1.0, per_tick * cfg.rate * cfg.rtf))


#: real-time factor of the clock while the processes wait for each other (sim time all but stands)
_HOLD_RTF = 1e-6


def _start_processes_line(cfg: RunConfig, recorder: Any, executor: Any, env: dict[str, str],
                          procs: dict[str, Any], logs: Path, stream: IO[str]) -> None:
    """Start ``line_clock`` as a process once every node process hears it, then let sim time run.

    DDS discovery between processes takes from 0.1 s to several seconds here (Fast DDS
    repeats its announcements every few seconds), so a clock started at full speed would
    run for a while before some node, or the recorder, hears it. The clock starts at the
    nodes' first tick (``1/rate`` s, a grid point of every node's timer) at a real-time
    factor that all but stops sim time; once every node that publishes has published at
    that tick (so it hears the clock) and the recorder hears the clock, ``rtf`` is set to
    ``cfg.rtf`` through the clock's parameter service, and the line runs from there.
    """
    from rclpy.parameter import Parameter
    from rclpy.parameter_client import AsyncParameterClient

    from folder_line.nodes.common import CLOCK_TOPIC, SHEET_COUNT_TOPIC, SUPERVISOR_STATE_TOPIC, joint_states_topic

    t0 = min(1.0 / cfg.rate, 0.5 * cfg.duration)
    clock_cmd = [sys.executable, '-m', 'folder_line.nodes.line_clock', '--ros-args',
                 '-p', f'start_time:={t0!r}', '-p', f'duration:={cfg.duration - t0!r}', '-p', f'rtf:={_HOLD_RTF!r}',
                 '-p', f'publish_rate:={_clock_publish_rate(cfg, per_tick=2)!r}']
    with open(logs / 'line_clock.log', 'wb') as log:
        procs['line_clock'] = subprocess.Popen(clock_cmd, env=env, stdout=subprocess.DEVNULL, stderr=log)
    topics = [joint_states_topic(n) for n in LINE_NODES] + [SHEET_COUNT_TOPIC, SUPERVISOR_STATE_TOPIC]
    expected = [CLOCK_TOPIC] + [t for t in topics if recorder.count_publishers(t) > 0]
    client = AsyncParameterClient(recorder, 'line_clock')
    deadline = time.monotonic() + 60.0
    while time.monotonic() < deadline and not (client.services_are_ready()
                                               and all(recorder.counts[t] for t in expected)):
        if procs['line_clock'].poll() is not None:
            return
        executor.spin_once(timeout_sec=0.05)
    deaf = [t for t in expected if not recorder.counts[t]]
    if deaf:
        print(f'warning: starting the line although nothing arrived yet on {", ".join(deaf)}', file=stream)
    future = client.set_parameters([Parameter('rtf', value=float(cfg.rtf))])
    while time.monotonic() < deadline + 10.0 and not future.done():
        executor.spin_once(timeout_sec=0.05)
    recorder.clock_wall = None  # the achieved real-time factor counts from here


def _node_parameters(cfg: RunConfig, name: str) -> dict[str, Any]:
    params: dict[str, Any] = {'scene': cfg.scene, 'horizon': cfg.duration + 1.0, 'rate': cfg.rate}
    if cfg.overrides:  # rcl cannot parse an empty '-p overrides:=' rule
        params['overrides'] = ';'.join(cfg.overrides)
    return params


class _Progress:
    """A progress bar on a terminal; on a pipe or file, one line per tenth."""

    def __init__(self, stream: IO[str], total: float, width: int = 40) -> None:
        self.stream, self.total, self.width = stream, total, width
        self.tty = hasattr(stream, 'isatty') and stream.isatty()
        self.tenths = -1

    def show(self, t: float) -> None:
        fraction = min(max(t / self.total, 0.0), 1.0)
        done = int(self.width * fraction)
        line = f'[{"#" * done}{"." * (self.width - done)}] {t:7.2f} / {self.total:g} s of line time'
        if self.tty:
            self.stream.write('\r' + line)
        elif int(10 * fraction) > self.tenths:
            self.tenths = int(10 * fraction)
            self.stream.write(line + '\n')
        self.stream.flush()

    def close(self) -> None:
        if self.tty:
            self.stream.write('\n')


def _clear_previous_bag(path: Path) -> None:
    """Remove the bag of a previous run at ``path``; refuse anything that is not one."""
    from folder_line.bag import BagError

    if not path.exists():
        return
    ours = path.is_dir() and all(
        p.is_file() and (p.name == 'metadata.yaml' or p.suffix in ('.mcap', '.truncated', '.tmp'))
        for p in path.iterdir())
    if not ours:
        msg = f'{path}: exists and is not a bag of a previous run; move it away or choose another --out'
        raise BagError(msg)
    shutil.rmtree(path)


def _published_counts(nodes: list[Any]) -> dict[str, int]:
    counts: dict[str, int] = {}
    for node in nodes:
        for topic, n in node.published_counts().items():
            counts[topic] = counts.get(topic, 0) + n
    return counts


def wait_until_matched(nodes: list[Any], executor: Any, timeout: float) -> bool:
    """Spin ``executor`` until every line-topic publisher and subscription of ``nodes`` has matched all
    its peers among ``nodes``, or ``timeout`` s of wall time pass; True if they all matched.

    Starting sim time before that loses the first ticks' messages to subscribers not yet
    discovered (the supervisor would judge cycle 0 without its events and hold the line).
    """
    from collections import Counter

    from folder_line.recorder import LINE_TOPICS

    pubs = [p for n in nodes for p in n.publishers if p.topic_name in LINE_TOPICS]
    subs = [s for n in nodes for s in n.subscriptions if s.topic_name in LINE_TOPICS]
    n_pubs = Counter(p.topic_name for p in pubs)
    n_subs = Counter(s.topic_name for s in subs)

    def matched() -> bool:
        return (all(s.get_publisher_count() >= n_pubs[s.topic_name] for s in subs)
                and all(p.get_subscription_count() >= n_subs[p.topic_name] for p in pubs))

    deadline = time.monotonic() + timeout
    while not matched():
        if time.monotonic() > deadline:
            return False
        executor.spin_once(timeout_sec=0.01)
    return True


def add_machine_nodes(cfg: RunConfig, context: Any, executor: Any) -> list[Any]:
    """Build the five machine nodes of :data:`LINE_NODES` in ``context`` with the run's parameters
    (scene, overrides, horizon, rate) and add them to ``executor``; returns them in that order."""
    from rclpy.parameter import Parameter

    from folder_line.nodes import belt_conveyor, crank_drive, feed_transporter, sheet_counter, supervisor

    classes = {'crank_drive': crank_drive.CrankDrive, 'belt_conveyor': belt_conveyor.BeltConveyor,
               'feed_transporter': feed_transporter.FeedTransporter,
               'sheet_counter': sheet_counter.SheetCounter, 'supervisor': supervisor.Supervisor}
    nodes = []
    for name in LINE_NODES:
        overrides = [Parameter(k, value=v) for k, v in _node_parameters(cfg, name).items()]
        node = classes[name](parameter_overrides=overrides, context=context)
        executor.add_node(node)
        nodes.append(node)
    return nodes


def run_line(cfg: RunConfig, stream: IO[str] = sys.stdout) -> RunResult:
    """Run the line for ``cfg.duration`` s of sim time; record ``<out>/bag/``; write ``run.json`` to ``cfg.out``."""
    import rclpy
    import yaml
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    from folder_line.bag import BagWriter
    from folder_line.core.scene import parse_scene
    from folder_line.nodes.line_clock import LineClock
    from folder_line.recorder import LINE_TOPICS, LineRecorder
    from folder_line.scenes import parse_set, scene_mapping

    mapping = scene_mapping(cfg.scene, parse_set(cfg.overrides))
    scene = parse_scene(mapping)  # fail early, before any node starts
    cfg.out.mkdir(parents=True, exist_ok=True)
    bag_path = cfg.out / BAG_DIR
    _clear_previous_bag(bag_path)
    bag = BagWriter(bag_path, scene_source=yaml.safe_dump(mapping, sort_keys=False), effects=list(scene.effects),
                    scene_name=scene.name, topics=LINE_TOPICS,
                    custom={'folder_line.scene_arg': str(cfg.scene), 'folder_line.overrides': json.dumps(cfg.overrides),
                            'folder_line.mode': 'processes' if cfg.processes else 'in-process'})
    ctx = rclpy.Context()
    rclpy.init(context=ctx, signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
    result = RunResult()
    procs: dict[str, subprocess.Popen[bytes]] = {}
    nodes: list[Any] = []
    executor = SingleThreadedExecutor(context=ctx)
    interrupted = False

    def on_signal(signum: int, frame: object) -> None:
        nonlocal interrupted
        interrupted = True

    previous = signal.signal(signal.SIGINT, on_signal)
    t_wall = time.perf_counter()
    try:
        recorder = LineRecorder(sink=bag.write, context=ctx)
        executor.add_node(recorder)
        if cfg.processes:
            env = dict(os.environ)
            logs = cfg.out / 'logs'  # each process's stderr
            logs.mkdir(exist_ok=True)
            for name in LINE_NODES:
                args = [f'{k}:={v}' for k, v in _node_parameters(cfg, name).items()]
                cmd = [sys.executable, '-m', f'folder_line.nodes.{name}', '--ros-args']
                for a in args:
                    cmd += ['-p', a]
                # a file, not a pipe nobody reads: a node that logs a lot would block on a full pipe
                with open(logs / f'{name}.log', 'wb') as log:
                    procs[name] = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=log)
            recorder.wait_for_publishers(len(LINE_NODES), executor, timeout=30.0)
            _start_processes_line(cfg, recorder, executor, env, procs, logs, stream)
            done: Callable[[], bool] = lambda: procs['line_clock'].poll() is not None  # noqa: E731
        else:
            nodes += add_machine_nodes(cfg, ctx, executor)
            # sim time starts once every line topic is matched among the nodes and the recorder
            wait_until_matched([*nodes, recorder], executor, timeout=10.0)
            clock = LineClock(parameter_overrides=[Parameter('duration', value=float(cfg.duration)),
                                                   Parameter('rtf', value=float(cfg.rtf)),
                                                   Parameter('publish_rate', value=_clock_publish_rate(cfg))],
                              context=ctx)
            nodes.append(clock)
            executor.add_node(clock)
            done = clock.done.done
        last_draw = 0.0
        progress = _Progress(stream, cfg.duration)
        while not done() and not interrupted:
            executor.spin_once(timeout_sec=0.05)
            now = time.perf_counter()
            if now - last_draw > 0.2:
                progress.show(recorder.sim_time)
                last_draw = now
        if interrupted and not cfg.processes:
            executor.remove_node(clock)  # sim time stops, so nothing more is published while draining
        # let the last messages arrive
        deadline = time.perf_counter() + 1.0
        while time.perf_counter() < deadline:
            executor.spin_once(timeout_sec=0.05)
        progress.show(recorder.sim_time)
        progress.close()
        result.counts = dict(recorder.counts)
        published = None if cfg.processes else _published_counts(nodes)
        bag.close(published)
        result.summary = _summary(cfg, scene, recorder, time.perf_counter() - t_wall, interrupted)
        result.summary.update(_bag_summary(bag, published))
    finally:
        for name, proc in procs.items():
            if proc.poll() is None:
                proc.send_signal(signal.SIGINT)
        for name, proc in procs.items():
            try:
                proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
            result.exit_codes[name] = proc.returncode
        executor.shutdown()
        bag.close()  # no-op after a normal end; after an error, finishes what was recorded
        for node in nodes:
            node.destroy_node()
        ctx.try_shutdown()
        signal.signal(signal.SIGINT, previous)
    if procs:
        result.summary['exit_codes'] = result.exit_codes
    write_json_atomic(cfg.out / 'run.json', result.summary)
    return result


def _summary(cfg: RunConfig, scene: Any, recorder: Any, wall: float, interrupted: bool) -> dict[str, Any]:
    from folder_line.core.line import simulate

    expected = simulate(scene, min(recorder.sim_time, cfg.duration) or cfg.duration, sample_rate=0.0).summary()
    return {
        'scene': scene.name,
        'duration_s': cfg.duration,
        'sim_time_reached_s': recorder.sim_time,
        'wall_time_s': wall,
        'rtf_requested': cfg.rtf,
        'rtf_achieved': (recorder.sim_time / (recorder.clock_wall[1] - recorder.clock_wall[0])
                         if recorder.clock_wall and recorder.clock_wall[1] > recorder.clock_wall[0] else 0.0),
        'mode': 'processes' if cfg.processes else 'in-process',
        'interrupted': interrupted,
        'messages': dict(sorted(recorder.counts.items())),
        'events_received': dict(sorted(recorder.event_counts.items())),
        'sheets_counted': recorder.sheet_count,
        'supervisor_state': recorder.state,
        'expected_from_simulate': {'sheets_counted': expected['sheets_counted'], 'events': expected['events'],
                                   'violations': expected['violations']['count']},
    }


def _bag_summary(bag: Any, published: dict[str, int] | None) -> dict[str, Any]:
    recorded = dict(sorted(bag.counts.items()))
    out: dict[str, Any] = {
        'bag': {'path': str(bag.path), 'segments': len(bag.files), 'messages': recorded},
        'published': None if published is None else {t: published.get(t, 0) for t in recorded},
        'lost': None if published is None else {t: published.get(t, 0) - n for t, n in recorded.items()},
    }
    out['loss_accounting'] = (_PROCESSES_LOSS if published is None else
                              'in-process: published counted by the nodes, recorded counted in the bag')
    return out


def print_run_summary(summary: dict[str, Any], out_dir: Path, stream: IO[str]) -> None:
    """Human-readable end of ``folder-line run``."""
    print(f"scene {summary['scene']}: {summary['sim_time_reached_s']:.3f} s of line time in "
          f"{summary['wall_time_s']:.1f} s ({summary['mode']}, rtf {summary['rtf_achieved']:.2f})", file=stream)
    print(f"supervisor: {summary['supervisor_state']}   sheets counted: {summary['sheets_counted']} "
          f"(simulate: {summary['expected_from_simulate']['sheets_counted']})", file=stream)
    print('messages received per topic:', file=stream)
    for topic, n in summary['messages'].items():
        print(f'  {topic:<40} {n}', file=stream)
    if 'bag' in summary:
        lost = summary.get('lost')
        if lost is None:
            print(f"lost messages: unknown ({summary.get('loss_accounting', '')})", file=stream)
        elif any(lost.values()):
            print('lost messages: ' + ', '.join(f'{t} {n}' for t, n in lost.items() if n), file=stream)
        else:
            print('lost messages: 0 on every topic', file=stream)
        print(f"wrote {summary['bag']['path']} ({summary['bag']['segments']} segments)", file=stream)
    print(f'wrote {out_dir / "run.json"}', file=stream)
