"""Animations of the line (``folder-line animate``, ``analyze --animate``): the machine seen from the side, frame
by frame, with the line time, the machine cycle, the PackML state and the violations written on it, encoded to
``.mp4`` or ``.gif`` with the ffmpeg of ``imageio-ffmpeg``.

The modules, in the order the data flows:

:mod:`~folder_line.analysis.animation.timeline`
    the time scale (which line time each frame shows, the frame count) and the overlays' text;
:mod:`~folder_line.analysis.animation.runs`
    what is shown: the batch model with the supervisor in the loop, or a recorded run;
:mod:`~folder_line.analysis.animation.frames`
    one frame drawn with matplotlib from the core's scenery (:mod:`folder_line.core.line.scenery`);
:mod:`~folder_line.analysis.animation.encode`
    frames streamed to ffmpeg, the file written beside its target and renamed into place;
:mod:`~folder_line.analysis.animation.render`
    :func:`render`: every frame drawn and encoded.
"""

from folder_line.analysis.animation.encode import FORMATS, check_video_target, parse_size, video_writer
from folder_line.analysis.animation.frames import Extent, FrameDrawer, SceneryLike, ShapeLike, extent
from folder_line.analysis.animation.render import Animation, render
from folder_line.analysis.animation.runs import AnimatedRun, batch_run, recorded_run, scale_note
from folder_line.analysis.animation.timeline import (
    DEFAULT_FPS,
    DEFAULT_SLOWDOWN,
    FPS,
    MAX_FRAMES,
    SLOWDOWN,
    Flag,
    OverlayText,
    Timeline,
    TimeScale,
    frame_count,
)

__all__ = [
    'DEFAULT_FPS',
    'DEFAULT_SLOWDOWN',
    'FORMATS',
    'FPS',
    'MAX_FRAMES',
    'SLOWDOWN',
    'AnimatedRun',
    'Animation',
    'Extent',
    'Flag',
    'FrameDrawer',
    'OverlayText',
    'SceneryLike',
    'ShapeLike',
    'TimeScale',
    'Timeline',
    'batch_run',
    'check_video_target',
    'extent',
    'frame_count',
    'parse_size',
    'recorded_run',
    'render',
    'scale_note',
    'video_writer',
]
