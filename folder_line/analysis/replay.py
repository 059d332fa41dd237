"""The recorded run judged again, window by window: the line's constraints on the recorded events, the
recorded events against the line model, the supervisor replayed.

Everything here goes through the run in windows of line time
(:data:`~folder_line.analysis.streaming.WINDOW`) and keeps, of
what it has seen, only running figures (:mod:`folder_line.analysis.streaming`): its memory
does not grow with the run's line time beyond what the recording itself holds (the
recorded events, :class:`~folder_line.analysis.recording.Recording`).

The same constraint code as the line
------------------------------------
:func:`evaluate` judges the events of a recording with the functions the streamed line and
the live supervisor call, :func:`folder_line.core.line.constraints.folder_evaluation` and
:func:`folder_line.core.line.constraints.evaluate_layup_constraints`, on the scene stored in
the bag and its drive under the recorded supervisor commands and tunings. A folder cycle is
judged in the window that holds its knife contact (its decision time), on every recorded row
of that cycle (a signature's rows carry the cycle it was handed over in), as one call on the
whole table would judge it (a signature still on its way at the end of the recording is
bounded by the recording's last event, as ``simulate`` bounds it by the end of its run); a
release and a leaf's exit in the window of their own time. Its numbers are therefore those
of ``simulate(scene, t_end, commands=...)`` for a run of ``t_end`` s, up to the ns rounding
of the event times, whatever the windows.

The recorded events against the model, the supervisor replayed
---------------------------------------------------------------
:mod:`folder_line.analysis.event_check` compares the recorded events with the streamed line
model's (:func:`~folder_line.analysis.event_check.compare_events`);
:mod:`folder_line.analysis.supervisor_replay` replays the supervisor on the recorded inputs
(:func:`~folder_line.analysis.supervisor_replay.replay_transitions`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from folder_line.analysis.recording import Recording
from folder_line.analysis.streaming import CHUNK, WINDOW, MarginHistogram, window_ends
from folder_line.core.line.constraints import FOLDER_CONSTRAINTS, evaluate_layup_constraints, folder_evaluation
from folder_line.core.line.delivery_plan import DeliveryPlan, delivery_plan
from folder_line.core.line.drives import make_drive
from folder_line.core.line.line_summary import MarginFigures, SpanSummary, ViolationRecord, Violations
from folder_line.core.line.stream import ConstraintTally
from folder_line.core.mechanisms.cyclogram import CycleTiming, cycle_timing
from folder_line.core.mechanisms.drive import Drive
from folder_line.core.types.events import EVENT_KINDS, ConstraintSeries, empty_events, event_kind
from folder_line.errors import ParameterError
from folder_line.interfaces import NS_PER_S

__all__ = [
    'CYCLES_KEPT',
    'ConstraintMargins',
    'Evaluation',
    'Violation',
    'evaluate',
]

#: folder cycles whose margins :func:`evaluate` keeps by default (the first ones, for the cyclogram)
CYCLES_KEPT = 8
#: recent folder cycles whose margins are kept while the windows pass (a release is judged this many
#: cycles after its knife contact at most), so the neighbours of the first violated cycle are at hand
_RECENT_CYCLES = 16
#: the kinds a folder cycle is judged on (its knife contact and its signatures' rows)
_JUDGED_KINDS = np.array(
    [event_kind(k) for k in ('knife_contact', 'sheet_handover', 'at_stops', 'settled', 'bounce')], dtype=np.int16
)
_CONTACT = event_kind('knife_contact')
_RELEASE = event_kind('released_on_pile')
_LOWEST = np.iinfo(np.int64).min


# --------------------------------------------------------------------------- judged rows


class _Cursor:
    """A forward scan of a time-sorted event table: the first row at which the largest cycle of the judged
    rows so far reaches a threshold (the thresholds asked for do not decrease; if one does, it rescans)."""

    def __init__(self, events: np.ndarray) -> None:
        self.events = events
        self.pos = 0  # the rows before pos have been scanned
        self.top = _LOWEST  # the largest judged cycle before pos

    def first_reaching(self, threshold: int) -> int:
        """The first row index ``i`` with ``max(cycle of the judged rows <= i) >= threshold`` (the table's
        size if none)."""
        if self.top >= threshold:  # asked for less than before: scan again from the start
            self.pos, self.top = 0, _LOWEST
        ev = self.events
        while self.pos < ev.size:
            part = ev[self.pos : self.pos + CHUNK]
            cyc = np.where(np.isin(part['kind'], _JUDGED_KINDS), part['cycle'], _LOWEST)
            top = np.maximum.accumulate(np.maximum(cyc, self.top))
            hit = np.flatnonzero(top >= threshold)
            if hit.size:
                i = int(hit[0])
                self.top = int(top[i - 1]) if i else self.top
                self.pos += i
                return self.pos
            self.top = int(top[-1])
            self.pos += part.size
        return int(ev.size)


class _CycleRows:
    """The rows of the judged kinds of given folder cycles, found in a time-sorted event table without an index.

    A first scan measures how far a judged row's cycle may lag behind the largest cycle of the judged
    rows before it (``lag``); the rows of cycles ``kA .. kB`` then lie from the first judged row of a
    cycle ``>= kA`` to the first row where the largest cycle so far passes ``kB + lag``. Two cursors
    move forward through the table once in all.
    """

    def __init__(self, events: np.ndarray) -> None:
        self.events = events
        lag, top = 0, _LOWEST
        for i in range(0, int(events.size), CHUNK):
            part = events[i : i + CHUNK]
            cyc = part['cycle'][np.isin(part['kind'], _JUDGED_KINDS)]
            if cyc.size:
                run = np.maximum.accumulate(np.maximum(cyc, top))
                lag = max(lag, int((run - cyc).max()))
                top = int(run[-1])
        self.lag = lag
        self._lo = _Cursor(events)
        self._hi = _Cursor(events)

    def rows(self, cycles: np.ndarray) -> np.ndarray:
        """The judged rows of ``cycles``, in table order."""
        lo = self._lo.first_reaching(int(cycles.min()))
        hi = self._hi.first_reaching(int(cycles.max()) + self.lag + 1)
        part = self.events[lo:hi]
        out: np.ndarray = part[np.isin(part['kind'], _JUDGED_KINDS) & np.isin(part['cycle'], cycles)]
        return out


# --------------------------------------------------------------------------- evaluation


@dataclass(frozen=True, eq=False)
class ConstraintMargins:
    """One constraint's margins over the run, as the windows passed.

    Attributes
    ----------
    name, unit, description : str
    tally : ConstraintTally
        Evaluations, violations, the smallest margin and its first cycle (or leaf).
    histogram : MarginHistogram
        The margins binned (:mod:`folder_line.analysis.streaming`): what ``margins.png`` draws.
    """

    name: str
    unit: str
    description: str
    tally: ConstraintTally
    histogram: MarginHistogram = field(default_factory=MarginHistogram)

    def add(self, rows: ConstraintSeries) -> None:
        """Count a window's rows."""
        self.tally.add(rows)
        self.histogram.add(rows.margin)


@dataclass(frozen=True)
class Violation:
    """A violated constraint row.

    Attributes
    ----------
    t : float
        Decision time, s (a knife contact, a release, a leaf's exit).
    cycle : int
        The cycle (or leaf) judged.
    constraint, unit : str
    margin : float
        In the SI ``unit``, negative.
    """

    t: float
    cycle: int
    constraint: str
    margin: float
    unit: str


@dataclass(frozen=True, eq=False)
class Evaluation:
    """The recorded events judged by the line's constraint code (:func:`evaluate`).

    Attributes
    ----------
    drive : Drive
        The scene's drive under the recorded commands and tunings.
    timing : CycleTiming or None
        The folder's cycle timing (None without the folder).
    plan : DeliveryPlan or None
        The delivery's plan (None without the folder).
    margins : dict of str to ConstraintMargins
        Every constraint of the scene, in the order the line judges them (the folder's, then the
        layup's), with its running figures; ``evaluations`` 0 where nothing was judged.
    violations : list of Violation
        Every violated row judged, sorted by cycle, then constraint (they grow with the violations
        only, and the report lists them all).
    first_cycles : tuple of int
        The first folder cycles judged (at most ``keep_cycles``), ascending.
    first_violated : int or None
        The smallest folder cycle with a violated row (None if none).
    around_violated : tuple of int
        ``first_violated`` and its neighbours that were judged.
    cycle_margins : dict of int to dict of str to float
        The folder constraints' margins of the cycles of ``first_cycles`` and ``around_violated``.
    cycles, sheets_counted : int
    summary : SpanSummary
        The ``simulate``-style summary of the recorded events, every violation listed.
    keep_cycles : int
        The first folder cycles whose margins were kept (``evaluate``'s ``keep_cycles``).
    windows : int
        Windows gone through.
    """

    drive: Drive
    timing: CycleTiming | None
    plan: DeliveryPlan | None
    margins: dict[str, ConstraintMargins]
    violations: list[Violation]
    first_cycles: tuple[int, ...]
    first_violated: int | None
    around_violated: tuple[int, ...]
    cycle_margins: dict[int, dict[str, float]]
    cycles: int
    sheets_counted: int
    summary: SpanSummary
    keep_cycles: int = CYCLES_KEPT
    windows: int = 0


def _empty_margins(
    rec: Recording, drive: Drive, timing: CycleTiming | None, plan: DeliveryPlan | None
) -> dict[str, ConstraintMargins]:
    """Every constraint the scene is judged on, in the line's order, with nothing counted."""
    series: list[ConstraintSeries] = []
    empty = empty_events()
    if timing is not None:
        series += folder_evaluation(empty, timing, rec.scene, drive, plan=plan).constraints
    if rec.scene.has_layup:
        series += evaluate_layup_constraints(empty, rec.scene)
    return {
        c.name: ConstraintMargins(c.name, c.unit, c.description, ConstraintTally(c.name, c.unit, c.description))
        for c in series
    }


class _CycleMargins:
    """The folder constraints' margins of the cycles the cyclogram shows, gathered as the windows pass:
    the first ``keep`` judged, and the first violated one with its neighbours (the last
    :data:`_RECENT_CYCLES` cycles' margins are at hand when a violation turns up)."""

    def __init__(self, keep: int) -> None:
        self.keep = keep
        self.first: list[int] = []
        self.violated: int | None = None
        self.around: set[int] = set()
        self.kept: dict[int, dict[str, float]] = {}
        self.recent: dict[int, dict[str, float]] = {}
        self.judged_recent: set[int] = set()
        self.top = _LOWEST

    def window(self, judged: np.ndarray, rows: Sequence[ConstraintSeries]) -> None:
        """A window's judged cycles (their knife contacts) and folder rows."""
        for k in judged.tolist():
            if len(self.first) < self.keep and k not in self.first:
                self.first.append(k)
            self.judged_recent.add(k)
            self.top = max(self.top, k)
        bad: list[int] = []
        for c in rows:
            for k, m in zip(c.cycle.tolist(), c.margin.tolist(), strict=True):
                self.recent.setdefault(k, {})[c.name] = m
            bad += c.cycle[c.margin < 0.0].tolist()
        if bad and (self.violated is None or min(bad) < self.violated):
            self.violated = min(bad)
            self.around = {k for k in (self.violated - 1, self.violated, self.violated + 1) if k in self.judged_recent}
        elif self.violated is not None:
            self.around |= {k for k in judged.tolist() if abs(k - self.violated) <= 1}
        watch = set(self.first) | (set() if self.violated is None else {self.violated + d for d in (-1, 0, 1)})
        for k in watch & set(self.recent):
            self.kept.setdefault(k, {}).update(self.recent[k])
        self.kept = {k: v for k, v in self.kept.items() if k in watch}
        floor = self.top - _RECENT_CYCLES
        self.recent = {k: v for k, v in self.recent.items() if k >= floor}
        self.judged_recent = {k for k in self.judged_recent if k >= floor}


class _Judge:
    """The running figures of :func:`evaluate` as the windows pass: the margins, the violations, the
    cycles shown, the events counted by kind and the signatures judged."""

    def __init__(self, rec: Recording, keep_cycles: int) -> None:
        scene = self.scene = rec.scene
        self.drive = make_drive(scene, rec.commands)
        self.timing: CycleTiming | None = None
        self.plan: DeliveryPlan | None = None
        if scene.has_folder:
            self.timing = cycle_timing(scene.machine('cyclogram'), scene.machine('knife'))
            self.plan = delivery_plan(scene, self.timing)
        self.margins = _empty_margins(rec, self.drive, self.timing, self.plan)
        events = rec.events
        self.t_last = float(events['t'][-1]) if events.size else 0.0  # where the table ends, for every cycle
        self.finder = _CycleRows(events) if self.timing is not None else None
        self.shown = _CycleMargins(keep_cycles)
        self.violations: list[Violation] = []
        self.kinds = np.zeros(len(EVENT_KINDS), dtype=np.int64)
        self.signatures = 0

    def window(self, part: np.ndarray) -> None:
        """Judge a window's events ``part`` and count them."""
        self.kinds += np.bincount(part['kind'], minlength=len(EVENT_KINDS))
        rows, judged = self._folder_rows(part)
        self.shown.window(judged, [c for c in rows if c.name in FOLDER_CONSTRAINTS])
        if self.scene.has_layup:
            rows += evaluate_layup_constraints(part, self.scene)
        for c in rows:
            if c.margin.size:
                self.margins[c.name].add(c)
                bad = np.flatnonzero(c.margin < 0.0)
                self.violations += [
                    Violation(float(c.t[i]), int(c.cycle[i]), c.name, float(c.margin[i]), c.unit) for i in bad
                ]

    def _folder_rows(self, part: np.ndarray) -> tuple[list[ConstraintSeries], np.ndarray]:
        """The folder's rows decided in a window: its cycles judged on all their rows (their knife
        contacts in ``part``), its releases; and the cycles judged."""
        rows: list[ConstraintSeries] = []
        judged = np.zeros(0, dtype=np.int64)
        timing, plan, finder = self.timing, self.plan, self.finder
        if timing is None or finder is None:
            return rows, judged
        judged = np.unique(part['cycle'][part['kind'] == _CONTACT])
        if judged.size:
            fe = folder_evaluation(finder.rows(judged), timing, self.scene, self.drive, plan=plan, t_end=self.t_last)
            rows += [c for c in fe.constraints if c.name != 'release_at_min_speed']
            self.signatures += int(fe.signatures.sum())
        released = part[part['kind'] == _RELEASE]
        if plan is not None and released.size:
            rows += [
                c
                for c in folder_evaluation(released, timing, self.scene, self.drive, plan=plan).constraints
                if c.name == 'release_at_min_speed'
            ]
        return rows, judged

    def cycles_and_sheets(self, rec: Recording, t_from: float, counts: Mapping[str, int]) -> tuple[int, int]:
        """The machine cycles and the sheets counted from ``t_from`` (s) on: the folder's knife contacts and
        releases (or signatures without a delivery), else the layup's crank turns and leaves landed."""
        if self.scene.has_folder:
            sheets = counts['released_on_pile'] if self.plan is not None else self.signatures
            return counts['knife_contact'], sheets
        lp = self.scene.machine('layup')
        drive = self.drive

        def turns(t: float) -> int:
            return math.floor(float(np.asarray(drive.theta(np.asarray(t)), dtype=float)) * (lp.n_kr / 60.0))

        return turns(rec.t_end) - (turns(t_from) if t_from > 0.0 else 0), counts['leaf_landed']


def evaluate(
    rec: Recording, t_from: float = 0.0, *, window: float = WINDOW, keep_cycles: int = CYCLES_KEPT
) -> Evaluation:
    """The recorded events judged by the line's constraint code, window by window; the simulate-style summary.

    Parameters
    ----------
    rec : Recording
        The recording (up to its ``t_end``).
    t_from : float, optional
        Start of the span reported, s of line time (``analyze --from``): a cycle decided (its
        knife contact) from ``t_from`` on is judged on all its recorded rows, those before
        ``t_from`` too; the constraints decided, the events, cycles and sheets counted from
        ``t_from`` on are reported.
    window : float, optional
        Line time per window, s (> 0). The result does not depend on it.
    keep_cycles : int, optional
        The first folder cycles whose margins are kept for the cyclogram (>= 1).

    Returns
    -------
    Evaluation
    """
    if not (isinstance(keep_cycles, int) and keep_cycles >= 1):
        raise ParameterError('keep_cycles', keep_cycles, 'must be a whole number >= 1')
    judge = _Judge(rec, keep_cycles)
    events, event_ns = rec.events, rec.event_ns
    i0 = int(np.searchsorted(event_ns, round(t_from * NS_PER_S), side='left'))
    cuts = window_ends(t_from, rec.t_end, window)
    for n, cut in enumerate(cuts, start=1):
        i1 = events.size if n == len(cuts) else int(np.searchsorted(event_ns, round(cut * NS_PER_S), side='left'))
        judge.window(events[i0:i1])
        i0 = i1
    violations = judge.violations
    violations.sort(key=lambda v: (v.cycle, v.constraint))
    counts = dict(zip(EVENT_KINDS, judge.kinds.tolist(), strict=True))
    cycles, sheets = judge.cycles_and_sheets(rec, t_from, counts)
    summary = _summary(rec, t_from, judge.margins, violations, counts, (cycles, sheets))
    shown = judge.shown
    return Evaluation(
        drive=judge.drive,
        timing=judge.timing,
        plan=judge.plan,
        margins=judge.margins,
        violations=violations,
        first_cycles=tuple(sorted(shown.first)),
        first_violated=shown.violated,
        around_violated=tuple(sorted(shown.around)),
        cycle_margins=shown.kept,
        cycles=cycles,
        sheets_counted=sheets,
        summary=summary,
        keep_cycles=keep_cycles,
        windows=len(cuts),
    )


def _summary(
    rec: Recording,
    t_from: float,
    margins: Mapping[str, ConstraintMargins],
    violations: Sequence[Violation],
    counts: Mapping[str, int],
    cycles_and_sheets: tuple[int, int],
) -> SpanSummary:
    """The ``simulate`` summary's numbers for the recorded events (every violation listed)."""
    scene = rec.scene
    min_margin = {
        name: MarginFigures(tl.min_margin, tl.unit, tl.min_cycle, tl.evaluations, tl.violations)
        for name, tl in ((name, cm.tally) for name, cm in margins.items())
        if tl.evaluations
    }
    return SpanSummary(
        scene=scene.name,
        duration_s=max(rec.t_end - t_from, 1e-9),
        seed=scene.seed,
        effects=list(scene.effects),
        cycles=cycles_and_sheets[0],
        sheets_counted=cycles_and_sheets[1],
        violations=Violations(
            len(violations), [ViolationRecord(v.cycle, v.constraint, v.margin, v.unit) for v in violations]
        ),
        min_margin=min_margin,
        events={k: n for k, n in counts.items() if n},
    )
