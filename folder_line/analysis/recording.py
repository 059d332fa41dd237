"""Reading a recorded run: a run directory or a bag decoded into a :class:`Recording`.

:func:`read_recording` opens the bag (:func:`folder_line.bag.reader.read_bag`; ``RUN_DIR`` is
what ``folder-line run --out RUN_DIR`` wrote: ``run.json`` and ``bag/``), parses the
scene stored in it and decodes, in one pass over the messages, what the analysis
needs: the events of ``/line/events`` (``time_ref``: the event time to the ns;
``source``: :func:`folder_line.interfaces.parse_event_source`), every machine node's
joint states (a bounded sample, :class:`RecordedJoints`), the supervisor's state
changes, drive commands and ``/diagnostics`` statuses, the sheet counter's count and
landing positions, and the latest ``/clock``. No ROS is needed: the bag is read with
rosbags.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from folder_line.analysis.gap_cycles import Unjudged, unjudged, without_unjudged
from folder_line.analysis.streaming import stamp_priority
from folder_line.bag.gaps import Gap
from folder_line.bag.reader import BagContents, read_bag
from folder_line.config.run_config import BAG_DIR
from folder_line.core.line.scene import Scene, parse_scene
from folder_line.core.line.tuning import LineCommand, command_of
from folder_line.core.types.events import EVENT_DTYPE, event_kind
from folder_line.errors import InputFileError
from folder_line.files.atomic import describe_path
from folder_line.files.json_types import JsonObject
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
    stamp_ns,
)

if TYPE_CHECKING:  # the message classes of the typestore the bags are read with (folder_line.bag.types)
    from rosbags.typesys.stores.ros2_kilted import (
        diagnostic_msgs__msg__DiagnosticArray as DiagnosticArray,
    )
    from rosbags.typesys.stores.ros2_kilted import (
        sensor_msgs__msg__JointState as JointState,
    )
    from rosbags.typesys.stores.ros2_kilted import (
        sensor_msgs__msg__TimeReference as TimeReference,
    )

__all__ = ['JOINT_SAMPLES', 'SUPERVISOR_STATUS_PREFIX', 'RecordedJoints', 'Recording', 'read_recording']

_NONE = np.zeros(0, dtype=np.int64)  # no cycle, no leaf

#: joint-state samples kept per node at most (:class:`RecordedJoints`); the figures draw them
JOINT_SAMPLES = 5000
#: rows of a block of messages (joint states, events, clock) handled at once
_CHUNK = 4096
_QUANTITIES = ('position', 'velocity', 'effort')
#: the statuses the supervisor publishes on /diagnostics for its decisions
SUPERVISOR_STATUS_PREFIX = 'folder_line/supervisor/'


@dataclass(frozen=True, eq=False)
class RecordedJoints:
    """The joint states one node published: all of them counted, a bounded sample of them kept.

    An hour of a 200 Hz node is 720 000 messages; the figures draw a few thousand. So
    :func:`read_recording` keeps a pseudo-random ``fraction`` (1, 1/2, 1/4, ...) of the
    ticks, chosen by a hash of the stamp: the largest that keeps at most
    ``joint_samples`` per node. Every node keeps the same ticks, and the choice has no
    pattern in time, so a sample does not alias with the machines' periods. The count
    and each column's extremes are those of every message.

    Attributes
    ----------
    node : str
        ``crank_drive``, ``belt_conveyor``, ``feed_transporter`` or ``sheet_counter``.
    names : tuple of str
        Joint names (the columns).
    t : ndarray, shape (N,)
        ``header.stamp`` of each kept message (the node's tick), s, sorted.
    position, velocity : ndarray, shape (N, J)
    effort : ndarray, shape (N, J), or None
        None where the node published no efforts.
    count : int
        Messages recorded (with the node's joints), kept or not.
    fraction : float
        The fraction of the ticks kept (1: every message).
    low, high : ndarray, shape (3, J)
        Smallest and largest position, velocity and effort of every message (NaN left
        out; ``inf``/``-inf`` where there is no finite value).
    """

    node: str
    names: tuple[str, ...]
    t: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    effort: np.ndarray | None
    count: int = 0
    fraction: float = 1.0
    low: np.ndarray = field(default_factory=lambda: np.zeros((3, 0)))
    high: np.ndarray = field(default_factory=lambda: np.zeros((3, 0)))

    def extent(self, joint: str, quantity: str = 'position') -> tuple[float, float]:
        """(smallest, largest) ``position``, ``velocity`` or ``effort`` of one joint over every message."""
        self.column(joint, quantity)  # KeyError as column's
        row, col = _QUANTITIES.index(quantity), self.names.index(joint)
        return float(self.low[row, col]), float(self.high[row, col])

    def column(self, joint: str, quantity: str = 'position') -> np.ndarray:
        """One joint's ``position``, ``velocity`` or ``effort`` over the recording (KeyError if absent)."""
        if joint not in self.names:
            msg = f'{self.node} has no joint {joint!r}; joints: {", ".join(self.names)}'
            raise KeyError(msg)
        data = getattr(self, quantity)
        if data is None:
            msg = f'{self.node} published no {quantity}'
            raise KeyError(msg)
        column: np.ndarray = data[:, self.names.index(joint)]  # ``data`` comes from getattr: Any
        return column


@dataclass(frozen=True, eq=False)
class Recording:
    """What :func:`read_recording` decoded from a bag.

    Attributes
    ----------
    bag : BagContents
        The bag (:func:`folder_line.bag.reader.read_bag`).
    run : dict or None
        ``run.json`` of the run directory, if there is one.
    scene : Scene
        The scene stored in the bag.
    t_end : float
        Line time reached: the last ``/clock`` (the bag's end if it has none), s.
    duration : float
        The run's duration, s: ``run.json``'s ``duration_s`` (what ``folder-line run`` was
        asked for), else ``t_end``; at least ``t_end``. The line under the recorded
        commands is known up to there (an animation's axes may look that far).
    events : ndarray of EVENT_DTYPE
        The events of ``/line/events``, ``t`` = ``time_ref`` in s, sorted as
        :func:`folder_line.core.types.events.merge_events` sorts (time, kind, sheet).
    event_ns : ndarray of int64
        The same events' ``time_ref`` in ns (exact).
    joints : dict of str to RecordedJoints
        Node -> its joint states (counted, their extremes, a bounded sample; from
        ``read_recording``'s ``t_from`` on).
    states : list of (int, str)
        ``(log time ns, state)`` of the first ``/line/supervisor/state`` message and of
        every one whose state differs from the message before (the state is published
        every tick; its changes are what the analysis uses).
    commands : tuple of Command or Tuning
        The drive commands and tunings of ``/line/supervisor/commands`` (effective time, kind),
        sorted by time, duplicates dropped -- what the nodes applied.
    sheet_count : int or None
        The last ``/line/sheet_counter/count``.
    landing_x : ndarray
        ``/line/sheet_counter/landing_x`` values, m.
    bad_events : int
        ``/line/events`` messages whose ``source`` is not an event.
    diagnostics_ns : ndarray of int64
        ``header.stamp`` of every ``/diagnostics`` message, ns.
    supervisor_status : list of (int, str, dict)
        ``(stamp ns, name, values)`` of every ``folder_line/supervisor/...`` status of
        ``/diagnostics`` (violations, balances, operator commands).
    bad_values : list of (float, str, int)
        ``(stamp s, topic, count)`` of joint states carrying NaN or inf.
    gaps : tuple of Gap
        Line time whose messages a repair found lost (:mod:`folder_line.bag.gaps`).
    unjudged : Unjudged
        The folder cycles and leaves a gap may have taken events from: their events are left
        out of ``events`` (:mod:`folder_line.analysis.gap_cycles`).
    """

    bag: BagContents
    run: JsonObject | None
    scene: Scene
    t_end: float
    duration: float
    events: np.ndarray
    event_ns: np.ndarray
    joints: dict[str, RecordedJoints]
    states: list[tuple[int, str]]
    commands: tuple[LineCommand, ...]
    sheet_count: int | None
    landing_x: np.ndarray
    bad_events: int
    diagnostics_ns: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    supervisor_status: list[tuple[int, str, dict[str, str]]] = field(default_factory=list)
    bad_values: list[tuple[float, str, int]] = field(default_factory=list)
    gaps: tuple[Gap, ...] = ()
    unjudged: Unjudged = field(default_factory=lambda: Unjudged(_NONE, _NONE))

    def events_of(self, kind: str) -> np.ndarray:
        """Rows of one event kind."""
        rows: np.ndarray = self.events[self.events['kind'] == event_kind(kind)]  # a field is typed Any
        return rows


def _run_duration(run: JsonObject | None, t_end: float) -> float:
    """The run's duration (``run.json``'s ``duration_s``, else the line time reached), at least ``t_end``, s."""
    duration = t_end
    value = None if run is None else run.get('duration_s')
    if isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value) and value > 0:
        duration = float(value)
    return max(duration, t_end)


def _resolve(path: str | os.PathLike[str]) -> tuple[Path, JsonObject | None]:
    """(bag directory, run.json or None) of a run directory or a bag directory."""
    bag_dir = BAG_DIR
    p = Path(path)
    if not p.is_dir():
        what = (
            'no such directory'
            if not os.path.lexists(p)
            else f'{describe_path(p)}, not a run directory or a bag directory'
        )
        raise InputFileError('RUN_DIR|BAG', str(path), what)
    run_dir: Path | None
    if (p / bag_dir).is_dir():
        bag, run_dir = p / bag_dir, p
    elif os.path.lexists(p / 'metadata.yaml') or any(p.glob('*.mcap')):  # read_bag says what is wrong with it
        bag = p
        run_dir = p.parent if p.name == bag_dir else None
    else:
        raise InputFileError(
            'RUN_DIR|BAG', str(path), f'neither a run directory (with {bag_dir}/) nor a bag (with metadata.yaml)'
        )
    run = None
    if run_dir is not None and (run_dir / 'run.json').is_file():
        text = read_text_bounded(run_dir / 'run.json', 'RUN_DIR|BAG', METADATA_LIMIT)
        try:
            run = json.loads(text)
        except ValueError as exc:
            raise InputFileError('RUN_DIR|BAG', str(path), f'run.json cannot be read: {exc}') from None
    return bag, run


class _Grow:
    """A numpy array appended to row by row, in chunks of :data:`_CHUNK` rows joined once at the
    end: memory is the data's, with no Python object per message and no copy while growing (an
    hour of a 200 Hz topic is 720 000 rows)."""

    def __init__(self, dtype: npt.DTypeLike) -> None:
        self.dtype = dtype
        self.chunks: list[np.ndarray] = []
        self.chunk = np.zeros(_CHUNK, dtype=dtype)
        self.i = 0

    def add(self, row: npt.ArrayLike) -> None:
        if self.i == _CHUNK:
            self.chunks.append(self.chunk)
            self.chunk = np.zeros(_CHUNK, dtype=self.dtype)
            self.i = 0
        self.chunk[self.i] = row
        self.i += 1

    def done(self) -> np.ndarray:
        out: np.ndarray = np.concatenate([*self.chunks, self.chunk[: self.i]])
        return out


class _Sampler:
    """The sampling of every node's joint states, shared so that the nodes keep the same ticks.

    A sample is kept if the :func:`~folder_line.analysis.streaming.stamp_priority` of its stamp
    is below ``2**64 / 2**level``: a pseudo-random ``1 / 2**level`` of the ticks, the same for every node, with no
    aliasing against the machines' periods (which a sample every k ticks has). ``level``
    is 0 (every sample kept) until a node keeps more than ``cap``, then raised until
    every node keeps at most half of ``cap``. The kept sets nest, so sampling what was
    kept equals sampling every message.
    """

    def __init__(self, cap: int) -> None:
        self.cap = cap
        self.level = 0
        self.nodes: list[_Joints] = []

    def keep(self, priority: np.ndarray) -> np.ndarray:
        """Which of these priorities the current level keeps."""
        if self.level == 0:
            return np.ones(priority.shape, dtype=bool)
        out: np.ndarray = (priority >> np.uint64(64 - self.level)) == 0
        return out

    def raise_level(self) -> None:
        """Halve the fraction kept, on every node, until each keeps at most half of ``cap``."""
        while True:
            self.level += 1
            for node in self.nodes:
                node.sample()
            if all(node.n <= self.cap // 2 for node in self.nodes) or self.level == 63:
                return

    def finish(self, nodes: Mapping[str, _Joints]) -> dict[str, RecordedJoints]:
        """Every node's joint states at the final level (each node's last block flushed first)."""
        for node in nodes.values():
            node.flush()
        return {name: node.done() for name, node in nodes.items()}


class _Joints:
    """One node's joint states: every sample counted with its extremes, a bounded sampling of them kept.

    Messages are gathered in a block of :data:`_CHUNK` rows; a full block is counted,
    its extremes taken and its samples sampled into the kept rows in a few numpy calls.
    """

    def __init__(self, node: str, names: Sequence[str], sampler: _Sampler) -> None:
        self.node, self.names, self.sampler = node, tuple(names), sampler
        j = len(self.names)
        self.block_t = np.zeros(_CHUNK, dtype=np.int64)
        self.block = np.zeros((_CHUNK, 3, j))  # position, velocity, effort
        self.i = 0
        self.t = np.zeros(sampler.cap + _CHUNK, dtype=np.int64)
        self.priority = np.zeros(sampler.cap + _CHUNK, dtype=np.uint64)
        self.data = np.zeros((sampler.cap + _CHUNK, 3, j))
        self.n = 0
        self.count = 0
        self.low = np.full((3, j), np.inf)
        self.high = np.full((3, j), -np.inf)
        self.has_eff = True
        sampler.nodes.append(self)

    def add(
        self, msg: JointState, stamp_ns: int, position: np.ndarray, velocity: np.ndarray, effort: np.ndarray
    ) -> None:
        """Append ``msg`` (stamped ``stamp_ns``, its three arrays already as float arrays) to the block."""
        j = len(self.names)
        if position.size != j or velocity.size != j or tuple(msg.name) != self.names:
            return  # a model rebuilt with other joints: keep the first layout
        if self.i == _CHUNK:
            self.flush()
        row = self.block[self.i]
        row[0], row[1] = position, velocity
        if effort.size == j:
            row[2] = effort
        else:
            self.has_eff = False
            row[2] = 0.0
        self.block_t[self.i] = stamp_ns
        self.i += 1

    def flush(self) -> None:
        """Count the block, take its extremes and sample it into the kept rows."""
        if self.i == 0:
            return
        t, rows = self.block_t[: self.i], self.block[: self.i]
        self.count += self.i
        if self.names:  # NaN (counted in bad_values) does not hide the extremes
            np.fmin(self.low, np.fmin.reduce(rows, axis=0), out=self.low)
            np.fmax(self.high, np.fmax.reduce(rows, axis=0), out=self.high)
        priority = stamp_priority(t)
        keep = self.sampler.keep(priority)
        end = self.n + int(np.count_nonzero(keep))
        self.t[self.n : end], self.priority[self.n : end], self.data[self.n : end] = t[keep], priority[keep], rows[keep]
        self.n, self.i = end, 0
        if self.n > self.sampler.cap:
            self.sampler.raise_level()

    def sample(self) -> None:
        """Keep what the sampler's current level keeps of the kept rows."""
        keep = np.flatnonzero(self.sampler.keep(self.priority[: self.n]))
        self.n = keep.size
        self.t[: self.n], self.priority[: self.n], self.data[: self.n] = (
            self.t[keep],
            self.priority[keep],
            self.data[keep],
        )

    def done(self) -> RecordedJoints:
        """What was kept (after :meth:`_Sampler.finish` flushed every node)."""
        t = self.t[: self.n] / NS_PER_S
        order = np.argsort(t, kind='stable')
        data = self.data[: self.n][order]
        has_eff = self.has_eff and self.n > 0
        return RecordedJoints(
            node=self.node,
            names=self.names,
            t=t[order],
            position=data[:, 0].copy(),
            velocity=data[:, 1].copy(),
            effort=data[:, 2].copy() if has_eff else None,
            count=self.count,
            fraction=0.5**self.sampler.level,
            low=self.low.copy(),
            high=self.high.copy(),
        )


class _Decoder:
    """What :func:`read_recording` keeps of each message, in one pass over a bag."""

    def __init__(self, topics: Iterable[str], t_from: float, joint_samples: int) -> None:
        self.clock_end = -1  # the latest /clock, ns
        self.diag_ns = _Grow(np.int64)
        self.status: list[tuple[int, str, dict[str, str]]] = []
        self.bad_values: list[tuple[float, str, int]] = []
        self.ev_ns = _Grow(np.int64)
        self.ev_rows = _Grow(EVENT_DTYPE)
        self.bad_events = 0
        self.joints: dict[str, _Joints] = {}
        self.sampler = _Sampler(joint_samples)
        self.from_ns = round(t_from * NS_PER_S)
        # topic -> the node whose joint states it carries (looked up once per topic, not per message)
        self.node_of = {topic: node for topic in topics if (node := joint_states_node(topic)) is not None}
        self.states: list[tuple[int, str]] = []
        self.commands: dict[tuple[int, str], None] = {}
        self.sheet_count: int | None = None
        self.landing = _Grow(float)

    def message(self, topic: str, t_ns: int, msg: Any) -> None:
        """Keep what the analysis needs of one message (logged at ``t_ns``; of the topic's type)."""
        if topic == CLOCK_TOPIC:
            self.clock_end = max(self.clock_end, stamp_ns(msg.clock))
        elif topic == EVENTS_TOPIC:
            self._event(msg)
        elif (node := self.node_of.get(topic)) is not None:
            self._joint_states(topic, node, msg)
        elif topic == DIAGNOSTICS_TOPIC:
            self._diagnostics(msg)
        elif topic == SUPERVISOR_STATE_TOPIC:
            state = str(msg.data)
            if not self.states or self.states[-1][1] != state:
                self.states.append((t_ns, state))
        elif topic == COMMANDS_TOPIC:
            self.commands[(stamp_ns(msg.time_ref), str(msg.source))] = None
        elif topic == SHEET_COUNT_TOPIC:
            self.sheet_count = int(msg.data)
        elif topic == LANDING_TOPIC:
            self.landing.add(float(msg.data))

    def _event(self, msg: TimeReference) -> None:
        """An event of ``/line/events`` (counted in ``bad_events`` if its source is not one)."""
        try:
            kind, sheet, cycle, value = parse_event_source(msg.source)
        except ValueError:
            self.bad_events += 1
            return
        t_ev = stamp_ns(msg.time_ref)
        self.ev_ns.add(t_ev)
        self.ev_rows.add((0.0, EVENT_KINDS.index(kind), sheet, cycle, value))  # t set later, from the ns

    def _joint_states(self, topic: str, node: str, msg: JointState) -> None:
        """A node's joint states: sampled from ``t_from`` on, their NaN and inf counted."""
        t_ns = stamp_ns(msg.header.stamp)
        three = [np.asarray(a, dtype=float) for a in (msg.position, msg.velocity, msg.effort)]
        if t_ns >= self.from_ns:
            acc = self.joints.get(node)
            if acc is None:
                acc = self.joints[node] = _Joints(node, msg.name, self.sampler)
            acc.add(msg, t_ns, *three)
        arrays = [a for a in three if a.size]
        # a finite sum (the usual case) means no NaN or inf; a non-finite one may be an overflow, so count
        if arrays and not math.isfinite(sum(float(a.sum()) for a in arrays)):
            bad = sum(int(np.count_nonzero(~np.isfinite(a))) for a in arrays)
            if bad:
                self.bad_values.append((t_ns / NS_PER_S, topic, bad))

    def _diagnostics(self, msg: DiagnosticArray) -> None:
        """A ``/diagnostics`` message: its stamp, and the supervisor's statuses in it."""
        t_ns = stamp_ns(msg.header.stamp)
        self.diag_ns.add(t_ns)
        for st in msg.status:
            if str(st.name).startswith(SUPERVISOR_STATUS_PREFIX):
                self.status.append((t_ns, str(st.name), {str(kv.key): str(kv.value) for kv in st.values}))

    def events(self, gaps: Sequence[Gap]) -> tuple[np.ndarray, np.ndarray, Unjudged]:
        """The events sorted (time, kind, sheet), those of the cycles and leaves a gap took events from left
        out: (events, their times in ns, what was left out)."""
        ns = self.ev_ns.done()
        events = self.ev_rows.done()
        events['t'] = ns / NS_PER_S
        order = np.lexsort((events['sheet'], events['kind'], ns))
        events, ns = events[order], ns[order]
        skip = unjudged(events, ns, gaps)
        if skip:  # the events of cycles and leaves a gap took events from are not judged at all
            keep = without_unjudged(events, skip)
            events, ns = events[keep], ns[keep]
        return events, ns, skip


def _bag_scene(contents: BagContents, path: str | os.PathLike[str]) -> Scene:
    """The scene stored in a bag (``path`` named in the errors)."""
    if not contents.scene_source:
        raise InputFileError('RUN_DIR|BAG', str(path), 'the bag holds no scene (custom data folder_line.scene)')
    mapping = load_yaml(contents.scene_source, 'RUN_DIR|BAG', f'{path} (its scene, custom data folder_line.scene)')
    if not isinstance(mapping, dict):
        raise InputFileError('RUN_DIR|BAG', str(path), 'the scene stored in the bag is not a mapping')
    return parse_scene(mapping)


def read_recording(
    path: str | os.PathLike[str],
    on_message: Callable[[str, int, object], None] | None = None,
    *,
    t_to: float | None = None,
    t_from: float = 0.0,
    joint_samples: int = JOINT_SAMPLES,
) -> Recording:
    """Decode a run's bag: events, joint states, states, commands, counts (one pass over the bag).

    Parameters
    ----------
    path : path-like
        A run directory (``run.json`` and ``bag/``) or a bag directory.
    on_message : callable, optional
        Called with ``(topic, log time ns, message)`` for every message (the CSV export).
    t_to : float, optional
        Read the messages logged up to this line time only, s (``analyze --to``): the
        recording is then that of a run that ended there.
    t_from : float, optional
        Keep the joint states stamped from this line time on, s (``analyze --from``: what
        the figures draw). Everything else is read from the start: the replay needs it.
    joint_samples : int, optional
        Joint-state samples kept per node at most (:class:`RecordedJoints`).

    The bag is read once, message by message. What is kept grows only with the events
    (34 bytes each), the supervisor's statuses and
    state changes, and the samples carrying NaN or inf; the joint states, most of a
    bag, are kept to ``joint_samples`` per node.

    Raises
    ------
    ParameterError
        ``path`` is neither; the bag holds no scene, or one that does not validate.
    BagError
        The bag cannot be opened (:func:`folder_line.bag.reader.read_bag`).
    """
    bag_dir, run = _resolve(path)
    contents = read_bag(bag_dir)
    scene = _bag_scene(contents, path)
    dec = _Decoder(contents.topics, t_from, joint_samples)
    stop_ns = None if t_to is None else round(t_to * NS_PER_S) + 1
    for topic, t_ns, msg in contents.messages(stop_ns=stop_ns):
        if on_message is not None:
            on_message(topic, t_ns, msg)
        dec.message(topic, t_ns, msg)

    cmds = tuple(sorted((command_of(t / NS_PER_S, k) for t, k in dec.commands), key=lambda c: c.t))
    end_ns = contents.end_ns if t_to is None else min(contents.end_ns, round(t_to * NS_PER_S))
    t_end = (dec.clock_end if dec.clock_end >= 0 else end_ns) / NS_PER_S
    gaps = tuple(contents.gaps)
    events, ns, skip = dec.events(gaps)
    return Recording(
        bag=contents,
        run=run,
        scene=scene,
        t_end=t_end,
        duration=_run_duration(run, t_end),
        events=events,
        event_ns=ns,
        gaps=gaps,
        unjudged=skip,
        joints=dec.sampler.finish(dec.joints),
        states=dec.states,
        commands=cmds,
        sheet_count=dec.sheet_count,
        landing_x=dec.landing.done(),
        bad_events=dec.bad_events,
        diagnostics_ns=dec.diag_ns.done(),
        supervisor_status=dec.status,
        bad_values=dec.bad_values,
    )
