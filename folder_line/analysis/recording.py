"""Reading a recorded run: a run directory or a bag decoded into a :class:`Recording`.

:func:`read_recording` opens the bag (:func:`folder_line.bag.reader.read_bag`; ``RUN_DIR`` is
what ``folder-line run --out RUN_DIR`` wrote: ``run.json`` and ``bag/``), parses the
scene stored in it and decodes, in one pass over the messages, what the analysis
needs: the events of ``/line/events`` (``time_ref``: the event time to the ns;
``source``: :func:`folder_line.interfaces.parse_event_source`), every machine node's
joint states, the supervisor's states, drive commands and ``/diagnostics`` statuses,
the sheet counter's count and landing positions, and the ``/clock``. No ROS is
needed: the bag is read with rosbags.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from folder_line.bag.reader import read_bag
from folder_line.config.run_config import BAG_DIR, RunConfig
from folder_line.core.line.events import EVENT_DTYPE, event_kind
from folder_line.core.line.scene import Scene, parse_scene
from folder_line.core.mechanisms.drive import Command
from folder_line.errors import ParameterError
from folder_line.files.atomic import describe_path
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

__all__ = ['SUPERVISOR_STATUS_PREFIX', 'RecordedJoints', 'Recording', 'read_recording']

#: the statuses the supervisor publishes on /diagnostics for its decisions
SUPERVISOR_STATUS_PREFIX = 'folder_line/supervisor/'


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
    horizon : float
        The horizon the run's machine nodes built their line model for (``folder-line
        run``'s rule from ``run.json``'s duration; ``t_end`` without ``run.json``), at
        least ``t_end``, s. It matters only for a scene with ``motor_dynamics``, whose
        drive is integrated up to the horizon.
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
    horizon: float
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
        rows: np.ndarray = self.events[self.events['kind'] == event_kind(kind)]  # a field is typed Any
        return rows


def _live_horizon(run: Mapping[str, Any] | None, t_end: float) -> float:
    """The horizon the run's nodes built their line model for (``folder-line run``'s rule), s.

    It matters only for a scene with ``motor_dynamics``, whose drive is integrated up to
    the horizon; without ``run.json`` the line time reached is used.
    """
    horizon = t_end
    if run is not None and isinstance(run.get('duration_s'), (int, float)) and run['duration_s'] > 0:
        horizon = RunConfig(duration=float(run['duration_s'])).horizon
    return max(horizon, t_end, 1e-3)


def _resolve(path: str | os.PathLike[str]) -> tuple[Path, dict[str, Any] | None]:
    """(bag directory, run.json or None) of a run directory or a bag directory."""
    bag_dir = BAG_DIR
    p = Path(path)
    if not p.is_dir():
        what = (
            'no such directory'
            if not os.path.lexists(p)
            else f'{describe_path(p)}, not a run directory or a bag directory'
        )
        raise ParameterError('RUN_DIR|BAG', str(path), what)
    run_dir: Path | None
    if (p / bag_dir).is_dir():
        bag, run_dir = p / bag_dir, p
    elif os.path.lexists(p / 'metadata.yaml') or any(p.glob('*.mcap')):  # read_bag says what is wrong with it
        bag = p
        run_dir = p.parent if p.name == bag_dir else None
    else:
        raise ParameterError(
            'RUN_DIR|BAG', str(path), f'neither a run directory (with {bag_dir}/) nor a bag (with metadata.yaml)'
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


class _Grow:
    """A numpy array appended to row by row, its capacity doubled when full: memory is the data's, with no
    Python object per message (an hour of a 200 Hz topic is 720 000 rows)."""

    def __init__(self, dtype: Any, width: int = 0) -> None:
        self.width = width
        self.data = np.zeros((1024, width) if width else 1024, dtype=dtype)
        self.n = 0

    def add(self, row: Any) -> None:
        if self.n == len(self.data):
            self.data = np.concatenate([self.data, np.zeros_like(self.data)])
        self.data[self.n] = row
        self.n += 1

    def done(self) -> np.ndarray:
        out: np.ndarray = self.data[: self.n].copy()
        return out


class _Joints:
    """Accumulates one node's joint states."""

    def __init__(self, node: str, names: Sequence[str]) -> None:
        self.node, self.names = node, tuple(names)
        j = max(len(self.names), 1)
        self.t = _Grow(np.int64)
        self.pos = _Grow(float, j)
        self.vel = _Grow(float, j)
        self.eff = _Grow(float, j)
        self.has_eff = True

    def add(self, msg: Any, position: np.ndarray, velocity: np.ndarray, effort: np.ndarray) -> None:
        """Append ``msg`` (its three arrays already as float arrays)."""
        if tuple(msg.name) != self.names:  # a model rebuilt with other joints: keep the first layout
            return
        j = len(self.names)
        self.t.add(_time_ns(msg.header.stamp))
        self.pos.add(position.reshape(j) if j else 0.0)
        self.vel.add(velocity.reshape(j) if j else 0.0)
        if effort.size == j and j:
            self.eff.add(effort)
        else:
            self.has_eff = False
            self.eff.add(0.0)

    def done(self) -> RecordedJoints:
        j = len(self.names)
        n = self.t.n
        pos = self.pos.done()[:, :j]
        vel = self.vel.done()[:, :j]
        eff = self.eff.done()[:, :j] if n > 0 and self.has_eff else None
        t = self.t.done() / NS_PER_S
        order = np.argsort(t, kind='stable')
        return RecordedJoints(
            self.node, self.names, t[order], pos[order], vel[order], None if eff is None else eff[order]
        )


def read_recording(
    path: str | os.PathLike[str],
    on_message: Callable[[str, int, Any], None] | None = None,
    *,
    t_to: float | None = None,
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

    The bag is read once, message by message; what is kept grows with the numbers the
    analysis needs (numpy arrays), not with Python objects per message.

    Raises
    ------
    ParameterError
        ``path`` is neither; the bag holds no scene, or one that does not validate.
    BagError
        The bag cannot be opened (:func:`folder_line.bag.reader.read_bag`).
    """
    bag_dir, run = _resolve(path)
    contents = read_bag(bag_dir)
    if not contents.scene_source:
        raise ParameterError('RUN_DIR|BAG', str(path), 'the bag holds no scene (custom data folder_line.scene)')
    mapping = load_yaml(contents.scene_source, 'RUN_DIR|BAG', f'{path} (its scene, custom data folder_line.scene)')
    if not isinstance(mapping, dict):
        raise ParameterError('RUN_DIR|BAG', str(path), 'the scene stored in the bag is not a mapping')
    scene = parse_scene(mapping)

    clock = _Grow(np.int64)
    diag_ns = _Grow(np.int64)
    status: list[tuple[int, str, dict[str, str]]] = []
    bad_values: list[tuple[float, str, int]] = []
    ev_ns = _Grow(np.int64)
    ev_rows = _Grow(EVENT_DTYPE)
    bad_events = 0
    joints: dict[str, _Joints] = {}
    # topic -> the node whose joint states it carries (looked up once per topic, not per message)
    node_of = {topic: node for topic in contents.topics if (node := joint_states_node(topic)) is not None}
    states: list[tuple[int, str]] = []
    commands: dict[tuple[int, str], None] = {}
    sheet_count: int | None = None
    landing: list[float] = []
    stop_ns = None if t_to is None else round(t_to * NS_PER_S) + 1
    for topic, t_ns, msg in contents.messages(stop_ns=stop_ns):
        if on_message is not None:
            on_message(topic, t_ns, msg)
        if topic == CLOCK_TOPIC:
            clock.add(_time_ns(msg.clock))
        elif topic == EVENTS_TOPIC:
            try:
                kind, sheet, cycle, value = parse_event_source(msg.source)
            except ValueError:
                bad_events += 1
                continue
            t_ev = _time_ns(msg.time_ref)
            ev_ns.add(t_ev)
            ev_rows.add((0.0, EVENT_KINDS.index(kind), sheet, cycle, value))  # t set below, from the ns
        elif (node := node_of.get(topic)) is not None:
            acc = joints.get(node)
            if acc is None:
                acc = joints[node] = _Joints(node, msg.name)
            three = [np.asarray(a, dtype=float) for a in (msg.position, msg.velocity, msg.effort)]
            acc.add(msg, *three)
            arrays = [a for a in three if a.size]
            # a finite sum (the usual case) means no NaN or inf; a non-finite one may be an overflow, so count
            if arrays and not math.isfinite(sum(float(a.sum()) for a in arrays)):
                bad = sum(int(np.count_nonzero(~np.isfinite(a))) for a in arrays)
                if bad:
                    bad_values.append((_time_ns(msg.header.stamp) / NS_PER_S, topic, bad))
        elif topic == DIAGNOSTICS_TOPIC:
            stamp_ns = _time_ns(msg.header.stamp)
            diag_ns.add(stamp_ns)
            for st in msg.status:
                if str(st.name).startswith(SUPERVISOR_STATUS_PREFIX):
                    status.append((stamp_ns, str(st.name), {str(kv.key): str(kv.value) for kv in st.values}))
        elif topic == SUPERVISOR_STATE_TOPIC:
            states.append((t_ns, str(msg.data)))
        elif topic == COMMANDS_TOPIC:
            commands[(_time_ns(msg.time_ref), str(msg.source))] = None
        elif topic == SHEET_COUNT_TOPIC:
            sheet_count = int(msg.data)
        elif topic == LANDING_TOPIC:
            landing.append(float(msg.data))

    ns = ev_ns.done()
    events = ev_rows.done()
    events['t'] = ns / NS_PER_S
    order = np.lexsort((events['sheet'], events['kind'], ns))
    cmds = tuple(sorted((Command(t=t / NS_PER_S, kind=k) for t, k in commands), key=lambda c: c.t))
    clock_ns = clock.done()
    end_ns = contents.end_ns if t_to is None else min(contents.end_ns, round(t_to * NS_PER_S))
    t_end = (int(clock_ns.max()) if clock_ns.size else end_ns) / NS_PER_S
    return Recording(
        bag=contents,
        run=run,
        scene=scene,
        t_end=t_end,
        horizon=_live_horizon(run, t_end),
        events=events[order],
        event_ns=ns[order],
        joints={node: acc.done() for node, acc in joints.items()},
        states=states,
        commands=cmds,
        sheet_count=sheet_count,
        landing_x=np.asarray(landing, dtype=float),
        bad_events=bad_events,
        clock=clock_ns / NS_PER_S,
        diagnostics_ns=diag_ns.done(),
        supervisor_status=status,
        bad_values=bad_values,
    )
