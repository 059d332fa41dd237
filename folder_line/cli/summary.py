"""The summary of the ``simulate`` verb: computed streamed (:func:`line_summary`), printed (:func:`print_summary`).

A run is streamed window by window (:class:`folder_line.core.line.stream.LineStream`), in memory
that does not grow with its line time. Without ``--from`` the summary is
:func:`folder_line.core.line.model.run_summary`'s: ``simulate(...).summary()`` bit for bit.

``--from S`` (:func:`window_summary`): the line still starts at line time 0 (from standstill,
its start-up first, as every run) and is fast-forwarded to ``S`` in windows of
:data:`FAST_FORWARD` s, nothing kept; the summary is then that of the window ``(S, S + D]``:
what the stream hands out from ``S`` on is collected afresh -- the events, the constraint rows
(a cycle counts where it is judged: one started before ``S`` and judged after it is in; the
cycles still waiting at ``S + D`` are judged as a run ending there judges them), the cycles
and sheets counted, the landing histogram. The parts' cumulative figures (the ``folder`` and
``layup`` blocks: design figures, exit-speed statistics, sheets in the machine) are a run's
from 0 and are left out; ``simulate`` without ``--from`` gives them.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from typing import IO, Protocol

import numpy as np

from folder_line.core.effects import leaf_flight
from folder_line.core.limits import DURATION
from folder_line.core.line import model
from folder_line.core.line.folder_figures import FolderFigures
from folder_line.core.line.layup_figures import LandingHistogram
from folder_line.core.line.line_summary import LineSummary, MarginFigures, WindowSummary
from folder_line.core.line.margin_text import best_possible, format_margin, margin_at, margin_legend
from folder_line.core.line.scene import Scene
from folder_line.core.line.stream import MAX_VIOLATIONS, ConstraintTally, LineStream, Window, judged_figures
from folder_line.core.line.tuning import LineCommand
from folder_line.core.types.events import EVENT_KINDS, ConstraintSeries, event_kind
from folder_line.errors import ParameterError

__all__ = [
    'FAST_FORWARD',
    'WINDOW',
    'Observer',
    'check_window',
    'fast_forward',
    'line_summary',
    'print_margins',
    'print_summary',
    'span_text',
    'window_summary',
]

#: line time per window of the streamed summary, s (the core's :data:`folder_line.core.line.model.WINDOW`)
WINDOW = model.WINDOW
#: line time per window of a fast-forward to ``--from``, s: nothing is kept, so as long as a window's arrays allow
FAST_FORWARD = model.WINDOW


def fast_forward(
    stream: LineStream, start: float, *, window: float = FAST_FORWARD, progress: Callable[[float], None] | None = None
) -> None:
    """Advance ``stream`` to line time ``start`` (s) in windows of ``window`` s, keeping nothing of them.

    ``progress`` is called with the line time reached after each window, s. A ``start`` of 0 hands out
    nothing: the first window of the stream then holds what happens at line time 0, as a run's does.
    """
    while start > 0.0 and stream.t < start:
        stream.advance(min(start, max(stream.t, 0.0) + window))
        if progress is not None:
            progress(stream.t)


def check_window(start: float, duration: float) -> float:
    """The end of the window ``(start, start + duration]``, s; ParameterError naming ``--from`` if it lies
    past the longest line time a run may reach (:data:`folder_line.core.limits.DURATION`)."""
    end = start + duration
    if not end <= DURATION.hi:
        raise ParameterError(
            '--from',
            start,
            f'--from + --duration = {end:.10g} s of line time; a run reaches at most {DURATION.hi:.10g} s '
            f'({DURATION.hi / 86400.0:.0f} days) of line time',
        )
    return end


class Observer(Protocol):
    """What watches a streamed run besides its summary (``simulate --plots``' figures)."""

    def window(self, stream: LineStream, window: Window) -> None:
        """One window handed out (``stream`` advanced to its end; joint states sampled within it)."""

    def finish(self, stream: LineStream, rows: list[ConstraintSeries]) -> None:
        """The run's end: the rows of the cycles still waiting, judged (:meth:`LineStream.finish`)."""


def _windows(
    stream: LineStream,
    start: float,
    end: float,
    step: float,
    progress: Callable[[float], None] | None,
    observers: Sequence[Observer],
) -> Iterator[Window]:
    """Advance ``stream`` from ``start`` to ``end`` (s) in windows of ``step`` s, each shown to ``observers``."""
    k = 1
    while stream.t < end:
        w = stream.advance(min(end, start + k * step))
        k += 1
        for obs in observers:
            obs.window(stream, w)
        yield w
        if progress is not None:
            progress(stream.t)


def _finish(stream: LineStream, observers: Sequence[Observer]) -> list[ConstraintSeries]:
    rows = stream.finish()
    for obs in observers:
        obs.finish(stream, rows)
    return rows


def window_summary(
    scene: Scene,
    start: float,
    duration: float,
    *,
    commands: Iterable[LineCommand] = (),
    window: float | None = None,
    progress: Callable[[float], None] | None = None,
    max_violations: int = MAX_VIOLATIONS,
    keep: float = 0.0,
    observers: Sequence[Observer] = (),
) -> WindowSummary:
    """The summary of the window ``(start, start + duration]`` of a run from 0 (see the module docstring).

    Parameters
    ----------
    scene : Scene
    start : float
        Line time the window starts at, s (>= 0): the run is fast-forwarded to it (:func:`fast_forward`).
    duration : float
        Line time of the window, s (in :data:`folder_line.core.limits.DURATION`).
    commands : iterable of Command or Tuning
        With their effective times (line time from 0; those before ``start`` act in the fast-forward).
    window : float, optional
        Line time per window from ``start`` on, s (default :data:`WINDOW`).
    progress : callable, optional
        Called with the line time reached (from 0) after each window, s.
    max_violations : int
        Violations listed.
    keep : float
        Line time before each window the stream keeps, s (:class:`~folder_line.core.line.stream.LineStream`).
    observers : sequence of Observer
        Shown every window from ``start`` on, and the end.

    Returns
    -------
    WindowSummary
        The cycles (folder cycles judged at the knife, else layup crank turns completed), sheets counted,
        violations, smallest margins and events of the window; with ``leaf_flight`` the landings in it.
    """
    duration = DURATION.check('--duration', duration)
    if not (math.isfinite(start) and start >= 0.0):
        raise ParameterError('--from', start, 'must be a line time >= 0 s')
    end = check_window(start, duration)
    stream = LineStream(scene, commands, keep=keep)
    fast_forward(stream, start, progress=progress)
    before = stream.summary()
    tallies = {name: ConstraintTally(name, tl.unit, tl.description) for name, tl in stream.tallies.constraints.items()}
    kinds = np.zeros(len(EVENT_KINDS), dtype=np.int64)
    cont = scene.machine('container') if before.layup is not None and before.layup.landing is not None else None
    counts = np.zeros(cont.bins if cont is not None else 0, dtype=np.int64)
    landed = event_kind('leaf_landed')
    for w in _windows(stream, start, end, WINDOW if window is None else window, progress, observers):
        if w.events.size:
            kinds += np.bincount(w.events['kind'], minlength=len(EVENT_KINDS))
            if cont is not None:
                x = w.events['value'][w.events['kind'] == landed]
                counts += np.histogram(x, bins=cont.bins, range=(cont.x_left, cont.x_right))[0]
        for rows in w.constraints:
            tallies[rows.name].add(rows)
    for rows in _finish(stream, observers):
        tallies[rows.name].add(rows)
    after = stream.summary()
    judged = judged_figures(tallies.values(), kinds, max_violations)
    landing = None
    if cont is not None:
        landing = LandingHistogram.of(leaf_flight.histogram_of_counts(counts, cont.x_left, cont.x_right))
    return WindowSummary(
        scene=scene.name,
        from_s=start,
        to_s=end,
        duration_s=duration,
        seed=scene.seed,
        effects=list(scene.effects),
        cycles=after.cycles - before.cycles,
        sheets_counted=after.sheets_counted - before.sheets_counted,
        violations=judged.violations,
        min_margin=judged.min_margin,
        events=judged.events,
        landing=landing,
    )


def line_summary(
    scene: Scene,
    duration: float,
    *,
    start: float | None = None,
    commands: Iterable[LineCommand] = (),
    progress: Callable[[float], None] | None = None,
    window: float | None = None,
    keep: float = 0.0,
    observers: Sequence[Observer] = (),
) -> LineSummary | WindowSummary:
    """The ``simulate`` verb's summary, streamed in windows of ``window`` s (default :data:`WINDOW`).

    Without ``start``: the summary of ``duration`` s from 0, ``simulate(...).summary()`` bit for bit
    (:func:`folder_line.core.line.model.run_summary` when nothing else watches the run); with it
    (``--from``): :func:`window_summary` of ``(start, start + duration]``. ``keep`` and ``observers``
    as :func:`window_summary`'s.
    """
    step = WINDOW if window is None else window
    if start is not None:
        return window_summary(
            scene, start, duration, commands=commands, window=step, progress=progress, keep=keep, observers=observers
        )
    if not observers:
        return model.run_summary(scene, duration, commands=commands, window=step, progress=progress)
    duration = DURATION.check('--duration', duration)
    stream = LineStream(scene, commands, keep=keep)
    for _ in _windows(stream, 0.0, duration, step, progress, observers):
        pass
    _finish(stream, observers)
    return stream.summary()


def print_margins(min_margin: Mapping[str, MarginFigures], out: IO[str]) -> None:
    """The smallest margin of each constraint (a summary's ``min_margin``), where it was judged, and a legend."""
    if not min_margin:
        return
    print('smallest margin per constraint (>= 0 passes):', file=out)
    for name, m in min_margin.items():
        best = '; best possible' if best_possible(name, m.margin) else ''
        print(
            f'  {name:<22} {format_margin(m.margin, m.unit, name):>17}  at {margin_at(name, m.cycle):<10} '
            f'{m.violations} of {m.evaluations} violated{best}',
            file=out,
        )
    print('what the margins mean:', file=out)
    for line in margin_legend(min_margin):
        print(line, file=out)


def _print_folder(folder: FolderFigures | None, out: IO[str]) -> None:
    """The folder's design figures: the feed speed it needs, the knife window, the delivery's efficiency."""
    if folder is None:
        return
    print(
        f'V_tr min = {folder.V_tr_min:.4f} m/s = {folder.V_tr_min_over_V_d:.4f} V_d '
        f'(V_d = {folder.V_d:.4f} m/s; V_tr = {folder.V_tr:g} m/s)',
        file=out,
    )
    print(
        f'knife window: {folder.knife_window_s * 1e3:.4f} ms, {folder.knife_window_deg:.3f} deg of crank '
        f'({folder.knife_in_deg:+.3f}..{folder.knife_out_deg:+.3f} deg)',
        file=out,
    )
    dlv = folder.delivery
    if dlv is not None:
        print(
            f'delivery: efficiency minimum {dlv.eta_min:.4f} at stroke position u = {dlv.eta_min_u:.4f} '
            f'({dlv.eta_min_travel_m:.4f} m of chain from the stroke start); '
            f'sprocket torque peak {dlv.sprocket_torque_peak_Nm:.4g} N m, '
            f'mean {dlv.sprocket_torque_mean_Nm:.4g} N m',
            file=out,
        )


def span_text(summary: LineSummary | WindowSummary) -> str:
    """``'60 s of line time'``, or for a window (``--from``) ``'line time 3600..3660 s (60 s from --from 3600)'``."""
    if isinstance(summary, WindowSummary):
        return (
            f'line time {summary.from_s:g}..{summary.to_s:g} s '
            f'({summary.duration_s:g} s from --from {summary.from_s:g})'
        )
    return f'{summary.duration_s:g} s of line time'


def _print_landing(hist: LandingHistogram, out: IO[str]) -> None:
    """The landings across the container: one bar per bin."""
    counts = hist.counts
    top = max(counts) or 1
    cv_text = 'n/a: no leaf landed' if hist.cv is None else f'{hist.cv:.3f}'
    print(f'landing across the container (cv {cv_text}):', file=out)
    edges = hist.edges
    for i, c in enumerate(counts):
        print(f'  {edges[i]:+.3f}..{edges[i + 1]:+.3f} m {"#" * round(40 * c / top):<40} {c}', file=out)


def _landing_of(summary: LineSummary | WindowSummary) -> LandingHistogram | None:
    """The landings of a summary (None without ``leaf_flight``)."""
    if isinstance(summary, WindowSummary):
        return summary.landing
    landing = summary.layup.landing if summary.layup is not None else None
    return None if landing is None else landing.histogram


def print_summary(summary: LineSummary | WindowSummary, out: IO[str]) -> None:
    """Print a summary of :func:`line_summary` (``simulate(...).summary()``, or a window's)."""
    print(
        f'scene {summary.scene}: {span_text(summary)}, seed {summary.seed}, '
        f'effects: {", ".join(summary.effects) or "none"}',
        file=out,
    )
    if isinstance(summary, WindowSummary):
        print(
            f'  (the line ran from 0 s; counted from {summary.from_s:g} s on: cycles, sheets, events, '
            'constraints judged; the design figures: simulate without --from)',
            file=out,
        )
    for tu in summary.tunings or []:
        print(f'tuned: {tu.key} = {tu.value:g} {tu.unit} from {tu.t:.9g} s (--tune)', file=out)
    print(f'cycles: {summary.cycles}   sheets counted: {summary.sheets_counted}', file=out)
    if isinstance(summary, LineSummary):
        _print_parts(summary, out)
    v = summary.violations
    print(f'violations: {v.count}', file=out)
    for item in v.first:
        name = item.constraint
        print(
            f'  {margin_at(name, item.cycle)}: {name} margin {format_margin(item.margin, item.unit, name)}',
            file=out,
        )
    print_margins(summary.min_margin, out)
    hist = _landing_of(summary)
    if hist is not None:
        _print_landing(hist, out)
    print('events: ' + ', '.join(f'{k} {n}' for k, n in summary.events.items()), file=out)


def _print_parts(summary: LineSummary, out: IO[str]) -> None:
    """The parts' figures of a run from 0: the folder's speed ratio and design figures, the leaves."""
    if summary.folder is not None:
        print(f'V_tr / V_d = {summary.folder.v_tr_over_v_d:.4f}', file=out)
    _print_folder(summary.folder, out)
    layup = summary.layup
    if layup is not None:
        print(
            f'leaves: {layup.leaves} entered, {layup.leaves_landed} landed, {layup.leaves_spilled} spilled, '
            f'{layup.leaves_damaged} damaged',
            file=out,
        )
