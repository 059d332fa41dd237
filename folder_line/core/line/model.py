"""The line over a span, in one window, kept: ``LineModel``, ``simulate(scene, duration)``, and the streamed
``run_summary``.

The line is computed by :class:`folder_line.core.line.stream.LineStream`, window by window
for ever. :class:`LineModel` runs it over ``[0, horizon]`` in one window and keeps what it
handed out, for random access: every event, the per-cycle constraint margins, the parts'
summaries, and the joint states at any time of the span (:meth:`LineModel.sample`). Its
memory grows with the span: it is the reference a streamed run must equal, and the tool
for short spans (tests, the papers' figures). :func:`simulate` is
``LineModel(scene, duration, commands).result(duration, rate)``.

:func:`run_summary` is what a long run wants: the summary of ``duration`` s, streamed in
windows of :data:`WINDOW` s, in memory that does not depend on the duration; it equals
``simulate(...).summary()`` bit for bit.

What a node publishes at stamp t depends only on the scene, t and the commands: every
event time is a closed form or a root in the drive's phase, each sheet's and leaf's on
its own, and the random draws are taken in order, so a span cut anywhere, or a longer
span, agrees on everything up to its end.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal, overload

import numpy as np
import numpy.typing as npt

from folder_line.core.limits import DURATION, SAMPLE_RATE
from folder_line.core.line.cycles import MachineCycles
from folder_line.core.line.folder_figures import FolderFigures
from folder_line.core.line.folder_sim import join_rows
from folder_line.core.line.layup_figures import LayupFigures
from folder_line.core.line.line_summary import LineSummary
from folder_line.core.line.stream import LineStream
from folder_line.core.line.tuning import LineCommand, tunings_of
from folder_line.core.mechanisms.drive import Drive
from folder_line.core.types.events import EVENT_KINDS, ConstraintSeries, JointSamples
from folder_line.errors import ParameterError

if TYPE_CHECKING:
    from folder_line.core.line.folder_stream import FolderStream
    from folder_line.core.line.layup_stream import LayupStream
    from folder_line.core.line.scene import Scene

__all__ = [
    'WINDOW',
    'LineModel',
    'LineResult',
    'run_summary',
    'sample_times',
    'simulate',
]

#: line time per window of :func:`run_summary`, s: long enough that a window's fixed cost is lost in its
#: work, short enough that its arrays stay small (10 min of the folder is 8300 cycles)
WINDOW = 600.0


@dataclass(frozen=True, eq=False)
class LineResult:
    """Everything :func:`simulate` computes.

    Attributes
    ----------
    scene : Scene
        The scene simulated.
    duration : float
        Line time simulated, s.
    events : ndarray of EVENT_DTYPE
        Exact events sorted by time.
    samples : dict of str to JointSamples
        Unit (:data:`~folder_line.core.line.stream.UNITS`) -> joint states on the sample grid.
    constraints : list of ConstraintSeries
        Per-cycle constraint margins.
    parts : dict of str to FolderFigures or LayupFigures
        Per part (``'folder'``, ``'layup'``) its figures.
    stream_summary : callable
        ``max_violations -> LineSummary``: the stream's summary (:meth:`summary`).
    """

    scene: Scene
    duration: float
    events: np.ndarray
    samples: dict[str, JointSamples]
    constraints: list[ConstraintSeries]
    parts: dict[str, FolderFigures | LayupFigures]
    stream_summary: Callable[[int], LineSummary]

    def events_of(self, kind: str) -> np.ndarray:
        """Rows of one event kind."""
        rows: np.ndarray = self.events[self.events['kind'] == EVENT_KINDS.index(kind)]  # a field is typed Any
        return rows

    def constraint(self, name: str) -> ConstraintSeries:
        """A constraint by name (KeyError listing the names)."""
        for c in self.constraints:
            if c.name == name:
                return c
        msg = f'constraint {name!r} not evaluated; evaluated: {", ".join(c.name for c in self.constraints)}'
        raise KeyError(msg)

    def summary(self, max_violations: int = 10) -> LineSummary:
        """The summary (see the ``simulate`` verb of the CLI; ``as_json()`` its document): the stream's
        (:meth:`folder_line.core.line.stream.LineStream.summary`)."""
        return self.stream_summary(max_violations)


def sample_times(duration: float, rate: float) -> np.ndarray:
    """The sample grid ``i / rate`` for i = 0 .. floor(duration·rate), s (empty if rate = 0)."""
    if rate <= 0.0:
        return np.zeros(0)
    n = math.floor(duration * rate * (1.0 + 1e-15)) + 1
    return np.arange(n, dtype=float) / rate


class LineModel:
    """The line of a scene over ``[0, horizon]``: one window of the stream, kept, sampled anywhere.

    Parameters
    ----------
    scene : Scene
        Validated scene.
    horizon : float
        Line time the model covers, s (in :data:`folder_line.core.limits.DURATION`).
    commands : iterable of Command or Tuning
        The supervisor's drive commands (:mod:`folder_line.core.mechanisms.drive`) and
        the operator's tunings (:mod:`folder_line.core.line.tuning`), sorted by effective
        time (ParameterError otherwise). Events before the earliest one's time are the
        same, bit for bit, with and without it.

    Attributes
    ----------
    scene : Scene
    horizon : float
    commands : tuple of Command or Tuning
    tunings : tuple of Tuning
        The tunings among the commands.
    stream : LineStream
        The stream that computed it (everything kept: ``keep`` is infinite).
    pile : PileStream
        The table under the counted sheets (:mod:`folder_line.core.mechanisms.pile`).
    drive : Drive
    events : ndarray of EVENT_DTYPE
        All events in ``[0, horizon]``, sorted by time (then kind, then sheet).
    constraints : list of ConstraintSeries
    parts : dict of str to FolderFigures or LayupFigures
        Per part (``'folder'``, ``'layup'``) its figures.
    """

    def __init__(self, scene: Scene, horizon: float, commands: Iterable[LineCommand] = ()) -> None:
        self.scene = scene
        self.horizon = DURATION.check('horizon', horizon)
        self.stream = LineStream(scene, commands, keep=math.inf)
        self.commands = self.stream.commands
        self.tunings = tunings_of(self.commands)
        window = self.stream.advance(self.horizon)
        rows = window.constraints + self.stream.finish()
        self.drive: Drive = self.stream.drive
        self.events = window.events
        self._event_t = np.ascontiguousarray(self.events['t'])
        names = list(self.stream.tallies.constraints)
        empty = {
            name: ConstraintSeries(
                name, tl.unit, np.zeros(0, dtype=np.int64), np.zeros(0), tl.description, t=np.zeros(0)
            )
            for name, tl in self.stream.tallies.constraints.items()
        }
        self.constraints: list[ConstraintSeries] = join_rows(rows, names, empty)
        summary = self.stream.summary()
        self.parts: dict[str, FolderFigures | LayupFigures] = {}
        if summary.folder is not None:
            self.parts['folder'] = summary.folder
        if summary.layup is not None:
            self.parts['layup'] = summary.layup
        self.pile = self.stream.pile
        self.cycles = MachineCycles(scene)
        self._theta_end = float(np.asarray(self.drive.theta(np.array([self.horizon])), dtype=float)[0])

    # ------------------------------------------------------------------ joint states

    @property
    def units(self) -> dict[str, tuple[str, ...]]:
        """Unit -> its joint names (in the order of :meth:`sample`'s columns); units without joints absent."""
        return dict(self.stream.units)

    def sample(self, unit: str, t: npt.ArrayLike) -> JointSamples:
        """Joint states of one unit at line times ``t`` (s, in ``[0, horizon]``).

        Parameters
        ----------
        unit : {'drive', 'belts', 'feed', 'counter'}
            A unit of :attr:`units` (:data:`~folder_line.core.line.stream.UNITS`).
        t : array_like, shape (N,)
            Line times, s (a node's tick: one element).

        Returns
        -------
        JointSamples
            Positions and velocities shaped (N, J) (efforts where the scene computes
            them), the joints of L and F of the same unit concatenated F first.
            ``counter``: one joint, ``pile_table`` with the delivery, else
            ``container_floor`` (m, m/s; no effort; :mod:`folder_line.core.mechanisms.pile`).

        Raises
        ------
        KeyError
            ``unit`` has no joints in this scene (the message lists the units).
        """
        return self.stream.sample(unit, t)

    def sample_all(self, t: npt.ArrayLike) -> dict[str, JointSamples]:
        """Joint states of every unit at line times ``t`` (unit -> JointSamples)."""
        return self.stream.sample_all(t)

    @overload
    def part(self, name: Literal['folder']) -> FolderStream: ...
    @overload
    def part(self, name: Literal['layup']) -> LayupStream: ...
    @overload
    def part(self, name: str) -> FolderStream | LayupStream: ...
    def part(self, name: str) -> FolderStream | LayupStream:
        """The streamed part ``'folder'`` or ``'layup'`` of the scene (KeyError naming the parts)."""
        return self.stream.part(name)

    # ------------------------------------------------------------------ events

    def events_between(self, t0: float, t1: float) -> np.ndarray:
        """The events with ``t0 < t <= t1`` (a tick's; ``t0`` may be ``-inf``), in table order."""
        if math.isnan(t0) or math.isnan(t1):
            raise ValueError(f'events_between: times must not be NaN, got ({t0!r}, {t1!r})')
        i0, i1 = np.searchsorted(self._event_t, [t0, t1], side='right')
        return self.events[i0 : max(i0, i1)]

    # ------------------------------------------------------------------ machine cycles

    def cycle_index(self, t: float) -> int:
        """The machine cycle running at line time ``t`` (:meth:`MachineCycles.index`, within the horizon)."""
        return self.cycles.index(self.drive, min(t, self.horizon), self._theta_end)

    def next_cycle_boundary(self, t: float) -> float:
        """The start of the next machine cycle strictly after ``t``, s (``inf`` if none within the horizon)."""
        return self.cycles.next_boundary(self.drive, t, self._theta_end)

    # ------------------------------------------------------------------ batch

    def result(self, duration: float | None = None, sample_rate: float | None = None) -> LineResult:
        """The batch result of ``duration`` s (default: the horizon), sampled at ``sample_rate`` Hz.

        For a duration other than the horizon a model of that duration is built (the
        events, constraints and summaries of a run are those of its own length).

        Parameters
        ----------
        duration : float, optional
            Line time, s (> 0); default :attr:`horizon`.
        sample_rate : float, optional
            Joint-state rate, Hz; default the scene's; 0 for events only.
        """
        duration = self.horizon if duration is None else DURATION.check('duration', duration)
        if duration != self.horizon:
            return LineModel(self.scene, duration, self.commands).result(duration, sample_rate)
        rate = self.scene.sample_rate if sample_rate is None else SAMPLE_RATE.check('sample_rate', sample_rate)
        t = sample_times(duration, rate)
        return LineResult(
            scene=self.scene,
            duration=duration,
            events=self.events,
            samples=self.sample_all(t) if t.size else {},
            constraints=list(self.constraints),
            parts=dict(self.parts),
            stream_summary=self.stream.summary,
        )


def simulate(
    scene: Scene, duration: float, *, sample_rate: float | None = None, commands: Iterable[LineCommand] = ()
) -> LineResult:
    """Simulate ``duration`` seconds of line time, everything kept (:class:`LineModel`).

    Parameters
    ----------
    scene : Scene
        Validated scene.
    duration : float
        Line time, s (> 0).
    sample_rate : float, optional
        Joint-state rate, Hz; default the scene's; 0 for events only.
    commands : iterable of Command or Tuning
        Supervisor commands and tunings with their effective times (:class:`LineModel`).

    Returns
    -------
    LineResult
    """
    duration = DURATION.check('duration', duration)
    rate = scene.sample_rate if sample_rate is None else SAMPLE_RATE.check('sample_rate', sample_rate)
    try:
        model = LineModel(scene, duration, commands)
    except ParameterError as exc:
        if exc.key != 'horizon':
            raise
        raise ParameterError('duration', duration, exc.reason) from None
    return model.result(duration, rate)


def run_summary(
    scene: Scene,
    duration: float,
    *,
    commands: Iterable[LineCommand] = (),
    window: float = WINDOW,
    progress: Callable[[float], None] | None = None,
) -> LineSummary:
    """The summary of ``duration`` s of line time, streamed in windows (memory independent of the duration).

    Parameters
    ----------
    scene : Scene
    duration : float
        Line time, s (in :data:`folder_line.core.limits.DURATION`).
    commands : iterable of Command or Tuning
        Known up front, each with its effective time.
    window : float
        Line time per window, s (> 0).
    progress : callable, optional
        Called with the line time done after each window, s.

    Returns
    -------
    LineSummary
        ``simulate(scene, duration, sample_rate=0, commands=commands).summary()``, bit for bit.
    """
    duration = DURATION.check('duration', duration)
    if not (math.isfinite(window) and window > 0.0):
        raise ParameterError('window', window, 'must be a positive number of seconds')
    stream = LineStream(scene, commands)
    k = 1
    while stream.t < duration:
        stream.advance(min(duration, k * window))
        k += 1
        if progress is not None:
            progress(stream.t)
    stream.finish()
    return stream.summary()
