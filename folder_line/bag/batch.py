"""The bag a live lockstep run would record, written from the batch model without DDS (``simulate --bag``).

``folder-line run`` records what the nodes publish in lockstep; every message depends only
on the scene, its tick and the supervisor's commands (:mod:`folder_line.ros.nodes.machine`).
So this module computes them with the same core the nodes use, tick by tick on the run's
grid (``rate`` = :data:`folder_line.config.run_config.RATE`, 200 Hz of line time; model horizon
``duration + 1 s`` as ``run`` gives its nodes), and writes them with
:class:`folder_line.bag.writer.BagWriter`, the recorder's writer:

* ``/clock``: every tick ``k / rate``, 0 to ``duration``;
* ``/line/participants``: the clock's announcement (``clock=lockstep end=<ns> participants=...``),
  logged at 0;
* ``/line/<node>/joint_states`` of each machine node at every tick: the node's model sampled
  100 grid points at a time as the node samples it (:data:`SAMPLE_BATCH`);
* ``/line/events``: each machine node's exact events of ``(t_prev, t]`` at tick ``t``;
* ``/line/sheet_counter/{count,rate,landing_x}`` as the ``sheet_counter`` node computes them;
* ``/line/markers`` at ``marker_rate`` (the ``sheet_counter`` node's grid, stamps ``i / marker_rate``,
  each at the first tick at or after it): the scenery of the model of that tick
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
from typing import Any

import numpy as np

from folder_line.bag.cdr import (
    JointStateLayout,
    clock_cdr,
    float64_cdr,
    string_cdr,
    time_reference_cdr,
    uint64_cdr,
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
from folder_line.bag.types import typestore
from folder_line.bag.writer import BagWriter
from folder_line.config.run_config import MARKER_RATE, RATE, SUPERVISOR_DEFAULTS, supervisor_logic
from folder_line.config.scenes import scene_text
from folder_line.core.limits import HORIZON_MARGIN
from folder_line.core.line.events import EVENT_DTYPE
from folder_line.core.line.model import LineModel, check_size
from folder_line.core.line.scene import Scene
from folder_line.core.line.scenery import Scenery
from folder_line.core.line.tuning import LineCommand, Tuning
from folder_line.core.mechanisms.pile import counted_event
from folder_line.core.supervision.supervisor import Supervisor
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
    event_source,
    joint_states_topic,
    seconds_to_ns,
)

__all__ = ['DIAG_RATE', 'RATE_WINDOW', 'SAMPLE_BATCH', 'BatchBag', 'announcement', 'check_duration', 'write_batch_bag']

#: grid points a machine node samples from its model in one call (``folder_line.ros.nodes.machine``)
SAMPLE_BATCH = 100
#: the supervisor's ``diag_rate`` default, Hz of line time
DIAG_RATE = 1.0
#: the sheet counter's ``rate_window`` default, s
RATE_WINDOW = 5.0
#: ticks computed and written at a time (bounds the memory of an hour-long bag)
BLOCK_TICKS = 2000


@dataclass
class BatchBag:
    """What :func:`write_batch_bag` wrote.

    Attributes
    ----------
    path : str
        The bag directory.
    counts : dict of str to int
        Messages per topic.
    segments : int
        ``.mcap`` files.
    state : str
        The supervisor's state at the last tick.
    commands : list of (float, str)
        The supervisor's drive commands: (effective time, s; kind).
    """

    path: str
    counts: dict[str, int] = field(default_factory=dict)
    segments: int = 0
    state: str = ''
    commands: list[tuple[float, str]] = field(default_factory=list)


def _own_kinds(node: str) -> np.ndarray:
    return np.array([EVENT_KINDS.index(k) for k, n in EVENT_OWNER.items() if n == node], dtype=np.int16)


class _Machine:
    """One machine node's view of a model: its events and its joints, sampled as the node samples them."""

    def __init__(self, node: str, step_ns: int, horizon_ns: int) -> None:
        self.node = node
        self.unit = {n: u for u, n in NODE_OF_UNIT.items()}.get(node, '')
        self.kinds = _own_kinds(node)
        self.step_ns = step_ns
        self.horizon_ns = horizon_ns
        self.topic = joint_states_topic(node)
        self.layout: JointStateLayout | None = None
        self._batch: tuple[int, np.ndarray, np.ndarray, np.ndarray | None] | None = None  # first k, pos, vel, eff
        self.model: LineModel | None = None

    def set_model(self, model: LineModel) -> None:
        self.model = model
        ev = model.events
        self.events = ev[np.isin(ev['kind'], self.kinds)] if ev.size else ev
        self.event_t = self.events['t']
        self._batch = None  # the node drops its sampled batch when its model changes

    def joints(self, k0: int, k1: int) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """Position, velocity, effort rows of ticks ``k0 .. k1 - 1``, batched as the node batches them."""
        assert self.model is not None
        pos, vel, eff = [], [], []
        k = k0
        while k < k1:
            b = self._batch
            if b is None or not (b[0] <= k < b[0] + len(b[1])):
                g = k * self.step_ns
                n = max(1, min(SAMPLE_BATCH, (self.horizon_ns - g) // self.step_ns + 1))
                times = np.array([g + i * self.step_ns for i in range(n)], dtype=float) / NS_PER_S
                js = self.model.sample(self.unit, times)
                if self.layout is None:
                    effort = 0 if js.effort is None else js.effort.shape[1]
                    width = js.position.shape[1]
                    self.layout = JointStateLayout.of(self.node, list(js.names), (width, width, effort))
                b = self._batch = (k, js.position, js.velocity, js.effort)
            i0, i1 = k - b[0], min(k1, b[0] + len(b[1])) - b[0]
            pos.append(b[1][i0:i1])
            vel.append(b[2][i0:i1])
            if b[3] is not None:
                eff.append(b[3][i0:i1])
            k = b[0] + i1
        return np.vstack(pos), np.vstack(vel), (np.vstack(eff) if eff else None)


class _Drawing:
    """The ``sheet_counter`` node's ``/line/markers``: its grid and the scenery of its current model."""

    def __init__(self, rate: float) -> None:
        self.rate = rate
        self.last_ns: int | None = None
        self.scenery: Scenery | None = None

    def tick(self, model: LineModel, stamp_ns: int) -> list[bytes]:
        """CDR of the marker arrays the node publishes at the tick ``stamp_ns`` (ns)."""
        out = []
        for g in marker_stamps(self.last_ns, stamp_ns, self.rate):
            if self.scenery is None or self.scenery.model is not model:
                self.scenery = Scenery(model)
            out.append(markers_cdr(marker_specs(self.scenery.at(g / NS_PER_S)), g, delete_all=self.last_ns is None))
            self.last_ns = g
        return out


def _status_msg(s: Status) -> Any:  # a typestore diagnostic_msgs/msg/DiagnosticStatus
    types = typestore().types
    kv = types['diagnostic_msgs/msg/KeyValue']
    return types['diagnostic_msgs/msg/DiagnosticStatus'](
        level=s.level,
        name=s.name,
        message=s.message,
        hardware_id=s.hardware_id,
        values=[kv(key=k, value=v) for k, v in s.values],
    )


def _array_cdr(stamp: int, statuses: list[Status]) -> bytes:
    """CDR of the supervisor's ``diagnostic_msgs/msg/DiagnosticArray`` of ``statuses`` stamped ``stamp`` (ns)."""
    types = typestore().types
    header = types['std_msgs/msg/Header'](
        stamp=types['builtin_interfaces/msg/Time'](sec=stamp // NS_PER_S, nanosec=stamp % NS_PER_S),
        frame_id=SUPERVISOR,
    )
    msg = types['diagnostic_msgs/msg/DiagnosticArray'](header=header, status=[_status_msg(s) for s in statuses])
    return bytes(typestore().serialize_cdr(msg, 'diagnostic_msgs/msg/DiagnosticArray', little_endian=True))


class _SupervisorOut:
    """What the ``supervisor`` node publishes from its logic besides its state (``ros/nodes/supervisor.py``)."""

    def __init__(self, logic: Supervisor, hardware_id: str) -> None:
        self.logic = logic
        self.hardware_id = hardware_id
        self._n_violations = self._n_balances = 0
        self._tunings: list[tuple[str, bytes, int]] = []

    def _event(self, what: str, said: tuple[bool, str, dict[str, Any]], t: float) -> tuple[str, bytes, int]:
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
        violations = self.logic.violations
        out += [self._event('violation', violation_status(v), v.t) for v in violations[self._n_violations :]]
        self._n_violations = len(violations)
        balances = self.logic.balances
        out += [self._event('balance', balance_status(b), b.t) for b in balances[self._n_balances :]]
        self._n_balances = len(balances)
        return out

    def diagnostics(self, model: LineModel, stamp: int) -> bytes:
        """The periodic array at ``stamp`` (ns): the constraints of ``model``, then the inputs (none rejected)."""
        return _array_cdr(stamp, constraint_statuses(model, stamp / NS_PER_S, self.hardware_id, {}, []))


def announcement(duration_ns: int) -> str:
    """``line_clock``'s announcement of a lockstep run of ``folder-line run`` (``folder_line.ros.lockstep``)."""
    return f'clock=lockstep end={duration_ns} participants={",".join(KNOWN_PARTICIPANTS)}'


def _heard(model: LineModel) -> tuple[np.ndarray, np.ndarray]:
    """The machines' events of ``model`` as the supervisor hears them (time rounded to the ns, as
    ``time_ref`` carries it), and their model times (which decide the tick that publishes each)."""
    owned = np.isin(model.events['kind'], np.concatenate([_own_kinds(n) for n in JOINT_NODES]))
    events = model.events[owned]
    heard = events.astype(EVENT_DTYPE)
    heard['t'] = np.maximum(0, np.round(events['t'] * NS_PER_S).astype(np.int64)) / NS_PER_S
    return heard, events['t']


def check_duration(scene: Scene, duration: float) -> None:
    """Refuse a ``duration`` (s) that is not a positive whole number of ticks, or whose model would not fit.

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
    check_size(scene, duration, duration + HORIZON_MARGIN, '--duration')


def write_batch_bag(
    directory: str | os.PathLike[str],
    scene: Scene,
    duration: float,
    *,
    custom: Mapping[str, str] | None = None,
    progress: Callable[[float], None] | None = None,
    tunings: Sequence[Tuning] = (),
    marker_rate: float = MARKER_RATE,
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
        Called with the line time written so far (s), after each block of ticks.
    tunings : sequence of Tuning
        Operator's tunings, each effective at its ``t`` (> 0): the supervisor is asked at
        the last tick before it (:meth:`~folder_line.core.supervision.supervisor.Supervisor.tune`
        with that effective time), as the live one would be by a machine node, and the
        bag holds the tuning and its status as a live run's does.
    marker_rate : float, optional
        ``/line/markers`` per second of line time, as ``run --marker-rate`` (0: none).

    Returns
    -------
    BatchBag

    Raises
    ------
    ParameterError
        ``duration`` not a positive whole number of ticks, or too long for memory.
    folder_line.errors.BagError
        The directory is not missing or empty.
    """
    check_duration(scene, duration)
    step_ns = round(NS_PER_S / RATE)
    duration_ns = seconds_to_ns(duration)
    horizon = duration + HORIZON_MARGIN
    horizon_ns = round(horizon * NS_PER_S)
    n_ticks = duration_ns // step_ns + 1
    models: dict[tuple[LineCommand, ...], LineModel] = {}

    def model_of(commands: tuple[LineCommand, ...]) -> LineModel:
        if commands not in models:
            models[commands] = LineModel(scene, horizon, commands)
        return models[commands]

    logic = supervisor_logic(scene, horizon, SUPERVISOR_DEFAULTS, model_of)
    sup = _SupervisorOut(logic, scene.name)
    model = logic.model
    machines = [_Machine(n, step_ns, horizon_ns) for n in JOINT_NODES]
    with_joints = [m for m in machines if m.unit in model.units]
    for m in machines:
        m.set_model(model)
    heard, heard_t = _heard(model)
    landed = EVENT_KINDS.index('leaf_landed')
    counted = EVENT_KINDS.index(counted_event(scene.has_delivery))
    bag = BagWriter(
        directory,
        scene_source=scene_text(scene),
        effects=list(scene.effects),
        scene_name=scene.name,
        topics=LINE_TOPIC_TYPES,
        custom={'folder_line.mode': 'batch', 'folder_line.clock': 'lockstep', **(custom or {})},
        rewrite_metadata=False,
    )
    result = BatchBag(str(bag.path))
    diag_step = round(NS_PER_S / DIAG_RATE)
    next_diag = 0
    states: dict[str, bytes] = {}
    # each tuning is asked at the last tick before its effective time
    pending = sorted(((-(-seconds_to_ns(tu.t) // step_ns) - 1, tu) for tu in tunings), key=lambda x: x[1].t)
    if pending and pending[0][0] < 0:
        raise ParameterError('tunings', pending[0][1].t, 'a tuning takes effect after the start of the line (t > 0)')
    drawing = _Drawing(marker_rate)
    try:
        bag.write_serialized(PARTICIPANTS_TOPIC, string_cdr(announcement(duration_ns)), 0, 0)
        k = 0
        prev_t = -math.inf
        while k < n_ticks:
            # ticks k .. end - 1 run on one model: a drive command ends the block at the tick it is decided
            end = min(k + BLOCK_TICKS, n_ticks)
            stamps = np.arange(k, end, dtype=np.int64) * step_ns
            t = stamps / NS_PER_S
            # the supervisor hears every machine's events of the tick, their time as sent (to the ns)
            bounds = np.searchsorted(heard_t, np.concatenate(([prev_t], t)), side='right')
            per_tick: list[tuple[str, list[tuple[str, bytes, int]], bool]] = []
            for i in range(end - k):
                if bounds[i + 1] > bounds[i]:
                    logic.feed(heard[bounds[i] : bounds[i + 1]])
                logic.tick(float(t[i]))
                while pending and pending[0][0] == k + i:
                    tu = pending.pop(0)[1]
                    sup.tune(float(t[i]), tu)
                outs = sup.outputs()
                diag = bool(stamps[i] >= next_diag)
                if diag:
                    next_diag = int(stamps[i]) + diag_step
                per_tick.append((logic.state, outs, diag))
                if logic.model is not model:
                    end = k + i + 1
                    break
            _write_block(
                bag, machines, with_joints, sup, model, k, end, step_ns, per_tick, landed, counted, states, drawing
            )
            prev_t = float((end - 1) * step_ns / NS_PER_S)
            k = end
            if progress is not None:
                progress(prev_t)
            if logic.model is not model:
                model = logic.model
                for m in machines:
                    m.set_model(model)
                heard, heard_t = _heard(model)
        bag.close(published=dict(bag.counts))
    except BaseException:
        bag.abandon()  # what was written stays readable, marked partial (Ctrl-C, a full disk)
        raise
    result.counts = dict(bag.counts)
    result.segments = len(bag.files)
    result.state = logic.state
    result.commands = [(c.t, c.kind) for c in logic.commands]
    return result


def _write_block(
    bag: BagWriter,
    machines: list[_Machine],
    with_joints: list[_Machine],
    sup: _SupervisorOut,
    model: LineModel,
    k0: int,
    k1: int,
    step_ns: int,
    per_tick: list[tuple[str, list[tuple[str, bytes, int]], bool]],
    landed: int,
    counted: int,
    states: dict[str, bytes],
    drawing: _Drawing,
) -> None:
    """Write ticks ``k0 .. k1 - 1``: per tick ``/clock``, then node by node what it publishes."""
    n = k1 - k0
    stamps = np.arange(k0, k1, dtype=np.int64) * step_ns
    t = stamps / NS_PER_S
    joints: dict[str, tuple[bytes, int]] = {}
    for m in with_joints:
        pos, vel, eff = m.joints(k0, k1)
        assert m.layout is not None
        joints[m.node] = (m.layout.many(stamps, pos, vel, eff), len(m.layout.template))
    counter = machines[JOINT_NODES.index('sheet_counter')]
    counted_t = model.events['t'][model.events['kind'] == counted]
    count = np.searchsorted(counted_t, t, side='right')
    window = np.minimum(RATE_WINDOW, t)
    with np.errstate(invalid='ignore', divide='ignore'):
        rate = np.where(window <= 0.0, 0.0, (count - np.searchsorted(counted_t, t - window, side='right')) / window)
    prev = -math.inf if k0 == 0 else (k0 - 1) * step_ns / NS_PER_S
    ev_lo = {m.node: int(np.searchsorted(m.event_t, prev, side='right')) for m in machines}
    ev_hi = {m.node: np.searchsorted(m.event_t, t, side='right') for m in machines}
    clocks = [clock_cdr(int(x)) for x in stamps]
    counts = [uint64_cdr(int(c)) for c in count]
    rates = [float64_cdr(float(r)) for r in rate]
    for i in range(n):
        stamp = int(stamps[i])
        items: list[tuple[str, bytes, int]] = [(CLOCK_TOPIC, clocks[i], stamp)]
        for m in machines:
            j0, j1 = ev_lo[m.node], int(ev_hi[m.node][i])
            if j1 > j0:
                ev_lo[m.node] = j1
                mine = m.events[j0:j1]
                for row in mine:
                    source = event_source(EVENT_KINDS[row['kind']], row['sheet'], row['cycle'], row['value'])
                    time_ref = max(0, round(float(row['t']) * NS_PER_S))
                    items.append((EVENTS_TOPIC, time_reference_cdr(stamp, m.node, time_ref, source), stamp))
            else:
                mine = m.events[0:0]
            if m.node in joints:
                blob, size = joints[m.node]
                items.append((m.topic, blob[i * size : (i + 1) * size], stamp))
            if m is counter:
                items.append((SHEET_COUNT_TOPIC, counts[i], stamp))
                items.append((SHEET_RATE_TOPIC, rates[i], stamp))
                for row in mine[mine['kind'] == landed]:
                    items.append((LANDING_TOPIC, float64_cdr(float(row['value'])), stamp))
                items.extend((MARKERS_TOPIC, cdr, stamp) for cdr in drawing.tick(model, stamp))
        state, outs, diag = per_tick[i]
        items.extend(outs)
        if state not in states:
            states[state] = string_cdr(state)
        items.append((SUPERVISOR_STATE_TOPIC, states[state], stamp))
        if diag:
            items.append((DIAGNOSTICS_TOPIC, sup.diagnostics(model, stamp), stamp))
        bag.write_many(stamp, items)
