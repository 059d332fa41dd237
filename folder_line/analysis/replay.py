"""The recorded run judged again, window by window: the line's constraints on the recorded events, the
recorded events against the line model, the supervisor replayed.

Everything here goes through the run in windows of line time (:data:`WINDOW`) and keeps, of
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

The recorded events against the model
-------------------------------------
:func:`compare_events` advances the streamed line
(:class:`folder_line.core.line.stream.LineStream`, under every recorded command and tuning at
once) window by window and compares its events with the recorded ones of the same window:
the time to the ns (as a node publishes it), the kind, the sheet, the cycle and the value
(:class:`EventCheck`). With ``t_from`` the stream is first fast-forwarded to ``t_from`` in
windows of :data:`FAST_FORWARD` s, keeping nothing.

State transitions
-----------------
The recorded inputs of the live supervisor -- the events, the joint-state stamps
(liveness), the ``/clock`` messages, the operator's commands -- are replayed through
:func:`folder_line.core.supervision.offline.replay`, the logic the live node runs
(:func:`replay_transitions`): the transitions with their decision times and causes, and
the violations as the supervisor decided them (causal, with the action taken).
:func:`transitions_agree` says whether they agree with the states recorded on
``/line/supervisor/state`` (:func:`recorded_transitions`). The node's parameters are
read from the bag's custom data ``folder_line.supervisor`` (JSON) if it is there, else
they are the ones ``folder-line run`` starts the node with (:data:`SUPERVISOR_DEFAULTS`).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from folder_line.analysis.gap_cycles import without_unjudged
from folder_line.analysis.recording import Recording
from folder_line.analysis.streaming import CHUNK, MarginHistogram
from folder_line.bag.statuses import accepted_tunings
from folder_line.core.line.constraints import FOLDER_CONSTRAINTS, evaluate_layup_constraints, folder_evaluation
from folder_line.core.line.delivery_plan import delivery_plan
from folder_line.core.line.drives import make_drive
from folder_line.core.line.model import WINDOW as FAST_FORWARD
from folder_line.core.line.stream import ConstraintTally, LineStream
from folder_line.core.mechanisms.cyclogram import cycle_timing
from folder_line.core.mechanisms.drive import Drive
from folder_line.core.supervision.offline import replay
from folder_line.core.types.events import EVENT_KINDS, ConstraintSeries, empty_events, event_kind
from folder_line.errors import FolderLineError, ParameterError
from folder_line.interfaces import NS_PER_S

__all__ = [
    'CYCLES_KEPT',
    'FAST_FORWARD',
    'KEY_SUPERVISOR',
    'SUPERVISOR_DEFAULTS',
    'WINDOW',
    'ConstraintMargins',
    'Evaluation',
    'EventCheck',
    'Violation',
    'compare_events',
    'evaluate',
    'recorded_transitions',
    'replay_transitions',
    'supervisor_parameters',
    'transitions_agree',
]

#: line time per window of the replay, s (a minute of the ``line`` scene is about 10 000 events)
WINDOW = 60.0
#: folder cycles whose margins :func:`evaluate` keeps by default (the first ones, for the cyclogram)
CYCLES_KEPT = 8
#: the differences between the recorded events and the model's listed at most
MAX_DIFFERENCES = 10
#: an event this close (ns) before a window's end may round into the next window: compared there too
_CARRY_NS = 1000
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
    summary : dict
        The ``simulate``-style summary of the recorded events (as
        :meth:`folder_line.core.line.stream.LineStream.summary` words it, without the parts'
        figures), every violation listed.
    keep_cycles : int
        The first folder cycles whose margins were kept (``evaluate``'s ``keep_cycles``).
    windows : int
        Windows gone through.
    """

    drive: Drive
    timing: Any
    plan: Any
    margins: dict[str, ConstraintMargins]
    violations: list[Violation]
    first_cycles: tuple[int, ...]
    first_violated: int | None
    around_violated: tuple[int, ...]
    cycle_margins: dict[int, dict[str, float]]
    cycles: int
    sheets_counted: int
    summary: dict[str, Any]
    keep_cycles: int = CYCLES_KEPT
    windows: int = 0


def _cuts(start: float, end: float, window: float) -> list[float]:
    """Window ends after ``start``: the whole multiples of ``window`` before ``end``, then ``end``."""
    if not (math.isfinite(window) and window > 0.0):
        raise ParameterError('window', window, 'must be a positive number of seconds')
    k = math.floor(start / window) + 1
    cuts = []
    while k * window < end:
        cuts.append(k * window)
        k += 1
    cuts.append(end)
    return cuts


def _empty_margins(rec: Recording, drive: Drive, timing: Any, plan: Any) -> dict[str, ConstraintMargins]:
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
    scene = rec.scene
    drive = make_drive(scene, rec.commands)
    timing = plan = None
    if scene.has_folder:
        timing = cycle_timing(scene.machine('cyclogram'), scene.machine('knife'))
        plan = delivery_plan(scene, timing)
    margins = _empty_margins(rec, drive, timing, plan)
    events, event_ns = rec.events, rec.event_ns
    t_last = float(events['t'][-1]) if events.size else 0.0  # where the table ends, for every cycle
    finder = _CycleRows(events) if timing is not None else None
    shown = _CycleMargins(keep_cycles)
    violations: list[Violation] = []
    kinds = np.zeros(len(EVENT_KINDS), dtype=np.int64)
    signatures = 0
    i0 = int(np.searchsorted(event_ns, round(t_from * NS_PER_S), side='left'))
    cuts = _cuts(t_from, rec.t_end, window)
    for n, cut in enumerate(cuts, start=1):
        i1 = events.size if n == len(cuts) else int(np.searchsorted(event_ns, round(cut * NS_PER_S), side='left'))
        part = events[i0:i1]
        i0 = i1
        kinds += np.bincount(part['kind'], minlength=len(EVENT_KINDS))
        rows: list[ConstraintSeries] = []
        judged = np.zeros(0, dtype=np.int64)
        if timing is not None and finder is not None:
            judged = np.unique(part['cycle'][part['kind'] == _CONTACT])
            if judged.size:
                fe = folder_evaluation(finder.rows(judged), timing, scene, drive, plan=plan, t_end=t_last)
                rows += [c for c in fe.constraints if c.name != 'release_at_min_speed']
                signatures += int(fe.signatures.sum())
            released = part[part['kind'] == _RELEASE]
            if plan is not None and released.size:
                rows += [
                    c
                    for c in folder_evaluation(released, timing, scene, drive, plan=plan).constraints
                    if c.name == 'release_at_min_speed'
                ]
        shown.window(judged, [c for c in rows if c.name in FOLDER_CONSTRAINTS])
        if scene.has_layup:
            rows += evaluate_layup_constraints(part, scene)
        for c in rows:
            if c.margin.size:
                margins[c.name].add(c)
                bad = np.flatnonzero(c.margin < 0.0)
                violations += [
                    Violation(float(c.t[i]), int(c.cycle[i]), c.name, float(c.margin[i]), c.unit) for i in bad
                ]
    violations.sort(key=lambda v: (v.cycle, v.constraint))
    counts = dict(zip(EVENT_KINDS, kinds.tolist(), strict=True))
    if scene.has_folder:
        cycles = counts['knife_contact']
        sheets = counts['released_on_pile'] if plan is not None else signatures
    else:
        lp = scene.machine('layup')

        def turns(t: float) -> int:
            return math.floor(float(np.asarray(drive.theta(np.asarray(t)), dtype=float)) * (lp.n_kr / 60.0))

        cycles = turns(rec.t_end) - (turns(t_from) if t_from > 0.0 else 0)
        sheets = counts['leaf_landed']
    summary = _summary(rec, t_from, margins, violations, counts)
    summary['cycles'] = cycles
    summary['sheets_counted'] = sheets
    return Evaluation(
        drive=drive,
        timing=timing,
        plan=plan,
        margins=margins,
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
) -> dict[str, Any]:
    """The ``simulate`` summary's words for the recorded events (every violation listed)."""
    scene = rec.scene
    min_margin: dict[str, dict[str, Any]] = {}
    for name, cm in margins.items():
        tl = cm.tally
        if tl.evaluations:
            min_margin[name] = {
                'margin': tl.min_margin,
                'unit': tl.unit,
                'cycle': tl.min_cycle,
                'evaluations': tl.evaluations,
                'violations': tl.violations,
            }
    return {
        'scene': scene.name,
        'duration_s': max(rec.t_end - t_from, 1e-9),
        'seed': scene.seed,
        'effects': list(scene.effects),
        'cycles': 0,
        'sheets_counted': 0,
        'violations': {
            'count': len(violations),
            'first': [
                {'cycle': v.cycle, 'constraint': v.constraint, 'margin': v.margin, 'unit': v.unit} for v in violations
            ],
        },
        'min_margin_s': {k: v['margin'] for k, v in min_margin.items() if v['unit'] == 's'},
        'min_margin': min_margin,
        'events': {k: n for k, n in counts.items() if n},
    }


# --------------------------------------------------------------------------- against the model


@dataclass
class EventCheck:
    """The recorded events against the line model's (:func:`compare_events`).

    Attributes
    ----------
    t_from, t_end : float
        The span compared, s (from ``t_from`` -- its ns -- to ``t_end``).
    recorded, model : int
        Events compared, of the recording and of the model.
    matched : int
        Recorded events with a model event of the same time (ns), kind, sheet and cycle.
    values_differ : int
        Of those, the ones whose value differs.
    largest_difference : float
        The largest ``|recorded - model| / max(|recorded|, |model|)`` of a value that differs
        (0 if none).
    recorded_only, model_only : int
        Events with no counterpart on the other side.
    differences : list of dict
        The first :data:`MAX_DIFFERENCES` differences: ``t`` (s), ``kind``, ``sheet``, ``cycle``,
        ``recorded``, ``model`` (the values; None where the event is missing).
    windows : int
        Windows of the model compared.
    error : str or None
        Why the model could not be replayed (None if it was).
    """

    t_from: float
    t_end: float
    recorded: int = 0
    model: int = 0
    matched: int = 0
    values_differ: int = 0
    largest_difference: float = 0.0
    recorded_only: int = 0
    model_only: int = 0
    differences: list[dict[str, Any]] = field(default_factory=list)
    windows: int = 0
    error: str | None = None

    @property
    def agree(self) -> bool:
        """Every recorded event is the model's, value bit for bit, and none is missing."""
        return self.error is None and self.values_differ == 0 and self.recorded_only == 0 and self.model_only == 0

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready, with :meth:`text` as ``text``."""
        return {
            'agree': self.agree,
            'text': self.text(),
            't_from': self.t_from,
            't_end': self.t_end,
            'recorded': self.recorded,
            'model': self.model,
            'matched': self.matched,
            'values_differ': self.values_differ,
            'largest_difference': self.largest_difference,
            'recorded_only': self.recorded_only,
            'model_only': self.model_only,
            'differences': list(self.differences),
            'windows': self.windows,
            'error': self.error,
        }

    def text(self) -> str:
        """The outcome in one sentence."""
        if self.error is not None:
            return f'the line model could not be replayed: {self.error}'
        span = f'{self.recorded} recorded events from {self.t_from:.9g} to {self.t_end:.9g} s'
        if self.agree:
            return f"{span}: every one is the line model's (time to the ns, kind, sheet, cycle, value bit for bit)"
        parts = []
        if self.values_differ:
            parts.append(
                f'{self.values_differ} with another value (largest relative difference {self.largest_difference:.3g})'
            )
        if self.recorded_only:
            parts.append(f'{self.recorded_only} not in the model')
        if self.model_only:
            parts.append(f'{self.model_only} of the model not recorded')
        return f'{span}, {self.model} of the model: ' + '; '.join(parts)


_KEY = np.dtype([('ns', 'i8'), ('kind', 'i2'), ('sheet', 'i8'), ('cycle', 'i8'), ('value', 'f8')])


def _keys(ns: np.ndarray, events: np.ndarray) -> np.ndarray:
    out = np.zeros(events.size, dtype=_KEY)
    out['ns'] = ns
    for name in ('kind', 'sheet', 'cycle', 'value'):
        out[name] = events[name]
    return out


def _sorted(rows: np.ndarray) -> np.ndarray:
    out: np.ndarray = rows[np.lexsort((rows['value'], rows['cycle'], rows['sheet'], rows['kind'], rows['ns']))]
    return out


class _Comparison:
    """Recorded and model events matched window by window (an event within :data:`_CARRY_NS` of a window's
    end unmatched there is tried again in the next window: its ns may round across the cut)."""

    def __init__(self, check: EventCheck) -> None:
        self.check = check
        self.rec_carry = np.zeros(0, dtype=_KEY)
        self.mod_carry = np.zeros(0, dtype=_KEY)

    def _differ(self, row: Any, recorded: float | None, model: float | None) -> None:
        ck = self.check
        if len(ck.differences) < MAX_DIFFERENCES:
            ck.differences.append(
                {
                    't': int(row['ns']) / NS_PER_S,
                    'kind': EVENT_KINDS[int(row['kind'])],
                    'sheet': int(row['sheet']),
                    'cycle': int(row['cycle']),
                    'recorded': recorded,
                    'model': model,
                }
            )

    def window(self, recorded: np.ndarray, model: np.ndarray, end_ns: int | None) -> None:
        """Match a window's events (``end_ns`` its end; None: the last window, nothing carried on)."""
        ck = self.check
        ck.recorded += recorded.size
        ck.model += model.size
        r = _sorted(np.concatenate((self.rec_carry, recorded)))
        m = _sorted(np.concatenate((self.mod_carry, model)))
        key = ['ns', 'kind', 'sheet', 'cycle']
        if r.size == m.size and all(np.array_equal(r[k], m[k]) for k in key):
            r_only, m_only = np.zeros(0, dtype=_KEY), np.zeros(0, dtype=_KEY)
            pairs = [(r, m)]
        else:  # some differ: pair them by key
            pool: dict[tuple[int, int, int, int], list[int]] = {}
            for j, row in enumerate(m[key].tolist()):
                pool.setdefault(row, []).append(j)
            ri, mi, lone = [], [], []
            for i, row in enumerate(r[key].tolist()):
                js = pool.get(row)
                if js:
                    ri.append(i)
                    mi.append(js.pop(0))
                else:
                    lone.append(i)
            used = np.zeros(m.size, dtype=bool)
            used[mi] = True
            r_only, m_only = r[lone], m[~used]
            pairs = [(r[ri], m[mi])]
        for a, b in pairs:
            same = a['value'] == b['value']
            ck.matched += a.size
            diff = np.flatnonzero(~same)
            ck.values_differ += diff.size
            if diff.size:
                va, vb = a['value'][diff], b['value'][diff]
                scale = np.maximum(np.abs(va), np.abs(vb))
                rel = np.abs(va - vb) / np.where(scale > 0.0, scale, 1.0)
                ck.largest_difference = max(ck.largest_difference, float(rel.max()))
                for i in diff[: MAX_DIFFERENCES - len(ck.differences)].tolist():
                    self._differ(a[i], float(a['value'][i]), float(b['value'][i]))
        if end_ns is None:
            self.rec_carry, self.mod_carry = np.zeros(0, dtype=_KEY), np.zeros(0, dtype=_KEY)
        else:
            near_r, near_m = r_only['ns'] > end_ns - _CARRY_NS, m_only['ns'] > end_ns - _CARRY_NS
            self.rec_carry, self.mod_carry = r_only[near_r], m_only[near_m]
            r_only, m_only = r_only[~near_r], m_only[~near_m]
        ck.recorded_only += r_only.size
        ck.model_only += m_only.size
        for row in r_only:
            self._differ(row, float(row['value']), None)
        for row in m_only:
            self._differ(row, None, float(row['value']))


def _model_ns(events: np.ndarray) -> np.ndarray:
    """A model event's time as a node publishes it (``time_ref``: rounded to the ns, not before 0)."""
    return np.maximum(0, np.round(events['t'] * NS_PER_S).astype(np.int64))


def compare_events(
    rec: Recording, t_from: float = 0.0, *, window: float = WINDOW, fast_forward: float = FAST_FORWARD
) -> EventCheck:
    """The recorded events against the streamed line's, window by window (see the module docstring).

    Parameters
    ----------
    rec : Recording
    t_from : float, optional
        Compare from this line time on, s (``analyze --from``): the line is fast-forwarded there first.
    window : float, optional
        Line time per window compared, s (> 0). The result does not depend on it.
    fast_forward : float, optional
        Line time per window of the fast-forward, s (> 0).

    Returns
    -------
    EventCheck
        With ``error`` set if the line model cannot be built under the recorded commands.
    """
    check = EventCheck(t_from, rec.t_end)
    try:
        stream = LineStream(rec.scene, rec.commands)
    except (FolderLineError, ValueError) as exc:
        check.error = f'{type(exc).__name__}: {exc}'
        return check
    cmp = _Comparison(check)
    from_ns = round(t_from * NS_PER_S)
    pending = np.zeros(0, dtype=_KEY)  # the model's events at t_from (to the ns) from the fast-forward
    start = max(t_from, 0.0)
    if t_from > 0.0:  # fast-forward: nothing kept but the last window's events at t_from
        for cut in _cuts(0.0, t_from, fast_forward):
            w = stream.advance(cut)
        ns = _model_ns(w.events)
        keep = (ns >= from_ns) & without_unjudged(w.events, rec.unjudged)
        pending = _keys(ns[keep], w.events[keep])
    events, event_ns = rec.events, rec.event_ns
    lo = int(np.searchsorted(event_ns, from_ns, side='left'))
    cuts = _cuts(start, rec.t_end, window) if rec.t_end >= start else []
    for n, cut in enumerate(cuts, start=1):
        w = stream.advance(cut)
        last = n == len(cuts)
        end_ns = round(cut * NS_PER_S)
        hi = events.size if last else int(np.searchsorted(event_ns, end_ns, side='right'))
        judged = without_unjudged(w.events, rec.unjudged)  # a gap's cycles are not in the recording either
        model = np.concatenate((pending, _keys(_model_ns(w.events[judged]), w.events[judged])))
        pending = np.zeros(0, dtype=_KEY)
        cmp.window(_keys(event_ns[lo:hi], events[lo:hi]), model, None if last else end_ns)
        lo = hi
        check.windows += 1
    if pending.size:  # no window after the fast-forward
        cmp.window(_keys(event_ns[lo:], events[lo:]), pending, None)
    return check


# --------------------------------------------------------------------------- the supervisor


def recorded_transitions(states: Sequence[tuple[int, str]]) -> list[dict[str, Any]]:
    """The state changes of a ``/line/supervisor/state`` sequence.

    Returns
    -------
    list of dict
        ``{'t': log time of the first message in the new state (s), 'from': ..., 'to': ...}``;
        the first state is reported as a change from ``''``.
    """
    out: list[dict[str, Any]] = []
    prev = ''
    for t_ns, state in states:
        if state != prev:
            out.append({'t': t_ns / NS_PER_S, 'from': prev, 'to': state})
            prev = state
    return out


#: the live supervisor node's parameters as ``folder-line run`` starts it (its defaults, and the
#: rate of :class:`folder_line.ros.run.RunConfig`); a bag's custom data ``folder_line.supervisor``
#: (JSON) overrides them. test/test_analysis.py keeps them equal to the node's.
SUPERVISOR_DEFAULTS: dict[str, Any] = {'rate': 200.0, 'command_lead': 0.1, 'enforce': True, 'double_sheet': 'hold'}
#: custom data key of the supervisor's parameters in a bag
KEY_SUPERVISOR = 'folder_line.supervisor'


def supervisor_parameters(rec: Recording) -> dict[str, Any]:
    """The live supervisor's parameters: :data:`SUPERVISOR_DEFAULTS`, updated from the bag if it has them."""
    params = dict(SUPERVISOR_DEFAULTS)
    text = rec.bag.custom.get(KEY_SUPERVISOR)
    if text:
        try:
            stored = json.loads(text)
        except ValueError:
            stored = None
        if isinstance(stored, dict):
            params.update({k: v for k, v in stored.items() if k in params})
    return params


def replay_transitions(rec: Recording, params: Mapping[str, Any] | None = None) -> tuple[list[dict[str, Any]], Any]:
    """Replay the recorded inputs through :func:`folder_line.core.supervision.offline.replay`.

    The live supervisor node runs in lockstep: at every tick it is fed the events up to
    that tick (all of them: it waits until every machine node's tick is complete), the
    NaN/inf values found and the operator's commands, and decides exactly at the tick.
    All of these are in the bag (the operator's commands, lost participants and the
    first watermark in the supervisor's ``/diagnostics`` statuses). Its parameters:
    :func:`supervisor_parameters`, updated from ``params``. The logic needs no line model:
    it keeps the drive under the commands it issues.

    A bag with gaps (:mod:`folder_line.bag.gaps`) is replayed up to its first gap: what the
    supervisor decided after it depends on what it saw in it.

    Returns
    -------
    (list of dict, Supervisor)
        The transitions ``{'t', 'from', 'to', 'cause'}`` (decision time, s) and the
        replayed supervisor (its ``violations``, ``commands``, ``balances``).
    """
    p = supervisor_parameters(rec)
    p.update(params or {})
    period = 1.0 / float(p['rate'])
    starts = [float(v['t_start']) for _, _, v in rec.supervisor_status if 't_start' in v]
    if starts:
        t_start = starts[0]
    elif rec.diagnostics_ns.size:  # the first tick published the first /diagnostics, stamped with its time
        t_start = int(rec.diagnostics_ns.min()) / NS_PER_S  # the first watermark
    else:
        t_start = 0.0
    operator = [
        (float(v['t']), v['command'])
        for _, name, v in rec.supervisor_status
        if name.endswith('/operator') and 't' in v and 'command' in v
    ]
    tunings = accepted_tunings((name, v) for _, name, v in rec.supervisor_status)
    lost = [
        (float(v['t']), str(v['constraint']).split(':', 1)[1], -float(v['margin']))
        for _, name, v in rec.supervisor_status
        if name.endswith('/violation') and str(v.get('constraint', '')).startswith('lost:')
    ]
    kwargs: dict[str, Any] = {
        'periods': {},
        'lead': float(p['command_lead']),
        'check_period': period,
        'enforce': bool(p['enforce']),
        'double': str(p['double_sheet']),
        'state': 'STARTING',
        't_start': t_start,
    }
    events, until = rec.events, max(rec.t_end, t_start)
    if rec.gaps:  # what the supervisor did after a gap depends on what it saw in it: replayed up to the first
        until = min(until, max(rec.gaps[0].first_ns / NS_PER_S, t_start))
        events = events[rec.event_ns < rec.gaps[0].first_ns]
    sup = replay(
        rec.scene,
        events,
        bad_values=[b for b in rec.bad_values if b[0] <= until],
        operator=[o for o in operator if o[0] <= until],
        lost=[x for x in lost if x[0] <= until],
        tunings=[x for x in tunings if x[0] <= until],
        until=until,
        **kwargs,
    )
    out = [
        {'t': float(tr.t), 'from': tr.source, 'to': tr.target, 'cause': getattr(tr, 'cause', '')}
        for tr in sup.transitions
    ]
    return out, sup


def transitions_agree(
    replayed: Sequence[Mapping[str, Any]], recorded: Sequence[Mapping[str, Any]], initial: str = 'STARTING'
) -> bool:
    """Whether the recorded state sequence is the replayed one, as the state topic can show it.

    The supervisor publishes its state once per tick: states it passes through within
    one tick do not appear on the topic. So the recorded sequence of states must be
    the replayed one (``initial`` then each transition's target) with at most such
    states left out, ending in the same state; and each state shown must have been
    decided no later than it is shown, each showing paired with its own transition (a
    state the line enters twice, EXECUTE after an unhold, is two transitions).
    """
    full = [initial] + [str(t['to']) for t in replayed]
    decided = [-math.inf] + [float(t['t']) for t in replayed]
    seen = [str(t['to']) for t in recorded]
    if not seen:
        return not replayed
    if seen[-1] != full[-1]:
        return False
    i = 0
    for shown in recorded:  # a subsequence of full, each shown no earlier than it was decided
        state = str(shown['to'])
        while i < len(full) and full[i] != state:
            i += 1
        if i == len(full) or decided[i] > float(shown['t']):
            return False
        i += 1
    return True
