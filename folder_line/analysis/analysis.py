"""Replay analysis of a recorded run: ``folder-line analyze RUN_DIR|BAG [--out DIR] [--csv]``.

:func:`analyze` reads a run's bag (:mod:`folder_line.bag.bag`; ``RUN_DIR`` is what
``folder-line run --out RUN_DIR`` wrote: ``run.json`` and ``bag/``) and writes to
``--out`` (default ``RUN_DIR/analysis``)

``report.md``
    the run's numbers -- cycles, sheets counted, per-constraint minimum margins, the
    violations (cycle, constraint, margin), the supervisor's state transitions, the
    messages recorded and lost -- and the figures;
``exit_speeds.png`` (scenes with the layup)
    the chutes' exit speeds ``v_C = ω3 l3``, ``v_E = ω5 l5`` and the absolute ones
    ``v_aC``, ``v_aE`` with the recorded belt speed against the recorded crank angle,
    over the model's curves (paper L, figs. 4-5), with the leaves' exit speeds;
``efficiency.png`` (scenes with the delivery)
    the efficiency ``η`` and the carriage speed ratio ``K_v`` at the recorded carriage
    positions along the stroke, over the model's curves (paper D, fig. 2), and the
    recorded sprocket torque (``chain_friction``);
``cyclogram.png`` (scenes with the folder)
    the first cycles as a Gantt chart of the operations А (feed: hand-over -> at the
    stops), Б (settle and dwell: at the stops -> settled -> knife contact), В (knife:
    contact -> exit) and Г (delivery: knife exit -> released on the pile), each cycle
    annotated with its margins (paper F, figs. 1-2);
``margins.png``
    a histogram of each constraint's margins over all cycles, violations in red;
``landing.png`` (scenes with ``leaf_flight``)
    where the leaves landed across the container (``leaf_landed`` events), with the
    spilled ones;
``csv/<topic>.csv`` (``--csv``)
    every message of every topic of the bag, one row each, the message flattened
    to columns (:func:`flatten_message`), written atomically.

The same constraint code as the line
------------------------------------
The events are decoded from ``/line/events`` (``time_ref``: the event time to the
ns; ``source``: :func:`folder_line.event_text.parse_event_source`) and judged by the
functions the batch simulator and the live supervisor call,
:func:`folder_line.core.line.constraints.folder_evaluation` and
:func:`folder_line.core.line.constraints.evaluate_layup_constraints`, on the scene stored
in the bag and its drive under the recorded supervisor commands. The numbers of
``report.md`` are therefore those of ``simulate(scene, t_end, commands=...)`` for a run of
``t_end`` s (up to the ns rounding of the event times), and the per-constraint
figures are computed by :meth:`folder_line.core.line.model.LineResult.summary`, as the
``simulate`` verb's are.

State transitions: the recorded inputs of the live supervisor -- the events, the
joint-state stamps (liveness), the ``/clock`` messages, the operator's commands --
are replayed through :func:`folder_line.core.supervision.decisions.replay`, the logic the live
node runs (:func:`replay_transitions`); the report gives the replayed transitions
with their decision times and causes, the violations as the supervisor decided them
(causal, with the action taken), and whether they agree with the states recorded on
``/line/supervisor/state`` (:func:`transitions_agree`). The node's parameters are
read from the bag's custom data ``folder_line.supervisor`` (JSON) if it is there,
else they are the ones ``folder-line run`` starts the node with
(:data:`SUPERVISOR_DEFAULTS`).

No ROS is needed: the bag is read with rosbags.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from folder_line.config.run_config import SUPERVISOR_DEFAULTS
from folder_line.core.line.constraints import FOLDER_CONSTRAINTS, evaluate_layup_constraints, folder_evaluation
from folder_line.core.line.events import EVENT_DTYPE, ConstraintSeries, event_kind
from folder_line.core.line.scene import Scene, parse_scene
from folder_line.core.mechanisms.drive import Command, Drive
from folder_line.errors import FolderLineError, ParameterError
from folder_line.files.atomic import (
    check_output_file,
    claim_output_dir,
    describe_path,
    write_csv_atomic,
    write_text_atomic,
)
from folder_line.files.yamlio import METADATA_LIMIT, load_yaml, read_text_bounded
from folder_line.interfaces import (
    CLOCK_TOPIC,
    COMMANDS_TOPIC,
    DIAGNOSTICS_TOPIC,
    EVENT_KINDS,
    EVENTS_TOPIC,
    LANDING_TOPIC,
    NS_PER_S,
    SHEET_COUNT_TOPIC,
    SUPERVISOR_STATE_TOPIC,
    joint_states_node,
    parse_event_source,
)

__all__ = [
    'CLOCK_TOPIC',
    'COMMANDS_TOPIC',
    'DIAGNOSTICS_TOPIC',
    'EVENTS_TOPIC',
    'FIGURES',
    'KEY_SUPERVISOR',
    'LANDING_TOPIC',
    'SHEET_COUNT_TOPIC',
    'STATE_TOPIC',
    'SUPERVISOR_DEFAULTS',
    'AnalysisResult',
    'RecordedJoints',
    'Recording',
    'analyze',
    'csv_name',
    'cycle_rows',
    'efficiency_data',
    'exit_speed_data',
    'flatten_message',
    'landing_data',
    'print_analysis',
    'read_recording',
    'recorded_transitions',
    'replay_transitions',
    'supervisor_parameters',
    'transitions_agree',
]

STATE_TOPIC = SUPERVISOR_STATE_TOPIC
#: the statuses the supervisor publishes on /diagnostics for its decisions
SUPERVISOR_STATUS_PREFIX = 'folder_line/supervisor/'

#: figure file -> what it shows (the captions of report.md)
FIGURES: dict[str, str] = {
    'exit_speeds.png': 'L: exit speeds against the crank angle, recorded (points) over the model (lines); '
    'paper L figs. 4-5',
    'efficiency.png': 'D: efficiency, carriage speed ratio and sprocket torque at the recorded carriage '
    'positions along the stroke; paper D fig. 2',
    'cyclogram.png': 'F: the first cycles as a Gantt chart of the operations А, Б, В, Г with their margins; '
    'paper F figs. 1-2',
    'margins.png': 'margins of every constraint over all cycles (violations in red)',
    'landing.png': 'L: where the leaves landed across the container',
}

#: cycles shown in the Gantt chart by default
GANTT_CYCLES = 8


# --------------------------------------------------------------------------- reading


@dataclass(frozen=True, eq=False)
class RecordedJoints:
    """The joint states one node published, as recorded.

    Attributes
    ----------
    node : str
        ``crank_drive``, ``belt_conveyor`` or ``feed_transporter``.
    names : tuple of str
        Joint names (the columns).
    t : ndarray, shape (N,)
        ``header.stamp`` of each message (the node's tick), s.
    position, velocity : ndarray, shape (N, J)
    effort : ndarray, shape (N, J), or None
        None where the node published no efforts.
    """

    node: str
    names: tuple[str, ...]
    t: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    effort: np.ndarray | None

    def column(self, joint: str, quantity: str = 'position') -> np.ndarray:
        """One joint's ``position``, ``velocity`` or ``effort`` over the recording (KeyError if absent)."""
        if joint not in self.names:
            msg = f'{self.node} has no joint {joint!r}; joints: {", ".join(self.names)}'
            raise KeyError(msg)
        data = getattr(self, quantity)
        if data is None:
            msg = f'{self.node} published no {quantity}'
            raise KeyError(msg)
        return data[:, self.names.index(joint)]


@dataclass(frozen=True, eq=False)
class Recording:
    """What :func:`read_recording` decoded from a bag.

    Attributes
    ----------
    bag : BagContents
        The bag (:func:`folder_line.bag.bag.read_bag`).
    run : dict or None
        ``run.json`` of the run directory, if there is one.
    scene : Scene
        The scene stored in the bag.
    t_end : float
        Line time reached: the last ``/clock`` (the bag's end if it has none), s.
    events : ndarray of EVENT_DTYPE
        The events of ``/line/events``, ``t`` = ``time_ref`` in s, sorted as
        :func:`folder_line.core.line.events.merge_events` sorts (time, kind, sheet).
    event_ns : ndarray of int64
        The same events' ``time_ref`` in ns (exact).
    joints : dict of str to RecordedJoints
        Node -> its joint states.
    states : list of (int, str)
        ``(log time ns, state)`` of every ``/line/supervisor/state`` message.
    commands : tuple of Command
        The drive commands of ``/line/supervisor/commands`` (effective time, kind),
        sorted by time, duplicates dropped -- what the nodes applied.
    sheet_count : int or None
        The last ``/line/sheet_counter/count``.
    landing_x : ndarray
        ``/line/sheet_counter/landing_x`` values, m.
    bad_events : int
        ``/line/events`` messages whose ``source`` is not an event.
    clock : ndarray
        The ``/clock`` times, s.
    diagnostics_ns : ndarray of int64
        ``header.stamp`` of every ``/diagnostics`` message, ns.
    supervisor_status : list of (int, str, dict)
        ``(stamp ns, name, values)`` of every ``folder_line/supervisor/...`` status of
        ``/diagnostics`` (violations, balances, operator commands).
    bad_values : list of (float, str, int)
        ``(stamp s, topic, count)`` of joint states carrying NaN or inf.
    """

    bag: Any
    run: dict[str, Any] | None
    scene: Scene
    t_end: float
    events: np.ndarray
    event_ns: np.ndarray
    joints: dict[str, RecordedJoints]
    states: list[tuple[int, str]]
    commands: tuple[Command, ...]
    sheet_count: int | None
    landing_x: np.ndarray
    bad_events: int
    clock: np.ndarray = field(default_factory=lambda: np.zeros(0))
    diagnostics_ns: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    supervisor_status: list[tuple[int, str, dict[str, str]]] = field(default_factory=list)
    bad_values: list[tuple[float, str, int]] = field(default_factory=list)

    def events_of(self, kind: str) -> np.ndarray:
        """Rows of one event kind."""
        return self.events[self.events['kind'] == event_kind(kind)]


def _resolve(path: str | os.PathLike[str]) -> tuple[Path, dict[str, Any] | None]:
    """(bag directory, run.json or None) of a run directory or a bag directory."""
    from folder_line.config.run_config import BAG_DIR

    p = Path(path)
    if not p.is_dir():
        what = (
            'no such directory'
            if not os.path.lexists(p)
            else f'{describe_path(p)}, not a run directory or a bag directory'
        )
        raise ParameterError('RUN_DIR|BAG', str(path), what)
    if (p / BAG_DIR).is_dir():
        bag, run_dir = p / BAG_DIR, p
    elif os.path.lexists(p / 'metadata.yaml') or any(p.glob('*.mcap')):  # read_bag says what is wrong with it
        bag = p
        run_dir = p.parent if p.name == BAG_DIR else None
    else:
        raise ParameterError(
            'RUN_DIR|BAG', str(path), f'neither a run directory (with {BAG_DIR}/) nor a bag (with metadata.yaml)'
        )
    run = None
    if run_dir is not None and (run_dir / 'run.json').is_file():
        text = read_text_bounded(run_dir / 'run.json', 'RUN_DIR|BAG', METADATA_LIMIT)
        try:
            run = json.loads(text)
        except ValueError as exc:
            raise ParameterError('RUN_DIR|BAG', str(path), f'run.json cannot be read: {exc}') from None
    return bag, run


def _time_ns(stamp: Any) -> int:
    return int(stamp.sec) * NS_PER_S + int(stamp.nanosec)


class _Joints:
    """Accumulates one node's joint states."""

    def __init__(self, node: str, names: Sequence[str]) -> None:
        self.node, self.names = node, tuple(names)
        self.t: list[int] = []
        self.pos: list[np.ndarray] = []
        self.vel: list[np.ndarray] = []
        self.eff: list[np.ndarray] = []

    def add(self, msg: Any) -> None:
        if tuple(msg.name) != self.names:  # a model rebuilt with other joints: keep the first layout
            return
        self.t.append(_time_ns(msg.header.stamp))
        self.pos.append(np.asarray(msg.position, dtype=float))
        self.vel.append(np.asarray(msg.velocity, dtype=float))
        self.eff.append(np.asarray(msg.effort, dtype=float))

    def done(self) -> RecordedJoints:
        j = len(self.names)
        n = len(self.t)
        pos = np.array(self.pos).reshape(n, j) if n else np.zeros((0, j))
        vel = np.array(self.vel).reshape(n, j) if n else np.zeros((0, j))
        has_eff = n > 0 and all(e.size == j for e in self.eff)
        eff = np.array(self.eff).reshape(n, j) if has_eff else None
        t = np.asarray(self.t, dtype=np.int64) / NS_PER_S
        order = np.argsort(t, kind='stable')
        return RecordedJoints(
            self.node, self.names, t[order], pos[order], vel[order], None if eff is None else eff[order]
        )


def read_recording(
    path: str | os.PathLike[str], on_message: Callable[[str, int, Any], None] | None = None
) -> Recording:
    """Decode a run's bag: events, joint states, states, commands, counts (one pass over the bag).

    Parameters
    ----------
    path : path-like
        A run directory (``run.json`` and ``bag/``) or a bag directory.
    on_message : callable, optional
        Called with ``(topic, log time ns, message)`` for every message (the CSV export).

    Raises
    ------
    ParameterError
        ``path`` is neither; the bag holds no scene, or one that does not validate.
    BagError
        The bag cannot be opened (:func:`folder_line.bag.bag.read_bag`).
    """
    from folder_line.bag.bag import read_bag

    bag_dir, run = _resolve(path)
    contents = read_bag(bag_dir)
    if not contents.scene_source:
        raise ParameterError('RUN_DIR|BAG', str(path), 'the bag holds no scene (custom data folder_line.scene)')
    mapping = load_yaml(contents.scene_source, 'RUN_DIR|BAG', f'{path} (its scene, custom data folder_line.scene)')
    if not isinstance(mapping, dict):
        raise ParameterError('RUN_DIR|BAG', str(path), 'the scene stored in the bag is not a mapping')
    scene = parse_scene(mapping)

    clock: list[int] = []
    diag_ns: list[int] = []
    status: list[tuple[int, str, dict[str, str]]] = []
    bad_values: list[tuple[float, str, int]] = []
    ev_rows: list[tuple[int, int, int, int, float]] = []
    bad_events = 0
    joints: dict[str, _Joints] = {}
    states: list[tuple[int, str]] = []
    commands: dict[tuple[int, str], None] = {}
    sheet_count: int | None = None
    landing: list[float] = []
    for topic, t_ns, msg in contents.messages():
        if on_message is not None:
            on_message(topic, t_ns, msg)
        if topic == CLOCK_TOPIC:
            clock.append(_time_ns(msg.clock))
        elif topic == EVENTS_TOPIC:
            try:
                kind, sheet, cycle, value = parse_event_source(msg.source)
            except ValueError:
                bad_events += 1
                continue
            ev_rows.append((_time_ns(msg.time_ref), EVENT_KINDS.index(kind), sheet, cycle, value))
        elif (node := joint_states_node(topic)) is not None:
            acc = joints.get(node)
            if acc is None:
                acc = joints[node] = _Joints(node, msg.name)
            acc.add(msg)
            bad = sum(
                int(np.count_nonzero(~np.isfinite(np.asarray(a, dtype=float))))
                for a in (msg.position, msg.velocity, msg.effort)
                if len(a)
            )
            if bad:
                bad_values.append((_time_ns(msg.header.stamp) / NS_PER_S, topic, bad))
        elif topic == DIAGNOSTICS_TOPIC:
            diag_ns.append(_time_ns(msg.header.stamp))
            for st in msg.status:
                if str(st.name).startswith(SUPERVISOR_STATUS_PREFIX):
                    status.append((diag_ns[-1], str(st.name), {str(kv.key): str(kv.value) for kv in st.values}))
        elif topic == STATE_TOPIC:
            states.append((t_ns, str(msg.data)))
        elif topic == COMMANDS_TOPIC:
            commands[(_time_ns(msg.time_ref), str(msg.source))] = None
        elif topic == SHEET_COUNT_TOPIC:
            sheet_count = int(msg.data)
        elif topic == LANDING_TOPIC:
            landing.append(float(msg.data))

    ns = np.array([r[0] for r in ev_rows], dtype=np.int64)
    events = np.zeros(len(ev_rows), dtype=EVENT_DTYPE)
    if ev_rows:
        events['t'] = ns / NS_PER_S
        events['kind'] = [r[1] for r in ev_rows]
        events['sheet'] = [r[2] for r in ev_rows]
        events['cycle'] = [r[3] for r in ev_rows]
        events['value'] = [r[4] for r in ev_rows]
    order = np.lexsort((events['sheet'], events['kind'], ns))
    cmds = tuple(sorted((Command(t=t / NS_PER_S, kind=k) for t, k in commands), key=lambda c: c.t))
    t_end = (max(clock) if clock else contents.end_ns) / NS_PER_S
    return Recording(
        bag=contents,
        run=run,
        scene=scene,
        t_end=t_end,
        events=events[order],
        event_ns=ns[order],
        joints={node: acc.done() for node, acc in joints.items()},
        states=states,
        commands=cmds,
        sheet_count=sheet_count,
        landing_x=np.asarray(landing, dtype=float),
        bad_events=bad_events,
        clock=np.asarray(clock, dtype=np.int64) / NS_PER_S,
        diagnostics_ns=np.asarray(diag_ns, dtype=np.int64),
        supervisor_status=status,
        bad_values=bad_values,
    )


# --------------------------------------------------------------------------- CSV


@functools.lru_cache(maxsize=64)
def _field_names(msgtype: str) -> tuple[str, ...]:
    """The fields of a message type (constants excluded), from the rosbags typestore."""
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_KILTED)
    return tuple(name for name, _ in store.fielddefs[msgtype][1])


def _is_message(value: Any) -> bool:
    return hasattr(value, '__msgtype__') and dataclasses.is_dataclass(value)


def _join(prefix: str, name: str) -> str:
    return f'{prefix}.{name}' if prefix else name


def _flatten(value: Any, prefix: str, out: dict[str, Any]) -> None:
    if _is_message(value):
        mt = value.__msgtype__
        if mt == 'sensor_msgs/msg/JointState':
            joints = [str(n) for n in value.name]
            for name in _field_names(mt):
                data = getattr(value, name)
                if name == 'name':
                    continue
                if name in ('position', 'velocity', 'effort') and joints and len(data) == len(joints):
                    for joint, x in zip(joints, np.asarray(data).tolist(), strict=True):
                        out[_join(_join(prefix, name), joint)] = x
                else:
                    _flatten(data, _join(prefix, name), out)
            return
        for name in _field_names(mt):
            _flatten(getattr(value, name), _join(prefix, name), out)
        return
    if isinstance(value, np.ndarray):
        for i, x in enumerate(value.reshape(-1).tolist()):
            out[f'{prefix}[{i}]'] = x
        return
    if isinstance(value, (list, tuple)):
        if value and all(_is_message(v) and v.__msgtype__ == 'diagnostic_msgs/msg/KeyValue' for v in value):
            for kv in value:
                out[_join(prefix, str(kv.key))] = kv.value
            return
        for i, v in enumerate(value):
            _flatten(v, f'{prefix}[{i}]', out)
        return
    out[prefix or 'data'] = value


def flatten_message(msg: Any) -> dict[str, Any]:
    """A bag message (rosbags) as ``{column: scalar}``.

    Nested fields are joined with ``.`` (``header.stamp.sec``), sequences indexed
    (``status[0].level``); joint states are named by joint (``position.knife_crank``;
    the ``name`` list itself is dropped) and ``diagnostic_msgs/KeyValue`` lists by key
    (``status[0].values.margin``).
    """
    out: dict[str, Any] = {}
    _flatten(msg, '', out)
    return out


def csv_name(topic: str) -> str:
    """File name of a topic's CSV: ``/line/crank_drive/joint_states`` -> ``line__crank_drive__joint_states.csv``."""
    return topic.strip('/').replace('/', '__') + '.csv'


class _CsvCollector:
    """Rows of every topic, flattened; written one CSV per topic."""

    def __init__(self) -> None:
        self.rows: dict[str, list[dict[str, Any]]] = {}

    def __call__(self, topic: str, t_ns: int, msg: Any) -> None:
        row = {'log_time_ns': int(t_ns)}
        row.update(flatten_message(msg))
        self.rows.setdefault(topic, []).append(row)

    def write(self, directory: Path, topics: Sequence[str]) -> dict[str, Path]:
        written: dict[str, Path] = {}
        for topic in topics:
            rows = self.rows.get(topic, [])
            names: dict[str, None] = {'log_time_ns': None}
            for row in rows:
                names.update(dict.fromkeys(row))
            columns = {name: [row.get(name, '') for row in rows] for name in names}
            written[topic] = write_csv_atomic(directory / csv_name(topic), columns)
        return written


# --------------------------------------------------------------------------- evaluation


def _live_horizon(run: Mapping[str, Any] | None, t_end: float) -> float:
    """The horizon the run's nodes built their line model for (``folder-line run``'s rule), s.

    It matters only for a scene with ``motor_dynamics``, whose drive is integrated up to
    the horizon; without ``run.json`` the line time reached is used.
    """
    from folder_line.config.run_config import RunConfig, node_parameters

    horizon = t_end
    if run is not None and isinstance(run.get('duration_s'), (int, float)) and run['duration_s'] > 0:
        horizon = float(node_parameters(RunConfig(duration=float(run['duration_s'])), 'crank_drive')['horizon'])
    return max(horizon, t_end, 1e-3)


@dataclass(frozen=True, eq=False)
class _Evaluation:
    drive: Drive
    timing: Any
    plan: Any
    constraints: list[ConstraintSeries]
    signatures: np.ndarray
    cycles: int
    sheets_counted: int
    summary: dict[str, Any]


def _evaluate(rec: Recording) -> _Evaluation:
    """The recorded events judged by the line's constraint code; the simulate-style summary."""
    from folder_line.core.line.model import LineResult, make_drive

    scene = rec.scene
    drive = make_drive(scene, _live_horizon(rec.run, rec.t_end), rec.commands)
    timing = plan = None
    constraints: list[ConstraintSeries] = []
    signatures = np.zeros(0, dtype=np.int64)
    if scene.has_folder:
        from folder_line.core.line.folder_sim import delivery_plan
        from folder_line.core.mechanisms.cyclogram import cycle_timing

        timing = cycle_timing(scene.machines['cyclogram'], scene.machines['knife'])
        plan = delivery_plan(scene, timing)
        fe = folder_evaluation(rec.events, timing, scene, drive, plan=plan)
        constraints += fe.constraints
        signatures = fe.signatures
    if scene.has_layup:
        constraints += evaluate_layup_constraints(rec.events, scene)
    if scene.has_folder:
        cycles = int(rec.events_of('knife_contact').size)
        sheets = int(rec.events_of('released_on_pile').size if plan is not None else signatures.sum())
    else:
        lp = scene.machine('layup')
        theta_end = float(np.asarray(drive.theta(np.asarray(rec.t_end)), dtype=float))
        cycles = math.floor(theta_end * (lp.n_kr / 60.0))
        sheets = int(rec.events_of('leaf_landed').size)
    n_viol = sum(int(np.count_nonzero(c.violated)) for c in constraints)
    summary = LineResult(
        scene=scene, duration=max(rec.t_end, 1e-9), events=rec.events, samples={}, constraints=constraints, parts={}
    ).summary(max_violations=max(n_viol, 1))
    summary['cycles'] = cycles
    summary['sheets_counted'] = sheets
    return _Evaluation(drive, timing, plan, constraints, signatures, cycles, sheets, summary)


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
    """Replay the recorded inputs through :func:`folder_line.core.supervision.decisions.replay`.

    The live supervisor node runs in lockstep: at every tick it is fed the events up to
    that tick (all of them: it waits until every machine node's tick is complete), the
    NaN/inf values found and the operator's commands, and decides exactly at the tick.
    All of these are in the bag (the operator's commands, lost participants and the
    first watermark in the supervisor's ``/diagnostics`` statuses). Its parameters:
    :func:`supervisor_parameters`, updated from ``params``.

    Returns
    -------
    (list of dict, Supervisor)
        The transitions ``{'t', 'from', 'to', 'cause'}`` (decision time, s) and the
        replayed supervisor (its ``violations``, ``commands``, ``balances``).
    """
    from folder_line.core.line.model import LineModel
    from folder_line.core.supervision import decisions as supervision

    p = supervisor_parameters(rec)
    p.update(params or {})
    scene = rec.scene
    horizon = _live_horizon(rec.run, rec.t_end)
    period = 1.0 / float(p['rate'])
    base = LineModel(scene, horizon)
    cache: dict[tuple[Command, ...], Any] = {(): base}

    def model_factory(commands: tuple[Command, ...]) -> Any:
        if commands not in cache:
            cache[commands] = LineModel(scene, horizon, commands)
        return cache[commands]

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
        'model_factory': model_factory,
    }
    sup = supervision.replay(
        scene,
        horizon,
        rec.events,
        bad_values=rec.bad_values,
        operator=operator,
        lost=lost,
        until=max(rec.t_end, t_start),
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
    states left out, ending in the same state; and each replayed transition must be
    decided before the recording first shows its target.
    """
    full = [initial] + [str(t['to']) for t in replayed]
    seen = [str(t['to']) for t in recorded]
    if not seen:
        return not replayed
    if seen[-1] != full[-1]:
        return False
    i = 0
    for state in seen:  # a subsequence of full
        while i < len(full) and full[i] != state:
            i += 1
        if i == len(full):
            return False
        i += 1
    shown = {}
    for t in recorded:
        shown.setdefault(str(t['to']), float(t['t']))
    return all(float(t['t']) <= shown.get(str(t['to']), math.inf) for t in replayed)


# --------------------------------------------------------------------------- figures


#: most points drawn per recorded series (an hour of samples is thinned evenly for the figure)
MAX_POINTS = 5000


def _wrap(phi: np.ndarray) -> np.ndarray:
    return np.mod(phi, 2.0 * math.pi)


def _thin(n: int, cap: int = MAX_POINTS) -> slice:
    """Every k-th sample so that at most ``cap`` of ``n`` are drawn."""
    return slice(None, None, max(1, math.ceil(n / cap)))


def exit_speed_data(rec: Recording) -> dict[str, np.ndarray] | None:
    """The layup's exit speeds from the recorded crank_drive (and belt) joint states, or None.

    Returns
    -------
    dict or None
        ``t`` (s), ``phi`` (crank angle in [0, 2π), rad), ``vC = ω3 l3``, ``vE = ω5 l5``
        (m/s, signed), ``v_belt`` (recorded chute belt speed at the same stamps, m/s;
        0 without belts), ``vaC``, ``vaE`` (``sqrt(v² + v_belt²)``, m/s). None if the
        scene has no layup or nothing of it was recorded.
    """
    scene = rec.scene
    crank = rec.joints.get('crank_drive')
    if not scene.has_layup or crank is None or 'layup_crank' not in crank.names or crank.t.size == 0:
        return None
    lp = scene.machine('layup')
    t = crank.t
    phi = _wrap(crank.column('layup_crank'))
    w3, w5 = crank.column('transporter3', 'velocity'), crank.column('transporter4', 'velocity')
    keep = np.ones(t.size, dtype=bool)
    v_belt = np.zeros(t.size)
    belts = rec.joints.get('belt_conveyor')
    if scene.has('chute_belts'):
        if belts is None or 'chute_belts' not in belts.names or belts.t.size == 0:
            keep[:] = False
        else:  # the belt's sample of the same tick
            i = np.minimum(np.searchsorted(belts.t, t), belts.t.size - 1)
            keep = belts.t[i] == t
            v_belt = np.where(keep, belts.column('chute_belts', 'velocity')[i], 0.0)
    vC, vE = w3 * lp.l3, w5 * lp.l5
    data = {
        't': t,
        'phi': phi,
        'vC': vC,
        'vE': vE,
        'v_belt': v_belt,
        'vaC': np.sqrt(vC * vC + v_belt * v_belt),
        'vaE': np.sqrt(vE * vE + v_belt * v_belt),
    }
    return {k: v[keep] for k, v in data.items()}


def _plot_exit_speeds(rec: Recording, ev: _Evaluation, out: Path) -> Path | None:
    from folder_line.analysis.plots import exit_speed_curves, pyplot, save_figure

    data = exit_speed_data(rec)
    if data is None:
        return None
    plt = pyplot()
    scene = rec.scene
    n_samples = data['t'].size
    lp = scene.machine('layup')
    v_tr = float(lp.v_tr) if scene.has('chute_belts') else 0.0
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(9, 7.5), sharex=True)
    exit_speed_curves(ax1, ax2, lp, v_tr, show_swing_on_abs=False)
    k = _thin(data['t'].size)
    data = {name: v[k] for name, v in data.items()}
    deg = np.degrees(data['phi'])
    ax1.plot(deg, data['vC'], 'o', ms=3, color='C0', alpha=0.7, label=r'recorded $\omega_3 l_3$')
    ax1.plot(deg, data['vE'], 's', ms=3, color='C1', mfc='none', alpha=0.7, label=r'recorded $\omega_5 l_5$')
    ax2.plot(deg, data['vaC'], 'o', ms=3, color='C0', alpha=0.7, label='recorded $v_{aC}$')
    ax2.plot(deg, data['vaE'], 's', ms=3, color='C1', mfc='none', alpha=0.7, label='recorded $v_{aE}$')
    exits = rec.events_of('leaf_exit')
    if exits.size:
        kin_phi = _wrap(2.0 * math.pi * (lp.n_kr / 60.0) * np.asarray(ev.drive.theta(exits['t']), dtype=float))
        c_e = exits['sheet'] % 2 == 1
        ax2.plot(
            np.degrees(kin_phi[~c_e]),
            exits['value'][~c_e],
            'v',
            ms=6,
            color='C3',
            label=f'leaf exits at C ({int(np.count_nonzero(~c_e))})',
        )
        ax2.plot(
            np.degrees(kin_phi[c_e]),
            exits['value'][c_e],
            '^',
            ms=6,
            color='C4',
            label=f'leaf exits at E ({int(np.count_nonzero(c_e))})',
        )
    if scene.has('chute_belts'):
        vmin = float(scene.effect('chute_belts').v_min)
        ax2.axhline(vmin, color='r', ls='--', lw=1, label=f'v_min = {vmin:g} m/s')
    ax1.set_ylabel('swing speed across the chute, m/s')
    ax1.set_title(
        f'L: exit speeds, {n_samples} recorded samples over {rec.t_end:.3f} s '
        '(lines: model at nominal speed; paper Fig. 4)',
        fontsize=10,
    )
    ax1.legend(loc='upper right', fontsize=8)
    ax2.set_ylabel('absolute exit speed, m/s')
    ax2.set_xlabel(r'crank angle $\varphi$, deg')
    belt = (
        f'recorded belt speed {data["v_belt"].min():.3f}..{data["v_belt"].max():.3f} m/s'
        if scene.has('chute_belts') and data['v_belt'].size
        else 'no belts'
    )
    ax2.set_title(f'L: absolute exit speeds with the belts ({belt}; paper Fig. 5)', fontsize=10)
    ax2.legend(loc='lower right', fontsize=8, ncol=2)
    fig.tight_layout()
    return save_figure(fig, out / 'exit_speeds.png')


def efficiency_data(rec: Recording, ev: _Evaluation) -> dict[str, np.ndarray] | None:
    """η, K_v and the sprocket torque at the recorded carriage positions, or None without a delivery.

    The stroke position ``u`` of each sample is the recorded carriage displacement
    ``x = u x_max + l (1 - cos α(u))`` inverted (x is increasing in u); samples with
    no carriage on the stroke (position and speed 0) are left out.

    Returns
    -------
    dict or None
        ``t`` (s), ``x`` (m), ``u``, ``eta`` (model at u), ``K_v_model``, ``K_v``
        (recorded carriage speed / chain speed; NaN-free: 0 where the chain stood),
        ``torque`` (recorded sprocket torque, N m; empty without efforts).
    """
    from folder_line.core.mechanisms import delivery as dlv

    plan = ev.plan
    ft = rec.joints.get('feed_transporter')
    if plan is None or ft is None or 'carriage' not in ft.names or ft.t.size == 0:
        return None
    x = ft.column('carriage')
    v = ft.column('carriage', 'velocity')
    v_chain = ft.column('chain', 'velocity')
    on = (x > 0.0) | (v > 0.0)
    u_grid = np.linspace(0.0, 2.0, 20001)
    st = dlv.evaluate_stroke(plan.params, u_grid, return_section='geometric')
    x_grid = u_grid * plan.chain.x_max + plan.rod * (1.0 - np.cos(st.alpha))
    u = np.interp(x[on], x_grid, u_grid)
    at = dlv.evaluate_stroke(plan.params, u, return_section='geometric')
    moving = v_chain[on] > 0.0
    kv = np.divide(v[on], v_chain[on], out=np.zeros(u.size), where=moving)
    torque = np.zeros(0)
    if ft.effort is not None and rec.scene.has('chain_friction'):
        torque = ft.column('chain', 'effort')[on]
    return {
        't': ft.t[on],
        'x': x[on],
        'u': u,
        'eta': at.eta,
        'K_v_model': at.K_v,
        'K_v': kv,
        'moving': moving,
        'torque': torque,
    }


def _plot_efficiency(rec: Recording, ev: _Evaluation, out: Path) -> Path | None:
    from folder_line.analysis.plots import pyplot, save_figure, stroke_curves

    data = efficiency_data(rec, ev)
    if data is None:
        return None
    plt = pyplot()
    plan = ev.plan
    with_torque = data['torque'].size > 0
    rows = 3 if with_torque else 2
    fig, axes = plt.subplots(rows, 1, figsize=(9, 3.1 * rows + 0.6), sharex=True)
    ax_eta, ax_kv = axes[0], axes[1]
    stroke_curves(ax_eta, ax_kv, plan.params, ('geometric',), pairs=True)
    k = _thin(data['u'].size)
    ax_eta.plot(
        data['u'][k],
        data['eta'][k],
        'o',
        ms=3,
        color='k',
        alpha=0.6,
        label=f'at the recorded carriage positions ({data["u"].size})',
    )
    m = data['moving'][k]
    ax_kv.plot(
        data['u'][k][m],
        data['K_v'][k][m],
        'o',
        ms=3,
        color='k',
        alpha=0.6,
        label='recorded carriage speed / chain speed',
    )
    for ax in axes:
        ax.axvline(plan.u_rel, color='tab:purple', ls='--', lw=1)
    ax_eta.text(plan.u_rel, ax_eta.get_ylim()[0], ' release', color='tab:purple', va='bottom', fontsize=8)
    ax_eta.set_ylabel('efficiency $\\eta$')
    ax_eta.set_title(
        f'D: efficiency along the stroke (paper Fig. 2), recorded over {rec.t_end:.3f} s; '
        f'min eta at the samples {data["eta"].min():.3f}'
        if data['eta'].size
        else 'D: efficiency along the stroke (paper Fig. 2)',
        fontsize=10,
    )
    ax_eta.legend(fontsize=8, loc='lower left')
    ax_kv.set_ylabel('carriage speed ratio $K_v$')
    ax_kv.legend(fontsize=8, loc='lower left')
    if with_torque:
        from folder_line.core.effects import chain_friction

        ax_t = axes[2]
        sch = plan.schedule
        theta = sch.theta_enter0 + np.linspace(0.0, sch.T, 4001, endpoint=False)
        a0, slack = sch.stroke_travel(theta)
        on = a0 <= sch.S + slack
        u_m = plan.path.position(np.clip(a0[on], 0.0, sch.S))
        tq = np.asarray(chain_friction.sprocket_torque(rec.scene, theta[on]), dtype=float)
        order = np.argsort(u_m)
        ax_t.plot(u_m[order], tq[order], color='C2', label='model: all carriages on the stroke')
        ax_t.plot(data['u'][k], data['torque'][k], 'o', ms=3, color='k', alpha=0.6, label='recorded (effort on chain)')
        ax_t.set_ylabel('sprocket torque $M_1$, N m')
        ax_t.legend(fontsize=8, loc='upper right')
        ax_t.grid(alpha=0.3)
    axes[-1].set_xlabel('stroke position u of the newest carriage (deceleration 0..1, acceleration 1..2)')
    fig.tight_layout()
    return save_figure(fig, out / 'efficiency.png')


#: the operations of the cyclogram (paper F): letter, label, colour
OPERATIONS = (
    ('А', 'feed: hand-over -> at the stops', 'tab:green'),
    ('Б', 'settle + dwell: at the stops -> settled -> knife contact', 'tab:blue'),
    ('В', 'knife: contact -> exit', 'tab:red'),
    ('Г', 'delivery: knife exit -> released on the pile', 'tab:purple'),
)


_MARGIN_FORMAT = {
    'feed_window': ('feed', 1e3, 'ms'),
    'settled_before_knife': ('settled', 1e3, 'ms'),
    'one_per_cycle': ('sheets', 1.0, ''),
    'rebound': ('rebound', 1e3, 'mm'),
    'release_at_min_speed': ('K_v at release', 1.0, ''),
}


def cycle_rows(rec: Recording, ev: _Evaluation, n: int = GANTT_CYCLES) -> list[dict[str, Any]]:
    """The first ``n`` judged folder cycles (and the first violated one with its neighbours): the
    operations' times and the margins.

    Returns
    -------
    list of dict
        Per cycle: ``cycle``, ``start`` (knife exit that opens the cycle's feed window,
        s), ``contact``, ``exit`` (its knife, s; ``exit`` None if not recorded),
        ``deadline`` (end of the allowed feed time, s), ``sheets`` (list of dicts
        ``sheet``, ``handover``, ``at_stops``, ``settled``, ``release``, None where
        absent) and ``margins`` (constraint -> margin of the cycle).
    """
    timing = ev.timing
    if timing is None:
        return []
    contact = rec.events_of('knife_contact')
    judged = np.unique(contact['cycle'])
    cycles = judged[:n]
    bad = [int(c.cycle[i]) for c in ev.constraints if c.name in FOLDER_CONSTRAINTS for i in np.flatnonzero(c.violated)]
    if bad and min(bad) not in cycles:  # show the first violated cycle too, between its neighbours
        around = np.arange(min(bad) - 1, min(bad) + 2)
        cycles = np.union1d(cycles, around[np.isin(around, judged)])
    if cycles.size == 0:
        return []
    drive = ev.drive
    th_start = cycles * timing.T + timing.knife.t_out
    # to the ns, as the recorded event times (a cycle starts at the knife exit of the cycle before)
    t_start = np.round(np.asarray(drive.time_of(th_start), dtype=float) * NS_PER_S) / NS_PER_S

    def first_time(rows: np.ndarray, key: str, value: int) -> float | None:
        hit = rows[rows[key] == value]
        return float(hit['t'][0]) if hit.size else None

    exits = rec.events_of('knife_exit')
    hand = rec.events_of('sheet_handover')
    stops = rec.events_of('at_stops')
    settled = rec.events_of('settled')
    release = rec.events_of('released_on_pile')
    bouncing = rec.scene.has('stop_bounce')
    margins = {c.name: dict(zip(c.cycle.tolist(), c.margin.tolist(), strict=True)) for c in ev.constraints}
    out = []
    for k, t0 in zip(cycles.tolist(), t_start.tolist(), strict=True):
        tc = first_time(contact, 'cycle', k)
        assert tc is not None
        th_dead = float(np.asarray(drive.theta(np.asarray(tc)))) - (timing.T - timing.t_knife - timing.t_allowed)
        sheets = []
        for s in hand[hand['cycle'] == k]:
            sid = int(s['sheet'])
            t_a = first_time(stops, 'sheet', sid)
            sheets.append(
                {
                    'sheet': sid,
                    'handover': float(s['t']),
                    'at_stops': t_a,
                    'settled': first_time(settled, 'sheet', sid) if bouncing else t_a,
                    'release': first_time(release, 'sheet', sid),
                }
            )
        out.append(
            {
                'cycle': k,
                'start': t0,
                'contact': tc,
                'exit': first_time(exits, 'cycle', k),
                'deadline': float(np.asarray(drive.time_of(np.asarray(th_dead)))),
                'sheets': sheets,
                'margins': {name: m[k] for name, m in margins.items() if k in m and name in FOLDER_CONSTRAINTS},
            }
        )
    return out


def _margin_text(margins: Mapping[str, float]) -> str:
    parts = []
    for name, m in margins.items():
        label, scale, unit = _MARGIN_FORMAT.get(name, (name, 1.0, ''))
        if name == 'one_per_cycle':
            parts.append('1 sheet' if m == 0.0 else f'{round(-m)} sheet(s) off')
        else:
            parts.append(f'{label} {m * scale:+.3g}{" " + unit if unit else ""}')
    return ' | '.join(parts)


def _plot_cyclogram(rec: Recording, ev: _Evaluation, out: Path, n: int) -> Path | None:
    from folder_line.analysis.plots import PHASE_COLOURS, pyplot, save_figure

    rows = cycle_rows(rec, ev, n)
    timing = ev.timing
    if timing is None:
        return None
    plt = pyplot()
    ms = 1e3
    fig, ax = plt.subplots(figsize=(12, 2.2 + 0.55 * (len(rows) + 1)))
    colours = {letter: colour for letter, _, colour in OPERATIONS}
    x_max = timing.T * ms
    # the nominal cycle of the paper's cyclogram, from the knife exit
    for ph in timing.timeline:
        a = (ph.t_start - timing.knife.t_out) % timing.T
        b = a + ph.duration
        for lo, hi in ((a, min(b, timing.T)), (0.0, b - timing.T)) if b > timing.T else ((a, b),):
            if hi > lo:
                ax.barh(-1, (hi - lo) * ms, left=lo * ms, height=0.5, color=PHASE_COLOURS[ph.name], alpha=0.35)
        ax.text((a + min(b, timing.T)) / 2 * ms, -1, ph.name, ha='center', va='center', fontsize=7)
    ax.axvline(timing.t_allowed * ms, color='k', ls=':', lw=1)
    for i, row in enumerate(rows):
        t0 = row['start']
        n_s = max(len(row['sheets']), 1)
        h = 0.6 / n_s
        for j, s in enumerate(row['sheets']):
            y = i - 0.3 + h * (j + 0.5)
            segs = [
                ('А', s['handover'], s['at_stops'], None),
                ('Б', s['at_stops'], s['settled'], '////'),
                (
                    'Б',
                    s['settled'],
                    row['contact'] if s['settled'] is not None and s['settled'] <= row['contact'] else None,
                    None,
                ),
            ]
            if s['release'] is not None and row['exit'] is not None:
                segs.append(('Г', row['exit'], s['release'], None))
            for letter, a, b, hatch in segs:
                if a is None or b is None or b < a:
                    continue
                ax.barh(
                    y,
                    (b - a) * ms,
                    left=(a - t0) * ms,
                    height=h * 0.9,
                    color=colours[letter],
                    alpha=0.45 if hatch else 0.8,
                    hatch=hatch,
                    edgecolor='white' if hatch else None,
                )
                x_max = max(x_max, (b - t0) * ms)
        if not row['sheets']:
            ax.text(1.0, i, 'no signature (missing)', va='center', fontsize=8, color='r')
        if row['exit'] is not None:
            ax.barh(
                i,
                (row['exit'] - row['contact']) * ms,
                left=(row['contact'] - t0) * ms,
                height=0.6,
                color=colours['В'],
                alpha=0.8,
            )
            x_max = max(x_max, (row['exit'] - t0) * ms)
        ax.plot([(row['deadline'] - t0) * ms] * 2, [i - 0.38, i + 0.38], color='k', lw=2)
        x_max = max(x_max, (row['deadline'] - t0) * ms)
    text_x = x_max * 1.03
    for i, row in enumerate(rows):
        bad = any(m < 0.0 for m in row['margins'].values())
        ax.text(text_x, i, _margin_text(row['margins']), va='center', fontsize=7.5, color='r' if bad else 'k')
    ax.text(text_x, -1, 'margins of the cycle', va='center', fontsize=8, style='italic')
    ax.set_yticks([-1] + list(range(len(rows))), ['nominal'] + [f'cycle {r["cycle"]}' for r in rows])
    for i, (label, row) in enumerate(zip(ax.get_yticklabels()[1:], rows, strict=True)):
        if any(m < 0.0 for m in row['margins'].values()):
            label.set_color('r')
        if i and row['cycle'] != rows[i - 1]['cycle'] + 1:  # cycles left out
            ax.axhline(i - 0.5, color='grey', ls='--', lw=0.8)
    ax.invert_yaxis()
    ax.set_xlim(0, x_max * 1.9)
    from matplotlib.ticker import MaxNLocator

    ticks = MaxNLocator(nbins=8).tick_values(0.0, x_max)
    ax.set_xticks(ticks[(ticks >= 0.0) & (ticks <= x_max)])
    ax.axvline(x_max * 1.015, color='grey', lw=0.5)
    ax.set_xlabel('time from the start of the cycle (the knife exit of the cycle before), ms')
    handles = [plt.Rectangle((0, 0), 1, 1, color=c, alpha=0.8) for _, _, c in OPERATIONS]
    labels = [f'{letter}: {label}' for letter, label, _ in OPERATIONS]
    handles.append(plt.Line2D([0], [0], color='k', lw=2))
    labels.append('feed deadline of the cycle (window start + t_allowed)')
    fig.legend(handles, labels, loc='lower center', ncol=2, fontsize=8, frameon=False)
    shown = (
        f'the first {len(rows)}'
        if [r['cycle'] for r in rows] == list(range(len(rows)))
        else f'the first {n} and the first violated'
    )
    ax.set_title(
        f'F: cyclogram of {shown} of {ev.cycles} cycles (paper F figs. 1-2), '
        f'T = {timing.T * ms:.1f} ms; hatched: bouncing at the stops',
        fontsize=10,
    )
    ax.grid(axis='x', alpha=0.3)
    fig.tight_layout(rect=(0.0, 0.85 / fig.get_figheight(), 1.0, 1.0))
    return save_figure(fig, out / 'cyclogram.png')


_DISPLAY_UNITS = {'s': (1e3, 'ms'), 'm': (1e3, 'mm')}


def _margin_bins(m: np.ndarray, unit: str, bins: int = 30) -> np.ndarray:
    """Histogram edges for margins ``m``: whole numbers for ``sheets``; one bin about the value where
    the margins are equal to rounding (relative spread <= 1e-6)."""
    lo, hi = float(m.min()), float(m.max())
    if unit == 'sheets':
        return np.arange(math.floor(lo) - 0.5, math.ceil(hi) + 1.0)
    if hi - lo <= 1e-6 * max(abs(lo), abs(hi)):
        mid = 0.5 * (lo + hi)
        half = max(abs(mid) * 0.02, 1e-12)
        return np.array([mid - half, mid + half])
    return np.linspace(lo, hi, bins + 1)


def _plot_margins(ev: _Evaluation, out: Path) -> Path:
    from folder_line.analysis.plots import pyplot, save_figure

    plt = pyplot()
    series = [c for c in ev.constraints]
    n = max(len(series), 1)
    cols = 2 if n > 1 else 1
    nrows = math.ceil(n / cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(5.2 * cols, 3.0 * nrows + 0.4), squeeze=False)
    for ax in axes.ravel()[len(series) :]:
        ax.axis('off')
    if not series:
        axes[0, 0].text(0.5, 0.5, 'no constraint evaluated in this scene', ha='center', va='center')
    for ax, c in zip(axes.ravel(), series, strict=False):
        scale, unit = _DISPLAY_UNITS.get(c.unit, (1.0, c.unit))
        m = c.margin * scale
        nv = int(np.count_nonzero(c.violated))
        ax.set_title(
            f'{c.name}: {c.margin.size} evaluations, {nv} violated', fontsize=9, color='tab:red' if nv else 'k'
        )
        ax.set_xlabel(f'margin, {unit}' if unit not in ('', '1') else 'margin (dimensionless)')
        ax.set_ylabel('count')
        if m.size == 0:
            ax.text(0.5, 0.5, 'no evaluation', ha='center', va='center', transform=ax.transAxes)
            continue
        edges = _margin_bins(m, c.unit)
        ax.hist(
            [m[m >= 0.0], m[m < 0.0]],
            bins=edges,
            stacked=True,
            color=['C0', 'tab:red'],
            label=['passed', f'violated ({nv})' if nv else '_nolegend_'],
        )
        if edges[0] <= 0.0 <= edges[-1]:
            ax.axvline(0.0, color='k', lw=1)
        ax.axvline(float(m.min()), color='tab:orange', ls='--', lw=1, label=f'min {m.min():.4g}')
        ax.legend(fontsize=7)
        ax.ticklabel_format(axis='x', style='sci', scilimits=(-3, 4), useOffset=False)
        if edges.size == 2:  # equal margins (to rounding): one bar
            width = edges[1] - edges[0]
            ax.set_xlim(edges[0] - width, edges[1] + width)
    fig.tight_layout()
    return save_figure(fig, out / 'margins.png')


def landing_data(rec: Recording) -> dict[str, Any] | None:
    """The leaves' landing positions, or None without ``leaf_flight``.

    Returns
    -------
    dict or None
        ``x`` (landed, m), ``spilled`` (m), ``edges``, ``counts`` and ``cv`` of the
        histogram across the container (:func:`folder_line.core.effects.leaf_flight.histogram`,
        the simulator's), ``x_left``, ``x_right`` (walls, m).
    """
    scene = rec.scene
    if not scene.has('leaf_flight') or 'container' not in scene.machines:
        return None
    from folder_line.core.effects import effect_module

    cont = scene.machine('container')
    x = rec.events_of('leaf_landed')['value']
    hist = effect_module('leaf_flight').histogram(x, cont.x_left, cont.x_right, cont.bins)
    return {
        'x': x,
        'spilled': rec.events_of('leaf_spilled')['value'],
        'edges': np.asarray(hist.edges),
        'counts': np.asarray(hist.counts),
        'cv': hist.cv,
        'x_left': float(cont.x_left),
        'x_right': float(cont.x_right),
    }


def _plot_landing(rec: Recording, out: Path) -> Path | None:
    from folder_line.analysis.plots import pyplot, save_figure

    data = landing_data(rec)
    if data is None:
        return None
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(9, 4.5))
    edges, counts = data['edges'], data['counts']
    ax.bar(
        edges[:-1],
        counts,
        width=np.diff(edges),
        align='edge',
        color='C0',
        edgecolor='white',
        label=f'landed ({int(counts.sum())})',
    )
    if data['spilled'].size:
        ax.plot(
            data['spilled'],
            np.zeros(data['spilled'].size),
            'x',
            color='tab:red',
            ms=8,
            mew=2,
            label=f'spilled over a wall ({data["spilled"].size})',
        )
    ax.plot(
        data['x'],
        np.full(data['x'].size, -0.04 * max(counts.max(initial=1), 1)),
        '|',
        color='k',
        ms=10,
        label='landing x of each leaf',
    )
    for wall in (data['x_left'], data['x_right']):
        ax.axvline(wall, color='k', lw=3)
    width = data['x_right'] - data['x_left']
    ax.set_xlim(data['x_left'] - 0.1 * width, data['x_right'] + 0.1 * width)
    cv = 'n/a' if data['cv'] is None else f'{data["cv"]:.3f}'
    ax.set_title(
        f'L: leaf landing across the container ({len(counts)} bins, CV of the counts {cv}) over {rec.t_end:.3f} s',
        fontsize=10,
    )
    ax.set_xlabel('x on the container floor, m (thick lines: the walls)')
    ax.set_ylabel('leaves per bin')
    from matplotlib.ticker import MaxNLocator

    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax.legend(fontsize=8, loc='upper right')
    fig.tight_layout()
    return save_figure(fig, out / 'landing.png')


# --------------------------------------------------------------------------- report


@dataclass(frozen=True, eq=False)
class AnalysisResult:
    """What :func:`analyze` wrote and computed.

    Attributes
    ----------
    out : Path
        The output directory.
    report : Path
        ``report.md``.
    figures : dict of str to Path
        Figure file name -> path, for the figures the scene has.
    csv : dict of str to Path
        Topic -> its CSV (empty without ``csv=True``).
    summary : dict
        The numbers of the report: ``scene``, ``t_end``, ``cycles``,
        ``sheets_counted``, ``sheet_counter``, ``min_margin`` (per constraint:
        ``margin``, ``unit``, ``cycle``, ``evaluations``, ``violations``),
        ``violations`` (count and every one), ``events`` (count per kind),
        ``transitions``, ``transitions_source``, ``replay_matches``, ``messages``, ``lost``.
    recording : Recording
    constraints : list of ConstraintSeries
        The constraints judged on the recorded events.
    """

    out: Path
    report: Path
    figures: dict[str, Path]
    csv: dict[str, Path]
    summary: dict[str, Any]
    recording: Recording
    constraints: list[ConstraintSeries] = field(default_factory=list)


def _fmt(x: float) -> str:
    return f'{x:.6g}'


def _report_lines(
    rec: Recording, ev: _Evaluation, summary: dict[str, Any], figures: Mapping[str, Path], csv_files: Mapping[str, Path]
) -> list[str]:
    scene = rec.scene
    bag = rec.bag
    lines = [
        f'# Analysis of the run: scene `{scene.name}`',
        '',
        f'- bag: `{bag.path}` ({len(bag.files)} files, {bag.message_count} messages)',
        f'- effects: {", ".join(scene.effects) or "none"}; seed {scene.seed}',
        f'- line time reached: {rec.t_end:.9g} s; drive commands recorded: '
        + (', '.join(f'{c.kind} at {c.t:.9g} s' for c in rec.commands) or 'none'),
        (
            "- numbers: the recorded events judged by the line's constraint code "
            '(`folder_line.core.line.constraints`), as `simulate(scene, line time reached)` judges its own'
        ),
        '',
        '## Summary',
        '',
        '| quantity | value |',
        '|---|---|',
        f'| cycles | {summary["cycles"]} |',
        f'| sheets counted | {summary["sheets_counted"]} |',
        (
            f'| sheets counted by sheet_counter (last /line/sheet_counter/count) | '
            f'{"-" if rec.sheet_count is None else rec.sheet_count} |'
        ),
        f'| events | {int(rec.events.size)} |',
        f'| violations | {summary["violations"]["count"]} |',
    ]
    if rec.bad_events:
        lines.append(f'| /line/events messages that are not events | {rec.bad_events} |')
    lines += ['', '## Events', '', '| kind | count |', '|---|---|']
    lines += [f'| {k} | {n} |' for k, n in summary['events'].items()]
    lines += [
        '',
        '## Constraints',
        '',
        '| constraint | unit | evaluations | min margin | at cycle | violations |',
        '|---|---|---|---|---|---|',
    ]
    for name, m in summary['min_margin'].items():
        lines.append(
            f'| {name} | {m["unit"]} | {m["evaluations"]} | {_fmt(m["margin"])} | {m["cycle"]} | {m["violations"]} |'
        )
    if not summary['min_margin']:
        lines.append('| (none evaluated) | | | | | |')
    lines += ['', '## Violations', '']
    viol = summary['violations']['first']
    if viol:
        decided = {c.name: dict(zip(c.cycle.tolist(), c.t.tolist(), strict=True)) for c in ev.constraints}
        lines += ['| cycle | constraint | margin | unit | decided at t, s |', '|---|---|---|---|---|']
        lines += [
            f'| {v["cycle"]} | {v["constraint"]} | {_fmt(v["margin"])} | {v["unit"]} | '
            f'{decided.get(v["constraint"], {}).get(v["cycle"], float("nan")):.9g} |'
            for v in viol
        ]
    else:
        lines.append('No constraint was violated.')
    lines += ['', '## State transitions', '', f'Source: {summary["transitions_source"]}.', '']
    recorded = summary.get('recorded_transitions', [])
    shown = {}
    for tr in recorded:
        shown.setdefault(tr['to'], tr['t'])
    if summary['transitions']:
        lines += ['| t, s | from | to | cause | first recorded on /line/supervisor/state, s |', '|---|---|---|---|---|']
        lines += [
            f'| {tr["t"]:.9g} | {tr["from"] or "(first state)"} | {tr["to"]} | {tr.get("cause", "")} | '
            f'{shown[tr["to"]]:.9g} |'
            if tr['to'] in shown
            else f'| {tr["t"]:.9g} | {tr["from"] or "(first state)"} | {tr["to"]} | {tr.get("cause", "")} | - |'
            for tr in summary['transitions']
        ]
    else:
        lines.append('No state transition.')
    lines += [
        '',
        'Recorded states: ' + (' -> '.join(f'{tr["to"]} ({tr["t"]:.3f} s)' for tr in recorded) or 'none') + '.',
    ]
    decided = summary.get('replay_violations')
    if decided:
        lines += [
            '',
            '### Violations as the supervisor decided them (replay, causal)',
            '',
            '| t, s | cycle | constraint | margin | unit | action | state |',
            '|---|---|---|---|---|---|---|',
        ]
        lines += [
            f'| {v["t"]:.9g} | {v["cycle"]} | {v["constraint"]} | {_fmt(v["margin"])} | {v["unit"]} | '
            f'{v["action"]} | {v["state"]} |'
            for v in decided
        ]
    lines += ['', '## Messages', '']
    published = rec.bag.published
    lost = summary.get('lost')
    lines += ['| topic | type | recorded | published | lost |', '|---|---|---|---|---|']
    for topic, info in rec.bag.topics.items():
        pub = '-' if published is None else published.get(topic, '-')
        ls = '-' if lost is None else lost.get(topic, '-')
        lines.append(f'| {topic} | {info.type} | {info.count} | {pub} | {ls} |')
    if rec.run is not None and rec.run.get('loss_accounting'):
        lines += ['', f'Loss accounting (run.json): {rec.run["loss_accounting"]}.']
    elif rec.run is None:
        lines += ['', 'No run.json: lost messages unknown.']
    if csv_files:
        lines += [
            '',
            '## CSV',
            '',
            f'One file per topic in `csv/` ({len(csv_files)} files): '
            + ', '.join(f'`{p.name}`' for p in csv_files.values())
            + '.',
        ]
    lines += ['', '## Figures', '']
    for name, path in figures.items():
        lines += [f'**{name}**: {FIGURES[name]}.', '', f'![{path.stem}]({path.name})', '']
    missing = [n for n in FIGURES if n not in figures]
    if missing:
        lines.append('Not drawn (the scene has no such part): ' + ', '.join(missing) + '.')
    return lines


def analyze(
    path: str | os.PathLike[str],
    out: str | os.PathLike[str] | None = None,
    csv: bool = False,
    *,
    gantt_cycles: int = GANTT_CYCLES,
) -> AnalysisResult:
    """Analyse a recorded run: figures, ``report.md`` and, with ``csv``, one CSV per topic.

    Parameters
    ----------
    path : path-like
        A run directory (``run.json``, ``bag/``) or a bag directory.
    out : path-like, optional
        Output directory; default ``<run directory>/analysis`` (the bag's parent
        directory when a bag is given).
    csv : bool
        Also write ``csv/<topic>.csv`` for every topic of the bag.
    gantt_cycles : int
        Cycles in the cyclogram (>= 1).

    Returns
    -------
    AnalysisResult

    Raises
    ------
    ParameterError, BagError
        A bad path, a bag that cannot be read or holds no valid scene.
    """
    if not (isinstance(gantt_cycles, int) and gantt_cycles >= 1):
        raise ParameterError('gantt_cycles', gantt_cycles, 'must be a whole number >= 1')
    collector = _CsvCollector() if csv else None
    rec = read_recording(path, collector)
    out_dir = Path(rec.bag.path).parent / 'analysis' if out is None else Path(out)
    with claim_output_dir(out_dir, '--out', files=('report.md', *FIGURES), dirs=('csv',) if csv else ()):
        return _write_analysis(rec, out_dir, collector, gantt_cycles)


def _write_analysis(
    rec: Recording, out_dir: Path, collector: _CsvCollector | None, gantt_cycles: int
) -> AnalysisResult:
    """The evaluation, plots, CSVs and report of :func:`analyze`, into the claimed ``out_dir``."""
    if collector is not None:  # every CSV target is checked before anything is written
        for topic in rec.bag.topics:
            check_output_file(out_dir / 'csv' / csv_name(topic), '--out')
    ev = _evaluate(rec)

    summary = dict(ev.summary)
    summary['t_end'] = rec.t_end
    summary['sheet_counter'] = rec.sheet_count
    summary['messages'] = {t: s.count for t, s in rec.bag.topics.items()}
    summary['lost'] = None if rec.run is None else rec.run.get('lost')
    recorded = recorded_transitions(rec.states)
    summary['recorded_transitions'] = recorded
    try:
        replayed, sup = replay_transitions(rec)
    except (FolderLineError, ValueError, TypeError) as exc:  # a stream the logic rejects: say so, keep the record
        replayed, sup = None, None
        why = f'{type(exc).__name__}: {exc}'
    if replayed is None:
        summary['transitions'] = recorded
        summary['replay_matches'] = None
        summary['transitions_source'] = (
            'the states published on /line/supervisor/state (the replay through '
            f'folder_line.core.supervision.decisions.replay failed: {why})'
        )
    else:
        summary['transitions'] = replayed
        summary['replay_matches'] = transitions_agree(replayed, recorded)
        summary['replay_violations'] = [dataclasses.asdict(v) for v in sup.violations]
        summary['transitions_source'] = (
            'the recorded events, NaN/inf values, lost participants and operator commands replayed in lockstep '
            'through '
            'folder_line.core.supervision.decisions.replay (decision times); '
            + (
                'they agree with the states recorded on /line/supervisor/state'
                if summary['replay_matches']
                else 'they do NOT agree with the states recorded on /line/supervisor/state: '
                + ' -> '.join(t['to'] for t in recorded)
            )
        )

    figures: dict[str, Path] = {}
    for name, draw in (
        ('exit_speeds.png', lambda: _plot_exit_speeds(rec, ev, out_dir)),
        ('efficiency.png', lambda: _plot_efficiency(rec, ev, out_dir)),
        ('cyclogram.png', lambda: _plot_cyclogram(rec, ev, out_dir, gantt_cycles)),
        ('margins.png', lambda: _plot_margins(ev, out_dir)),
        ('landing.png', lambda: _plot_landing(rec, out_dir)),
    ):
        written = draw()
        if written is not None:
            figures[name] = written
    csv_files = collector.write(out_dir / 'csv', list(rec.bag.topics)) if collector is not None else {}
    report = write_text_atomic(
        out_dir / 'report.md', '\n'.join(_report_lines(rec, ev, summary, figures, csv_files)) + '\n'
    )
    return AnalysisResult(
        out=out_dir,
        report=report,
        figures=figures,
        csv=csv_files,
        summary=summary,
        recording=rec,
        constraints=ev.constraints,
    )


def print_analysis(result: AnalysisResult, stream: Any) -> None:
    """What ``folder-line analyze`` prints: the headline numbers and the files written."""
    s = result.summary
    print(
        f'scene {s["scene"]}: {s["t_end"]:.3f} s of line time, {s["cycles"]} cycles, '
        f'{s["sheets_counted"]} sheets counted, {s["violations"]["count"]} violations',
        file=stream,
    )
    for name, m in s['min_margin'].items():
        print(
            f'  {name:<24} min margin {m["margin"]:.6g} {m["unit"]} (cycle {m["cycle"]}), '
            f'{m["violations"]} of {m["evaluations"]} violated',
            file=stream,
        )
    if s['transitions']:
        print('states: ' + ' -> '.join(t['to'] for t in s['transitions']), file=stream)
    print(f'wrote {result.report}', file=stream)
    for path in result.figures.values():
        print(f'wrote {path}', file=stream)
    if result.csv:
        print(f'wrote {len(result.csv)} CSV files to {result.out / "csv"}', file=stream)
