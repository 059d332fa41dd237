"""The bag a live lockstep run would record, written from the batch model without DDS (``simulate --bag``).

``folder-line run`` records what the nodes publish in lockstep; every message depends only
on the scene, its tick and the supervisor's commands (:mod:`folder_line.ros.nodes.machine`).
So this module computes them with the same core the nodes use, the streamed line
(:class:`folder_line.core.line.stream.LineStream`), tick by tick on the run's grid (``rate`` =
:data:`folder_line.config.run_config.RATE`, 200 Hz of line time), one window per second of
line time (the supervisor's diagnostics period), and writes them with
:class:`folder_line.bag.writer.BagWriter`, the recorder's writer. Its memory does not grow
with the duration:

* ``/clock``: every tick ``k / rate``, 0 to ``duration``;
* ``/line/participants``: the clock's announcement (``clock=lockstep end=<ns> participants=...``),
  logged at 0;
* ``/line/<node>/joint_states`` of each machine node at every tick: the line sampled there;
* ``/line/events``: each machine node's exact events of ``(t_prev, t]`` at tick ``t``;
* ``/line/sheet_counter/{count,rate,landing_x}`` as the ``sheet_counter`` node computes them;
* ``/line/markers`` at ``marker_rate`` (the ``sheet_counter`` node's grid, stamps ``i / marker_rate``,
  each at the first tick at or after it): the scenery of the line at that stamp
  (:mod:`folder_line.bag.markers`);
* the supervisor's ``/line/supervisor/state`` at every tick, ``/line/supervisor/commands``,
  and ``/diagnostics`` (one array per second of line time, the violations, balances): the
  supervisor's logic (:class:`folder_line.core.supervision.supervisor.Supervisor`) fed the
  events of each tick as published (time rounded to the ns), then advanced to the tick, as
  the node does; its drive commands rebuild the machines' model from the next tick on.

Same topics, types, ``offered_qos_profiles`` (the recorder stores none), log times (the
tick), publish times (``header.stamp``, else the tick), header stamps and message contents
as the live bag (``test/bag/test_batch.py`` compares them with the independent
``mcap`` reader). What differs from a live bag:

* the order of messages *within one tick* across topics and publishers: live, it is the
  order in which DDS delivered them; here ``/clock``, then node by node. The MCAP
  ``sequence`` (a message's index on its topic in the bag) of ``/line/events`` and
  ``/diagnostics``, shared by several publishers, follows that order. Per topic and
  publisher the order is the same.
* ``custom_data``: ``folder_line.mode`` is ``batch`` (not ``in-process``/``processes``), and
  ``folder_line.published`` counts what was written (no publisher counted).
* What only a sick live run publishes, because it depends on wall time, is absent: the clock's
  ``folder_line/line_clock/lost`` and ``lateness`` diagnostics, the supervisor's
  ``lost:<node>`` abort, and rejected inputs (a batch bag is the bag of a healthy run:
  ``folder_line/supervisor/inputs`` says ``no input rejected``). Nothing of the live bag is
  wall-clock time (the recorder stores line time as log time), so nothing else differs.
  The lockstep acknowledgements (``/line/<node>/tick_done``) are not recorded by the live
  recorder either. Operator commands (services) are not simulated.
* ``metadata.yaml`` is written when the bag is opened (marked partial) and when it is closed,
  not after every 1 s file (``BagWriter(rewrite_metadata=False)``: thousands of files in a
  minute); an interrupted bag keeps its finished files readable and says it is partial
  (:meth:`~folder_line.bag.writer.BagWriter.abandon`), ``folder-line bag repair`` completes it.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from folder_line.bag.cdr import (
    JointStateLayout,
    clock_rows,
    diagnostic_array_cdr,
    float64_cdr,
    float64_rows,
    string_cdr,
    time_reference_cdr,
    time_references,
    uint64_rows,
)
from folder_line.bag.markers import marker_specs, marker_stamps, markers_cdr
from folder_line.bag.statuses import (
    Status,
    balance_status,
    constraint_statuses,
    event_status,
    status_stamp,
    tuning_status,
    violation_status,
)
from folder_line.bag.tick_messages import TickMessages
from folder_line.bag.writer import BagWriter
from folder_line.config.run_config import MARKER_RATE, RATE, SUPERVISOR_DEFAULTS, supervisor_logic
from folder_line.config.scenes import scene_text
from folder_line.core.line.scene import Scene
from folder_line.core.line.scenery import Scenery
from folder_line.core.line.stream import LineStream
from folder_line.core.line.tuning import Tuning
from folder_line.core.mechanisms.pile import counted_event
from folder_line.core.supervision.supervisor import Supervisor
from folder_line.core.types.events import EVENT_DTYPE
from folder_line.errors import ParameterError
from folder_line.interfaces import (
    CLOCK_TOPIC,
    COMMANDS_TOPIC,
    DIAGNOSTICS_TOPIC,
    EVENT_KINDS,
    EVENT_OWNER,
    EVENTS_TOPIC,
    JOINT_NODES,
    KNOWN_PARTICIPANTS,
    LANDING_TOPIC,
    LINE_TOPIC_TYPES,
    MARKERS_TOPIC,
    NODE_OF_UNIT,
    NS_PER_S,
    PARTICIPANTS_TOPIC,
    SHEET_COUNT_TOPIC,
    SHEET_RATE_TOPIC,
    SUPERVISOR,
    SUPERVISOR_STATE_TOPIC,
    joint_states_topic,
    seconds_to_ns,
)

__all__ = [
    'DIAG_RATE',
    'RATE_WINDOW',
    'BatchBag',
    'SheetRate',
    'WindowWriter',
    'announcement',
    'check_duration',
    'event_cdrs',
    'write_batch_bag',
]

#: the supervisor's ``diag_rate`` default, Hz of line time
DIAG_RATE = 1.0
#: the sheet counter's ``rate_window`` default, s
RATE_WINDOW = 5.0


@dataclass
class BatchBag:
    """What :func:`write_batch_bag` wrote.

    Attributes
    ----------
    path : str
        The bag directory.
    counts : dict of str to int
        Messages per topic.
    files : int
        ``.mcap`` files.
    state : str
        The supervisor's state at the last tick.
    commands : list of (float, str)
        The supervisor's drive commands: (effective time, s; kind).
    """

    path: str
    counts: dict[str, int] = field(default_factory=dict)
    files: int = 0
    state: str = ''
    commands: list[tuple[float, str]] = field(default_factory=list)


def _own_kinds(node: str) -> np.ndarray:
    return np.array([EVENT_KINDS.index(k) for k, n in EVENT_OWNER.items() if n == node], dtype=np.int16)


class SheetRate:
    """The sheet counter's count and rate from the counted sheets' times, in memory bounded by the window.

    Parameters
    ----------
    window : float
        ``rate_window``, s: the rate is the sheets counted in ``(t - window, t]`` over ``window``
        (over the elapsed time while ``t`` is shorter).
    """

    def __init__(self, window: float) -> None:
        self.window = window
        self.before = 0  # sheets counted and forgotten
        self.times = np.zeros(0)  # the counted sheets' times still in a window, s

    def add(self, times: np.ndarray) -> None:
        """Sheets counted at ``times`` (s, ascending, after those added before)."""
        self.times = np.concatenate((self.times, np.asarray(times, dtype=float)))

    def count(self, t: np.ndarray) -> np.ndarray:
        """Sheets counted at or before each ``t``."""
        return self.before + np.searchsorted(self.times, t, side='right')

    def rate(self, t: np.ndarray) -> np.ndarray:
        """Sheets per second over the window before each ``t`` (0 at t = 0)."""
        window = np.minimum(self.window, t)
        n = self.count(t) - self.count(t - window)
        with np.errstate(invalid='ignore', divide='ignore'):
            return np.where(window <= 0.0, 0.0, n / np.where(window <= 0.0, 1.0, window))

    def forget(self, t: float, window: float | None = None) -> None:
        """Forget the sheets no rate after ``t`` (s) reads (``window``: the longest window still to come)."""
        w = self.window if window is None else max(self.window, window)
        n = int(np.searchsorted(self.times, t - w, side='right'))
        self.before += n
        self.times = self.times[n:]


def _array_cdr(stamp: int, statuses: list[Status]) -> bytes:
    """CDR of the supervisor's ``diagnostic_msgs/msg/DiagnosticArray`` of ``statuses`` stamped ``stamp`` (ns)."""
    return diagnostic_array_cdr(
        stamp, SUPERVISOR, [(s.level, s.name, s.message, s.hardware_id, s.values) for s in statuses]
    )


class _SupervisorOut:
    """What the ``supervisor`` node publishes from its logic besides its state (``ros/nodes/supervisor.py``)."""

    def __init__(self, logic: Supervisor, hardware_id: str) -> None:
        self.logic = logic
        self.hardware_id = hardware_id
        self._tunings: list[tuple[str, bytes, int]] = []

    def _event(self, what: str, said: tuple[bool, str, dict[str, object]], t: float) -> tuple[str, bytes, int]:
        ok, message, values = said
        logic = self.logic
        status = event_status(
            what, ok, message, values, self.hardware_id, t_start=logic.t_start, watermark=logic.now, late=logic.late
        )
        stamp = status_stamp(t)
        return (DIAGNOSTICS_TOPIC, _array_cdr(stamp, [status]), stamp)

    def tune(self, t: float, tuning: Tuning) -> None:
        """Ask the logic for ``tuning`` at ``t`` (effective at its own time); its status is written with the outputs."""
        out = self.logic.tune(tuning.key, tuning.value, t, effective=tuning.t)
        if not out.ok:
            raise ParameterError(tuning.key, tuning.value, out.message)
        self._tunings.append(
            self._event('tuning', tuning_status(t, tuning.key, tuning.value, tuning.t, out.message), t)
        )

    def outputs(self) -> list[tuple[str, bytes, int]]:
        """``(topic, cdr, publish ns)`` of the commands, violations and balances issued since the last call."""
        out: list[tuple[str, bytes, int]] = []
        out += self._tunings
        self._tunings = []
        for t, command in self.logic.take_commands():
            stamp = max(0, round(t * NS_PER_S))
            cdr = time_reference_cdr(stamp, SUPERVISOR, round(command.t * NS_PER_S), command.kind)
            out.append((COMMANDS_TOPIC, cdr, stamp))
        out += [self._event('violation', violation_status(v), v.t) for v in self.logic.violations]
        self.logic.violations.clear()  # written: kept nowhere (the memory does not grow), as the node does
        out += [self._event('balance', balance_status(b), b.t) for b in self.logic.balances]
        self.logic.balances.clear()
        return out

    def diagnostics(self, line: LineStream, stamp: int) -> bytes:
        """The periodic array at ``stamp`` (ns, the time ``line`` was advanced to): the constraints, then the
        inputs (none rejected)."""
        return _array_cdr(stamp, constraint_statuses(line.tallies.constraints.values(), self.hardware_id, {}, []))


def announcement(duration_ns: int) -> str:
    """``line_clock``'s announcement of a lockstep run of ``folder-line run`` (``folder_line.ros.lockstep``)."""
    return f'clock=lockstep end={duration_ns} participants={",".join(KNOWN_PARTICIPANTS)}'


def check_duration(scene: Scene, duration: float) -> None:
    """Refuse a ``duration`` (s) that is not a positive whole number of ticks.

    Raises
    ------
    ParameterError
        Naming ``--duration``.
    """
    step_ns = round(NS_PER_S / RATE)
    if not (isinstance(duration, (int, float)) and math.isfinite(duration) and duration > 0.0):
        raise ParameterError('--duration', duration, 'must be a positive number of seconds')
    if seconds_to_ns(duration) % step_ns:
        raise ParameterError(
            '--duration', duration, f'must be a whole number of ticks of {step_ns / 1e6:g} ms ({RATE:g} Hz)'
        )


@dataclass
class _Tick:
    """What the supervisor said at one tick: its state, its outputs, whether the diagnostics are due."""

    state: str
    outs: list[tuple[str, bytes, int]]
    diag: bool


class WindowWriter:
    """One window of ticks at a time: the machines' messages from the stream, the supervisor's from its logic."""

    def __init__(self, bag: BagWriter, scene: Scene, line: LineStream, sup: _SupervisorOut, marker_rate: float) -> None:
        self.bag = bag
        self.line = line
        self.sup = sup
        self.units = {node: {n: u for u, n in NODE_OF_UNIT.items()}.get(node, '') for node in JOINT_NODES}
        self.owner = np.full(len(EVENT_KINDS), -1, dtype=np.int64)  # event kind -> its node's index
        for j, node in enumerate(JOINT_NODES):
            self.owner[_own_kinds(node)] = j
        self.layouts: dict[str, JointStateLayout] = {}
        self.landed = EVENT_KINDS.index('leaf_landed')
        self.counted = EVENT_KINDS.index(counted_event(scene.has_delivery))
        self.rates = SheetRate(RATE_WINDOW)
        self.marker_rate = marker_rate
        self.marker_ns: int | None = None
        self.scenery: Scenery | None = None
        self.states: dict[str, np.ndarray] = {}  # the CDR of each state

    def write(self, stamps: np.ndarray, events: np.ndarray, ticks: list[_Tick]) -> None:
        """Write the ticks ``stamps`` (ns): per tick ``/clock``, then node by node what it publishes.

        The window is written at once (:class:`~folder_line.bag.tick_messages.TickMessages`): each topic's
        messages of every tick as one column, put in the tick's order by their slot (``/clock``;
        per node its events, joint states and the counter's outputs and markers; the supervisor's
        outputs, state and diagnostics), as a tick-by-tick write would order them.
        """
        n = len(stamps)
        t = stamps / NS_PER_S
        out = TickMessages(stamps)
        out.add_rows(CLOCK_TOPIC, 0, clock_rows(stamps))
        self.rates.add(events['t'][events['kind'] == self.counted])
        count = self.rates.count(t)
        rate = self.rates.rate(t)
        self.rates.forget(float(t[-1]))
        # each event goes out at its tick: events[bounds[i]:bounds[i + 1]] at tick i
        bounds = np.searchsorted(events['t'], np.concatenate(([-math.inf], t)), side='right')
        tick_of = np.searchsorted(bounds, np.arange(len(events)), side='right') - 1
        sent = (tick_of >= 0) & (tick_of < n)
        kind = events['kind'].astype(np.int64)
        known = (kind >= 0) & (kind < len(self.owner))
        owner = np.where(known, self.owner[np.where(known, kind, 0)], -1)  # each event's node (index), -1: none
        for j, node in enumerate(JOINT_NODES):
            slot = 1 + 10 * j
            mine = sent & (owner == j)
            if mine.any():
                rows, at = events[mine], tick_of[mine]
                out.add_packed(EVENTS_TOPIC, slot, at, *event_cdrs(node, stamps[at], rows))
            self._joint_states(out, node, stamps, slot + 1)
            if node == 'sheet_counter':
                out.add_rows(SHEET_COUNT_TOPIC, slot + 2, uint64_rows(count))
                out.add_rows(SHEET_RATE_TOPIC, slot + 3, float64_rows(rate))
                landed = mine & (events['kind'] == self.landed)
                if landed.any():
                    values = events['value'][landed].tolist()
                    out.add_each(LANDING_TOPIC, slot + 4, tick_of[landed], [float64_cdr(v) for v in values])
                self._markers(out, stamps, slot + 5)
        self._supervisor(out, stamps, ticks[:n])
        self.bag.write_ticks(out)

    def _joint_states(self, out: TickMessages, node: str, stamps: np.ndarray, slot: int) -> None:
        """``node``'s joint states at the ticks ``stamps`` (none if the scene has not its unit)."""
        unit = self.units[node]
        if unit not in self.line.units:
            return
        js = self.line.sample(unit, stamps / NS_PER_S)
        layout = self.layouts.get(node)
        if layout is None:
            effort = 0 if js.effort is None else js.effort.shape[1]
            width = js.position.shape[1]
            layout = self.layouts[node] = JointStateLayout.of(node, list(js.names), (width, width, effort))
        out.add_rows(joint_states_topic(node), slot, layout.rows(stamps, js.position, js.velocity, js.effort))

    def _supervisor(self, out: TickMessages, stamps: np.ndarray, ticks: list[_Tick]) -> None:
        """The supervisor's outputs (its commands and tunings), state and diagnostics of ``ticks``."""
        outs = [(i, item) for i, tk in enumerate(ticks) for item in tk.outs]
        if outs:
            out.add_each(
                [topic for _, (topic, _, _) in outs],
                100,
                [i for i, _ in outs],
                [cdr for _, (_, cdr, _) in outs],
                [publish for _, (_, _, publish) in outs],
            )
        states = [tk.state for tk in ticks]
        for state in dict.fromkeys(states):
            if state not in self.states:
                self.states[state] = np.frombuffer(string_cdr(state), dtype=np.uint8)
            at = np.flatnonzero([s == state for s in states])
            row = self.states[state]
            out.add_rows(SUPERVISOR_STATE_TOPIC, 101, np.broadcast_to(row, (len(at), len(row))), at)
        diag = [i for i, tk in enumerate(ticks) if tk.diag]
        if diag:
            out.add_each(DIAGNOSTICS_TOPIC, 102, diag, [self.sup.diagnostics(self.line, int(stamps[i])) for i in diag])

    def _markers(self, out: TickMessages, stamps: np.ndarray, slot: int) -> None:
        """The marker arrays due in the ticks ``stamps``: each grid point at the first tick at or after it."""
        grid = list(marker_stamps(self.marker_ns, int(stamps[-1]), self.marker_rate))
        if not grid:
            return
        if self.scenery is None:
            self.scenery = Scenery(self.line)
        blobs = []
        for g, shapes in zip(grid, self.scenery.at_times([g / NS_PER_S for g in grid]), strict=True):
            blobs.append(markers_cdr(marker_specs(shapes), g, delete_all=self.marker_ns is None))
            self.marker_ns = g
        out.add_each(MARKERS_TOPIC, slot, np.searchsorted(stamps, grid, side='left'), blobs)


def event_cdrs(node: str, stamps: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The ``/line/events`` ``TimeReference`` of each event ``rows`` of ``node``, sent at ``stamps`` (ns):
    their CDR one after the other and the length of each (:func:`~folder_line.bag.cdr.time_references`).

    ``time_ref`` is the event's time rounded to the ns (not below 0); ``source`` is
    :func:`~folder_line.interfaces.event_source`'s text, formatted here for all rows at once.
    """
    time_ref = np.maximum(0, np.rint(rows['t'] * NS_PER_S).astype(np.int64))
    sources = [
        f'{_KIND_NAMES[k]} sheet={sheet} cycle={cycle} value={value!r}'  # event_source(kind, sheet, cycle, value)
        for k, sheet, cycle, value in zip(
            rows['kind'].tolist(), rows['sheet'].tolist(), rows['cycle'].tolist(), rows['value'].tolist(), strict=True
        )
    ]
    return time_references(stamps, node, time_ref, sources)


#: the event kinds by index, as :func:`~folder_line.interfaces.event_source` names them
_KIND_NAMES: tuple[str, ...] = tuple(EVENT_KINDS)


def _heard(events: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The machines' events as the supervisor hears them (time rounded to the ns, as ``time_ref`` carries it),
    and their line times (which decide the tick that publishes each)."""
    owned = np.isin(events['kind'], np.concatenate([_own_kinds(n) for n in JOINT_NODES]))
    heard = events[owned].astype(EVENT_DTYPE)
    heard['t'] = np.maximum(0, np.round(events['t'][owned] * NS_PER_S).astype(np.int64)) / NS_PER_S
    return heard, events['t'][owned]


def _run_window(
    line: LineStream, sup: _SupervisorOut, pending: list[tuple[int, Tuning]], k: int, end: int
) -> tuple[np.ndarray, np.ndarray, list[_Tick]]:
    """Run ticks ``k`` to ``end - 1`` (of :data:`RATE`) of the line under the supervisor: ``(stamps ns, the
    line's events, the supervisor's ticks)``. A command cuts the window after its tick: the line is run
    again from the window's start under it, and the stamps end there. The ``pending`` tunings due
    (``(tick, tuning)``, in order) are asked and removed."""
    logic = sup.logic
    step_ns = round(NS_PER_S / RATE)
    diag_step = round(NS_PER_S / DIAG_RATE)
    start = line.checkpoint()
    window = line.advance((end - 1) * step_ns / NS_PER_S)
    heard, heard_t = _heard(window.events)
    logic.preview(heard)  # the window's cycles evaluated at once (the decisions are the same)
    stamps = np.arange(k, end, dtype=np.int64) * step_ns
    t = stamps / NS_PER_S
    bounds = np.searchsorted(heard_t, np.concatenate(([window.t0], t)), side='right')
    ticks: list[_Tick] = []
    n_commands = len(logic.commands)
    # per tick as Python numbers (the same values: the loop runs 200 times a second of line time)
    cuts, times, diags = bounds.tolist(), t.tolist(), (stamps % diag_step == 0).tolist()
    for i in range(end - k):
        if cuts[i + 1] > cuts[i]:
            logic.feed(heard[cuts[i] : cuts[i + 1]])
        logic.tick(times[i])
        while pending and pending[0][0] == k + i:
            sup.tune(times[i], pending.pop(0)[1])
        ticks.append(_Tick(logic.state, sup.outputs(), diags[i]))
        if len(logic.commands) != n_commands:  # the line runs under it from the next tick on
            line.restore(start, logic.commands)
            window = line.advance(times[i])
            stamps = stamps[: i + 1]
            break
    return stamps, window.events, ticks


def write_batch_bag(
    directory: str | os.PathLike[str],
    scene: Scene,
    duration: float,
    *,
    custom: Mapping[str, str] | None = None,
    progress: Callable[[float], None] | None = None,
    tunings: Sequence[Tuning] = (),
    marker_rate: float = MARKER_RATE,
    max_duration_s: float = 0.0,
    max_size: int = 0,
) -> BatchBag:
    """Write the bag of a live lockstep ``folder-line run`` of ``scene`` for ``duration`` s, without DDS.

    Parameters
    ----------
    directory : path-like
        The bag directory: missing or empty (:class:`~folder_line.bag.writer.BagWriter`).
    scene : Scene
        The scene, parsed.
    duration : float
        Line time, s: a whole number of ticks (``1 / RATE`` = 5 ms), > 0.
    custom : mapping of str to str, optional
        Extra ``custom_data`` entries (``folder_line.scene_arg``, ``folder_line.overrides``).
    progress : callable, optional
        Called with the line time written so far (s), after each window.
    tunings : sequence of Tuning
        Operator's tunings, each effective at its ``t`` (> 0): the supervisor is asked at
        the last tick before it (:meth:`~folder_line.core.supervision.supervisor.Supervisor.tune`
        with that effective time), as the live one would be by a machine node, and the
        bag holds the tuning and its status as a live run's does.
    marker_rate : float, optional
        ``/line/markers`` per second of line time, as ``run --marker-rate`` (0: none).
    max_duration_s, max_size : float, int, optional
        Split the bag by line time (s) or size (bytes), as ``run --max-bag-duration`` and
        ``--max-bag-size`` (0: one file; :class:`~folder_line.bag.writer.BagWriter`).

    Returns
    -------
    BatchBag

    Raises
    ------
    ParameterError
        ``duration`` not a positive whole number of ticks.
    folder_line.errors.BagError
        The directory is not missing or empty.
    """
    check_duration(scene, duration)
    step_ns = round(NS_PER_S / RATE)
    duration_ns = seconds_to_ns(duration)
    n_ticks = duration_ns // step_ns + 1
    diag_step = round(NS_PER_S / DIAG_RATE)
    logic = supervisor_logic(scene, SUPERVISOR_DEFAULTS)
    sup = _SupervisorOut(logic, scene.name)
    line = LineStream(scene)
    # each tuning is asked at the last tick before its effective time
    pending = sorted(((-(-seconds_to_ns(tu.t) // step_ns) - 1, tu) for tu in tunings), key=lambda x: x[1].t)
    if pending and pending[0][0] < 0:
        raise ParameterError('tunings', pending[0][1].t, 'a tuning takes effect after the start of the line (t > 0)')
    bag = BagWriter(
        directory,
        scene_source=scene_text(scene),
        effects=list(scene.effects),
        scene_name=scene.name,
        topics=LINE_TOPIC_TYPES,
        custom={'folder_line.mode': 'batch', 'folder_line.clock': 'lockstep', **(custom or {})},
        rewrite_metadata=False,
        max_duration_s=max_duration_s,
        max_size=max_size,
    )
    result = BatchBag(str(bag.path))
    writer = WindowWriter(bag, scene, line, sup, marker_rate)
    try:
        bag.write_serialized(PARTICIPANTS_TOPIC, string_cdr(announcement(duration_ns)), 0, 0)
        k = 0
        while k < n_ticks:
            # a window ends at a diagnostics stamp (the tallies are read there), or at the last tick
            next_diag = -(-(k * step_ns) // diag_step) * diag_step
            stamps, events, ticks = _run_window(line, sup, pending, k, min(n_ticks, next_diag // step_ns + 1))
            writer.write(stamps, events, ticks)
            k += len(stamps)
            if progress is not None:
                progress(float(stamps[-1]) / NS_PER_S)
        bag.close(published=dict(bag.counts))
    except BaseException:
        bag.abandon()  # what was written stays readable, marked partial (Ctrl-C, a full disk)
        raise
    result.counts = dict(bag.counts)
    result.files = len(bag.files)
    result.state = logic.state
    result.commands = [(c.t, c.kind) for c in logic.commands]
    return result
