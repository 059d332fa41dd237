"""The supervisor's logic: :class:`Supervisor`, fed with what the live node sees, advanced by ticks.

:class:`Supervisor` is fed incrementally with what the live supervisor node sees —
the exact events as the machine nodes publish them (:meth:`Supervisor.feed`, any
batching, any order), the stamps at which it hears each node
(:meth:`Supervisor.heard`), non-finite values found in messages
(:meth:`Supervisor.bad_value`), the operator's commands
(:meth:`Supervisor.command`) — and advanced by :meth:`Supervisor.tick`. It decides
the PackML transitions (:class:`folder_line.core.supervision.packml.PackML`) and the drive
commands (:class:`folder_line.core.mechanisms.drive.Command`, with their effective times) to
issue, records every constraint violation (cycle, constraint, margin) and checks
the sheet balance at every stop. It takes its parts from the modules around it:
the checked parameters (:mod:`~folder_line.core.supervision.settings`), the cycle
evaluation (:mod:`~folder_line.core.supervision.evaluation`), liveness
(:mod:`~folder_line.core.supervision.liveness`), command scheduling and acting states
(:mod:`~folder_line.core.supervision.commands`) on the check grid
(:mod:`~folder_line.core.supervision.grid`), the sheet balance
(:mod:`~folder_line.core.supervision.balance`) and its records
(:mod:`~folder_line.core.supervision.records`).

Time and determinism
--------------------
``tick(W)`` declares that every input with a time at or before ``W`` (the
*watermark*, s of line time) has been fed. The supervisor then takes, in time
order, every decision due at or before ``W``. Each decision has an exact time that
depends on the inputs only, never on when the call came:

* a folder cycle at its ``knife_contact``, a release at its ``released_on_pile``
  time, a leaf at its ``leaf_exit`` (:mod:`folder_line.core.supervision.evaluation`);
* a non-finite value at the stamp of its message;
* liveness (:mod:`folder_line.core.supervision.liveness`) and the end of acting states
  (:mod:`folder_line.core.supervision.commands`) on the *check grid* ``t = n h``
  (``h = check_period``);
* an operator command at the time it is given (the watermark then).

Given the same inputs, any sequence of calls that respects the watermark contract
(no input at or before a watermark already passed) therefore takes the same
decisions at the same times. (Before its effective time a command changes nothing,
bit for bit: the drive under the commands is the same as before up to there.)
An input that breaks the contract (it came too late, e.g. a node's message delayed
past the watermark) is still used where possible and counted in
:attr:`Supervisor.late`: the live node keeps its watermark ``event_latency`` s
behind its clock so that this does not happen, and reports the count. Line time
starts at 0: the watermark is never below it.

Decisions
---------
After each judged cycle (or release, or leaf exit) with a negative margin:

* a timing constraint (``feed_window``, ``settled_before_knife``, ``rebound``,
  ``chute_speed``, ``release_at_min_speed``) -> ``hold``: HOLDING, then HELD at
  standstill;
* ``one_per_cycle`` with no signature at the knife (a missing sheet, or one handed
  over too late to be known at the knife contact: starvation) -> ``suspend``:
  SUSPENDING, then SUSPENDED at standstill;
* ``one_per_cycle`` with two signatures (a double sheet) -> ``hold`` by default
  (``double='hold'``): the double is a fault of the process — two signatures
  folded together, a bad product — not a hazard; the machine is whole and nothing
  jams, so the operator removes the double and unholds. ``double='abort'`` treats
  it as an interlock instead;
* a timing fault and a starvation in the same cycle: ``hold`` (the stronger one);
* a folder cycle is judged only once the sheets' publisher (``sheet_source``: the
  participant that runs the unit :data:`SHEET_UNIT`), if it is watched, has been heard: knife
  contacts without a feed node running are not a starvation of the line but a missing
  node (a liveness matter);
* a node not heard within ``k`` periods, or a NaN/inf in any message -> ``abort``:
  ABORTING, then ABORTED at standstill, which only ``clear`` leaves (CLEARING ->
  STOPPED). Staleness is edge-triggered: one abort per stale episode (the node must
  be heard again before it can trigger another).

A decision is applied only where PackML allows it (a hold while HOLDING changes
nothing); the violation is recorded either way, with the action taken (``'none'``
if none). With ``enforce=False`` nothing is commanded: violations are only
recorded. On entering HELD, SUSPENDED, STOPPED, ABORTED or COMPLETE the sheet
balance is checked (:mod:`folder_line.core.supervision.balance`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence

import numpy as np

from folder_line.core.line.margin_text import format_margin, margin_at
from folder_line.core.line.scene import Scene
from folder_line.core.line.tuning import TUNABLES, LineCommand, Tuning, check_tuning
from folder_line.core.mechanisms.drive import Command, Drive
from folder_line.core.numerics.validate import as_float
from folder_line.core.supervision.balance import Balance, SheetBalance
from folder_line.core.supervision.commands import (
    DRIVE_COMMANDS,
    STOP_STATES,
    ActingState,
    DriveFactory,
    DriveSchedule,
    line_drives,
)
from folder_line.core.supervision.evaluation import CycleEvaluation, Due
from folder_line.core.supervision.grid import CheckGrid
from folder_line.core.supervision.liveness import Liveness
from folder_line.core.supervision.packml import PackML, Transition
from folder_line.core.supervision.records import ConstraintStats, Outcome, Violation
from folder_line.core.supervision.settings import CHECK_PERIOD, SPEED_REACHED, STALE_PERIODS, Settings
from folder_line.core.types.events import EVENT_DTYPE
from folder_line.errors import ParameterError, TransitionError

__all__ = ['SHEET_UNIT', 'TIMING_CONSTRAINTS', 'Supervisor']

#: constraints whose violation is a timing fault of the process (-> HELD)
TIMING_CONSTRAINTS = ('feed_window', 'settled_before_knife', 'rebound', 'chute_speed', 'release_at_min_speed')
#: the machine unit (:data:`folder_line.core.line.stream.UNITS`) whose participant publishes the sheets'
#: events: the caller names that participant as ``sheet_source``
SHEET_UNIT = 'feed'
#: what a decision acts on: the evaluation due (``'eval'``), None (``'complete'``), or the topic and count
#: of bad values, the participant and its wall time waited, or the stale node and its last stamp
_DecisionArg = Due | tuple[str, float] | None


class Supervisor:
    """The line supervisor's logic (see the module docstring).

    Parameters
    ----------
    scene : Scene
        The line's scene.
    periods : mapping of str to float, optional
        Known node -> its publishing period, s of line time. A known node is watched
        from its first stamp on (or from ``t_start`` if ``expected``). Default: none.
    expected : iterable of str
        Known nodes that must be heard from ``t_start`` on (a node that never starts
        is then stale too).
    clock_ticks : bool
        Staleness also needs ``ceil(k)`` clock messages (:meth:`clock`) after the
        node's last stamp: the node missed ``k`` chances to publish, not only ``k``
        periods of sim time (a clock that steps by more than a period, at a high
        real-time factor or in a burst after a stall, does not make every node stale).
    stale_periods, lead, check_period, enforce, double, speed_reached
        The supervisor's settings, checked once into :attr:`settings`; each is documented
        at :class:`~folder_line.core.supervision.settings.Settings` (``stale_periods`` is its
        ``k``; default :data:`~folder_line.core.supervision.settings.STALE_PERIODS`).
    state : str
        Initial PackML state (default STARTING: the scene's drive starts the line at
        t = 0, which is when the run command is effective).
    t_start : float or None
        Time the supervisor starts watching, s: nodes are expected from then on.
        None: the first :meth:`tick`'s watermark (recorded in :attr:`t_start`;
        :func:`~folder_line.core.supervision.offline.replay` needs it).
    drive_factory : callable, optional
        ``(commands, previous drive) -> Drive`` (default
        :func:`~folder_line.core.supervision.commands.line_drives`): the drive under the
        issued commands, whose speed ends the acting states and whose phase times the
        machine cycles.
    sheet_source : str, optional
        The watched participant that publishes the sheets' events (the one that runs
        the unit :data:`SHEET_UNIT`): a folder cycle is judged only once it has been
        heard. Default None: no such wait.

    Attributes
    ----------
    settings : Settings
        The checked parameters.
    packml : PackML
        State and history (:attr:`transitions`).
    commands : tuple of Command
        Drive commands issued, sorted by effective time.
    violations : list of Violation
    balances : list of Balance
    stats : dict of str to ConstraintStats
    operator_log : list of (float, str, bool)
        Operator commands ``(t, command, accepted)``.
    tuning_log : list of (float, str, object, float)
        Tunings asked for ``(t, key, value, effective time)`` (NaN if refused).
    now : float
        The watermark: decisions up to it are taken (``-inf`` before the first tick).
    late : int
        Inputs that came at or before a watermark already passed.
    """

    def __init__(
        self,
        scene: Scene,
        *,
        periods: Mapping[str, float] | None = None,
        expected: Iterable[str] = (),
        clock_ticks: bool = False,
        stale_periods: float = STALE_PERIODS,
        lead: float = 0.0,
        check_period: float = CHECK_PERIOD,
        enforce: bool = True,
        double: str = 'hold',
        speed_reached: float = SPEED_REACHED,
        state: str = 'STARTING',
        t_start: float | None = 0.0,
        drive_factory: DriveFactory | None = None,
        sheet_source: str | None = None,
    ) -> None:
        self.scene = scene
        self.settings = Settings(stale_periods, lead, check_period, enforce, double, speed_reached)
        self.packml = PackML(state)
        self.t_start = None if t_start is None else as_float('t_start', t_start)
        grid = CheckGrid(self.settings.check_period)
        self.liveness = Liveness(periods, expected, self.t_start, self.settings.stale_periods, grid, clock_ticks)
        self.sheet_source = sheet_source
        factory = line_drives(scene) if drive_factory is None else drive_factory
        self._drive = DriveSchedule(scene, factory, self.settings.lead)
        # acting state: from the time its drive command is effective (or the command's time)
        since = 0.0 if self.t_start is None else max(self.t_start, 0.0)
        self._acting = ActingState(grid, self.settings.speed_reached, since)
        self._cycles = CycleEvaluation(scene)
        self._sheets = SheetBalance(scene, with_delivery=self._cycles.plan is not None)
        self.violations: list[Violation] = []
        self.balances: list[Balance] = []
        self.stats: dict[str, ConstraintStats] = {}
        self.operator_log: list[tuple[float, str, bool]] = []
        self.tuning_log: list[tuple[float, str, object, float]] = []
        self.now = -math.inf
        self.late = 0
        self._bad: list[tuple[float, str, int]] = []
        self._lost: list[tuple[float, str, float]] = []
        self.blind_from = math.inf  # no judgement from here on: a participant was lost
        self.lost_nodes: list[str] = []
        self._due: list[Due] = []

    # ------------------------------------------------------------------ properties

    @property
    def state(self) -> str:
        """The PackML state."""
        return self.packml.state

    @property
    def transitions(self) -> list[Transition]:
        """Every transition so far (the PackML history)."""
        return self.packml.history

    @property
    def commands(self) -> tuple[LineCommand, ...]:
        """Drive commands and tunings issued, sorted by effective time."""
        return self._drive.commands

    @property
    def drive(self) -> Drive:
        """The drive under the commands issued so far."""
        return self._drive.drive

    @property
    def watched(self) -> dict[str, float]:
        """Watched node -> period, s."""
        return self.liveness.watched

    @property
    def clock_ticks(self) -> bool:
        """Staleness also needs clock messages (:meth:`clock`)."""
        return self.liveness.clock_ticks

    def stale_nodes(self) -> list[str]:
        """Nodes in a stale episode now."""
        return self.liveness.stale_nodes()

    def _drive_before(self, t: float) -> Callable[[], Drive]:
        """The drive that is right at times before ``t``, when asked for."""
        return lambda: self._drive.drive

    # ------------------------------------------------------------------ inputs

    def feed(self, rows: np.ndarray) -> None:
        """Events as published (any batching, any order).

        Parameters
        ----------
        rows : ndarray of EVENT_DTYPE
            Exact events; a row with a non-finite time or value is not used and
            counts as a bad value of ``/line/events`` (at its time, or at the
            watermark if its time is not finite).
        """
        rows = np.asarray(rows)
        if rows.dtype != EVENT_DTYPE:
            raise ParameterError('rows', rows.dtype, 'must be an array of EVENT_DTYPE')
        rows = rows.reshape(-1)
        if rows.size == 0:
            return
        ok = np.isfinite(rows['t']) & np.isfinite(rows['value'])
        if not ok.all():
            for r in rows[~ok]:
                t = float(r['t']) if math.isfinite(float(r['t'])) else self.now
                self.bad_value('/line/events', t if math.isfinite(t) else 0.0)
            rows = rows[ok]
        self.late += int(np.count_nonzero(rows['t'] <= self.now))
        self._cycles.add(rows)
        self._sheets.add(rows)

    def preview(self, rows: np.ndarray) -> None:
        """Events that will be fed (:meth:`feed`, in any batching) before the drive changes: their
        cycles are evaluated now, at once, and judged at their times as if evaluated then
        (:meth:`CycleEvaluation.preview <folder_line.core.supervision.evaluation.CycleEvaluation.preview>`).
        Changes no decision; a run that knows its events ahead (``simulate --bag``) is faster.
        """
        rows = np.asarray(rows).reshape(-1)
        if rows.dtype != EVENT_DTYPE:
            raise ParameterError('rows', rows.dtype, 'must be an array of EVENT_DTYPE')
        rows = rows[np.isfinite(rows['t']) & np.isfinite(rows['value'])]
        self._cycles.preview(rows, self._drive.drive)

    def heard(self, node: str, t: float | Sequence[float] | np.ndarray) -> None:
        """Node ``node`` was heard at stamp(s) ``t`` (s); nodes not watched are ignored."""
        self.late += self.liveness.heard(node, t, self.now)

    def clock(self, t: float | Sequence[float] | np.ndarray) -> None:
        """Clock message(s) stamped ``t`` (s) received (used with ``clock_ticks``)."""
        self.liveness.clock(t)

    def lost(self, node: str, t: float, waited: float) -> None:
        """Participant ``node`` stopped answering: nothing of it is known after ``t`` (s).

        It is decided at ``t`` (or at once if that passed): ``abort`` with cause
        ``lost:<node>`` (margin: minus the wall seconds ``waited``, unit ``wall s``).
        From ``t`` on no cycle, release or leaf exit is judged any more: its input may be
        missing, and a judgement is never made on missing input (the balance at the stop
        still counts what was received, and says so in its detail).
        """
        t = as_float('t', t)
        if not math.isfinite(t):
            raise ParameterError('t', t, 'the time a node was lost must be finite')
        self._lost.append((max(t, self.now), str(node), float(waited)))
        self.blind_from = min(self.blind_from, max(t, self.now))

    def bad_value(self, topic: str, t: float, count: int = 1) -> None:
        """A message of ``topic`` stamped ``t`` (s) carried ``count`` NaN/inf values."""
        t = float(t)
        if not math.isfinite(t):
            raise ParameterError('t', t, 'the stamp of a message must be finite')
        if t <= self.now:
            self.late += 1
        self._bad.append((t, str(topic), max(int(count), 1)))

    # ------------------------------------------------------------------ operator

    def _operator_time(self, t: float | None, what: str) -> float:
        """The time of an operator's input: ``t`` (default the watermark), the watermark advanced to it."""
        if t is None:
            t = self.now if math.isfinite(self.now) else (self.t_start or 0.0)
        t = as_float('t', t)
        if t < self.now:
            raise ParameterError('t', t, f'{what} cannot be earlier than the watermark {self.now!r} s')
        if t > self.now:
            self.tick(t)
        return t

    def command(self, name: str, t: float | None = None) -> Outcome:
        """An operator command at time ``t`` (default: the watermark).

        A ``t`` later than the watermark first advances it (:meth:`tick`): the
        inputs up to ``t`` must be in. Returns the outcome; a command PackML refuses
        changes nothing and carries the reason.
        """
        t = self._operator_time(t, 'an operator command')
        try:
            cmd = self._apply(name, t, name)
        except TransitionError as err:
            self.operator_log.append((t, name, False))
            return Outcome(False, str(err))
        self.operator_log.append((t, name, True))
        if cmd is None:
            return Outcome(True, f'{name}: {self.state}')
        return Outcome(True, f'{name}: {self.state}, drive {cmd.kind} effective at {cmd.t:.9f} s', cmd)

    def tune(self, key: str, value: object, t: float | None = None, effective: float | None = None) -> Outcome:
        """An operator's change of a tunable setting at time ``t`` (default: the watermark).

        Checked against the scene (:func:`folder_line.core.line.tuning.check_tuning`); if
        accepted, it takes effect at the next machine cycle boundary at least ``lead``
        after ``t``, as a hold does (or at ``effective``, if given, which must be after
        ``t``: a batch run's change at a time the user chose, or a replay of a recorded
        one), and is issued with the drive commands (:meth:`take_commands`): the cycles
        after it are judged on the events of the line under it. A refusal changes
        nothing and carries the reason.
        """
        t = self._operator_time(t, 'a tuning')
        try:
            x = check_tuning(self.scene, key, value)
        except ParameterError as err:
            self.tuning_log.append((t, key, value, math.nan))
            return Outcome(False, str(err))
        if effective is None:
            when = self._drive.effective(t, True)
        else:
            when = as_float('effective', effective)
            if not when > t:
                raise ParameterError('effective', effective, f'a tuning must take effect after its decision at {t!r} s')
        tu = Tuning(when, key, x)
        self._drive.issue(t, tu)
        self.tuning_log.append((t, key, x, tu.t))
        return Outcome(True, f'{key} = {x!r} {TUNABLES[key].unit} effective at {tu.t:.9f} s', tu)

    def take_commands(self) -> list[tuple[float, LineCommand]]:
        """``(decision time, drive command or tuning)`` issued since the last call (by ticks, operator
        commands and tunings), in issue order."""
        return self._drive.take()

    # ------------------------------------------------------------------ tick

    def tick(self, t: float) -> list[LineCommand]:
        """Advance the watermark to ``t`` (s): every input at or before ``t`` is in.

        Takes every decision due by ``t`` in time order and returns the drive
        commands issued by them (also kept for :meth:`take_commands`). Line time
        starts at 0: a ``t`` below 0 is taken as 0 (what is due at 0, such as the end
        of STARTING on a drive at speed from the start, is decided at once).
        """
        W = max(as_float('t', t), 0.0)  # line time starts at 0: nothing is decided before
        if self.t_start is None:
            self.t_start = W
            self._acting.since = W
            self.liveness.start(W)
        if self.now >= W:
            return []
        if math.isfinite(self.now):  # no balance is asked for before the last watermark any more
            self._sheets.commit(self.now)
        n_before = len(self._drive.issued)
        self.liveness.merge_clock()
        self._due = self._cycles.due(W, self._drive_before(W))
        i = 0
        while (decision := self._next_decision(W, i)) is not None:
            when, what, arg = decision
            when = max(when, self.now)  # a late input is decided now
            n_issued = len(self._drive.issued)
            if what == 'eval':
                i += 1
            self._decide(what, arg, when)
            new = self._drive.issued[n_issued:]
            if new:
                # the drive changes from the new command's time on: re-judge what is due from then
                t_cmd = min(c.t for _, c in new)
                if any(it.t >= t_cmd for it in self._due[i:]):
                    self._cycles.commit()
                    self._due = self._cycles.due(W, self._drive_before(W))
                    i = 0
        self._cycles.commit()
        self.liveness.consume_heard(W)
        self.now = W
        return [c for _, c in self._drive.issued[n_before:]]

    def _next_decision(self, W: float, i: int) -> tuple[float, str, _DecisionArg] | None:
        """The earliest decision due by ``W`` (``(time, what, its argument)``; None if none). At equal
        times the end of the acting state comes first, then the evaluation ``self._due[i]``, then bad
        values and lost participants, then stale nodes."""
        cands: list[tuple[float, int, str, _DecisionArg]] = []
        if i < len(self._due):
            it = self._due[i]
            cands.append((it.t, 1, 'eval', it))
        c = self._acting.completion(self.state, W, self._drive_before(W))
        if c is not None:
            cands.append((c, 0, 'complete', None))
        if self._bad:
            tb, topic, count = min(self._bad)
            if tb <= W:
                cands.append((tb, 2, 'bad', (topic, count)))
        if self._lost:
            tl, node, waited = min(self._lost)
            if tl <= W:
                cands.append((tl, 2, 'lost', (node, waited)))
        for ts, node, last in self.liveness.candidates(W):
            cands.append((ts, 3, 'stale', (node, last)))
        if not cands:
            return None
        when, _, what, arg = min(cands, key=lambda x: (x[0], x[1]))
        return when, what, arg

    def _decide(self, what: str, arg: _DecisionArg, when: float) -> None:
        """Take the decision ``what`` (:meth:`_next_decision`) at ``when``."""
        if isinstance(arg, Due):  # 'eval'
            self._on_item(arg, when)
        elif arg is None:  # 'complete'
            tr = self._acting.end(self.packml, when)
            if tr.target in STOP_STATES:
                self.balances.append(self.balance(when, tr.target))
        elif what == 'bad':
            self._bad.remove(min(self._bad))
            topic, count = arg
            self._interlock(when, f'finite:{topic}', -float(count), 'values', f'{count} non-finite value(s) on {topic}')
        elif what == 'lost':
            self._lost.remove(min(self._lost))
            node, waited = arg
            self.lost_nodes.append(node)
            self._interlock(
                when,
                f'lost:{node}',
                -waited,
                'wall s',
                f'participant {node} lost: no answer for {waited:.3g} s of wall time',
            )
        else:
            node, last = arg
            margin, cause = self.liveness.stale(node, last, when)
            self._interlock(when, f'liveness:{node}', margin, 's', cause)

    # ------------------------------------------------------------------ internals: commands

    def _apply(self, name: str, t: float, cause: str) -> Command | None:
        """PackML command ``name`` at ``t`` (TransitionError with the reason if unknown or illegal), with
        its drive command."""
        if not self.packml.allowed(name):
            self.packml.command(name, t, cause)  # raises: unknown, or not legal in this state
        drive_kind, at_boundary = DRIVE_COMMANDS[name]
        cmd = None if drive_kind is None else Command(self._drive.effective(t, at_boundary), drive_kind)
        self.packml.command(name, t, cause)
        self._acting.begin(t if cmd is None else cmd.t)
        if cmd is not None:
            self._drive.issue(t, cmd)
        return cmd

    def _automatic(self, action: str, t: float, cause: str) -> str:
        """Apply an automatic ``hold``/``suspend``/``abort`` if enforcing and legal; the action taken."""
        if not self.settings.enforce or not self.packml.allowed(action):
            return 'none'
        self._apply(action, t, cause)
        return action

    # ------------------------------------------------------------------ internals: decisions

    def _record(self, t: float, cycle: int, name: str, margin: float, unit: str, action: str, state: str) -> None:
        self.violations.append(Violation(t, int(cycle), name, float(margin), unit, action, state))

    def _stats(self, name: str, unit: str) -> ConstraintStats:
        st = self.stats.get(name)
        if st is None:
            st = self.stats[name] = ConstraintStats(name, unit)
        return st

    def _on_item(self, it: Due, t: float) -> None:
        """Take the evaluation ``it`` (decided at ``t``: its own time, unless it came late)."""
        self._cycles.taken(it)
        if it.source == 'folder' and self.liveness.never_heard_by(self.sheet_source, it.t):
            return  # the sheets' publisher was never heard: the cycle cannot be judged
        if it.t >= self.blind_from:
            return  # a participant was lost: its input may be missing, so nothing is judged
        for name, unit, margin in it.margins:
            self._stats(name, unit).add(t, it.cycle, margin)
        bad = [(n, u, m) for n, u, m in it.margins if m < 0.0]
        if not bad:
            return
        timing = [b for b in bad if b[0] in TIMING_CONSTRAINTS]
        starving = any(n == 'one_per_cycle' for n, _, _ in bad) and it.signatures == 0
        double = any(n == 'one_per_cycle' for n, _, _ in bad) and it.signatures >= 2
        if timing or (double and self.settings.double == 'hold'):
            action = 'hold'
        elif double:
            action = 'abort'
        else:  # one_per_cycle fails with 0 or >= 2 signatures: starvation
            action = 'suspend'
        worst = min(bad, key=lambda b: b[2])
        what = 'double sheet' if double and not timing else ('missing sheet' if starving and not timing else worst[0])
        where, shown = margin_at(worst[0], it.cycle), format_margin(worst[2], worst[1], worst[0])
        cause = f'{what}: {worst[0]} violated in {where} (margin {shown})'
        state = self.state
        taken = self._automatic(action, t, cause)
        for name, unit, margin in bad:
            self._record(t, it.cycle, name, margin, unit, taken, state)

    def _interlock(self, t: float, name: str, margin: float, unit: str, cause: str) -> None:
        state = self.state
        cycle = int(self._drive.cycles.index(self._drive.drive, t))
        taken = self._automatic('abort', t, cause)
        self._record(t, cycle, name, margin, unit, taken, state)
        self._stats(name, unit).add(t, cycle, margin)

    # ------------------------------------------------------------------ balance

    def balance(self, t: float, state: str = '') -> Balance:
        """The sheet balance from the events up to ``t`` (:class:`~folder_line.core.supervision.balance.Balance`)."""
        return self._sheets.at(t, state, self.lost_nodes, self.blind_from)
