"""An animation drawn frame by frame from the streamed line and streamed to the encoder: :func:`render`.

The line is a :class:`~folder_line.core.line.stream.LineStream`: it is fast-forwarded to the first
frame's time in windows of :data:`~folder_line.core.line.model.WINDOW` s, keeping nothing (:func:`fast_forward`), then
advanced window by window (:data:`FRAME_WINDOW` s of line time at most) as the frames are drawn, each
frame from the scenery of the window that holds its time (:func:`sceneries`). Its state at the first
frame is kept (a checkpoint) and gone back to for each pass over the frames' span: one to fix the
axes (:data:`EXTENT_SAMPLES` looks over :data:`EXTENT_SPAN` s), one for a GIF's palette, one for the
frames. A frame at line time t is therefore the same whatever the first frame's time and the windows
(the stream's results do not depend on where its windows are cut), and the memory does not grow
with the line time animated or skipped.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from folder_line.analysis.animation.encode import PALETTE_FRAMES, video_writer
from folder_line.analysis.animation.frames import FrameDrawer, extent
from folder_line.analysis.animation.timeline import Timeline, TimeScale
from folder_line.core.line.model import WINDOW as FAST_FORWARD
from folder_line.core.line.scenery import Scenery, Shape
from folder_line.core.line.stream import LineStream

__all__ = [
    'EXTENT_SAMPLES',
    'EXTENT_SPAN',
    'FRAME_WINDOW',
    'Animation',
    'fast_forward',
    'render',
    'sceneries',
]

#: line times at which the shapes are looked at to fix the axes
EXTENT_SAMPLES = 240
#: the axes cover what the machine does over at least this much line time from the first frame, s
#: (a crank turn of the layup at its 30 rev/min: both chutes at both swing extremes)
EXTENT_SPAN = 2.0
#: line time per window of the stream while frames are drawn, s
FRAME_WINDOW = 1.0


@dataclass(frozen=True)
class Animation:
    """What :func:`render` wrote.

    Attributes
    ----------
    path : Path
        The file.
    frames : int
        Frames written.
    video_s : float
        Length of the video, s (frames / fps).
    wall_s : float
        Wall time to draw and encode, s.
    size : (int, int)
        Width, height, px.
    """

    path: Path
    frames: int
    video_s: float
    wall_s: float
    size: tuple[int, int]


def fast_forward(line: LineStream, t: float, window: float = FAST_FORWARD) -> None:
    """Advance ``line`` to line time ``t`` (s) in windows of ``window`` s, keeping nothing of them (nothing if
    it is there already)."""
    if not (math.isfinite(window) and window > 0.0):
        raise ValueError(f'fast_forward: window must be a positive number of seconds, got {window!r}')
    k = 1 if not math.isfinite(line.t) else math.floor(line.t / window) + 1
    while line.t < t:
        line.advance(min(t, k * window))
        k += 1


def sceneries(
    line: LineStream, times: Iterable[float], window: float = FRAME_WINDOW
) -> Iterator[tuple[float, Scenery]]:
    """``(t, scenery)`` for each line time of ``times`` (ascending, none before the line's last window): the
    line advanced to a window holding ``t`` (at most ``window`` s past it), the scenery of that window.

    One :class:`~folder_line.core.line.scenery.Scenery` is drawn from for as long as the line is not
    gone back (its ``at(t)`` is valid until the next advance).
    """
    scenery = Scenery(line)
    for t in times:
        t = float(t)
        if t > line.t:
            line.advance(t + window)
        yield t, scenery


def render(
    line: LineStream,
    timeline: Timeline,
    scale: TimeScale,
    out: str | os.PathLike[str],
    option: str,
    size: tuple[int, int],
    *,
    title: str,
    note: str,
    until: float = math.inf,
    progress: Callable[[float], None] | None = None,
) -> Animation:
    """Draw every frame of ``scale`` from the streamed ``line`` and encode it to ``out`` (``.mp4`` or ``.gif``).

    Parameters
    ----------
    line : LineStream
        The line under the run's commands, not advanced past the first frame's time (it is fast-forwarded
        there, then advanced as the frames are drawn).
    timeline : Timeline
        The overlays.
    scale : TimeScale
        The frames' line times (checked: 1 to MAX_FRAMES frames).
    out : path-like
        The file; ``option`` names it in errors.
    size : (int, int)
        Frame width and height, px (even).
    title, note : str
        The header: what is shown, and the time scale in words.
    until : float
        Line time the line is known to, s: the axes cover up to :data:`EXTENT_SPAN` s from the first frame,
        up to there.
    progress : callable, optional
        Called with the line time drawn so far since the first frame, s.

    Returns
    -------
    Animation

    Raises
    ------
    ValueError
        ``line`` was advanced past the first frame's time.
    OutputError
        The target is refused or cannot be written (:func:`~folder_line.analysis.animation.encode.video_writer`).
    """
    if line.t > scale.t_from:
        raise ValueError(f'render: the line is at {line.t!r} s, past the first frame ({scale.t_from!r} s)')
    t0 = time.perf_counter()
    n = scale.frames
    fast_forward(line, scale.t_from)
    start = line.checkpoint()
    span_end = min(until, max(scale.t_end, scale.t_from + EXTENT_SPAN))
    looks = np.linspace(scale.t_from, max(span_end, scale.t_from), EXTENT_SAMPLES)
    ext = extent(_Looks(line, looks), looks)
    drawer = FrameDrawer(ext, size, title, note)

    def frames(times: Iterable[float]) -> Iterator[tuple[float, np.ndarray]]:
        line.restore(start)
        for t, scenery in sceneries(line, times):
            yield t, drawer.draw(scenery.at(t), timeline.text(t))

    def palette_frames() -> Iterator[np.ndarray]:  # a GIF's palette: frames spread over the film
        chosen = np.unique(np.linspace(0, n - 1, PALETTE_FRAMES).round().astype(int))
        for _, frame in frames(scale.time(int(i)) for i in chosen):
            yield frame

    try:
        with video_writer(out, option, size, scale.fps, palette_frames) as writer:
            for t, frame in frames(scale.time(i) for i in range(n)):
                writer.write(frame)
                if progress is not None:
                    progress(t - scale.t_from)
    finally:
        drawer.close()
    return Animation(Path(out), n, n / scale.fps, time.perf_counter() - t0, size)


class _Looks:
    """The shapes at the times the axes are fixed from, in order: a scenery-like view of the streamed line
    advanced as it is asked (:func:`~folder_line.analysis.animation.frames.extent` asks each time once, in
    order)."""

    def __init__(self, line: LineStream, times: np.ndarray) -> None:
        self._it = sceneries(line, times)

    def at(self, t: float) -> tuple[Shape, ...]:
        shown, scenery = next(self._it)
        if shown != float(t):
            raise ValueError(f'the axes are fixed from the times in order: asked {t!r}, at {shown!r}')
        return scenery.at(shown)
