"""The view of ``folder-line monitor``: what the monitor knows of the line, and that as lines of text.

:class:`MonitorState` ingests the line's messages, each with a wall time (when the
publisher wrote it; see :class:`folder_line.ros.monitor.MonitorNode`), and keeps, per
topic, the message count, the rate over a sliding window of wall time and a summary of
the latest value; besides that the sim time (``/clock``) and the real-time factor
achieved, the supervisor's state, the sheet count and rate, the latest joint states of
every machine, the latest event of each kind with its time, the drive commands, and per
constraint (one ``DiagnosticStatus`` of ``/diagnostics`` each) the latest margin, the
smallest margin so far and the violations. :meth:`MonitorState.render` turns that into
the lines of a screen of a given size.

Pure Python: messages are read by their fields (duck typing), so this module imports
neither rclpy nor any message package, and its tests need no ROS graph. The terminal
(``curses``, ``--once``) is :mod:`folder_line.cli.monitor`.

Rates are in messages per second of wall time, from the times the publishers wrote
the messages: a line running at a real-time factor of 0.5 shows its 200 Hz (sim
time) topics at 100/s.
"""

from __future__ import annotations

import math
import re
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any, ClassVar, TypeVar

from folder_line.cli.operator_keys import OperatorKeys
from folder_line.core.line.margin_text import format_margin
from folder_line.interfaces import (
    CLOCK_TOPIC,
    COMMANDS_TOPIC,
    DIAGNOSTICS_TOPIC,
    EVENT_KINDS,
    EVENTS_TOPIC,
    JOINT_STATES_TOPIC_PATTERN,
    LANDING_TOPIC,
    MARKERS_TOPIC,
    NS_PER_S,
    PARTICIPANTS_TOPIC,
    SHEET_COUNT_TOPIC,
    SHEET_RATE_TOPIC,
    SUPERVISOR_STATE_TOPIC,
)
from folder_line.ros.message_fields import (
    ClockLike,
    DataLike,
    DiagnosticArrayLike,
    JointStateLike,
    MarkerArrayLike,
    StampLike,
    TimeReferenceLike,
)
from folder_line.ros.signing import without_signature

__all__ = [
    'LEVELS',
    'MIN_HEIGHT',
    'MIN_WIDTH',
    'WINDOW',
    'ConstraintView',
    'EventView',
    'JointView',
    'MonitorState',
    'TopicStats',
]

WINDOW = 2.0
"""Default sliding window of the rates, s of wall time."""

MIN_WIDTH = 40
"""Narrowest screen the monitor draws on, characters."""

MIN_HEIGHT = 6
"""Lowest screen the monitor draws on, lines."""

_JOINT_STATES = re.compile(
    '^' + re.escape(JOINT_STATES_TOPIC_PATTERN).replace(re.escape('{node}'), '(?P<node>[^/]+)') + '$'
)

LEVELS = {0: 'OK', 1: 'WARN', 2: 'ERROR', 3: 'STALE'}
"""Names of the ``level`` values of ``diagnostic_msgs/msg/DiagnosticStatus`` (its constants
``OK`` ... ``STALE``, bytes ``b'\\x00'`` ... ``b'\\x03'``)."""

_KIND_ORDER = {kind: i for i, kind in enumerate(EVENT_KINDS)}


@dataclass
class TopicStats:
    """Arrivals on one topic.

    Attributes
    ----------
    count : int
        Messages received so far.
    first_wall, last_wall : float or None
        Wall time of the first and the latest arrival, s (None before the first).
    arrivals : deque of float
        Wall times of the arrivals within the rate window, s, in order of arrival.
    latest : str
        One-line summary of the latest message ('-' before the first).
    """

    count: int = 0
    first_wall: float | None = None
    last_wall: float | None = None
    arrivals: deque[float] = field(default_factory=deque)
    latest: str = '-'

    def add(self, wall: float, window: float) -> None:
        """Count one arrival at wall time ``wall`` (s) and forget those older than ``window`` s."""
        self.count += 1
        self.first_wall = wall if self.first_wall is None else min(self.first_wall, wall)
        self.last_wall = wall if self.last_wall is None else max(self.last_wall, wall)
        self.arrivals.append(wall)
        self._trim(self.last_wall - window)

    def _trim(self, horizon: float) -> None:
        while self.arrivals and self.arrivals[0] <= horizon:
            self.arrivals.popleft()

    def rate(self, now: float, window: float) -> float | None:
        """Messages per second of wall time over the window ``(now - window, now]``.

        Once the topic has been received for longer than the window, that is the
        number of arrivals in it over ``window``, so the rate falls to 0 within one
        window after the publisher stops. Before that, the ``n`` arrivals since the
        first one span ``n - 1`` intervals over ``now - first_wall``.

        Parameters
        ----------
        now : float
            Wall time, s (not before the latest arrival for a meaningful value).
        window : float
            Window length, s (> 0).

        Returns
        -------
        float or None
            Rate, 1/s: 0 if nothing was ever received; None while a single arrival,
            younger than the window, is all there is to go by.
        """
        self._trim(now - window)
        n = sum(1 for t in self.arrivals if now - window < t <= now)  # (a late, older stamp may sit at the end)
        if self.first_wall is None or n == 0:
            return 0.0
        if self.first_wall > now - window:
            span = now - self.first_wall
            return (n - 1) / span if n > 1 and span > 0.0 else None
        return n / window


@dataclass(frozen=True)
class JointView:
    """Latest joint states of one machine (``sensor_msgs/JointState``).

    Attributes
    ----------
    node : str
        The machine node (from the topic name).
    stamp : float
        Header stamp, s of sim time.
    names : tuple of str
        Joint names.
    position, velocity, effort : tuple of float
        Per joint (rad or m, rad/s or m/s, N m or N); may be shorter than ``names``
        (an empty ``effort`` means the machine publishes none).
    """

    node: str
    stamp: float
    names: tuple[str, ...]
    position: tuple[float, ...]
    velocity: tuple[float, ...]
    effort: tuple[float, ...]


@dataclass(frozen=True)
class EventView:
    """Latest event of one kind (``/line/events``) and how many of that kind arrived.

    Attributes
    ----------
    kind : str
        Event kind (``folder_line.core.types.events.EVENT_KINDS``), or the first word of an
        unrecognised ``source``.
    count : int
        Events of this kind received so far.
    t : float
        Event time (``time_ref``), s of sim time.
    sheet, cycle : int or None
        Sheet (leaf) id and machine cycle, when given (-1 in the message: none).
    value : float or None
        Kind-specific value (see ``EVENT_KINDS``).
    node : str
        Publishing node (``header.frame_id``).
    """

    kind: str
    count: int
    t: float
    sheet: int | None
    cycle: int | None
    value: float | None
    node: str


@dataclass(frozen=True)
class ConstraintView:
    """One constraint as the supervisor last reported it on ``/diagnostics``.

    Attributes
    ----------
    name : str
        ``DiagnosticStatus.name`` (``folder_line/<constraint>``).
    level : str
        OK, WARN (violated before), ERROR (violated in the latest cycle) or STALE.
    message : str
        The status message.
    margin : float or None
        Margin of the latest evaluated cycle (negative: violated), in ``unit``.
    min_margin : float or None
        Smallest margin so far: the supervisor's ``min_margin``, or, if it sent none,
        the smallest ``margin`` the monitor has seen.
    unit : str
        Unit of the margins.
    cycle : int or None
        Cycle of the latest margin.
    violations, evaluations : int or None
        Cycles violated and cycles evaluated so far.
    stamp : float
        Stamp of the ``DiagnosticArray``, s of sim time.
    """

    name: str
    level: str
    message: str
    margin: float | None
    min_margin: float | None
    unit: str
    cycle: int | None
    violations: int | None
    evaluations: int | None
    stamp: float


_N = TypeVar('_N', int, float)


def _stamp_s(stamp: StampLike) -> float:
    # folder_line.ros.time_msg.time_msg_to_ns, on any object with sec and nanosec
    sec: int = stamp.sec
    nanosec: int = stamp.nanosec
    return (sec * NS_PER_S + nanosec) / NS_PER_S


def _number(text: str | None, kind: Callable[[str], _N]) -> _N | None:
    """``kind(text)``, or None for a value that is missing or not a number of that kind."""
    if text is None:
        return None
    try:
        return kind(text)
    except ValueError:
        return None


def _level(level: int | bytes | bytearray) -> str:
    if isinstance(level, (bytes, bytearray)):
        level = level[0] if level else 0
    return LEVELS.get(int(level), str(level))


def _g(x: float | None, fmt: str = '.5g') -> str:
    return '-' if x is None else format(x, fmt)


def _parse_event(source: str) -> tuple[str, int | None, int | None, float | None]:
    """``'<kind> sheet=<id> cycle=<k> value=<repr>'`` -> parts; tolerant of anything else."""
    words = source.split()
    kind = words[0] if words else '?'
    fields = dict(w.split('=', 1) for w in words[1:] if '=' in w)
    sheet, cycle = _number(fields.get('sheet'), int), _number(fields.get('cycle'), int)
    return (
        kind,
        None if sheet is None or sheet < 0 else sheet,
        None if cycle is None or cycle < 0 else cycle,
        _number(fields.get('value'), float),
    )


def _fit(text: str, width: int) -> str:
    """``text`` cut to ``width`` characters, a cut marked by a final ``~``."""
    if len(text) <= width:
        return text
    return text[: width - 1] + '~' if width > 0 else ''


class MonitorState:
    """What the monitor knows of the line; fed message by message, rendered as text.

    Parameters
    ----------
    topics : iterable of str, optional
        Topics to list even before their first message, in this order (the others
        follow in order of arrival).
    window : float, optional
        Sliding window of the rates, s of wall time (> 0; default :data:`WINDOW`).

    Raises
    ------
    ValueError
        ``window`` is not a finite positive number.
    """

    def __init__(self, topics: Iterable[str] = (), window: float = WINDOW) -> None:
        if not (isinstance(window, (int, float)) and math.isfinite(window) and window > 0.0):
            msg = f'window={window!r}: must be a finite number of seconds > 0'
            raise ValueError(msg)
        self.window = float(window)
        self.topics: dict[str, TopicStats] = {t: TopicStats() for t in topics}
        self.sim_time: float | None = None
        self._clock_track: deque[tuple[float, float]] = deque()  # (wall, sim) within the window
        self.state = ''
        self.state_since: float | None = None  # sim time when the monitor saw the state change
        self.sheet_count: int | None = None
        self.sheet_rate: float | None = None
        self.landing_x: float | None = None
        self.joints: dict[str, JointView] = {}
        self.events: dict[str, EventView] = {}
        self.constraints: dict[str, ConstraintView] = {}
        self.commands: list[tuple[str, float]] = []  # (command, effective sim time), oldest first
        self.last_wall: float | None = None  # latest wall time of any message, s
        self._total = 0
        self.operator: OperatorKeys | None = None  # the live view's keys (no row in a snapshot)

    # ------------------------------------------------------------------ ingest

    @property
    def total(self) -> int:
        """Messages received on all topics."""
        return self._total

    def ingest(self, topic: str, msg: object, wall: float) -> None:
        """Take one message of ``topic`` written (or received) at wall time ``wall`` (s).

        Messages are read by their fields (duck typing): ``rosgraph_msgs/Clock``,
        ``sensor_msgs/JointState`` (on ``/line/<node>/joint_states``),
        ``sensor_msgs/TimeReference`` (events and commands),
        ``diagnostic_msgs/DiagnosticArray``, ``std_msgs/String``, ``UInt64``,
        ``Float64`` and ``visualization_msgs/MarkerArray`` (counted) on the topics of
        :data:`folder_line.interfaces.TOPICS`; any
        other topic is only counted.
        """
        stats = self.topics.get(topic)
        if stats is None:
            stats = self.topics[topic] = TopicStats()
        stats.add(wall, self.window)
        self._total += 1
        self.last_wall = wall if self.last_wall is None else max(self.last_wall, wall)
        stats.latest = self._take(topic, msg, wall)

    def _take(self, topic: str, msg: Any, wall: float) -> str:  # Any: the message of ``topic`` (its type)
        take = self._TAKERS.get(topic)
        if take is not None:
            return take(self, msg, wall)
        m = _JOINT_STATES.match(topic)
        return type(msg).__name__ if m is None else self._take_joints(m['node'], msg)

    def _take_clock(self, msg: ClockLike, wall: float) -> str:
        t = _stamp_s(msg.clock)
        self.sim_time = t  # the latest, not the largest: a line started again shows its new time
        if self._clock_track and t < self._clock_track[-1][1]:  # time went back: a new line
            self._clock_track.clear()
        self._clock_track.append((wall, t))
        while self._clock_track and self._clock_track[0][0] <= wall - self.window:
            self._clock_track.popleft()
        return f'{t:.3f} s'

    def _take_joints(self, node: str, msg: JointStateLike) -> str:
        joint = JointView(
            node,
            _stamp_s(msg.header.stamp),
            tuple(msg.name),
            tuple(float(x) for x in msg.position),
            tuple(float(x) for x in msg.velocity),
            tuple(float(x) for x in msg.effort),
        )
        self.joints[joint.node] = joint
        return f'{len(joint.names)} joint{"" if len(joint.names) == 1 else "s"} at {joint.stamp:.3f} s'

    def _take_event(self, msg: TimeReferenceLike, wall: float) -> str:
        kind, sheet, cycle, value = _parse_event(msg.source)
        previous = self.events.get(kind)
        event = EventView(
            kind,
            1 if previous is None else previous.count + 1,
            _stamp_s(msg.time_ref),
            sheet,
            cycle,
            value,
            msg.header.frame_id,
        )
        self.events[kind] = event
        return f'{kind} at {event.t:.3f} s' + ('' if sheet is None else f' (sheet {sheet})')

    def _take_state(self, msg: DataLike[str], wall: float) -> str:
        state: str = msg.data
        if state != self.state:  # a change seen, not the state found on joining: since then
            self.state_since = self.sim_time if self.state else None
            self.state = state
        return state

    def _take_count(self, msg: DataLike[int], wall: float) -> str:
        self.sheet_count = int(msg.data)
        return str(self.sheet_count)

    def _take_rate(self, msg: DataLike[float], wall: float) -> str:
        self.sheet_rate = float(msg.data)
        return f'{self.sheet_rate:.3f} /s'

    def _take_landing(self, msg: DataLike[float], wall: float) -> str:
        self.landing_x = float(msg.data)
        return f'{self.landing_x:.4f} m'

    def _take_command(self, msg: TimeReferenceLike, wall: float) -> str:
        t = _stamp_s(msg.time_ref)
        source = without_signature(msg.source)
        self.commands.append((source, t))
        del self.commands[:-8]
        return f'{source} effective at {t:.3f} s'

    def _take_participants(self, msg: DataLike[str], wall: float) -> str:
        # 'clock=lockstep end=... participants=a,b'
        fields = dict(item.partition('=')[::2] for item in without_signature(str(msg.data)).split())
        names = [n for n in fields.get('participants', '').split(',') if n]
        return f'{fields.get("clock", "?")} clock, {len(names)} participants'

    def _take_markers(self, msg: MarkerArrayLike, wall: float) -> str:
        # the machine drawn: how many markers, of which stamp
        markers = list(msg.markers)
        at = f' at {_stamp_s(markers[-1].header.stamp):.3f} s' if markers else ''
        return f'{len(markers)} marker{"" if len(markers) == 1 else "s"}{at}'

    def _take_diagnostics_at(self, msg: DiagnosticArrayLike, wall: float) -> str:
        return self._take_diagnostics(msg)

    #: what the monitor takes of each topic's message (the joint states: by their pattern); ``Any``: each
    #: taker reads the message type of its topic
    _TAKERS: ClassVar[dict[str, Callable[[MonitorState, Any, float], str]]] = {
        CLOCK_TOPIC: _take_clock,
        EVENTS_TOPIC: _take_event,
        DIAGNOSTICS_TOPIC: _take_diagnostics_at,
        SUPERVISOR_STATE_TOPIC: _take_state,
        SHEET_COUNT_TOPIC: _take_count,
        SHEET_RATE_TOPIC: _take_rate,
        LANDING_TOPIC: _take_landing,
        COMMANDS_TOPIC: _take_command,
        PARTICIPANTS_TOPIC: _take_participants,
        MARKERS_TOPIC: _take_markers,
    }

    def _take_diagnostics(self, msg: DiagnosticArrayLike) -> str:
        stamp = _stamp_s(msg.header.stamp)
        for status in msg.status:
            values = {kv.key: kv.value for kv in status.values}
            margin = _number(values.get('margin'), float)
            min_margin = _number(values.get('min_margin'), float)
            previous = self.constraints.get(status.name)
            if min_margin is None and margin is not None:  # no min from the supervisor: ours
                seen = [m for m in (margin, None if previous is None else previous.min_margin) if m is not None]
                min_margin = min(seen)
            self.constraints[status.name] = ConstraintView(
                status.name,
                _level(status.level),
                status.message,
                margin,
                min_margin,
                values.get('unit', ''),
                _number(values.get('cycle'), int),
                _number(values.get('violations'), int),
                _number(values.get('evaluations'), int),
                stamp,
            )
        bad = sum(1 for c in self.constraints.values() if c.level in ('WARN', 'ERROR'))
        return f'{len(msg.status)} statuses at {stamp:.3f} s, {bad} WARN or ERROR'

    # ------------------------------------------------------------------ derived

    def rate(self, topic: str, now: float | None = None) -> float | None:
        """Messages per second of wall time of ``topic`` (0 if never received); see :meth:`TopicStats.rate`.

        ``now`` (s of wall time) defaults to the latest arrival on any topic.
        """
        stats = self.topics.get(topic)
        now = self._now(now)
        return 0.0 if stats is None or now is None else stats.rate(now, self.window)

    def rtf(self) -> float | None:
        """Sim seconds per wall second over the window of ``/clock`` arrivals (None with fewer than two)."""
        if len(self._clock_track) < 2:
            return None
        (w0, s0), (w1, s1) = self._clock_track[0], self._clock_track[-1]
        return (s1 - s0) / (w1 - w0) if w1 > w0 else None

    def _now(self, now: float | None) -> float | None:
        return self.last_wall if now is None else now

    # ------------------------------------------------------------------ render

    def render(self, width: int, height: int | None = None, now: float | None = None) -> list[str]:
        """The screen as lines of at most ``width`` characters, at most ``height`` of them.

        Parameters
        ----------
        width : int
            Columns of the screen.
        height : int, optional
            Lines of the screen; ``None``: as many as needed (the ``--once`` snapshot).
            When the content is longer, the last line says how many lines are hidden.
        now : float, optional
            Wall time of the rates, s (default: the latest arrival).

        Returns
        -------
        list of str
            The lines, top to bottom (a one-line notice if the screen is smaller than
            :data:`MIN_WIDTH` x :data:`MIN_HEIGHT`).
        """
        return [text for text, _ in self.render_styled(width, height, now)]

    def render_styled(self, width: int, height: int | None = None, now: float | None = None) -> list[tuple[str, str]]:
        """:meth:`render` with a style per line: ``'header'``, ``'title'``, ``'alert'`` or ``''``."""
        if width < MIN_WIDTH or (height is not None and height < MIN_HEIGHT):
            size = f'{width} columns' if height is None else f'{width}x{height}'
            text = f'terminal too small ({size}): need {MIN_WIDTH}x{MIN_HEIGHT}; q quits'
            rows = [text[i : i + width] for i in range(0, len(text), width)] if width > 0 else []
            return [(row, 'alert') for row in rows[: height if height is not None else None]]
        now = self._now(now)
        lines = self._header(now)
        if self.operator is not None:
            lines.append(self.operator.styled())
        lines += self._topics(now) + self._constraints() + self._joints() + self._events() + self._commands()
        lines = [(_fit(text, width), style) for text, style in lines]
        if height is not None and len(lines) > height:
            hidden = len(lines) - (height - 1)
            lines = [*lines[: height - 1], (_fit(f'... {hidden} more lines: enlarge the terminal', width), 'title')]
        return lines

    def _header(self, now: float | None) -> list[tuple[str, str]]:
        sim = '-' if self.sim_time is None else f'{self.sim_time:.3f} s'
        rtf = self.rtf()
        state = self.state or '?'
        if self.state and self.state_since is not None:
            state += f' since {self.state_since:.2f} s'
        sheets = '-' if self.sheet_count is None else str(self.sheet_count)
        if self.sheet_rate is not None:
            sheets += f' ({self.sheet_rate:.2f}/s)'
        head = (
            f'folder-line monitor | sim {sim} | rtf {"-" if rtf is None else f"{rtf:.2f}"} | '
            f'supervisor {state} | sheets {sheets} | q: quit'
        )
        if self.last_wall is None or now is None:
            info = 'waiting for the line (same ROS_DOMAIN_ID?): no message received yet'
        else:
            idle = now - self.last_wall
            info = (
                f'{self.total} messages on {sum(1 for s in self.topics.values() if s.count)} topics since '
                f'the monitor started, rates over {self.window:g} s of wall time'
                + (f' | no message for {idle:.1f} s' if idle > 1.0 else '')
            )
        return [(head, 'header'), (info, '')]

    def _topics(self, now: float | None) -> list[tuple[str, str]]:
        rows = [(f'{"TOPIC":<38} {"RATE/s":>8} {"COUNT":>9}  LATEST', 'title')]
        for topic, stats in self.topics.items():
            rate = 0.0 if now is None else stats.rate(now, self.window)
            rows.append((f'{topic:<38} {_g(rate, "8.1f"):>8} {stats.count:9d}  {stats.latest}', ''))
        return rows

    def _constraints(self) -> list[tuple[str, str]]:
        if not self.constraints:
            return []
        head = f'{"CONSTRAINT":<34} {"LEVEL":<5} {"MARGIN":>18} {"MIN MARGIN":>18} {"VIOL/EVAL":>11}  MESSAGE'
        rows = [(head, 'title')]
        for c in self.constraints.values():
            counts = f'{_g(c.violations, "d")}/{_g(c.evaluations, "d")}'
            style = 'alert' if c.level in ('WARN', 'ERROR') else ''
            name = c.name.rsplit('/', 1)[-1]  # folder_line/one_per_cycle: the constraint's own name

            def shown(x: float | None, name: str = name, unit: str = c.unit) -> str:
                # each margin in its own unit (ms, mm, m/s, sheets), as simulate and analyze print it
                return '-' if x is None else format_margin(x, unit, name, short=True)

            text = (
                f'{c.name:<34} {c.level:<5} {shown(c.margin):>18} {shown(c.min_margin):>18} {counts:>11}  {c.message}'
            )
            rows.append((text, style))
        return rows

    def _joints(self) -> list[tuple[str, str]]:
        if not self.joints:
            return []
        rows = [(f'{"JOINT":<38} {"POSITION":>12} {"VELOCITY":>12} {"EFFORT":>12}  STAMP', 'title')]
        order = list(self.topics)  # the machines in topic order (every joint view came from a topic)
        for node in sorted(self.joints, key=lambda n: order.index(JOINT_STATES_TOPIC_PATTERN.format(node=n))):
            js = self.joints[node]
            for i, name in enumerate(js.names):
                cells = [_g(v[i] if i < len(v) else None, '.6g') for v in (js.position, js.velocity, js.effort)]
                text = f'{node + "/" + name:<38} {cells[0]:>12} {cells[1]:>12} {cells[2]:>12}  {js.stamp:.3f} s'
                rows.append((text, ''))
        return rows

    def _events(self) -> list[tuple[str, str]]:
        if not self.events:
            return []
        rows = [(f'{"EVENT":<22} {"COUNT":>7} {"LAST AT":>12} {"SHEET":>7} {"CYCLE":>7} {"VALUE":>11}  NODE', 'title')]
        order = sorted(self.events, key=lambda k: (_KIND_ORDER.get(k, len(_KIND_ORDER)), k))
        for kind in order:
            e = self.events[kind]
            text = (
                f'{kind:<22} {e.count:7d} {e.t:10.3f} s {_g(e.sheet, "d"):>7} {_g(e.cycle, "d"):>7} '
                f'{_g(e.value, ".5g"):>11}  {e.node}'
            )
            rows.append((text, ''))
        return rows

    def _commands(self) -> list[tuple[str, str]]:
        if not self.commands:
            return []
        return [('DRIVE COMMANDS  ' + ', '.join(f'{c} at {t:.3f} s' for c, t in self.commands), 'title')]
