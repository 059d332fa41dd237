"""Benchmark of ``simulate --bag`` against its floor.

``python bench/bench_bag.py [SECONDS] [SCENE] [--repeat N] [--parts]``

Measures, in one run (default one hour of the ``folder`` scene at 200 Hz):

* ``folder-line simulate --scene SCENE --duration SECONDS --bag DIR`` as a process: wall
  time, CPU time (user + system) and peak RSS (the batch model, the supervisor's logic and
  the writing, markers at the default rate, everything);
* the floor: the ``rosbags`` writer (``rosbags.rosbag2.Writer``, MCAP storage) serialising the
  same messages (``Typestore.serialize_cdr``) and writing them, no model. The messages are
  read back from the bag just written and deserialized, a batch at a time, outside the
  timing; only serialize + write (and the writer's close) are timed (wall and CPU).
* with ``--parts``: the same ``write_batch_bag`` as a process with nothing written (its
  per-window writing replaced by nothing): the streamed line and the supervisor's logic
  alone, the part of ``simulate --bag`` that is not the bag's.

``--repeat N`` measures each N times, alternately, and keeps the fastest of each (on a
shared machine the slowest runs say more about the other processes than about the code).
Prints the times, their ratio (wall and CPU) against the goal (at most :data:`GOAL` x the
floor), the messages per second and the load average before and after. Everything is
written under a temporary folder that is removed at the end.
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from rosbags.rosbag2 import Reader, StoragePlugin, Writer

from folder_line.bag.types import typestore

REPO = Path(__file__).resolve().parent.parent
BATCH = 20_000  # messages deserialized (untimed) before they are serialized and written (timed)
#: the goal: ``simulate --bag`` at most this many times the floor measured in the same run
GOAL = 1.2


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _child(cmd: list[str]) -> tuple[float, float]:
    """Wall and CPU time (s) of ``cmd`` run as a child process from the repository."""
    env = {**os.environ, 'PYTHONPATH': str(REPO)}
    cpu0 = _children_cpu()
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, cwd=REPO, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f'{" ".join(cmd[1:4])} ... failed ({proc.returncode}):\n{proc.stderr}')
    return wall, _children_cpu() - cpu0


def simulate_bag(seconds: float, scene: str, out: Path) -> tuple[float, float]:
    """Wall and CPU time (s) of ``folder-line simulate --bag`` as a child process."""
    cmd = [sys.executable, '-m', 'folder_line.cli.main', 'simulate', '--scene', scene]
    return _child([*cmd, '--duration', f'{seconds:g}', '--bag', str(out)])


def without_writing(seconds: float, scene: str, out: Path) -> tuple[float, float]:
    """Wall and CPU time (s) of ``write_batch_bag`` with nothing written, as a child process."""
    return _child([sys.executable, __file__, '--no-writing', f'{seconds:g}', scene, str(out)])


def _no_writing(seconds: float, scene: str, out: Path) -> None:
    """``write_batch_bag`` of ``scene`` with its per-window writing (``WindowWriter.write``) doing nothing."""
    from folder_line.bag import batch
    from folder_line.config.scenes import load_scene

    batch.WindowWriter.write = lambda self, stamps, events, ticks: None  # type: ignore[method-assign]
    batch.write_batch_bag(out, load_scene(scene), seconds)


def floor(bag: Path, out: Path) -> tuple[float, float, int]:
    """Wall and CPU seconds the rosbags writer takes to serialize and write every message of ``bag``;
    and their number."""
    store = typestore()
    timed = 0.0
    cpu = 0.0
    n = 0
    with Reader(bag) as reader:
        writer = Writer(out, version=9, storage_plugin=StoragePlugin.MCAP)
        writer.open()
        conns: dict[int, Any] = {}
        t0, c0 = time.perf_counter(), time.process_time()
        for c in reader.connections:
            conns[c.id] = writer.add_connection(c.topic, c.msgtype, typestore=store)
        timed += time.perf_counter() - t0
        cpu += time.process_time() - c0
        batch: list[tuple[Any, int, Any, str]] = []

        def write_batch() -> tuple[float, float]:
            t, c = time.perf_counter(), time.process_time()
            for conn, stamp, msg, msgtype in batch:
                writer.write(conn, stamp, store.serialize_cdr(msg, msgtype))
            batch.clear()
            return time.perf_counter() - t, time.process_time() - c

        for conn, stamp, raw in reader.messages():
            batch.append((conns[conn.id], stamp, store.deserialize_cdr(raw, conn.msgtype), conn.msgtype))
            n += 1
            if len(batch) >= BATCH:
                dw, dc = write_batch()
                timed, cpu = timed + dw, cpu + dc
        dw, dc = write_batch()
        timed, cpu = timed + dw, cpu + dc
        t0, c0 = time.perf_counter(), time.process_time()
        writer.close()
        timed += time.perf_counter() - t0
        cpu += time.process_time() - c0
    return timed, cpu, n


def _load() -> str:
    return '/'.join(f'{x:.1f}' for x in os.getloadavg())


def main(argv: list[str]) -> None:
    if argv[:1] == ['--no-writing']:
        _no_writing(float(argv[1]), argv[2], Path(argv[3]))
        return
    parser = argparse.ArgumentParser(description='Benchmark of simulate --bag against its floor.')
    parser.add_argument('seconds', nargs='?', type=float, default=3600.0)
    parser.add_argument('scene', nargs='?', default='folder')
    parser.add_argument('--repeat', type=int, default=1, help='measure each N times, keep the fastest')
    parser.add_argument('--parts', action='store_true', help='also time the line and supervisor alone')
    args = parser.parse_args(argv)
    load_before = _load()
    ours: list[tuple[float, float]] = []
    base: list[tuple[float, float]] = []
    alone: list[tuple[float, float]] = []
    peak = 0.0
    with tempfile.TemporaryDirectory(prefix='bench_bag_') as tmp:
        for r in range(args.repeat):
            bag = Path(tmp) / f'batch{r}'
            ours.append(simulate_bag(args.seconds, args.scene, bag))
            if r == 0:
                peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
                size = sum(p.stat().st_size for p in bag.iterdir()) / 2**20
            wall, cpu, n = floor(bag, Path(tmp) / f'floor{r}')
            base.append((wall, cpu))
            if args.parts:
                alone.append(without_writing(args.seconds, args.scene, Path(tmp) / f'alone{r}'))
            if r:
                for p in (bag, Path(tmp) / f'floor{r}'):
                    for f in p.iterdir():
                        f.unlink()
    _print_table(args, load_before, ours, base, alone, peak, size, n)


def _print_table(
    args: argparse.Namespace,
    load_before: str,
    ours: list[tuple[float, float]],
    base: list[tuple[float, float]],
    alone: list[tuple[float, float]],
    peak: float,
    size: float,
    n: int,
) -> None:
    """The benchmark's table: the fastest of each (wall s, CPU s) and their ratio to the goal."""
    (o_wall, o_cpu), (b_wall, b_cpu) = (
        (min(x[0] for x in ours), min(x[1] for x in ours)),
        (
            min(x[0] for x in base),
            min(x[1] for x in base),
        ),
    )
    runs = f', fastest of {args.repeat} runs' if args.repeat > 1 else ''
    print(f'{args.seconds:g} s of {args.scene} at 200 Hz: {n} messages, bag {size:.0f} MiB{runs}')
    print(f'load average (1/5/15 min) before {load_before}, after {_load()}; {os.cpu_count()} CPUs')
    print('| what | wall s | CPU s | messages/s (wall) |')
    print('|---|---:|---:|---:|')
    print(
        f'| `simulate --bag` (model, supervisor, markers, writing; peak RSS {peak:.0f} MiB) '
        f'| {o_wall:.1f} | {o_cpu:.1f} | {n / o_wall:,.0f} |'
    )
    print(f'| floor: rosbags writer, serialize + write only | {b_wall:.1f} | {b_cpu:.1f} | {n / b_wall:,.0f} |')
    if alone:
        a_wall, a_cpu = min(x[0] for x in alone), min(x[1] for x in alone)
        print(f'| of `simulate --bag`: streamed line + supervisor, nothing written | {a_wall:.1f} | {a_cpu:.1f} | |')
    if args.repeat > 1:
        for name, xs in (('simulate --bag', ours), ('floor', base), ('nothing written', alone)):
            if xs:
                print(f'runs of {name}, wall/CPU s: ' + ', '.join(f'{w:.1f}/{c:.1f}' for w, c in xs))
    print(f'ratio simulate --bag / floor: wall {o_wall / b_wall:.2f}, CPU {o_cpu / b_cpu:.2f} (goal: at most {GOAL:g})')


if __name__ == '__main__':
    main(sys.argv[1:])
