"""The line, streamed: :class:`LineStream` advances window by window from a carried state, for ever.

A stream holds the parts of the line the scene has (the folder with its delivery,
:class:`~folder_line.core.line.folder_stream.FolderStream`; the layup,
:class:`~folder_line.core.line.layup_stream.LayupStream`), the master drive under the
supervisor's commands and the operator's tunings, and the table under the counted
sheets (:class:`~folder_line.core.mechanisms.pile.PileStream`).
:meth:`LineStream.advance` ``(t)`` returns a :class:`Window`: the exact events with
times in ``(t_prev, t]``, sorted by time, kind, sheet, and the constraint rows judged
with them; afterwards :meth:`LineStream.sample` gives the joint states at any time of
the window (and up to ``keep`` s before it). The running :meth:`LineStream.summary`
(a :class:`~folder_line.core.line.line_summary.LineSummary`) is that of the events handed out.

Every event and row comes out of the same elementwise computation whatever the
windows, so a run cut into windows anywhere (a cycle, a flight, a ramp cut mid-way)
gives the events, samples, rows and summary of one window spanning the run, bit for
bit. Memory does not grow with line time: what is carried is the state of what is in
the machine (docs/architecture.md, *Streaming the line*).

Commands and checkpoints
------------------------
The work of a window is done up to ``t + lookahead`` (``lookahead`` is one step of the
``guide_friction`` integrator, else 0), and depends on the drive up to there only. A
command or tuning effective after that time is taken as it is
(:meth:`LineStream.set_commands`); one effective earlier needs the state from before
it: :meth:`LineStream.checkpoint` copies the state at the end of a window,
:meth:`LineStream.restore` goes back to it, and the windows after it are computed
again under the new commands -- the cost of a command depends on how far back its
checkpoint is, not on how long the line has run.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Literal, overload

import numpy as np
import numpy.typing as npt

from folder_line.core.line import drives
from folder_line.core.line.constraints import chute_speed_series
from folder_line.core.line.folder_state import FolderState
from folder_line.core.line.folder_stream import FolderStream
from folder_line.core.line.layup_stream import LayupState, LayupStream
from folder_line.core.line.line_summary import (
    JudgedFigures,
    LineSummary,
    MarginFigures,
    ViolationRecord,
    Violations,
)
from folder_line.core.line.tuning import LineCommand, Tuning, check_tuning, tunings_of, values_from
from folder_line.core.mechanisms.drive import Command, Drive, check_commands, theta_rate
from folder_line.core.mechanisms.pile import T_LOWER, PileStream, counted_event
from folder_line.core.types.events import (
    EVENT_KINDS,
    ConstraintSeries,
    JointSamples,
    empty_events,
    merge_events,
)

if TYPE_CHECKING:
    from folder_line.core.line.scene import Scene

__all__ = [
    'MAX_VIOLATIONS',
    'UNITS',
    'Checkpoint',
    'ConstraintTally',
    'LineStream',
    'StreamDriveFactory',
    'StreamParts',
    'Window',
    'check_line_commands',
    'judged_figures',
]

#: the line's machine units that carry joints, in publishing order (``folder_line.interfaces.NODE_OF_UNIT``)
UNITS = ('drive', 'belts', 'feed', 'counter')
#: violations listed per constraint in a summary
MAX_VIOLATIONS = 10
#: ``(scene, commands, previous drive) -> Drive``: how a :class:`LineStream` makes its master drive
StreamDriveFactory = Callable[['Scene', tuple[LineCommand, ...], Drive | None], Drive]


def check_line_commands(commands: Iterable[LineCommand]) -> tuple[LineCommand, ...]:
    """The supervisor's drive commands and the operator's tunings as one tuple, checked: each a
    :class:`Command` or a :class:`~folder_line.core.line.tuning.Tuning`, sorted by effective time.

    Raises
    ------
    ParameterError
        Anything else, or one earlier than the one before it.
    """
    return check_commands(commands, (Command, Tuning), 'a drive Command or a Tuning')


@dataclass(frozen=True, eq=False)
class Window:
    """What one :meth:`LineStream.advance` hands out.

    Attributes
    ----------
    t0, t1 : float
        The window ``(t0, t1]``, s (``t0`` is ``-inf`` for the first).
    events : ndarray of EVENT_DTYPE
        The events of the window, sorted by time, kind, sheet.
    constraints : list of ConstraintSeries
        The rows judged in the window, per constraint (the folder's, then the layup's).
    """

    t0: float
    t1: float
    events: np.ndarray
    constraints: list[ConstraintSeries]


@dataclass
class ConstraintTally:
    """A constraint's rows so far: counts, the smallest margin and where, the first violations, the last row.

    Attributes
    ----------
    name, unit, description : str
    evaluations, violations : int
    min_margin : float
        ``inf`` before any row.
    min_cycle : int
        The first row with the smallest margin (its cycle, or leaf).
    first : list of (int, float)
        ``(cycle, margin)`` of the first :data:`MAX_VIOLATIONS` violations, in row order.
    last_margin, last_cycle, last_t
        The row decided last (its decision time ``last_t``, s).
    """

    name: str
    unit: str
    description: str
    evaluations: int = 0
    violations: int = 0
    min_margin: float = math.inf
    min_cycle: int = -1
    first: list[tuple[int, float]] = field(default_factory=list)
    last_margin: float = 0.0
    last_cycle: int = -1
    last_t: float = -math.inf

    def add(self, rows: ConstraintSeries) -> None:
        """Count the rows of a window (in their order)."""
        n = int(rows.margin.size)
        if n == 0:
            return
        self.evaluations += n
        bad = np.flatnonzero(rows.margin < 0.0)
        self.violations += int(bad.size)
        room = MAX_VIOLATIONS - len(self.first)
        if room > 0:
            self.first += [(int(rows.cycle[i]), float(rows.margin[i])) for i in bad[:room]]
        i = int(np.argmin(rows.margin))
        if rows.margin[i] < self.min_margin:
            self.min_margin, self.min_cycle = float(rows.margin[i]), int(rows.cycle[i])
        j = int(np.argmax(rows.t))
        if rows.t[j] >= self.last_t:
            self.last_margin, self.last_cycle, self.last_t = float(rows.margin[j]), int(rows.cycle[j]), float(rows.t[j])


@dataclass
class _Tallies:
    """The stream's running figures: constraints, event counts, the last event."""

    constraints: dict[str, ConstraintTally]
    kinds: np.ndarray = field(default_factory=lambda: np.zeros(len(EVENT_KINDS), dtype=np.int64))


@dataclass(frozen=True, eq=False)
class StreamParts:
    """What a :class:`Checkpoint` copies of a stream: each part's state, the pile, the running figures and
    the line time before the window that :meth:`LineStream.sample` may still be asked for (``t_keep``, s)."""

    folder: FolderState | None
    layup: LayupState | None
    pile: PileStream
    tallies: _Tallies
    t_keep: float


@dataclass(frozen=True, eq=False)
class Checkpoint:
    """The state of a :class:`LineStream` at the end of a window (:meth:`LineStream.checkpoint`).

    Attributes
    ----------
    t : float
        Line time handed out to, s.
    computed : float
        Line time the work was done to, s (``t`` plus the stream's lookahead).
    commands : tuple of Command or Tuning
        The commands the state was computed under.
    parts : StreamParts
        A copy of the parts' state.
    drive : Drive
        A copy of the master drive.
    """

    t: float
    computed: float
    commands: tuple[LineCommand, ...]
    parts: StreamParts
    drive: Drive


class LineStream:
    """The line of a scene, advanced window by window (see the module docstring).

    Parameters
    ----------
    scene : Scene
        Validated scene.
    commands : iterable of Command or Tuning
        The supervisor's drive commands and the operator's tunings known so far, sorted
        by effective time (more may follow: :meth:`set_commands`).
    keep : float
        Line time before each window that :meth:`sample` may still be asked for, s (>= 0).
    judge : bool
        Judge the constraints and keep the running summary (default). False hands out
        the events and joint states alone, faster (a machine node that publishes them):
        no rows, and :meth:`summary` counts nothing.
    drive_factory : callable, optional
        ``(scene, commands, previous drive) -> Drive`` (default
        :func:`folder_line.core.line.drives.make_drive`).

    Attributes
    ----------
    scene : Scene
    commands : tuple of Command or Tuning
    drive : Drive
    t : float
        Line time handed out so far, s (``-inf`` before the first window).
    computed : float
        Line time the work was done to, s.
    lookahead : float
        How far past a window's end its work goes, s.
    pile : PileStream
    units : dict of str to tuple of str
        Unit -> its joint names (in :meth:`sample`'s columns; units without joints absent).
    """

    def __init__(
        self,
        scene: Scene,
        commands: Iterable[LineCommand] = (),
        *,
        keep: float = 0.0,
        judge: bool = True,
        drive_factory: StreamDriveFactory | None = None,
    ) -> None:
        self.scene = scene
        self._factory = drive_factory or drives.make_drive
        self.commands = check_line_commands(commands)
        for tu in tunings_of(self.commands):
            check_tuning(scene, tu.key, tu.value)
        self.drive: Drive = self._factory(scene, self.commands, None)
        self.keep = float(keep)
        self.t = -math.inf
        self.computed = -math.inf
        self._t_keep = -math.inf
        self._before: list[Checkpoint] = []
        tunings = tunings_of(self.commands)
        self.judge = judge
        self.folder = FolderStream(scene, self.drive, tunings, judge=judge) if scene.has_folder else None
        self.layup = LayupStream(scene, self.drive, tunings, judge=judge) if scene.has_layup else None
        self.lookahead = self.layup.lookahead if self.layup is not None else 0.0
        self.pile = PileStream(
            scene.has_delivery, scene.sheets.thickness, values_from(tunings, 'pile.t_lower', T_LOWER)
        )
        self._counted = EVENT_KINDS.index(counted_event(scene.has_delivery))
        self._unit_parts = self._parts_of_units()
        self.units = {unit: tuple(n for p in ps for n in p.units[unit]) for unit, ps in self._unit_parts.items()}
        tallies: dict[str, ConstraintTally] = {}
        if self.folder is not None:
            for name in self.folder.constraint_names:
                empty = self.folder.empty_rows[name]
                tallies[name] = ConstraintTally(name, empty.unit, empty.description)
        if self.layup is not None and scene.has('chute_belts'):
            series = chute_speed_series(scene, np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0))
            assert series is not None
            tallies['chute_speed'] = ConstraintTally('chute_speed', series.unit, series.description)
        self.tallies = _Tallies(tallies)

    # ------------------------------------------------------------------ parts

    def _parts_of_units(self) -> dict[str, list[FolderStream | LayupStream | PileStream]]:
        """Unit -> the parts that sample its joints, the units in :data:`UNITS` order."""
        units: dict[str, list[FolderStream | LayupStream | PileStream]] = {}
        for p in [self.folder, self.layup, self.pile]:
            if p is not None:
                for unit in p.units:
                    units.setdefault(unit, []).append(p)
        return {unit: units[unit] for unit in UNITS if unit in units}

    @property
    def parts(self) -> dict[str, FolderStream | LayupStream]:
        """Part name -> its stream (``'folder'``, ``'layup'``)."""
        out: dict[str, FolderStream | LayupStream] = {}
        if self.folder is not None:
            out['folder'] = self.folder
        if self.layup is not None:
            out['layup'] = self.layup
        return out

    @overload
    def part(self, name: Literal['folder']) -> FolderStream: ...
    @overload
    def part(self, name: Literal['layup']) -> LayupStream: ...
    @overload
    def part(self, name: str) -> FolderStream | LayupStream: ...
    def part(self, name: str) -> FolderStream | LayupStream:
        """The part ``'folder'`` or ``'layup'`` (KeyError naming the parts)."""
        try:
            return self.parts[name]
        except KeyError:
            msg = f'scene {self.scene.name!r} has no part {name!r}; parts: {", ".join(self.parts)}'
            raise KeyError(msg) from None

    # ------------------------------------------------------------------ windows

    def advance(self, t: float) -> Window:
        """Hand out everything up to line time ``t`` (s, after the last window's end).

        Returns
        -------
        Window
        """
        t = float(t)
        if not math.isfinite(t):
            raise ValueError(f'LineStream.advance: t must be finite, got {t!r}')
        if t < self.t:
            raise ValueError(f'LineStream.advance({t!r}): already handed out to {self.t!r} s')
        t0 = self.t
        if self.lookahead > 0.0:  # the work of a window goes past its end: keep recent starts for a late command
            self._before = [*self._before[-2:], self.checkpoint()]
        c = max(t + self.lookahead, self.computed)
        extend = getattr(self.drive, 'extend', None)
        if extend is not None:
            extend(c)
        tables: list[np.ndarray] = []
        rows: list[ConstraintSeries] = []
        for p in (self.folder, self.layup):
            if p is not None:
                p.compute(c)
                ev, r = p.emit(t)
                tables.append(ev)
                rows += r
        self.computed = c
        self.t = t
        events = merge_events(tables) if len(tables) > 1 else (tables[0] if tables else empty_events())
        self._tally(events, rows)
        self._prune(t0)
        return Window(t0, t, events, rows)

    def finish(self) -> list[ConstraintSeries]:
        """The rows of the folder cycles still waiting for a signature at the end of the run (judged on the
        events so far, as a batch run of this length judges them); counted in the tallies."""
        rows = self.folder.finish() if self.folder is not None else []
        self._tally(empty_events(), rows)
        return rows

    def _tally(self, events: np.ndarray, rows: list[ConstraintSeries]) -> None:
        tl = self.tallies
        if events.size:
            tl.kinds += np.bincount(events['kind'], minlength=len(EVENT_KINDS))
            counted = events['t'][events['kind'] == self._counted]
            if counted.size:
                self.pile.add(counted)
        for r in rows:
            tl.constraints[r.name].add(r)

    def _prune(self, t0: float) -> None:
        """Forget what no query can ask for any more: before the window's start less ``keep``."""
        keep = t0 - self.keep
        if self.folder is not None:  # a cycle judged late reads the drive from its start on
            keep = min(keep, self.folder.earliest_needed())
        if not math.isfinite(keep) or keep <= self._t_keep:
            return
        self._t_keep = keep
        self.pile.prune(keep)
        for p in (self.folder, self.layup):
            if p is not None:
                p.prune(keep)
        prune = getattr(self.drive, 'prune', None)
        if prune is not None:
            prune(keep)

    # ------------------------------------------------------------------ commands

    def set_commands(self, commands: Iterable[LineCommand]) -> None:
        """The commands from now on: every one effective at or before the time handed out must be among the
        commands already taken (else :meth:`restore` a checkpoint from before it first).

        A command effective after the time handed out but within the last window's work (its lookahead)
        redoes that window from a copy of its start, the events handed out unchanged.

        Raises
        ------
        ValueError
            A command effective at or before :attr:`t` is new or gone.
        ParameterError
            A tuning the scene cannot take, or commands out of order.
        """
        new = check_line_commands(commands)
        for tu in tunings_of(new):
            check_tuning(self.scene, tu.key, tu.value)
        if self.computed > self.t and self._changed_by(new, self.t) is None:
            changed = self._changed_by(new, self.computed)
            if changed is not None:  # effective within the lookahead of the windows: redo them
                start = next((cp for cp in reversed(self._before) if cp.computed < changed.t), None)
                if start is not None:
                    ends = [cp.t for cp in self._before if cp.t > start.t] + [self.t]
                    self.restore(start, new)
                    for t_end in ends:
                        self.advance(t_end)
                    return
        old_past = [c for c in self.commands if c.t <= self.computed]
        new_past = [c for c in new if c.t <= self.computed]
        if old_past != new_past:
            changed = next((c for c in new if c.t <= self.computed and c not in old_past), None) or next(
                c for c in old_past if c not in new_past
            )
            raise ValueError(
                f'a command effective at {changed.t!r} s changes line time already computed '
                f'(to {self.computed!r} s): restore a checkpoint from before it first'
            )
        if new == self.commands:
            return
        self.commands = new
        self._apply_commands()

    def _changed_by(self, new: tuple[LineCommand, ...], t: float) -> LineCommand | None:
        """A command effective at or before ``t`` that ``new`` adds or drops (None if none)."""
        old_past = [c for c in self.commands if c.t <= t]
        new_past = [c for c in new if c.t <= t]
        if old_past == new_past:
            return None
        return next((c for c in new_past if c not in old_past), None) or next(c for c in old_past if c not in new_past)

    def _apply_commands(self) -> None:
        self.drive = self._factory(self.scene, self.commands, self.drive)
        tunings = tunings_of(self.commands)
        for p in (self.folder, self.layup):
            if p is not None:
                p.set_drive(self.drive)
                p.set_tunings(tunings)
        self.pile.set_steps(values_from(tunings, 'pile.t_lower', T_LOWER))

    def checkpoint(self) -> Checkpoint:
        """A copy of the state at the end of the last window (bounded in size, like the state)."""
        parts = StreamParts(
            None if self.folder is None else self.folder.state,
            None if self.layup is None else self.layup.state,
            self.pile,
            self.tallies,
            self._t_keep,
        )
        memo: dict[int, object] = {id(self.drive): self.drive, id(self.scene): self.scene}
        slider = None if self.layup is None else self.layup.state.slider
        if slider is not None:  # the kinematics are the stream's own, not state
            memo[id(slider.kin)], memo[id(slider.kin1)] = slider.kin, slider.kin1
        copied = copy.deepcopy(parts, memo)
        return Checkpoint(self.t, self.computed, self.commands, copied, copy.deepcopy(self.drive))

    def restore(self, cp: Checkpoint, commands: Iterable[LineCommand] | None = None) -> None:
        """Go back to ``cp`` (the state then), under ``commands`` (default: the checkpoint's; every one
        effective at or before the checkpoint's computed time must be the checkpoint's)."""
        new = check_line_commands(cp.commands if commands is None else commands)
        past = [c for c in cp.commands if c.t <= cp.computed]
        if [c for c in new if c.t <= cp.computed] != past:
            raise ValueError(
                f"commands effective by {cp.computed!r} s differ from the checkpoint's: take an earlier checkpoint"
            )
        for tu in tunings_of(new):
            check_tuning(self.scene, tu.key, tu.value)
        parts = copy.deepcopy(cp.parts, {id(self.scene): self.scene})
        self.drive = copy.deepcopy(cp.drive)
        self.t, self.computed, self.commands = cp.t, cp.computed, cp.commands
        self._t_keep = parts.t_keep
        self._before = []
        self.pile = parts.pile
        self._unit_parts = self._parts_of_units()  # the pile is a new object
        self.tallies = parts.tallies
        if self.folder is not None and parts.folder is not None:
            self.folder.set_drive(self.drive)
            self.folder.restore(parts.folder)
        if self.layup is not None and parts.layup is not None:
            self.layup.set_drive(self.drive)
            self.layup.restore(parts.layup)
        if new != self.commands:
            self.commands = new
            self._apply_commands()

    # ------------------------------------------------------------------ joint states

    def sample(self, unit: str, t: npt.ArrayLike) -> JointSamples:
        """Joint states of one unit at line times ``t`` (s, within ``[window start - keep, t]``).

        Raises
        ------
        KeyError
            ``unit`` has no joints in this scene (the message lists the units).
        """
        parts = self._unit_parts.get(unit)
        if parts is None:
            msg = f'unit {unit!r} has no joints in scene {self.scene.name!r}; units: {", ".join(self.units)}'
            raise KeyError(msg)
        tt = np.asarray(t, dtype=float).reshape(-1)
        theta, lam = theta_rate(self.drive, tt)
        return _merge(unit, [p.sample_unit(unit, tt, theta, lam) for p in parts])

    def sample_all(self, t: npt.ArrayLike) -> dict[str, JointSamples]:
        """Joint states of every unit at line times ``t`` (unit -> JointSamples)."""
        tt = np.asarray(t, dtype=float).reshape(-1)
        theta, lam = theta_rate(self.drive, tt)
        return {
            unit: _merge(unit, [p.sample_unit(unit, tt, theta, lam) for p in parts])
            for unit, parts in self._unit_parts.items()
        }

    # ------------------------------------------------------------------ summary

    def summary(self, max_violations: int = MAX_VIOLATIONS) -> LineSummary:
        """The summary of the events and rows handed out so far (the ``simulate`` summary)."""
        scene = self.scene
        folder = layup = None
        if self.folder is not None:
            folder = self.folder.summary()
        if self.layup is not None:
            theta = float(np.asarray(self.drive.theta(np.array([max(self.t, 0.0)])), dtype=float)[0])
            layup = self.layup.summary(theta)
        judged = judged_figures(self.tallies.constraints.values(), self.tallies.kinds, max_violations)
        if folder is not None:
            cycles, counted = folder.cycles, folder.sheets_counted
        else:
            cycles, counted = (layup.crank_cycles, layup.leaves_landed) if layup is not None else (0, 0)
        return LineSummary(
            scene=scene.name,
            duration_s=max(self.t, 0.0),
            seed=scene.seed,
            effects=list(scene.effects),
            cycles=cycles,
            sheets_counted=counted,
            violations=judged.violations,
            min_margin=judged.min_margin,
            events=judged.events,
            folder=folder,
            layup=layup,
        )


def judged_figures(
    tallies: Iterable[ConstraintTally], kinds: np.ndarray, max_violations: int = MAX_VIOLATIONS
) -> JudgedFigures:
    """The violations, smallest margins and event counts of some constraint rows and events.

    Parameters
    ----------
    tallies : iterable of ConstraintTally
        The rows, per constraint (margins in each constraint's unit).
    kinds : ndarray of int
        Events per kind, indexed as :data:`folder_line.core.types.events.EVENT_KINDS`.
    max_violations : int
        Violations listed per constraint, and in all.
    """
    violations: list[ViolationRecord] = []
    count = 0
    min_margin: dict[str, MarginFigures] = {}
    for tally in tallies:
        count += tally.violations
        violations += [ViolationRecord(cyc, tally.name, m, tally.unit) for cyc, m in tally.first[:max_violations]]
        if tally.evaluations:
            min_margin[tally.name] = MarginFigures(
                tally.min_margin, tally.unit, tally.min_cycle, tally.evaluations, tally.violations
            )
    violations.sort(key=lambda v: (v.cycle, v.constraint))
    events = {k: int(n) for k, n in zip(EVENT_KINDS, kinds.tolist(), strict=True) if n}
    return JudgedFigures(Violations(count, violations[:max_violations]), min_margin, events)


def _merge(unit: str, parts: list[JointSamples]) -> JointSamples:
    """Joints of one unit from several parts, concatenated in part order (efforts 0 where a part has none)."""
    merged = parts[0]
    for js in parts[1:]:
        prev = merged
        eff = None
        if prev.effort is not None or js.effort is not None:
            eff = np.hstack(
                [
                    prev.effort if prev.effort is not None else np.zeros_like(prev.position),
                    js.effort if js.effort is not None else np.zeros_like(js.position),
                ]
            )
        merged = JointSamples(
            unit,
            prev.names + js.names,
            prev.t,
            np.hstack([prev.position, js.position]),
            np.hstack([prev.velocity, js.velocity]),
            eff,
        )
    return merged
