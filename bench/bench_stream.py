"""What streaming costs: the streamed line against one window, and a command late in the line against one early.

Run: ``.venv/bin/python bench/bench_stream.py`` (about three minutes; ``--quick``: a tenth of the spans).

1. **Speed.** For each shipped scene the same span (1 h of line time) is computed twice, side by
   side and interleaved, best of seven: as one window (``simulate(scene, D).summary()``, the
   batch model) and streamed in 600 s windows keeping nothing behind them
   (:func:`folder_line.core.line.model.run_summary`, what ``folder-line simulate`` runs). The
   ratio is streamed line seconds per wall second over the batch's; the goal is >= 0.9. A scene
   whose hour takes less than ``MIN_WALL`` is timed over ten hours (the ``layup`` scenes: their
   hour is 70 ms, where a few ms of the machine's noise would be the ratio).
2. **A command's cost.** What a machine node does when a supervisor command lands in the window
   it computed ahead: restore the window's checkpoint under the new commands and compute the
   window again (``ros/nodes/machine.py``). Measured on a node-like stream (a window of
   ``CHUNK`` s, ``KEEP`` s kept behind it) that is 10 s into the line and one that was
   fast-forwarded 10 h in; the goal is that the late one costs no more than the early one.
"""

from __future__ import annotations

import argparse
import platform
import statistics
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from folder_line.config.scenes import list_scenes, load_scene
from folder_line.core.line.model import run_summary, simulate
from folder_line.core.line.scene import Scene
from folder_line.core.line.stream import LineStream
from folder_line.core.mechanisms.drive import Command

CHUNK = 0.25  # the machine nodes' window ahead, s (folder_line.ros.nodes.machine.CHUNK)
KEEP = 1.25  # what they keep behind it, s (machine.KEEP)
FAST_WINDOW = 600.0  # their fast-forward window, s (machine.FAST_WINDOW)
REDOS = 50  # redos timed per stream (their median is reported)
MIN_WALL = 0.3  # s: a scene whose one window takes less is timed over ten times the span


def wall(fn: Callable[[], Any]) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def one_window(scene: Scene, span: float) -> float:
    """Wall s of ``span`` s of ``scene`` as one window."""
    return wall(lambda: simulate(scene, span, sample_rate=0.0).summary())


def speed(scene: Scene, span: float, repeat: int) -> tuple[float, float]:
    """(best wall s of one window, best wall s streamed) for ``span`` s of ``scene``, interleaved."""
    batch, streamed = [], []
    for _ in range(repeat):
        batch.append(wall(lambda: simulate(scene, span, sample_rate=0.0).summary()))
        streamed.append(wall(lambda: run_summary(scene, span)))
    return min(batch), min(streamed)


def node_stream(scene: Scene, t: float) -> LineStream:
    """A machine node's stream at line time ``t``: fast-forwarded as the node does when ``t`` is far, then
    the last 2 s in windows of ``CHUNK`` s, as the node computes them while it publishes."""
    stream = LineStream(scene, keep=KEEP, judge=False)
    while stream.t < t - 2.0:
        stream.advance(min(t - 2.0, max(stream.t, 0.0) + FAST_WINDOW))
    while stream.t < t - CHUNK:
        stream.advance(max(stream.t, 0.0) + CHUNK)
    return stream


def command_cost(scene: Scene, t: float, repeat: int) -> float:
    """Median wall s of redoing the window ahead of ``t`` under a hold effective inside it."""
    stream = node_stream(scene, t)
    start = stream.checkpoint()
    stream.advance(t + CHUNK)
    end = stream.t
    commands = (Command(t + CHUNK / 2, 'hold'),)
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        stream.restore(start, commands)
        stream.advance(end)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument('--quick', action='store_true', help='a tenth of the spans, fewer repeats')
    args = ap.parse_args()
    span = 360.0 if args.quick else 3600.0
    late = 3600.0 if args.quick else 36000.0
    repeat = 1 if args.quick else 7
    print(f'python {platform.python_version()}, numpy {np.__version__}\n')

    print(f'streamed (600 s windows) against one window, at least {span:g} s of line time, best of {repeat}:\n')
    print('| scene | line time, s | one window, s | streamed, s | line s per wall s, streamed / one window |')
    print('|---|---:|---:|---:|---:|')
    worst = np.inf
    for name in list_scenes():
        scene = load_scene(name)
        d = span
        while d < 10 * span and one_window(scene, d) < MIN_WALL:
            d *= 10  # a scene this fast is timed over a longer span: a few ms of noise are not a ratio
        batch, streamed = speed(scene, d, repeat)
        worst = min(worst, batch / streamed)
        print(f'| {name} | {d:g} | {batch:.3f} | {streamed:.3f} | {batch / streamed:.2f} |')
    print(f'\nslowest ratio: {worst:.2f} (goal >= 0.9)\n')

    print(f'a hold landing in the window a node computed ahead (redo {CHUNK:g} s), median of {REDOS}:\n')
    print(f'| scene | at 10 s, ms | at {late:g} s, ms | late / early |')
    print('|---|---:|---:|---:|')
    for name in list_scenes():
        scene = load_scene(name)
        early = command_cost(scene, 10.0, REDOS)
        later = command_cost(scene, late, REDOS)
        print(f'| {name} | {1e3 * early:.1f} | {1e3 * later:.1f} | {later / early:.2f} |')
    print('\ngoal: late / early about 1 (the redo does not depend on how long the line has run)')


if __name__ == '__main__':
    main()
