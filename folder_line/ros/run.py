"""``folder-line run``: start the line's nodes, let it run in lockstep, stop cleanly, report.

In-process (default): ``line_clock`` and the five machine nodes in one process on
one executor (``rclpy.experimental.EventsExecutor``) in a private context, as a
component container would run them. With ``processes=True``: one process per node,
started from the node executables as a launch file would, and stopped with SIGINT;
each child dies with this process (``PR_SET_PDEATHSIG``), so a killed ``run`` leaves
nothing behind. Either way a recorder in this process (``line_recorder``, a lockstep
participant) subscribes to every line topic, hands every message to a
:class:`folder_line.bag.writer.BagWriter` (``<out>/bag/``: rosbag2, MCAP, one file per second
of line time) and compares what arrived with the simulation of the same span (``simulate``, streamed:
:func:`folder_line.core.line.model.run_summary`).

The scene is parsed once: ``run`` merges it with the ``--set`` overrides, validates it and
writes it to ``<out>/scene.yaml``; every node gets that path as its ``scene`` parameter
(what to run and the node parameters: :mod:`folder_line.config.run_config`).

Time is lockstep by default (:mod:`folder_line.ros.lockstep`): sim time advances a
tick only when every participant, the recorder included, has finished the previous
one, so a busy machine slows sim time down and never changes what is published.
``clock='wall'`` paces by the wall clock instead and counts late participants.

The outcome is honest (:func:`folder_line.ros.run_summary.outcome`): the run succeeds
only when the line reached the end of ``duration`` in the state the scene expects
(EXECUTE, as ``simulate`` says) with no participant lost; otherwise one line names the
state, the cause, the cycle and the node, and ``folder-line run`` exits non-zero. SIGTERM
is handled like SIGINT: the bag is closed, ``run.json`` written and every child ended.

Loss accounting: in-process, every node counts what it publishes (``published_counts()``),
so ``run.json`` has ``published`` and ``lost`` (= published - recorded) per topic. With
``processes=True`` the publishers live in other processes: ``published`` and ``lost``
are ``null`` there, and ``loss_accounting`` says so (the lockstep itself guarantees that
every acknowledged message was recorded).
"""

from __future__ import annotations

import contextlib
import ctypes
import json
import os
import shlex
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from subprocess import Popen
from typing import IO, TYPE_CHECKING, Any

import rclpy
from diagnostic_msgs.msg import DiagnosticStatus
from rclpy.clock import Clock
from rclpy.clock_type import ClockType
from rclpy.executors import Executor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.task import Future
from std_msgs.msg import String

from folder_line.bag.statuses import accepted_tunings
from folder_line.bag.writer import BagWriter
from folder_line.config.run_config import BAG_DIR, SCENE_FILE, RunConfig, clock_parameters, node_parameters
from folder_line.config.scenes import InputNames, load_scene, parse_set, write_scene
from folder_line.core.line.margin_text import margin_at
from folder_line.core.line.model import run_summary
from folder_line.core.line.tuning import Tuning
from folder_line.errors import BagError, FolderLineError
from folder_line.files.atomic import write_json_atomic
from folder_line.interfaces import CLOCK_TOPIC, GRANT_TOPIC, KNOWN_PARTICIPANTS, MACHINE_NODES, PARTICIPANTS_TOPIC
from folder_line.progress import LineTimeProgress, logs_above
from folder_line.ros.dds_profile import line_partition, use_line_profile
from folder_line.ros.line_key import KEY_VARIABLE, ensure_key
from folder_line.ros.lockstep import PARTICIPANTS_QOS
from folder_line.ros.lockstep_messages import parse_announcement
from folder_line.ros.nodes import belt_conveyor, crank_drive, feed_transporter, sheet_counter, supervisor
from folder_line.ros.nodes.line_clock import LineClock
from folder_line.ros.nodes.machine import MachineNode
from folder_line.ros.recorder import LINE_TOPICS, LineRecorder
from folder_line.ros.run_summary import BagAccount, ExpectedFromSimulate, RunSummary
from folder_line.ros.runtime import events_executor
from folder_line.ros.strangers import UNKNOWN_NODE

if TYPE_CHECKING:
    from folder_line.core.line.scene import Scene

__all__ = [
    'RunResult',
    'add_machine_nodes',
    'other_line',
    'ros_arg',
    'run_line',
]


_PROCESSES_LOSS = (
    'unavailable with --processes or --external-nodes: the publishers run in other processes and their counts '
    'are not collected'
)


@dataclass
class RunResult:
    """What a run produced: the summary written to ``run.json``, per-topic message counts and, with node
    processes, their exit codes."""

    summary: RunSummary
    counts: dict[str, int] = field(default_factory=dict)
    exit_codes: dict[str, int] = field(default_factory=dict)


def _clear_previous_bag(path: Path) -> None:
    """Remove the bag of a previous run at ``path``; refuse anything that is not one."""
    if not path.exists():
        return
    ours = path.is_dir() and all(
        p.is_file() and (p.name == 'metadata.yaml' or p.suffix in ('.mcap', '.truncated', '.damaged', '.tmp'))
        for p in path.iterdir()
    )
    if not ours:
        msg = f'{path}: exists and is not a bag of a previous run; move it away or choose another --out'
        raise BagError(msg)
    shutil.rmtree(path)


def _end_lost(proc: subprocess.Popen[bytes] | None) -> None:
    """End the process of a participant declared lost, at once: the line goes on without it, and a stopped
    (SIGSTOP) node holds shared-memory locks of Fast DDS that would hang the others' teardown at the end."""
    if proc is not None and proc.poll() is None:
        proc.send_signal(signal.SIGCONT)
        proc.send_signal(signal.SIGINT)


def _published_counts(nodes: Sequence[MachineNode | LineClock]) -> dict[str, int]:
    counts: dict[str, int] = {}
    for node in nodes:
        for topic, n in node.published_counts().items():
            counts[topic] = counts.get(topic, 0) + n
    return counts


def add_machine_nodes(
    cfg: RunConfig,
    context: rclpy.Context,
    executor: Executor,
    *,
    scene_file: str | os.PathLike[str] | None = None,
) -> list[MachineNode]:
    """Build the five machine nodes of :data:`MACHINE_NODES` in ``context`` with the run's parameters
    (:func:`folder_line.config.run_config.node_parameters`: the merged ``scene_file`` if given, else the
    scene and overrides of ``cfg``) and add them to ``executor``; returns them in that order."""
    classes = {
        'crank_drive': crank_drive.CrankDrive,
        'belt_conveyor': belt_conveyor.BeltConveyor,
        'feed_transporter': feed_transporter.FeedTransporter,
        'sheet_counter': sheet_counter.SheetCounter,
        'supervisor': supervisor.Supervisor,
    }
    nodes = []
    for name in MACHINE_NODES:
        overrides = [Parameter(k, value=v) for k, v in node_parameters(cfg, name, scene_file).items()]
        node = classes[name](parameter_overrides=overrides, context=context)
        executor.add_node(node)
        nodes.append(node)
    return nodes


def ros_arg(key: str, value: Any) -> str:
    """``key:=value`` for ``--ros-args -p`` (rcl reads the value as YAML): a float as its ``repr``, a string
    single-quoted, so that a path holding ``': '`` or ``' #'`` stays the string it is."""
    if isinstance(value, str):
        return "{}:='{}'".format(key, value.replace("'", "''"))
    return f'{key}:={value!r}' if isinstance(value, float) else f'{key}:={value}'


def _die_with_parent() -> None:  # pragma: no cover - runs in the child between fork and exec
    """Ask the kernel to SIGTERM this (child) process when its parent dies (Linux ``PR_SET_PDEATHSIG``)."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, signal.SIGTERM, 0, 0, 0)  # PR_SET_PDEATHSIG = 1
    except (OSError, AttributeError):
        pass


#: wall seconds ``run`` looks for another line before it starts its own: DDS discovery between two
#: processes takes 0.1 s, or up to the 3 s announcement period of Fast DDS when the first exchange is
#: missed (measured here: 24 of 62 probes found a running line only after 0.75-3.1 s, none later)
OTHER_LINE_WAIT = 4.0
WATCH = 0.2  # wall s between two looks at the bar, a foreign clock, the bag, lost nodes and signals
_NAME_WAIT = 1.0  # wall s to learn the node of a publisher found (DDS discovery reports its endpoint first)


def other_line(node: Node, executor: Executor, wait: float = OTHER_LINE_WAIT) -> str | None:
    """Another line on this domain, in words, or None: a ``/clock`` or ``/line/participants`` publisher that
    is not ours, seen within ``wait`` s of discovery. For an open line (no partition: every line's
    publishers reach it)."""
    deadline = time.monotonic() + wait
    seen: float | None = None  # when a publisher was first seen: its node's name follows its endpoint
    while True:
        for topic in (CLOCK_TOPIC, PARTICIPANTS_TOPIC):
            infos = node.get_publishers_info_by_topic(topic)
            named = [i for i in infos if i.node_name != UNKNOWN_NODE]
            if named or (infos and seen is not None and time.monotonic() > seen + _NAME_WAIT):
                who = (
                    named[0].node_namespace.rstrip('/') + '/' + named[0].node_name
                    if named
                    else 'a node whose name is not known yet'
                )
                return f'{topic} is already published on ROS_DOMAIN_ID={os.environ.get("ROS_DOMAIN_ID", "0")} by {who}'
            if infos and seen is None:
                seen = time.monotonic()
        if seen is None and time.monotonic() >= deadline:
            return None
        executor.spin_once(timeout_sec=0.05)


def same_key_line(node: Node, executor: Executor, wait: float = OTHER_LINE_WAIT) -> str | None:
    """Another line with this line's key, in words, or None: its ``line_clock``'s announcement on
    ``/line/participants`` (transient-local: a running line's reaches every late joiner), signed with the
    key, heard within ``wait`` s. Lines with other keys are in other partitions: they neither reach this
    one nor are reached by it, so they may run beside it. An announcement not signed with the key (someone
    who learnt the partition) is no line and is ignored."""
    heard: list[str] = []

    def on_announcement(msg: String) -> None:
        with contextlib.suppress(ValueError):
            parse_announcement(msg.data)
            heard.append(PARTICIPANTS_TOPIC)

    sub = node.create_subscription(String, PARTICIPANTS_TOPIC, on_announcement, PARTICIPANTS_QOS)
    deadline = time.monotonic() + wait
    try:
        while not heard and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
    finally:
        node.destroy_subscription(sub)
    if not heard:
        return None
    domain = os.environ.get('ROS_DOMAIN_ID', '0')
    return f'a line with this {KEY_VARIABLE} already publishes {heard[0]} on ROS_DOMAIN_ID={domain}'


def _shell_word(text: str) -> str:
    """``text`` as one shell word, readable: ``"scene:='folder'"`` rather than shlex's ``'scene:='"'"'folder'"'"''``."""
    if "'" in text and not any(c in text for c in '"$`\\!'):
        return f'"{text}"'
    return shlex.quote(text)


def _print_external(cfg: RunConfig, stream: IO[str]) -> None:
    """What to start on each machine's host (``--external-nodes``): the nodes' parameters, as ``ros2 run``."""
    domain = os.environ.get('ROS_DOMAIN_ID', '0')
    key = f'{KEY_VARIABLE}={os.environ[KEY_VARIABLE]} ' if os.environ.get(KEY_VARIABLE) else ''
    print(f'waiting for the machine nodes on ROS_DOMAIN_ID={domain}; start each on its host:', file=stream)
    for name in MACHINE_NODES:
        args = ' '.join(f'-p {_shell_word(ros_arg(k, v))}' for k, v in node_parameters(cfg, name).items())
        print(f'  {key}ros2 run folder_line {name} --ros-args {args}', file=stream)
    stream.flush()


def _line_key(stream: IO[str]) -> tuple[bool, str | None]:
    """This line's key and profile, before the first participant of this process: ``(made here, partition)``
    (partition None: the user's own profiles file, an open line). A key made here is printed for the operators."""
    _, made = ensure_key(os.environ)  # this line's key: its nodes and its operators share it
    use_line_profile()  # before the first participant of this process (and its node processes)
    partition = line_partition()
    made = made and partition is not None
    if made:
        print(
            f"line key (the operators' folder-line hold/tune/monitor and the nodes on other hosts need it): "
            f'{KEY_VARIABLE}={os.environ[KEY_VARIABLE]}',
            file=stream,
        )
    return made, partition


def _refuse_other_line(ctx: rclpy.Context, executor: Executor, made: bool, partition: str | None) -> None:
    """Raise ``FolderLineError`` if another line runs where this one would (a key made here is this line's
    alone; a line with a key given may meet another with the same; an open line meets every open line)."""
    probe = rclpy.create_node('folder_line_run_probe', context=ctx)
    executor.add_node(probe)
    other = None if made else other_line(probe, executor) if partition is None else same_key_line(probe, executor)
    executor.remove_node(probe)
    probe.destroy_node()
    if other is not None:
        cure = (
            'ROS_DOMAIN_ID (e.g. ROS_DOMAIN_ID=17 folder-line run ...)'
            if partition is None
            else f'{KEY_VARIABLE} (unset it, and run makes one)'
        )
        raise FolderLineError(f'another line is running: {other}; stop it, or give this run its own {cure}')


def _open_bag(cfg: RunConfig, scene: Scene, scene_file: Path) -> BagWriter:
    """Make ``cfg.out``, write the merged scene to ``scene_file`` and open the run's bag (a previous run's
    bag is replaced; anything else at its place is refused)."""
    cfg.out.mkdir(parents=True, exist_ok=True)
    bag_path = cfg.out / BAG_DIR
    _clear_previous_bag(bag_path)
    scene_source = write_scene(scene_file, scene)
    return BagWriter(
        bag_path,
        scene_source=scene_source,
        effects=list(scene.effects),
        scene_name=scene.name,
        topics=LINE_TOPICS,
        custom={
            'folder_line.scene_arg': str(cfg.scene),
            'folder_line.overrides': json.dumps(cfg.overrides),
            'folder_line.mode': 'processes' if cfg.processes else 'in-process',
            'folder_line.clock': cfg.clock,
        },
        max_duration_s=cfg.max_bag_duration,
        max_size=cfg.max_bag_size,
    )


def _start_processes(cfg: RunConfig, scene_file: Path, clock_params: Mapping[str, Any]) -> dict[str, Popen[bytes]]:
    """Start one process per node (the machines, then ``line_clock``), each logging to ``<out>/logs/<name>.log``."""
    logs = cfg.out / 'logs'  # each process's stderr
    logs.mkdir(exist_ok=True)
    commands = {
        name: [ros_arg(k, v) for k, v in node_parameters(cfg, name, scene_file).items()] for name in MACHINE_NODES
    }
    commands['line_clock'] = [ros_arg(k, v) for k, v in clock_params.items()]
    procs: dict[str, Popen[bytes]] = {}
    for name, args in commands.items():
        # through the light entry module: a stop while the node imports is a clean exit
        cmd = [sys.executable, '-m', 'folder_line.ros.entry', name, '--ros-args']
        for a in args:
            cmd += ['-p', a]
        # a file, not a pipe nobody reads: a node that logs a lot would block on a full pipe
        with open(logs / f'{name}.log', 'wb') as log:
            procs[name] = subprocess.Popen(
                cmd, env=dict(os.environ), stdout=subprocess.DEVNULL, stderr=log, preexec_fn=_die_with_parent
            )
    return procs


@dataclass
class _LineRun:
    """One run of :func:`run_line` in progress: what its steps share."""

    cfg: RunConfig
    stream: IO[str]
    ctx: rclpy.Context
    executor: Executor
    summary: RunSummary | None = None  # built by finish()
    counts: dict[str, int] = field(default_factory=dict)  # per topic, received by the recorder
    exit_codes: dict[str, int] = field(default_factory=dict)  # per node process
    procs: dict[str, Popen[bytes]] = field(default_factory=dict)
    nodes: list[MachineNode | LineClock] = field(default_factory=list)
    bag: BagWriter | None = None
    recorder: LineRecorder | None = None
    clock: LineClock | None = None
    ended_lost: set[str] = field(default_factory=set)  # lost participants whose process was ended
    interrupted: list[str] = field(default_factory=list)  # the reasons to stop early (a signal, a silent clock)

    def done(self) -> bool:
        """Whether the line's clock has ended (its process, or the in-process ``line_clock``)."""
        if self.clock is None:
            return self.procs['line_clock'].poll() is not None
        return self.clock.done.done()

    def start(self, scene_file: Path) -> None:
        """Start the recorder and the nodes: as processes, in-process, or (``--external-nodes``) the clock only."""
        cfg = self.cfg
        assert self.bag is not None
        self.recorder = LineRecorder(sink=self.bag.write_serialized, context=self.ctx, lost_timeout=cfg.lost_timeout)
        self.executor.add_node(self.recorder)
        clock_params = clock_parameters(cfg, KNOWN_PARTICIPANTS)
        if cfg.processes:
            self.procs.update(_start_processes(cfg, scene_file, clock_params))
            return
        if cfg.external:
            _print_external(cfg, self.stream)
        else:
            self.nodes += add_machine_nodes(cfg, self.ctx, self.executor, scene_file=scene_file)
        overrides = [Parameter(k, value=v) for k, v in clock_params.items()]
        self.clock = LineClock(parameter_overrides=overrides, context=self.ctx)
        self.nodes.append(self.clock)
        self.executor.add_node(self.clock)

    def watch(self, progress: LineTimeProgress, stop: Future[None]) -> None:
        """Every :data:`WATCH` s of wall time: draw the bar, look for what stops the run."""
        recorder = self.recorder
        assert recorder is not None
        progress.show(recorder.sim_time)
        # a foreign /clock changes nothing here: line_clock refuses and names it, the nodes take time
        # only from its grants. A silent clock that also left the graph will not come back
        if recorder.lockstep.clock_silent and recorder.count_publishers(GRANT_TOPIC) == 0:
            self.interrupted.append(f'line_clock silent for {recorder.lockstep.clock_silent:.1f} s and gone')
        if recorder.write_error is not None:
            self.interrupted.append('the bag could not be written')
        for name in set(recorder.lost) - self.ended_lost:  # once each
            self.ended_lost.add(name)
            _end_lost(self.procs.get(name))
        if (self.done() or self.interrupted) and not stop.done():
            stop.set_result(None)

    def spin(self) -> None:
        """Spin until the line ends or is stopped, then drain what its last tick still carries."""
        recorder = self.recorder
        assert recorder is not None
        progress = LineTimeProgress(self.stream, self.cfg.duration)
        stop: Future[None] = Future()  # the run's end: the clock done, or a reason to stop in ``interrupted``
        # a timer, not a spin's timeout: rclpy's EventsExecutor did not return from
        # spin_until_future_complete(timeout_sec=0.2) for a whole 30 s run of this line (and without a
        # timeout it ran no callback at all)
        watcher = recorder.create_timer(
            WATCH, lambda: self.watch(progress, stop), clock=Clock(clock_type=ClockType.STEADY_TIME)
        )
        with logs_above(progress):  # the nodes' log lines (rcutils, fd 2) above the bar, never through it
            while not (stop.done() or self.done() or self.interrupted):
                self.executor.spin_until_future_complete(stop, timeout_sec=WATCH)
            recorder.destroy_timer(watcher)
            if self.interrupted and self.clock is not None:
                self.executor.remove_node(self.clock)  # sim time stops: nothing more is published while draining
            # in lockstep every acknowledged message is recorded by now; drain what the last tick still carries
            deadline = time.perf_counter() + (1.0 if self.interrupted or self.cfg.clock == 'wall' else 0.2)
            while time.perf_counter() < deadline:
                self.executor.spin_once(timeout_sec=0.02)
            progress.show(recorder.sim_time, force=True)
            progress.close()

    def finish(self, scene: Scene, wall_s: float, partition: str | None) -> None:
        """Close the bag and build the run's summary (a bag write error is raised: the bag stays partial)."""
        recorder, bag, clock = self.recorder, self.bag, self.clock
        assert recorder is not None and bag is not None
        recorder.flush()
        if recorder.write_error is not None:  # the bag stays as far as it got, marked partial (repairable)
            raise recorder.write_error
        self.counts = dict(recorder.counts)
        published = None if self.cfg.processes or self.cfg.external else _published_counts(self.nodes)
        bag.close(published)
        lost = dict(recorder.lost)
        if clock is not None:
            lost.update({n: t for n, t in clock.lost.items() if n not in lost})
        rtf = None if clock is None else clock.rtf_achieved
        summary = _summary(self.cfg, scene, recorder, wall_s, self.interrupted, lost, rtf)
        # partition None: an open line (the user's own profiles file)
        self.summary = replace(summary, bag=_bag_account(bag, published, recorder.unrecorded), partition=partition)

    def end_processes(self) -> None:
        """Let the node processes end by themselves after a normal end (a lost one is ended at once), stop
        the rest with SIGINT, and collect every exit code (a process still there after 15 s is killed)."""
        procs = self.procs
        if procs and not self.interrupted and procs['line_clock'].poll() is not None:
            # the line ended: every node ends by itself after the announced last tick; a SIGINT while it is
            # ending would find the default handler back and kill it (exit -2, a KeyboardInterrupt traceback)
            lost_nodes = set(self.summary.lost_participants if self.summary is not None else ())
            for name in (lost_nodes & set(procs)) - self.ended_lost:  # a stopped node holds shared-memory locks
                _end_lost(procs[name])
            deadline = time.monotonic() + 15.0
            for name, proc in procs.items():
                if name not in lost_nodes:
                    with contextlib.suppress(subprocess.TimeoutExpired):
                        proc.wait(timeout=max(deadline - time.monotonic(), 0.0))
        for proc in procs.values():
            if proc.poll() is None:
                proc.send_signal(signal.SIGINT)
                proc.send_signal(signal.SIGCONT)  # a stopped child (SIGSTOP, Ctrl-Z) ends now, not in 15 s
        for name, proc in procs.items():
            try:
                proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
            self.exit_codes[name] = proc.returncode

    def tear_down(self) -> None:
        """End the processes, the executor, the bag (if an error left it open) and the nodes."""
        self.end_processes()
        self.executor.shutdown()
        if self.bag is not None and (self.recorder is None or self.recorder.write_error is None):
            self.bag.close()  # no-op after a normal end; after an error, finishes what was recorded
        for node in self.nodes:
            node.destroy_node()
        self.ctx.try_shutdown()


def run_line(cfg: RunConfig, stream: IO[str] = sys.stdout, names: InputNames | None = None) -> RunResult:
    """Run the line for ``cfg.duration`` s of sim time; record ``<out>/bag/``; write ``run.json`` to ``cfg.out``.

    The scene is parsed once, here: merged with the overrides, it is written to ``<out>/scene.yaml``
    (:data:`folder_line.config.run_config.SCENE_FILE`) and every node loads that file; in-process
    the nodes share the scene parsed here (:func:`folder_line.config.scenes.shared_scene`), with
    ``--processes`` each node process parses the file once. ``names`` says how the errors name
    the scene and the overrides (the command line: ``--scene``, ``--set``; default their plain names).

    Raises
    ------
    folder_line.errors.FolderLineError
        Bad scene or overrides, an ``--out`` that holds something else, or another line on this
        ROS domain (checked before anything is written).
    """
    names = names or InputNames()
    scene = load_scene(cfg.scene, parse_set(cfg.overrides, names), names=names)  # fail early, before any node
    made, partition = _line_key(stream)
    ctx = rclpy.Context()
    rclpy.init(context=ctx, signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
    run = _LineRun(cfg, stream, ctx, events_executor(ctx))

    def on_signal(signum: int, frame: object) -> None:
        run.interrupted.append(signal.Signals(signum).name)

    previous = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    t_wall = time.perf_counter()
    try:
        _refuse_other_line(ctx, run.executor, made, partition)
        scene_file = (cfg.out / SCENE_FILE).absolute()  # the nodes' processes may not share our cwd
        run.bag = _open_bag(cfg, scene, scene_file)
        run.start(scene_file)
        run.spin()
        run.finish(scene, time.perf_counter() - t_wall, partition)
    finally:
        run.tear_down()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    summary = run.summary
    assert summary is not None  # finish() built it or raised
    if run.procs:
        lost = summary.lost_participants
        if run.exit_codes.get('line_clock') not in (0, None) and not lost:
            lost = {'line_clock': summary.sim_time_reached_s}
        summary = replace(summary, lost_participants=lost, exit_codes=run.exit_codes)
    write_json_atomic(cfg.out / 'run.json', summary.as_json())
    return RunResult(summary, run.counts, run.exit_codes)


def _tunings(statuses: Iterable[DiagnosticStatus]) -> list[Tuning]:
    """The tunings the supervisor accepted, from its ``folder_line/supervisor/tuning`` statuses, by effective time."""
    recorded = accepted_tunings((st.name, {kv.key: kv.value for kv in st.values}) for st in statuses)
    return sorted((Tuning(effective, key, value) for _, key, value, effective in recorded), key=lambda tu: tu.t)


def _where(constraint: str, cycle: str | None) -> str:
    """``cycle k`` or ``leaf k`` (:func:`folder_line.core.line.margin_text.margin_at`) from a status value."""
    try:
        return margin_at(constraint, int(cycle or ''))
    except ValueError:
        return f'cycle {cycle}'


def _summary(
    cfg: RunConfig,
    scene: Scene,
    recorder: LineRecorder,
    wall: float,
    interrupted: list[str],
    lost: dict[str, float],
    rtf: float | None,
) -> RunSummary:
    """The run's summary, without its bag (``rtf``: the clock's achieved real-time factor, if it ran here)."""
    tunings = _tunings(recorder.diagnostics)  # the operator's changes: simulate runs them too
    span = min(recorder.sim_time, cfg.duration) or cfg.duration
    # streamed: the expected figures of a long run take no more memory than a short one's
    expected = run_summary(scene, span, commands=[tu for tu in tunings if tu.t <= span])
    cause = None
    for st in recorder.diagnostics:  # the first violation that changed the state, with its cycle and node
        values = {kv.key: kv.value for kv in st.values}
        if st.name == 'folder_line/supervisor/violation' and values.get('action') not in (None, 'none'):
            constraint = values.get('constraint', '')
            node = constraint.split(':', 1)[1] if constraint.startswith('lost:') else None
            where = _where(constraint, values.get('cycle'))
            cause = f'{constraint} in {where} at {float(values.get("t", "nan")):.6f} s -> {values.get("action")}' + (
                f' (node {node})' if node else ''
            )
            break
    return RunSummary(
        scene=scene.name,
        duration_s=cfg.duration,
        sim_time_reached_s=recorder.sim_time,
        wall_time_s=wall,
        rtf_requested=cfg.rtf if cfg.rtf > 0 else 'max',
        rtf_achieved=rtf if rtf is not None else recorder.rtf_achieved(),
        mode='processes' if cfg.processes else 'in-process',
        clock=cfg.clock,
        interrupted=', '.join(interrupted) if interrupted else None,
        lost_participants=lost,
        cause=cause,
        messages=dict(sorted(recorder.counts.items())),
        events_received=dict(sorted(recorder.event_counts.items())),
        sheets_counted=recorder.sheet_count,
        supervisor_state=recorder.state,
        tunings=tuple(tunings),
        expected_from_simulate=ExpectedFromSimulate(
            sheets_counted=expected.sheets_counted,
            events=expected.events,
            violations=expected.violations.count,
        ),
    )


def _bag_account(bag: BagWriter, published: dict[str, int] | None, unrecorded: Mapping[str, int]) -> BagAccount:
    """The closed bag's account (``published`` None: the publishers' counts are not known here; ``unrecorded``:
    per topic, messages of ticks after the last one recorded, a stopped line's, not lost)."""
    recorded = dict(sorted(bag.counts.items()))
    after = {t: n for t, n in sorted(unrecorded.items()) if n}
    return BagAccount(
        path=str(bag.path),
        files=len(bag.files),
        messages=recorded,
        published=None if published is None else {t: published.get(t, 0) for t in recorded},
        lost=None if published is None else {t: published.get(t, 0) - n - after.get(t, 0) for t, n in recorded.items()},
        after_last_tick=after,
        loss_accounting=_PROCESSES_LOSS
        if published is None
        else 'in-process: published counted by the nodes, recorded counted in the bag',
    )
