"""``folder-line run``: start the line's nodes, let it run, stop cleanly, report.

In-process (default): ``line_clock`` and the five machine nodes in one process on
one executor in a private context, as a component container would run them.
With ``processes=True``: one process per node, started from the node executables
as a launch file would, and stopped with SIGINT. Either way a recorder in this
process subscribes to every line topic, counts what arrives and compares it with
what the batch simulation (``simulate``) of the same scene says.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any, Callable

from folder_line.atomic import write_json_atomic

__all__ = ['LINE_NODES', 'RunConfig', 'RunResult', 'print_run_summary', 'run_line']

#: the nodes of the line, in start order (the clock last, so nobody misses t = 0)
LINE_NODES: tuple[str, ...] = ('crank_drive', 'belt_conveyor', 'feed_transporter', 'sheet_counter', 'supervisor')


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


def run_line(cfg: RunConfig, stream: IO[str] = sys.stdout) -> RunResult:
    """Run the line for ``cfg.duration`` s of sim time; write ``run.json`` to ``cfg.out``."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    from folder_line.nodes.line_clock import LineClock
    from folder_line.recorder import LineRecorder
    from folder_line.scenes import load_scene, parse_set

    scene = load_scene(cfg.scene, parse_set(cfg.overrides))  # fail early, before any node starts
    cfg.out.mkdir(parents=True, exist_ok=True)
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
        recorder = LineRecorder(context=ctx)
        executor.add_node(recorder)
        if cfg.processes:
            env = dict(os.environ)
            for name in LINE_NODES:
                args = [f'{k}:={v}' for k, v in _node_parameters(cfg, name).items()]
                cmd = [sys.executable, '-m', f'folder_line.nodes.{name}', '--ros-args']
                for a in args:
                    cmd += ['-p', a]
                procs[name] = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
            recorder.wait_for_publishers(len(LINE_NODES), executor, timeout=30.0)
            clock_cmd = [sys.executable, '-m', 'folder_line.nodes.line_clock', '--ros-args',
                         '-p', f'duration:={cfg.duration}', '-p', f'rtf:={cfg.rtf}']
            procs['line_clock'] = subprocess.Popen(clock_cmd, env=env, stdout=subprocess.DEVNULL,
                                                   stderr=subprocess.PIPE)
            done: Callable[[], bool] = lambda: procs['line_clock'].poll() is not None  # noqa: E731
        else:
            from folder_line.nodes import belt_conveyor, crank_drive, feed_transporter, sheet_counter, supervisor

            classes = {'crank_drive': crank_drive.CrankDrive, 'belt_conveyor': belt_conveyor.BeltConveyor,
                       'feed_transporter': feed_transporter.FeedTransporter,
                       'sheet_counter': sheet_counter.SheetCounter, 'supervisor': supervisor.Supervisor}
            for name in LINE_NODES:
                overrides = [Parameter(k, value=v) for k, v in _node_parameters(cfg, name).items()]
                node = classes[name](parameter_overrides=overrides, context=ctx)
                nodes.append(node)
                executor.add_node(node)
            clock = LineClock(parameter_overrides=[Parameter('duration', value=float(cfg.duration)),
                                                   Parameter('rtf', value=float(cfg.rtf))], context=ctx)
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
        # let the last messages arrive
        deadline = time.perf_counter() + 1.0
        while time.perf_counter() < deadline:
            executor.spin_once(timeout_sec=0.05)
        progress.show(recorder.sim_time)
        progress.close()
        result.counts = dict(recorder.counts)
        result.summary = _summary(cfg, scene, recorder, time.perf_counter() - t_wall, interrupted)
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


def print_run_summary(summary: dict[str, Any], out_dir: Path, stream: IO[str]) -> None:
    """Human-readable end of ``folder-line run``."""
    print(f"scene {summary['scene']}: {summary['sim_time_reached_s']:.3f} s of line time in "
          f"{summary['wall_time_s']:.1f} s ({summary['mode']}, rtf {summary['rtf_achieved']:.2f})", file=stream)
    print(f"supervisor: {summary['supervisor_state']}   sheets counted: {summary['sheets_counted']} "
          f"(simulate: {summary['expected_from_simulate']['sheets_counted']})", file=stream)
    print('messages received per topic:', file=stream)
    for topic, n in summary['messages'].items():
        print(f'  {topic:<40} {n}', file=stream)
    print(f'wrote {out_dir / "run.json"}', file=stream)
