"""An animation drawn frame by frame and streamed to the encoder: :func:`render`."""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from folder_line.analysis.animation.encode import PALETTE_FRAMES, video_writer
from folder_line.analysis.animation.frames import FrameDrawer, SceneryLike, extent
from folder_line.analysis.animation.timeline import Timeline, TimeScale

__all__ = ['EXTENT_SAMPLES', 'EXTENT_SPAN', 'Animation', 'render']

#: line times at which the shapes are looked at to fix the axes
EXTENT_SAMPLES = 240
#: the axes cover what the machine does over at least this much line time from the first frame, s
#: (a crank turn of the layup at its 30 rev/min: both chutes at both swing extremes)
EXTENT_SPAN = 2.0


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


def render(
    scenery: SceneryLike,
    timeline: Timeline,
    scale: TimeScale,
    out: str | os.PathLike[str],
    option: str,
    size: tuple[int, int],
    *,
    title: str,
    note: str,
    horizon: float,
    progress: Callable[[float], None] | None = None,
) -> Animation:
    """Draw every frame of ``scale`` and encode it to ``out`` (``.mp4`` or ``.gif``).

    Parameters
    ----------
    scenery : SceneryLike
        The machine's shapes at any line time.
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
    horizon : float
        The model's end, s: the axes cover up to :data:`EXTENT_SPAN` s from the first frame where the
        model reaches.
    progress : callable, optional
        Called with the line time drawn so far since the first frame, s.

    Returns
    -------
    Animation
    """
    t0 = time.perf_counter()
    n = scale.frames
    span_end = min(horizon, max(scale.t_end, scale.t_from + EXTENT_SPAN))
    ext = extent(scenery, np.linspace(scale.t_from, span_end, EXTENT_SAMPLES))
    drawer = FrameDrawer(ext, size, title, note)

    def palette_frames() -> Iterator[np.ndarray]:  # a GIF's palette: frames spread over the film
        for i in np.unique(np.linspace(0, n - 1, PALETTE_FRAMES).round().astype(int)):
            t = scale.time(int(i))
            yield drawer.draw(scenery.at(t), timeline.text(t))

    try:
        with video_writer(out, option, size, scale.fps, palette_frames) as writer:
            for i in range(n):
                t = scale.time(i)
                writer.write(drawer.draw(scenery.at(t), timeline.text(t)))
                if progress is not None:
                    progress(t - scale.t_from)
    finally:
        drawer.close()
    return Animation(Path(out), n, n / scale.fps, time.perf_counter() - t0, size)
