"""An animation's time scale and what each frame says: the line times of the frames, and the overlays.

Time scale
----------
The knife cycle is 72 ms, so the line at real time is a blur at any video frame rate. A video
therefore runs slower than the line: ``slowdown`` video seconds per line second (default
:data:`DEFAULT_SLOWDOWN`, 10: a knife cycle lasts 0.72 s on screen), at ``fps`` video frames per
second (default :data:`DEFAULT_FPS`). Frame ``i`` shows line time

    t_i = t_from + i dt,   dt = 1 / (fps x slowdown),   i = 0 .. N - 1,
    N = floor(duration x fps x slowdown)    (at least 1, at most :data:`MAX_FRAMES`),

so the video lasts ``N / fps`` = ``duration x slowdown`` s (:class:`TimeScale`). A slowdown
below 1 speeds the line up (0.1: ten line seconds per video second).

Overlays
--------
:class:`Timeline` gives the text of the frame at line time ``t`` (:class:`OverlayText`): the line
time (ms resolution), the machine cycle running (the folder's knife cycle, or without the folder
the layup's crank turn: :meth:`folder_line.core.line.model.LineModel.cycle_index`), the
supervisor's PackML state at ``t`` and the constraint violations decided shortly before ``t``
(:class:`Flag`): each from its decision time for :data:`FLAG_VIDEO_S` s of video or to the end of
the cycle in which it was decided, whichever is longer. Nothing here draws; the text is tested
as text.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from folder_line.core.limits import Limit
from folder_line.core.line.margin_text import format_margin, margin_at
from folder_line.errors import ParameterError

__all__ = [
    'DEFAULT_FPS',
    'DEFAULT_SLOWDOWN',
    'FLAGS_SHOWN',
    'FLAG_VIDEO_S',
    'FPS',
    'MAX_FRAMES',
    'SLOWDOWN',
    'Flag',
    'OverlayText',
    'TimeScale',
    'Timeline',
    'frame_count',
]

#: video frames per second, default
DEFAULT_FPS = 25.0
#: video seconds per line second, default: a 72 ms knife cycle lasts 0.72 s on screen
DEFAULT_SLOWDOWN = 10.0
#: most frames of one animation: 6 min 40 s of video at 25 frames/s (about 4 min to draw and encode at 1280x720)
MAX_FRAMES = 10_000
FPS = Limit('video frame rate (`animate --fps`)', 1.0, 60.0, 'frames/s', 'a slide show to a smooth video')
SLOWDOWN = Limit(
    'video seconds per line second (`animate --slowdown`)',
    0.001,
    10000.0,
    '',
    'a thousand line seconds per video second to a 72 ms knife cycle stretched over 12 min',
)
#: a violation stays on screen at least this long, s of video
FLAG_VIDEO_S = 1.0
#: violations listed on one frame at most (the newest; the rest are counted)
FLAGS_SHOWN = 3


def frame_count(duration: float, fps: float, slowdown: float) -> int:
    """``floor(duration x fps x slowdown)``: the frames of ``duration`` s of line time (a relative
    1e-9 forgives the rounding of a product meant to be whole, 2 x 25 x 10 = 500)."""
    return math.floor(duration * fps * slowdown * (1.0 + 1e-9))


@dataclass(frozen=True)
class TimeScale:
    """Which line times the frames of an animation show (see the module docstring).

    Attributes
    ----------
    t_from : float
        Line time of the first frame, s.
    duration : float
        Line time animated, s.
    fps : float
        Video frames per second.
    slowdown : float
        Video seconds per line second.
    """

    t_from: float
    duration: float
    fps: float
    slowdown: float

    @property
    def dt(self) -> float:
        """Line time between two frames, s: ``1 / (fps x slowdown)``."""
        return 1.0 / (self.fps * self.slowdown)

    @property
    def frames(self) -> int:
        """N = floor(duration x fps x slowdown)."""
        return frame_count(self.duration, self.fps, self.slowdown)

    @property
    def t_end(self) -> float:
        """The end of the span animated, s."""
        return self.t_from + self.duration

    def time(self, i: int) -> float:
        """Line time of frame ``i``, s."""
        return self.t_from + i * self.dt

    def times(self) -> np.ndarray:
        """Line times of every frame, s."""
        return self.t_from + np.arange(self.frames) * self.dt

    def check(self, option: str, value: object) -> None:
        """Refuse a span of no frame or of more than :data:`MAX_FRAMES`, naming ``option`` and ``value``.

        Raises
        ------
        ParameterError
        """
        n = self.frames
        settings = f'at --fps {self.fps:g} and --slowdown {self.slowdown:g}'
        formula = 'frames = floor(duration x fps x slowdown)'
        if n < 1:
            raise ParameterError(
                option,
                value,
                f'{self.duration:g} s of line time {settings} is no frame ({formula}); '
                f'at least {self.dt:.6g} s of line time',
            )
        if n > MAX_FRAMES:
            longest = MAX_FRAMES / (self.fps * self.slowdown)
            raise ParameterError(
                option,
                value,
                f'{self.duration:g} s of line time {settings} is {n} frames ({formula}); at most {MAX_FRAMES} '
                f'({MAX_FRAMES / self.fps:g} s of video): at most {longest:.6g} s of line time at these settings, '
                'or a smaller --slowdown or --fps',
            )


@dataclass(frozen=True)
class Flag:
    """A constraint violation as the overlay shows it.

    Attributes
    ----------
    t : float
        Decision time, s of line time (a knife contact, a release, a leaf's exit).
    constraint : str
        Constraint name.
    index : int
        Cycle (leaf for ``chute_speed``) it was judged in.
    margin : float
        The margin, in the SI ``unit`` (negative).
    unit : str
        ``s``, ``m``, ``m/s``, ``sheets`` or ``1``.
    """

    t: float
    constraint: str
    index: int
    margin: float
    unit: str

    def text(self) -> str:
        """``feed_window -14.5968 ms (cycle 3)``: the margin in the unit people read
        (:func:`folder_line.core.line.margin_text.format_margin`)."""
        margin = format_margin(self.margin, self.unit, self.constraint)
        return f'{self.constraint} {margin} ({margin_at(self.constraint, self.index)})'


@dataclass(frozen=True)
class OverlayText:
    """The words on one frame.

    Attributes
    ----------
    time : str
        ``t = 1.234 s``.
    cycle : str
        ``knife cycle 17``, ``crank turn 2``, or ``before knife cycle 0``.
    state : str
        The PackML state (``EXECUTE``), ``-`` when none is known yet.
    violations : tuple of str
        The violations on screen now, newest first (:meth:`Flag.text`), at most
        :data:`FLAGS_SHOWN`, then ``+k more``.
    count : int
        Violations decided up to ``t``.
    """

    time: str
    cycle: str
    state: str
    violations: tuple[str, ...]
    count: int


class Timeline:
    """The overlay text of every frame of an animation (:meth:`text`).

    Parameters
    ----------
    cycle_of : callable
        Line time -> the machine cycle running (:meth:`~folder_line.core.line.model.LineModel.cycle_index`,
        -1 before the first).
    next_boundary : callable
        Line time -> the start of the next cycle after it, s (``inf`` if none:
        :meth:`~folder_line.core.line.model.LineModel.next_cycle_boundary`).
    cycle_word : str
        What a cycle is: ``knife cycle`` or ``crank turn``.
    states : sequence of (float, str)
        ``(line time, state)`` of every state change, sorted by time; before the first, ``-``.
    flags : sequence of Flag
        The violations, any order.
    slowdown : float
        Video seconds per line second: a flag stays :data:`FLAG_VIDEO_S` s of video at least.
    """

    def __init__(
        self,
        cycle_of: Callable[[float], int],
        next_boundary: Callable[[float], float],
        cycle_word: str,
        states: Sequence[tuple[float, str]],
        flags: Sequence[Flag],
        slowdown: float,
    ) -> None:
        self.cycle_of = cycle_of
        self.cycle_word = cycle_word
        self.state_t = np.array([float(t) for t, _ in states], dtype=float)
        self.state_names = [str(s) for _, s in states]
        if self.state_t.size and np.any(np.diff(self.state_t) < 0):
            raise ParameterError('states', self.state_t.tolist(), 'must be sorted by time')
        self.flags = sorted(flags, key=lambda f: (f.t, f.constraint, f.index))
        self.flag_t = np.array([f.t for f in self.flags], dtype=float)
        least = FLAG_VIDEO_S / slowdown
        until = []
        for f in self.flags:
            boundary = next_boundary(f.t)
            until.append(max(f.t + least, boundary if math.isfinite(boundary) else -math.inf))
        self.flag_until = np.array(until, dtype=float)
        self._longest = float(np.max(self.flag_until - self.flag_t)) if self.flags else 0.0

    def state_at(self, t: float) -> str:
        """The PackML state at line time ``t`` (the last change at or before it), ``-`` before any."""
        i = int(np.searchsorted(self.state_t, t, side='right'))
        return self.state_names[i - 1] if i else '-'

    def text(self, t: float) -> OverlayText:
        """The overlay of the frame at line time ``t``, s."""
        k = self.cycle_of(t)
        cycle = f'{self.cycle_word} {k}' if k >= 0 else f'before {self.cycle_word} 0'
        n = int(np.searchsorted(self.flag_t, t, side='right'))  # decided up to t
        first = int(np.searchsorted(self.flag_t, t - self._longest, side='left'))  # none before is still shown
        on = [i for i in range(n - 1, first - 1, -1) if self.flag_until[i] > t]
        shown = tuple(self.flags[i].text() for i in on[:FLAGS_SHOWN])
        if len(on) > FLAGS_SHOWN:
            shown += (f'+{len(on) - FLAGS_SHOWN} more',)
        return OverlayText(time=f't = {t:.3f} s', cycle=cycle, state=self.state_at(t), violations=shown, count=n)
