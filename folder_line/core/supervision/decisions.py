"""The supervisor's logic: PackML state, constraint enforcement, liveness — pure, no ROS.

:class:`Supervisor` is fed incrementally with what the live supervisor node sees —
the exact events as the machine nodes publish them (:meth:`Supervisor.feed`, any
batching, any order), the stamps at which it hears each node
(:meth:`Supervisor.heard`), non-finite values found in messages
(:meth:`Supervisor.bad_value`), the operator's commands
(:meth:`Supervisor.command`) — and advanced by :meth:`Supervisor.tick`. It decides
the PackML transitions (:class:`folder_line.core.supervision.packml.PackML`) and the drive
commands (:class:`folder_line.core.mechanisms.drive.Command`, with their effective times) to
issue, records every constraint violation (cycle, constraint, margin) and checks
the sheet balance at every stop. :func:`replay` runs the same object over a recorded
stream offline and reproduces the live run's transitions exactly.

Time and determinism
--------------------
``tick(W)`` declares that every input with a time at or before ``W`` (the
*watermark*, s of line time) has been fed. The supervisor then takes, in time
order, every decision due at or before ``W``. Each decision has an exact time that
depends on the inputs only, never on when the call came:

* a folder cycle is judged at its ``knife_contact`` (the ``t`` of the constraint
  series), on the events up to that instant: the *same* code as the batch
  simulator, :func:`folder_line.core.line.constraints.folder_evaluation` with
  ``causal=True`` (each cycle sees only the rows up to its own knife contact, so
  the batching of the feed does not matter); ``release_at_min_speed`` at the
  ``released_on_pile`` time; the layup's ``chute_speed`` at each ``leaf_exit``
  (:func:`folder_line.core.line.constraints.evaluate_layup_constraints`);
* a non-finite value at the stamp of its message;
* liveness and the end of acting states on the *check grid* ``t = n h``
  (``h = check_period``): node N is stale at the first grid point ``g`` with no
  stamp of N in ``[g - k P_N, g]`` (``k = stale_periods``, ``P_N`` its publishing
  period) — and, with ``clock_ticks``, at least ``ceil(k)`` clock messages after its
  last stamp (it missed ``k`` chances to publish). A node is watched from its first
  stamp on (a node that is not part of the run is not missed), an ``expected`` one
  from ``t_start``; an acting state ends at the first grid point at or after its drive
  command's effective time where the drive is at speed (λ >= ``speed_reached``:
  STARTING, UNHOLDING, UNSUSPENDING) or at standstill (λ = 0: HOLDING, SUSPENDING,
  STOPPING, ABORTING, COMPLETING); RESETTING and CLEARING end at the next grid
  point;
* an operator command at the time it is given (the watermark then).

Given the same inputs, any sequence of calls that respects the watermark contract
(no input at or before a watermark already passed) therefore takes the same
decisions at the same times. (The line model under a new command is built only
when a decision needs the drive after that command's effective time — never in the
tick that issued it while the watermark is before that time — so that a node can
publish the command first; before its time a command changes nothing, bit for bit.)
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
* a folder cycle is judged only once the sheets' publisher (:data:`SHEET_SOURCE`),
  if it is a known node, has been heard: knife contacts without a feed node running
  are not a starvation of the line but a missing node (a liveness matter);
* a node not heard within ``k`` periods, or a NaN/inf in any message -> ``abort``:
  ABORTING, then ABORTED at standstill, which only ``clear`` leaves (CLEARING ->
  STOPPED). Staleness is edge-triggered: one abort per stale episode (the node must
  be heard again before it can trigger another).

A decision is applied only where PackML allows it (a hold while HOLDING changes
nothing); the violation is recorded either way, with the action taken (``'none'``
if none). With ``enforce=False`` nothing is commanded: violations are only
recorded.

Drive commands (:mod:`folder_line.core.mechanisms.drive`): ``hold``, ``suspend`` and ``stop``
take the drive down from the next machine cycle boundary at least ``lead`` s after
the decision (:meth:`folder_line.core.line.model.LineModel.next_cycle_boundary`; the line
stops between two sheets), ``abort`` from ``lead`` s after it (``stop`` kind),
``start``, ``unhold`` and ``unsuspend`` bring it back ``lead`` s after the command.
``lead`` is the time the command needs to reach every node before it is due;
effective times are rounded to the nanosecond (the resolution of the command
topic), so that the supervisor and the nodes build the same drive. The drive
ramps down by the scene's brake ramp, or with ``motor_dynamics`` along the motor
curve with the brake (:func:`folder_line.core.line.model.make_drive`).

Sheet balance
-------------
On entering HELD, SUSPENDED, STOPPED, ABORTED or COMPLETE, the sheets are counted
from the events up to that instant (:class:`Balance`): fed (handed over) =
delivered (released on the pile; without a delivery: folded) + in the machine (on
the feed belt, at the stops waiting for the knife, jammed after it, or folded on
the chain); for the layup, leaves entered = landed (or exited, without
``leaf_flight``) + on the chutes + in the air.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from folder_line.core.line.constraints import evaluate_layup_constraints, folder_evaluation
from folder_line.core.line.events import EVENT_DTYPE, event_kind
from folder_line.core.mechanisms.drive import Command
from folder_line.core.numerics.validate import as_float, one_of, positive
from folder_line.core.supervision.packml import ACTING, PackML, Transition
from folder_line.errors import ParameterError, TransitionError

if TYPE_CHECKING:
    from folder_line.core.line.scene import Scene

__all__ = [
    'CHECK_PERIOD',
    'DRIVE_COMMANDS',
    'SHEET_SOURCE',
    'SPEED_REACHED',
    'STALE_PERIODS',
    'STOP_STATES',
    'TIMING_CONSTRAINTS',
    'Balance',
    'ConstraintStats',
    'Outcome',
    'Supervisor',
    'Violation',
    'replay',
    'run_closed_loop',
]

#: constraints whose violation is a timing fault of the process (-> HELD)
TIMING_CONSTRAINTS = ('feed_window', 'settled_before_knife', 'rebound', 'chute_speed', 'release_at_min_speed')
#: PackML command -> (drive command kind or None, waits for the next machine cycle boundary)
DRIVE_COMMANDS: dict[str, tuple[str | None, bool]] = {
    'start': ('start', False),
    'stop': ('stop', True),
    'hold': ('hold', True),
    'unhold': ('unhold', False),
    'suspend': ('hold', True),
    'unsuspend': ('unhold', False),
    'abort': ('stop', False),
    'complete': ('stop', True),
    'reset': (None, False),
    'clear': (None, False),
}
#: acting state -> what ends it
_ENDS: dict[str, str] = {
    'STARTING': 'speed',
    'UNHOLDING': 'speed',
    'UNSUSPENDING': 'speed',
    'HOLDING': 'standstill',
    'SUSPENDING': 'standstill',
    'STOPPING': 'standstill',
    'ABORTING': 'standstill',
    'COMPLETING': 'standstill',
    'RESETTING': 'next',
    'CLEARING': 'next',
}
assert set(_ENDS) == set(ACTING)
#: waiting states in which the line stands: the sheet balance is checked on entering them
STOP_STATES = ('HELD', 'SUSPENDED', 'STOPPED', 'ABORTED', 'COMPLETE')
#: speed factor at which a run command's acting state ends
SPEED_REACHED = 0.99
#: default spacing of the check grid, s
CHECK_PERIOD = 0.005
#: default k: periods (and clock ticks) a node may stay silent
STALE_PERIODS = 10.0
#: the node that publishes the sheets' events: a folder cycle is judged only once it has been heard
SHEET_SOURCE = 'feed_transporter'

_FOLDER_KINDS = np.array(
    [event_kind(k) for k in ('sheet_handover', 'at_stops', 'bounce', 'settled', 'knife_contact')], dtype=np.int16
)
_BALANCE_KINDS = np.array(
    [
        event_kind(k)
        for k in (
            'sheet_handover',
            'at_stops',
            'knife_contact',
            'released_on_pile',
            'leaf_enter',
            'leaf_exit',
            'leaf_landed',
            'leaf_spilled',
        )
    ],
    dtype=np.int16,
)
_CONTACT = event_kind('knife_contact')
_RELEASE = event_kind('released_on_pile')
_LEAF_EXIT = event_kind('leaf_exit')
_NS = 1_000_000_000


def _ns_round(t: float) -> float:
    """``t`` rounded to the nanosecond (what a ``builtin_interfaces/Time`` carries), s."""
    return round(t * _NS) / _NS


# --------------------------------------------------------------------------- records


@dataclass(frozen=True)
class Violation:
    """One violated evaluation, as decided.

    Attributes
    ----------
    t : float
        Decision time, s (a knife contact, a release, a leaf exit, a check-grid
        point for liveness, a message stamp for a non-finite value).
    cycle : int
        Machine cycle of the evaluation (``chute_speed``: the leaf id; liveness and
        non-finite values: the cycle running at ``t``, -1 before the first).
    constraint : str
        Constraint name; ``liveness:<node>`` for a stale node, ``finite:<topic>``
        for a NaN/inf.
    margin : float
        Negative. Liveness: ``k P - silence`` in s at the decision; non-finite:
        minus the number of non-finite values in the message.
    unit : str
        Unit of the margin.
    action : str
        ``'hold'``, ``'suspend'`` or ``'abort'`` if that command was applied, else
        ``'none'`` (not enforcing, or PackML did not allow it in ``state``).
    state : str
        PackML state when it was decided.
    """

    t: float
    cycle: int
    constraint: str
    margin: float
    unit: str
    action: str
    state: str


@dataclass(frozen=True)
class Balance:
    """Sheets counted at a stop, from the events up to ``t``.

    Attributes
    ----------
    t : float
        Time of the transition into the stopped state, s.
    state : str
        That state.
    fed, delivered, in_machine : int
        Sheets (and leaves) fed, delivered, and still in the machine.
    detail : dict of str to int
        Where the ones in the machine are: ``on_feed``, ``at_stops``, ``jammed``,
        ``on_chain`` (folder), ``on_chutes``, ``in_air`` (layup); and ``folded``.
    ok : bool
        ``fed == delivered + in_machine`` and every delivered sheet was fed (no
        sheet lost, none counted twice); False when ``missing``.
    missing : str
        Empty, or why the balance cannot be judged: ``'events of <node> not received
        after <t> s'`` (a participant was lost: its counts stop there, the others' do not).
    """

    t: float
    state: str
    fed: int
    delivered: int
    in_machine: int
    detail: dict[str, int]
    ok: bool
    missing: str = ''


@dataclass(frozen=True)
class Outcome:
    """Answer to an operator command: ``ok``, a message (the reason of a refusal), the drive command issued."""

    ok: bool
    message: str
    command: Command | None = None


@dataclass
class ConstraintStats:
    """Running figures of one constraint (what ``/diagnostics`` reports).

    Attributes
    ----------
    name, unit : str
    evaluations, violations : int
    last_margin : float
        Margin of the latest evaluation (0 before any).
    last_cycle : int
    last_t : float
        Its decision time, s.
    min_margin : float
        Smallest margin so far (``inf`` before any evaluation).
    """

    name: str
    unit: str
    evaluations: int = 0
    violations: int = 0
    last_margin: float = 0.0
    last_cycle: int = -1
    last_t: float = -math.inf
    min_margin: float = math.inf

    def add(self, t: float, cycle: int, margin: float) -> None:
        self.evaluations += 1
        self.violations += int(margin < 0.0)
        self.last_margin, self.last_cycle, self.last_t = margin, cycle, t
        self.min_margin = min(self.min_margin, margin)


@dataclass(frozen=True)
class _Item:
    """A decision due at ``t``: one evaluated cycle (or release, or leaf exit)."""

    t: float
    order: int
    cycle: int
    margins: tuple[tuple[str, str, float], ...]  # (name, unit, margin)
    signatures: int = 1
    source: str = 'folder'  # 'folder', 'release', 'layup'


@dataclass
class _Node:
    """Liveness of one known node."""

    period: float
    expected: bool  # watched from t_start (else from its first stamp)
    last: float | None = None  # latest stamp taken into account (t_start for an expected node)
    first: float = math.inf  # earliest stamp ever fed
    stale_at: float | None = None  # decision time of the current stale episode
    pending: list[np.ndarray] = field(default_factory=list)


# --------------------------------------------------------------------------- the logic


class Supervisor:
    """The line supervisor's logic (see the module docstring).

    Parameters
    ----------
    scene : Scene
        The line's scene.
    horizon : float
        Line time the line model covers, s (the nodes' ``horizon``).
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
    stale_periods : float
        ``k``: a node is stale when not heard within ``k`` periods (> 0; default
        :data:`STALE_PERIODS`).
    lead : float
        Earliest effective time of a drive command after its decision, s (>= 0).
    check_period : float
        Spacing ``h`` of the check grid, s (> 0).
    enforce : bool
        Command holds, suspends and aborts (else only record violations).
    double : {'hold', 'abort'}
        What a double sheet leads to.
    speed_reached : float
        Speed factor in (0, 1] at which a run command's acting state ends.
    state : str
        Initial PackML state (default STARTING: the scene's drive starts the line at
        t = 0, which is when the run command is effective).
    t_start : float or None
        Time the supervisor starts watching, s: nodes are expected from then on.
        None: the first :meth:`tick`'s watermark (recorded in :attr:`t_start`;
        :func:`replay` needs it).
    model_factory : callable, optional
        ``commands -> LineModel`` (default: ``LineModel(scene, horizon, commands)``,
        cached): the drive, the machine cycles and the cycle boundaries under the
        issued commands.

    Attributes
    ----------
    packml : PackML
        State and history (:attr:`transitions`).
    commands : tuple of Command
        Drive commands issued, sorted by effective time.
    violations : list of Violation
    balances : list of Balance
    stats : dict of str to ConstraintStats
    operator_log : list of (float, str, bool)
        Operator commands ``(t, command, accepted)``.
    now : float
        The watermark: decisions up to it are taken (``-inf`` before the first tick).
    late : int
        Inputs that came at or before a watermark already passed.
    """

    def __init__(
        self,
        scene: Scene,
        horizon: float,
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
        model_factory: Callable[[tuple[Command, ...]], Any] | None = None,
    ) -> None:
        self.scene = scene
        self.horizon = positive('horizon', horizon)
        self.k = positive('stale_periods', stale_periods)
        self.lead = as_float('lead', lead)
        if not (math.isfinite(self.lead) and self.lead >= 0.0):
            raise ParameterError('lead', lead, 'must be finite and >= 0')
        self.h = positive('check_period', check_period)
        self.enforce = bool(enforce)
        self.double = one_of('double', double, ('hold', 'abort'))
        self.speed_reached = as_float('speed_reached', speed_reached)
        if not 0.0 < self.speed_reached <= 1.0:
            raise ParameterError('speed_reached', speed_reached, 'must be in (0, 1]')
        self.packml = PackML(state)
        self.t_start = None if t_start is None else as_float('t_start', t_start)
        self._nodes: dict[str, _Node] = {}
        expected = set(expected)
        unknown = expected - set(periods or {})
        if unknown:
            raise ParameterError('expected', sorted(unknown), 'expected nodes need a period')
        for node, period in (periods or {}).items():
            st = _Node(positive(f'periods.{node}', period), node in expected)
            if st.expected:
                st.last = self.t_start
            self._nodes[node] = st
        self.clock_ticks = bool(clock_ticks)
        self._clock = np.zeros(0)
        self._clock_pending: list[np.ndarray] = []
        if model_factory is None:
            from folder_line.core.line.model import LineModel

            cache: dict[tuple[Command, ...], Any] = {}

            def model_factory(commands: tuple[Command, ...]) -> Any:
                if commands not in cache:
                    if len(cache) > 4:
                        cache.pop(next(iter(cache)))
                    cache[commands] = LineModel(scene, self.horizon, commands)
                return cache[commands]

        self._factory = model_factory
        self.commands: tuple[Command, ...] = ()
        self._model: Any = None
        self._model_commands: tuple[Command, ...] = ()
        self.violations: list[Violation] = []
        self.balances: list[Balance] = []
        self.stats: dict[str, ConstraintStats] = {}
        self.operator_log: list[tuple[float, str, bool]] = []
        self.now = -math.inf
        self.late = 0
        self._issued: list[tuple[float, Command]] = []  # (decision time, command)
        # acting state: the time its drive command is effective (or the command's time)
        self._acting_from = 0.0 if self.t_start is None else max(self.t_start, 0.0)
        self._grid_from = -1  # first grid index not yet known to fail the acting state's condition
        # event buffers
        self._folder = np.zeros(0, dtype=EVENT_DTYPE)
        self._releases = np.zeros(0, dtype=EVENT_DTYPE)
        self._exits = np.zeros(0, dtype=EVENT_DTYPE)
        self._balance_rows: list[np.ndarray] = []
        self._folder_done = -1  # last folder cycle judged
        self._release_done = -math.inf  # last release time judged
        self._exit_done = -math.inf  # last leaf exit time judged
        self._bad: list[tuple[float, str, int]] = []
        self._lost: list[tuple[float, str, float]] = []
        self.blind_from = math.inf  # no judgement from here on: a participant was lost
        self.lost_nodes: list[str] = []
        self._due: list[_Item] = []
        self._timing = None
        self._plan = None
        if scene.has_folder:
            from folder_line.core.line.folder_sim import delivery_plan
            from folder_line.core.mechanisms.cyclogram import cycle_timing

            self._timing = cycle_timing(scene.machines['cyclogram'], scene.machines['knife'])
            self._plan = delivery_plan(scene, self._timing)

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
    def model(self) -> Any:
        """The line model under the commands issued so far (built on first use after a command)."""
        if self._model is None or self._model_commands != self.commands:
            self._model = self._factory(self.commands)
            self._model_commands = self.commands
        return self._model

    def _model_before(self, t: float) -> Any:
        """A line model that is right at times before ``t``: the one in use if no command issued since it
        was built is effective before ``t`` (a command changes nothing before its time), else :attr:`model`."""
        if self._model is not None:
            unbuilt = [c.t for c in self.commands if c not in self._model_commands]
            if not unbuilt or t < min(unbuilt):
                return self._model
        return self.model

    @property
    def watched(self) -> dict[str, float]:
        """Watched node -> period, s."""
        return {n: s.period for n, s in self._nodes.items()}

    def stale_nodes(self) -> list[str]:
        """Nodes in a stale episode now."""
        return [n for n, s in self._nodes.items() if s.stale_at is not None]

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
        kind = rows['kind']
        f = rows[np.isin(kind, _FOLDER_KINDS) & (rows['cycle'] > self._folder_done)]
        if f.size:
            self._folder = np.concatenate([self._folder, f])
        r = rows[kind == _RELEASE]
        if r.size:
            self._releases = np.concatenate([self._releases, r])
        x = rows[kind == _LEAF_EXIT]
        if x.size:
            self._exits = np.concatenate([self._exits, x])
        b = rows[np.isin(kind, _BALANCE_KINDS)]
        if b.size:
            self._balance_rows.append(b)

    def heard(self, node: str, t: float | Sequence[float] | np.ndarray) -> None:
        """Node ``node`` was heard at stamp(s) ``t`` (s); nodes not watched are ignored."""
        state = self._nodes.get(node)
        if state is None:
            return
        stamps = np.asarray(t, dtype=float).reshape(-1)
        stamps = stamps[np.isfinite(stamps)]
        if stamps.size:
            self.late += int(np.count_nonzero(stamps <= self.now))
            state.first = min(state.first, float(stamps.min()))
            state.pending.append(stamps)

    def clock(self, t: float | Sequence[float] | np.ndarray) -> None:
        """Clock message(s) stamped ``t`` (s) received (used with ``clock_ticks``)."""
        if not self.clock_ticks:
            return
        stamps = np.asarray(t, dtype=float).reshape(-1)
        stamps = stamps[np.isfinite(stamps)]
        if stamps.size:
            self._clock_pending.append(stamps)

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

    def command(self, name: str, t: float | None = None) -> Outcome:
        """An operator command at time ``t`` (default: the watermark).

        A ``t`` later than the watermark first advances it (:meth:`tick`): the
        inputs up to ``t`` must be in. Returns the outcome; a command PackML refuses
        changes nothing and carries the reason.
        """
        if t is None:
            t = self.now if math.isfinite(self.now) else (self.t_start or 0.0)
        t = as_float('t', t)
        if t < self.now:
            raise ParameterError('t', t, f'an operator command cannot be earlier than the watermark {self.now!r} s')
        if t > self.now:
            self.tick(t)
        try:
            cmd = self._apply(name, t, name)
        except TransitionError as err:
            self.operator_log.append((t, name, False))
            return Outcome(False, str(err))
        self.operator_log.append((t, name, True))
        if cmd is None:
            return Outcome(True, f'{name}: {self.state}')
        return Outcome(True, f'{name}: {self.state}, drive {cmd.kind} effective at {cmd.t:.9f} s', cmd)

    def take_commands(self) -> list[tuple[float, Command]]:
        """``(decision time, drive command)`` issued since the last call (by ticks and operator
        commands), in issue order."""
        out, self._issued = self._issued, []
        return out

    # ------------------------------------------------------------------ tick

    def tick(self, t: float) -> list[Command]:
        """Advance the watermark to ``t`` (s): every input at or before ``t`` is in.

        Takes every decision due by ``t`` in time order and returns the drive
        commands issued by them (also kept for :meth:`take_commands`). Line time
        starts at 0: a ``t`` below 0 is taken as 0 (what is due at 0, such as the end
        of STARTING on a drive at speed from the start, is decided at once).
        """
        W = max(as_float('t', t), 0.0)  # line time starts at 0: nothing is decided before
        if self.t_start is None:
            self.t_start = W
            self._acting_from = W
            for s in self._nodes.values():
                if s.expected:
                    s.last = W
        if self.now >= W:
            return []
        n_before = len(self._issued)
        self._merge_clock()
        self._due = self._evaluate(W)
        i = 0
        while True:
            cands: list[tuple[float, int, str, Any]] = []
            if i < len(self._due):
                it = self._due[i]
                cands.append((it.t, 1, 'eval', it))
            c = self._completion(W)
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
            for node in self._nodes:
                s = self._stale_candidate(node, W)
                if s is not None:
                    cands.append((s[0], 3, 'stale', (node, s[1])))
            if not cands:
                break
            when, _, what, arg = min(cands, key=lambda x: (x[0], x[1]))
            when = max(when, self.now)  # a late input is decided now
            n_issued = len(self._issued)
            if what == 'eval':
                i += 1
                self._on_item(arg, when)
            elif what == 'complete':
                self._complete(when)
            elif what == 'bad':
                self._bad.remove(min(self._bad))
                topic, count = arg
                self._interlock(
                    when, f'finite:{topic}', -float(count), 'values', f'{count} non-finite value(s) on {topic}'
                )
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
                st = self._nodes[node]
                st.last, st.stale_at = last, when
                silence = when - last
                self._interlock(
                    when,
                    f'liveness:{node}',
                    self.k * st.period - silence,
                    's',
                    f'{node} not heard for {silence:.6g} s (> {self.k:g} periods of {st.period:g} s)',
                )
            new = self._issued[n_issued:]
            if new:
                # the drive changes from the new command's time on: re-judge what is due from then
                t_cmd = min(c.t for _, c in new)
                if any(it.t >= t_cmd for it in self._due[i:]):
                    self._commit()
                    self._due = self._evaluate(W)
                    i = 0
        self._commit()
        self._consume_heard(W)
        self.now = W
        return [c for _, c in self._issued[n_before:]]

    # ------------------------------------------------------------------ internals: commands

    def _effective(self, t: float, at_boundary: bool) -> float:
        earliest = t + self.lead
        if at_boundary:
            b = float(self._model_before(earliest).next_cycle_boundary(earliest))
            if math.isfinite(b) and self._model_before(b) is not self._model_before(earliest):
                b = float(self.model.next_cycle_boundary(earliest))
            if math.isfinite(b):  # else no further cycle (the line stands, or the horizon): at once
                earliest = b
        return _ns_round(earliest)

    def _apply(self, name: str, t: float, cause: str) -> Command | None:
        """PackML command ``name`` at ``t`` (TransitionError with the reason if unknown or illegal), with
        its drive command."""
        if not self.packml.allowed(name):
            self.packml.command(name, t, cause)  # raises: unknown, or not legal in this state
        drive_kind, at_boundary = DRIVE_COMMANDS[name]
        cmd = None if drive_kind is None else Command(self._effective(t, at_boundary), drive_kind)
        self.packml.command(name, t, cause)
        self._acting_from = t if cmd is None else cmd.t
        self._grid_from = -1
        if cmd is not None:  # the model under it is built when first needed (after the node published it)
            self.commands = tuple(sorted(self.commands + (cmd,), key=lambda c: c.t))
            self._issued.append((t, cmd))
        return cmd

    def _automatic(self, action: str, t: float, cause: str) -> str:
        """Apply an automatic ``hold``/``suspend``/``abort`` if enforcing and legal; the action taken."""
        if not self.enforce or not self.packml.allowed(action):
            return 'none'
        self._apply(action, t, cause)
        return action

    # ------------------------------------------------------------------ internals: decisions

    def _record(self, t: float, cycle: int, name: str, margin: float, unit: str, action: str, state: str) -> None:
        self.violations.append(Violation(t, int(cycle), name, float(margin), unit, action, state))

    def _on_item(self, it: _Item, t: float) -> None:
        """Take the evaluation ``it`` (decided at ``t``: its own time, unless it came late)."""
        if it.source == 'folder':
            self._folder_done = max(self._folder_done, it.cycle)
            src = self._nodes.get(SHEET_SOURCE)
            if src is not None and not src.first <= it.t:
                return  # the sheets' publisher was never heard: the cycle cannot be judged
        elif it.source == 'release':
            self._release_done = max(self._release_done, it.t)
        else:
            self._exit_done = max(self._exit_done, it.t)
        if it.t >= self.blind_from:
            return  # a participant was lost: its input may be missing, so nothing is judged
        for name, unit, margin in it.margins:
            st = self.stats.get(name)
            if st is None:
                st = self.stats[name] = ConstraintStats(name, unit)
            st.add(t, it.cycle, margin)
        bad = [(n, u, m) for n, u, m in it.margins if m < 0.0]
        if not bad:
            return
        timing = [b for b in bad if b[0] in TIMING_CONSTRAINTS]
        starving = any(n == 'one_per_cycle' for n, _, _ in bad) and it.signatures == 0
        double = any(n == 'one_per_cycle' for n, _, _ in bad) and it.signatures >= 2
        if timing or (double and self.double == 'hold'):
            action = 'hold'
        elif double:
            action = 'abort'
        else:  # one_per_cycle fails with 0 or >= 2 signatures: starvation
            action = 'suspend'
        worst = min(bad, key=lambda b: b[2])
        what = 'double sheet' if double and not timing else ('missing sheet' if starving and not timing else worst[0])
        cause = f'{what}: {worst[0]} violated in cycle {it.cycle} (margin {worst[2]:.6g} {worst[1]})'
        state = self.state
        taken = self._automatic(action, t, cause)
        for name, unit, margin in bad:
            self._record(t, it.cycle, name, margin, unit, taken, state)

    def _interlock(self, t: float, name: str, margin: float, unit: str, cause: str) -> None:
        state = self.state
        cycle = int(self._model_before(t + 1e-9).cycle_index(t))
        taken = self._automatic('abort', t, cause)
        self._record(t, cycle, name, margin, unit, taken, state)
        st = self.stats.get(name)
        if st is None:
            st = self.stats[name] = ConstraintStats(name, unit)
        st.add(t, cycle, margin)

    # ------------------------------------------------------------------ internals: evaluation

    def _evaluate(self, W: float) -> list[_Item]:
        """The evaluations due by ``W`` that are not yet taken, with the current model, in time order."""
        items: list[_Item] = []
        drive = None
        fb = self._folder
        if self._timing is not None and fb.size:
            contact = (fb['kind'] == _CONTACT) & (fb['t'] <= W) & (fb['cycle'] > self._folder_done)
            if contact.any():
                drive = self._model_before(W).drive
                last = int(fb['cycle'][contact].max())
                sub = fb[
                    (fb['cycle'] > self._folder_done) & (fb['cycle'] <= last) & ((fb['kind'] != _CONTACT) | contact)
                ]
                ev = folder_evaluation(sub, self._timing, self.scene, drive, plan=self._plan, causal=True)
                per: dict[int, list[tuple[str, str, float]]] = {int(c): [] for c in ev.cycle}
                for s in ev.constraints:
                    if s.name == 'release_at_min_speed':
                        continue
                    for c, m in zip(s.cycle.tolist(), s.margin.tolist(), strict=True):
                        per[int(c)].append((s.name, s.unit, float(m)))
                for c, tc, n in zip(ev.cycle.tolist(), ev.t.tolist(), ev.signatures.tolist(), strict=True):
                    items.append(_Item(float(tc), 0, int(c), tuple(per[int(c)]), int(n), 'folder'))
        rb = self._releases
        if self._timing is not None and rb.size:
            due = (rb['t'] <= W) & (rb['t'] > self._release_done)
            if due.any():
                drive = self._model_before(W).drive if drive is None else drive
                ev = folder_evaluation(rb[due], self._timing, self.scene, drive, plan=self._plan, causal=True)
                for s in ev.constraints:
                    if s.name == 'release_at_min_speed':
                        for c, m, tr in zip(s.cycle.tolist(), s.margin.tolist(), s.t.tolist(), strict=True):
                            items.append(_Item(float(tr), 1, int(c), ((s.name, s.unit, float(m)),), 1, 'release'))
        xb = self._exits
        if xb.size:
            due = (xb['t'] <= W) & (xb['t'] > self._exit_done)
            if due.any():
                for s in evaluate_layup_constraints(xb[due], self.scene):
                    for c, m, tx in zip(s.cycle.tolist(), s.margin.tolist(), s.t.tolist(), strict=True):
                        items.append(_Item(float(tx), 2, int(c), ((s.name, s.unit, float(m)),), 1, 'layup'))
        items.sort(key=lambda it: (it.t, it.order, it.cycle))
        return items

    def _commit(self) -> None:
        """Drop the buffered rows of what has been judged."""
        fb = self._folder
        if fb.size:
            self._folder = fb[fb['cycle'] > self._folder_done]
        rb = self._releases
        if rb.size:
            self._releases = rb[rb['t'] > self._release_done]
        xb = self._exits
        if xb.size:
            self._exits = xb[xb['t'] > self._exit_done]

    # ------------------------------------------------------------------ internals: acting states

    def _grid_index_at_or_after(self, t: float) -> int:
        n = math.ceil(t / self.h)
        while n * self.h < t:
            n += 1
        while (n - 1) * self.h >= t:
            n -= 1
        return n

    def _grid_index_after(self, t: float) -> int:
        n = math.floor(t / self.h) + 1
        while n * self.h <= t:
            n += 1
        while (n - 1) * self.h > t:
            n -= 1
        return n

    def _completion(self, W: float) -> float | None:
        """Grid time at which the current acting state ends, if by ``W``."""
        end = _ENDS.get(self.state)
        if end is None:
            return None
        if end == 'next':
            n0 = self._grid_index_after(self._acting_from)
        else:
            n0 = self._grid_index_at_or_after(self._acting_from)
        n0 = max(n0, self._grid_from)
        n1 = self._grid_index_after(W) - 1  # last grid index <= W
        if n1 < n0:
            return None
        if end == 'next':
            return n0 * self.h
        g = np.arange(n0, n1 + 1, dtype=float) * self.h
        lam = np.asarray(self._model_before(W).drive.rate(g), dtype=float)
        hit = lam >= self.speed_reached if end == 'speed' else lam <= 0.0
        j = int(np.argmax(hit)) if hit.size else 0
        if hit.size and hit[j]:
            return float(g[j])
        self._grid_from = n1 + 1
        return None

    def _complete(self, t: float) -> None:
        end = _ENDS[self.state]
        cause = {'speed': 'drive at speed', 'standstill': 'drive at standstill', 'next': 'done'}[end]
        tr = self.packml.state_complete(t, cause)
        self._grid_from = -1
        if tr.target in STOP_STATES:
            self.balances.append(self.balance(t, tr.target))

    # ------------------------------------------------------------------ internals: liveness

    def _merge_clock(self) -> None:
        """Merge the clock stamps fed so far into the sorted clock array."""
        if self._clock_pending:
            self._clock = np.unique(np.concatenate([self._clock] + self._clock_pending))
            self._clock_pending = []

    def _first_grid_after(self, t: np.ndarray) -> np.ndarray:
        g = (np.floor(t / self.h) + 1.0) * self.h
        g = np.where(g <= t, g + self.h, g)
        return np.where(g - self.h > t, g - self.h, g)

    def _first_grid_at_or_after(self, t: np.ndarray) -> np.ndarray:
        fin = np.isfinite(t)
        tt = np.where(fin, t, 0.0)
        g = np.ceil(tt / self.h) * self.h
        g = np.where(g < tt, g + self.h, g)
        g = np.where(g - self.h >= tt, g - self.h, g)
        return np.where(fin, g, np.inf)

    def _stale_candidate(self, node: str, W: float) -> tuple[float, float] | None:
        """(grid time at which ``node`` is found stale, its last stamp before) if by ``W``."""
        st = self._nodes[node]
        s = np.concatenate(st.pending) if st.pending else np.zeros(0)
        lo = -math.inf if st.last is None else st.last
        s = np.unique(s[(s > lo) & (s <= W)])
        if st.stale_at is not None:
            s = s[s > st.stale_at]
            if s.size == 0:
                return None
            seq = s  # heard again: watched from there
        elif st.last is None:
            if s.size == 0:
                return None
            seq = s  # watched from its first stamp
        else:
            seq = np.concatenate([[st.last], s])
        g = self._first_grid_after(seq + self.k * st.period)
        if self.clock_ticks:
            clk = self._clock
            idx = np.searchsorted(clk, seq, side='right') + (math.ceil(self.k) - 1)
            c = np.where(idx < clk.size, clk[np.minimum(idx, max(clk.size - 1, 0))] if clk.size else np.inf, np.inf)
            g = np.maximum(g, self._first_grid_at_or_after(c))
        nxt = np.append(seq[1:], np.inf)
        gap = np.flatnonzero((nxt > g) & (g <= W))
        if gap.size == 0:
            return None
        i = int(gap[0])
        return float(g[i]), float(seq[i])

    def _consume_heard(self, W: float) -> None:
        for st in self._nodes.values():
            if not st.pending:
                continue
            s = np.concatenate(st.pending)
            keep = s[s > W]
            lo = -math.inf if st.last is None else st.last
            s = s[(s <= W) & (s > lo)]
            if st.stale_at is not None:
                s = s[s > st.stale_at]
                if s.size:
                    st.stale_at = None
            if s.size:
                st.last = float(s.max())
            st.pending = [keep] if keep.size else []
        if self.clock_ticks and self._clock.size:
            lasts = [st.last for st in self._nodes.values() if st.last is not None]
            lo = min(lasts) if lasts else W
            self._clock = self._clock[self._clock > min(lo, W)]

    # ------------------------------------------------------------------ balance

    def balance(self, t: float, state: str = '') -> Balance:
        """The sheet balance from the events up to ``t`` (see :class:`Balance`)."""
        rows = np.concatenate(self._balance_rows) if self._balance_rows else np.zeros(0, dtype=EVENT_DTYPE)
        rows = rows[rows['t'] <= t]
        kind = rows['kind']

        def of(name: str) -> np.ndarray:
            return rows[kind == event_kind(name)]

        fed = delivered = in_machine = 0
        detail: dict[str, int] = {}
        ok = True
        if self.scene.has_folder:
            hand = of('sheet_handover')
            ids = hand['sheet']
            ok &= np.unique(ids).size == ids.size
            stops = of('at_stops')
            contact = of('knife_contact')
            cc, first = np.unique(contact['cycle'], return_index=True)
            tc = contact['t'][first]
            arrived = np.isin(ids, stops['sheet'])
            t_stop = np.zeros(ids.size)
            if stops.size:
                order = np.argsort(stops['sheet'], kind='stable')
                ks, ts = stops['sheet'][order], stops['t'][order]
                pos = np.minimum(np.searchsorted(ks, ids), ks.size - 1)
                t_stop = np.where(arrived, ts[pos], 0.0)
            if cc.size:
                pos = np.minimum(np.searchsorted(cc, hand['cycle']), cc.size - 1)
                knifed = cc[pos] == hand['cycle']
                t_knife = np.where(knifed, tc[pos], np.inf)
            else:
                knifed = np.zeros(ids.size, dtype=bool)
                t_knife = np.full(ids.size, np.inf)
            folded = arrived & knifed & (t_stop <= t_knife)
            jammed = arrived & knifed & ~folded
            waiting = arrived & ~knifed
            on_feed = ~arrived
            if self._plan is not None:
                rel = of('released_on_pile')['sheet']
                ok &= bool(np.all(np.isin(rel, ids[folded]))) and np.unique(rel).size == rel.size
                delivered_f = int(rel.size)
                on_chain = int(np.count_nonzero(folded & ~np.isin(ids, rel)))
            else:
                delivered_f = int(np.count_nonzero(folded))
                on_chain = 0
            detail.update(
                on_feed=int(np.count_nonzero(on_feed)),
                at_stops=int(np.count_nonzero(waiting)),
                jammed=int(np.count_nonzero(jammed)),
                on_chain=on_chain,
                folded=int(np.count_nonzero(folded)),
            )
            fed += int(ids.size)
            delivered += delivered_f
            in_machine += detail['on_feed'] + detail['at_stops'] + detail['jammed'] + on_chain
        if self.scene.has_layup:
            entered = of('leaf_enter').size
            exited = of('leaf_exit').size
            if self.scene.has('leaf_flight'):
                down = of('leaf_landed').size + of('leaf_spilled').size
                in_air = exited - down
            else:
                down, in_air = exited, 0
            on_chutes = entered - exited
            ok &= on_chutes >= 0 and in_air >= 0
            detail.update(on_chutes=int(on_chutes), in_air=int(in_air))
            fed += int(entered)
            delivered += int(down)
            in_machine += int(on_chutes + in_air)
        ok &= fed == delivered + in_machine
        if self.lost_nodes and t >= self.blind_from:
            missing = f'events of {", ".join(self.lost_nodes)} not received after {self.blind_from:.6f} s'
            return Balance(float(t), state, fed, delivered, in_machine, detail, False, missing)
        return Balance(float(t), state, fed, delivered, in_machine, detail, bool(ok))


# --------------------------------------------------------------------------- offline


def replay(
    scene: Scene,
    horizon: float,
    events: np.ndarray,
    *,
    heard: Mapping[str, Iterable[float]] | None = None,
    clock: Iterable[float] = (),
    bad_values: Iterable[tuple[float, str, int]] = (),
    operator: Iterable[tuple[float, str]] = (),
    lost: Iterable[tuple[float, str, float]] = (),
    until: float | None = None,
    **params: Any,
) -> Supervisor:
    """Run a :class:`Supervisor` over a recorded stream.

    Parameters
    ----------
    scene : Scene
    horizon : float
        The live run's model horizon, s.
    events : ndarray of EVENT_DTYPE
        The events the live supervisor was fed (any order).
    heard : mapping of str to iterable of float, optional
        Node -> the stamps at which it was heard, s.
    clock : iterable of float
        Stamps of the clock messages, s (with ``clock_ticks``).
    bad_values : iterable of (float, str, int)
        ``(stamp, topic, count)`` of messages with NaN/inf.
    operator : iterable of (float, str)
        Operator commands ``(t, command)`` (the live ``operator_log``; refused ones
        are refused again).
    lost : iterable of (float, str, float)
        Participants lost ``(t, node, waited wall s)`` (the live ``lost:<node>`` violations).
    until : float, optional
        The live run's last watermark, s (default: the latest input time).
    **params
        :class:`Supervisor` parameters; ``t_start`` as the live one's.

    Returns
    -------
    Supervisor
        After the replay: its ``transitions``, ``commands``, ``violations`` and
        ``balances`` are the live run's.
    """
    sup = Supervisor(scene, horizon, **params)
    ev = np.sort(np.asarray(events).reshape(-1), order='t', kind='stable')
    hd = {n: np.sort(np.asarray(list(ts), dtype=float)) for n, ts in (heard or {}).items()}
    clk = np.sort(np.asarray(list(clock), dtype=float))
    bad = sorted((float(t), str(tp), int(c)) for t, tp, c in bad_values)
    ops = sorted(((float(t), str(name)) for t, name in operator), key=lambda x: x[0])
    gone = sorted((float(t), str(n), float(w)) for t, n, w in lost)
    times = [ev['t'][-1]] if ev.size else []
    times += [float(a[-1]) for a in hd.values() if a.size] + [b[0] for b in bad] + [o[0] for o in ops]
    times += [g[0] for g in gone]
    times += [float(clk[-1])] if clk.size else []
    end = float(until) if until is not None else (max(times) if times else 0.0)
    i_ev = i_c = 0
    i_h = dict.fromkeys(hd, 0)
    i_b = i_g = 0

    def feed_to(t: float) -> None:
        nonlocal i_ev, i_b, i_c, i_g
        j = int(np.searchsorted(ev['t'], t, side='right'))
        sup.feed(ev[i_ev:j])
        i_ev = max(i_ev, j)
        for n, a in hd.items():
            j = int(np.searchsorted(a, t, side='right'))
            sup.heard(n, a[i_h[n] : j])
            i_h[n] = max(i_h[n], j)
        j = int(np.searchsorted(clk, t, side='right'))
        sup.clock(clk[i_c:j])
        i_c = max(i_c, j)
        while i_b < len(bad) and bad[i_b][0] <= t:
            sup.bad_value(bad[i_b][1], bad[i_b][0], bad[i_b][2])
            i_b += 1
        while i_g < len(gone) and gone[i_g][0] <= t:
            sup.lost(gone[i_g][1], gone[i_g][0], gone[i_g][2])
            i_g += 1

    if sup.t_start is None:
        raise ParameterError('t_start', None, "replay needs the live run's t_start")
    for t_op, name in ops:
        feed_to(t_op)
        sup.tick(t_op)
        sup.command(name, t_op)
    feed_to(end)
    sup.tick(end)
    return sup


def run_closed_loop(
    scene: Scene,
    horizon: float,
    duration: float,
    *,
    step: float = CHECK_PERIOD,
    operator: Iterable[tuple[float, str]] = (),
    silent: Mapping[str, float] | None = None,
    bad_values: Iterable[tuple[float, str, int]] = (),
    **params: Any,
) -> tuple[Supervisor, Any, dict]:
    """The live loop offline: the line model's events fed step by step, the supervisor's commands fed back.

    Every ``step`` s of line time: the events of the current model (built with the
    commands issued so far) up to the step, every watched node heard at its own
    ticks (``n P``) unless ``silent`` from some time, a clock message (with
    ``clock_ticks``), the bad values due; then a tick;
    an operator command due is given at its step. A command whose effective time is
    not after the step at which it was issued would rewrite events already fed: it
    raises (choose ``lead`` >= ``step``).

    Parameters
    ----------
    scene, horizon
        As for :class:`Supervisor`.
    duration : float
        Line time to run, s (<= horizon).
    step : float
        Feed and tick spacing, s.
    operator : iterable of (float, str)
        Operator commands, given at the first step at or after their time.
    silent : mapping of str to float, optional
        Node -> time from which it is no longer heard (it died).
    bad_values : iterable of (float, str, int)
        NaN/inf observations ``(stamp, topic, count)``, fed at their step.
    **params
        :class:`Supervisor` parameters.

    Returns
    -------
    (Supervisor, LineModel, dict)
        The supervisor, the final model, and what was fed (``events``, ``heard``,
        ``clock``, ``bad_values``, ``operator`` as given to the supervisor, ``until``): the input
        of :func:`replay`.
    """
    sup = Supervisor(scene, horizon, **params)
    silent = dict(silent or {})
    ops = sorted(((float(t), str(n)) for t, n in operator), key=lambda x: x[0])
    bads = sorted((float(t), str(tp), int(c)) for t, tp, c in bad_values)
    fed: list[np.ndarray] = []
    heard: dict[str, list[float]] = {n: [] for n in sup.watched}
    given: list[tuple[float, str]] = []
    bad_given: list[tuple[float, str, int]] = []
    clock: list[float] = []
    n_steps = math.floor(duration / step + 1e-9)
    prev = -math.inf
    for i in range(1, n_steps + 1):
        W = i * step
        model = sup.model
        rows = model.events_between(prev, W)
        sup.feed(rows)
        fed.append(rows)
        for node, period in sup.watched.items():
            lo = 0 if not math.isfinite(prev) else math.floor(prev / period) + 1
            ticks = np.arange(lo, math.floor(W / period + 1e-9) + 1, dtype=float) * period
            ticks = ticks[(ticks > prev) & (ticks <= W) & (ticks < silent.get(node, math.inf))]
            sup.heard(node, ticks)
            heard[node] += ticks.tolist()
        if sup.clock_ticks:  # the clock publishes every step
            sup.clock(W)
            clock.append(W)
        while bads and bads[0][0] <= W:
            b = bads.pop(0)
            sup.bad_value(b[1], b[0], b[2])
            bad_given.append(b)
        new = sup.tick(W)
        while ops and ops[0][0] <= W:
            _, name = ops.pop(0)
            out = sup.command(name, W)
            given.append((W, name))
            if out.command is not None:
                new.append(out.command)
        for c in new:
            if c.t <= W:
                raise ParameterError(
                    'lead',
                    sup.lead,
                    f'command {c.kind} effective at {c.t!r} s, not after the '
                    f'events already fed up to {W!r} s: use lead >= step',
                )
        prev = W
    inputs = {
        'events': np.concatenate(fed) if fed else np.zeros(0, dtype=EVENT_DTYPE),
        'heard': {n: np.asarray(v) for n, v in heard.items()},
        'clock': np.asarray(clock),
        'bad_values': bad_given,
        'operator': given,
        'until': prev,
    }
    return sup, sup.model, inputs
