"""Node ``line_clock``: the owner of simulated time.

Sim time advances on a fixed grid, ``t_k = start_time + k / rate`` (integer ns),
up to ``start_time + duration`` exactly. Before its first tick the node announces
the line's participants and clock mode on ``/line/participants``; it grants ticks to
them on ``/line/grant`` and publishes every tick it grants on ``/clock`` (see
:mod:`folder_line.ros.lockstep`). It takes no ``/clock`` of anyone else: a foreign
``/clock`` message is counted, its publisher named once in the log and on
``/diagnostics`` (``folder_line/line_clock/foreign_clock``, WARN), and sim time goes on.

``clock = lockstep`` (default)
    The first tick is granted again every 0.2 s of wall time until every participant
    has answered it, so sim time does not advance until all of them are up and
    matched. Then ticks are granted up to ``window`` s of sim time ahead of the
    slowest participant's latest acknowledgement: no tick is ever skipped, and when
    the machine or the network is slow, sim time slows down. ``rtf`` is a ceiling at
    every moment (sim seconds per wall second; ``0`` = as fast as the slowest
    participant allows): after a stall, sim time does not run faster to catch up.
``clock = wall`` (hardware in the loop)
    Ticks are granted when the wall clock says (``rtf`` > 0 required), whatever the
    participants do; a participant whose acknowledgement of a tick is not in when the
    next tick is due is *late*. Lateness is counted per participant and published on
    ``/diagnostics`` (``folder_line/line_clock/lateness``, WARN) every second of sim
    time: its own state, never a constraint violation.

In both modes a participant that answers nothing for ``lost_timeout`` s of wall
time is *waited for*: named in the log and on ``/diagnostics``
(``folder_line/line_clock/waiting``, WARN, with the wall seconds) every few seconds,
and taken back when it answers (``folder_line/line_clock/resumed``). It is declared
*lost* once its DDS participant has also left the graph (its process ended, or its
lease ran out), or if it never answered the first tick in ``startup_timeout``:
named in the log and on ``/diagnostics`` (``folder_line/line_clock/lost``, ERROR),
and no longer waited for. With ``duration > 0`` the node stops once the last tick is
answered (as a process it then exits 0, or 3 if a participant was lost).

Parameters
----------
rate : float, Hz of sim time, [1, 10000], default 200.0
    Ticks per simulated second (dynamic).
rtf : float, [0, 1000], default 1.0
    Real-time factor ceiling; 0 = no ceiling (lockstep only); otherwise >= 0.001 (dynamic).
window : float, s of sim time, [0, 60], default 0.5 (read-only)
    How far the clock grants ahead of the slowest participant (0: one tick, a barrier per tick).
clock : str, lockstep or wall, default lockstep (read-only)
participants : str, default the five machine nodes (read-only)
    Comma-separated participant node names (``line_recorder`` for ``folder-line run``'s recorder).
start_time : float, s, [0, 1e7], default 0.0 (read-only)
duration : float, s, [0, 1e7], default 0.0 (read-only)
    Sim time to run for after ``start_time``; 0 runs until interrupted.
lost_timeout : float, s of wall time, [0.1, 3600], default 3.0 (read-only)
startup_timeout : float, s of wall time, [1, 3600], default 60.0 (read-only)
"""

from __future__ import annotations

import math
import sys
import time
from collections import deque
from collections.abc import Callable, Iterable, Mapping
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.clock import Clock
from rclpy.clock_type import ClockType
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.serialization import serialize_message
from rclpy.task import Future
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import TimeReference
from std_msgs.msg import String

from folder_line.core.limits import DURATION, LOST_TIMEOUT, RTF, TICK_RATE
from folder_line.core.supervision.lockstep import TickLedger
from folder_line.errors import ParameterError
from folder_line.interfaces import (
    CLOCK_TOPIC,
    DIAGNOSTICS_TOPIC,
    GRANT_TOPIC,
    KNOWN_PARTICIPANTS,
    NS_PER_S,
    PARTICIPANTS_TOPIC,
    TIME_MSG_MAX_NS,
    progress_topic,
    seconds_to_ns,
)
from folder_line.ros.dds_profile import line_partition
from folder_line.ros.line_key import KEY_VARIABLE
from folder_line.ros.lockstep import (
    ACK_QOS,
    CLOCK_SUB_QOS,
    DEFAULT_PARTICIPANTS,
    GRANT_QOS,
    HEARTBEAT,
    LINE_QOS,
    PARTICIPANTS_QOS,
    WAIT_REPORT,
)
from folder_line.ros.lockstep_messages import (
    CLOCK_MODES,
    Announcement,
    format_announcement,
    format_grant,
    participant_names,
    read_ack,
)
from folder_line.ros.parameters import ParamSpec, declare_parameters, given_values, guard_changes
from folder_line.ros.runtime import run_node
from folder_line.ros.strangers import foreign_publishers
from folder_line.ros.time_msg import ns_to_time_msg
from folder_line.ros.topics import CLOCK_QOS, PUBLISH_DEPTH

__all__ = ['EXIT_LOST', 'NODE_NAME', 'SPECS', 'LineClock', 'main', 'parse_participants']

NODE_NAME = 'line_clock'
EXIT_LOST = 3
MIN_RTF = RTF.lo
REPEAT_FIRST = 0.2  # wall s between repetitions of the first tick
#: wall s of lateness a grant may catch up (a late wake-up, a busy executor); later than that (a stall), the rtf
#: ceiling counts afresh: sim time never runs ahead of rtf x wall time by more than rtf x MAX_BURST
MAX_BURST = 0.1
#: wall s between two grants at least: at a high rtf a grant holds several ticks
GRANT_PERIOD = 0.005
#: wall s between two looks at the graph for publishers on the line's topics that are not the line's
STRANGER_SCAN = 2.0

SPECS: tuple[ParamSpec, ...] = (
    ParamSpec('rate', 200.0, 'Ticks per second of simulated time', unit='Hz', bounds=TICK_RATE.bounds),
    ParamSpec(
        'rtf',
        1.0,
        'Real-time factor ceiling: simulated seconds per wall second (0: as fast as the line '
        f'allows, lockstep only; else >= {RTF.lo:g})',
        bounds=(0.0, RTF.hi),
    ),
    ParamSpec(
        'window',
        0.5,
        'Lockstep: sim time granted ahead of the slowest participant (0: one tick, a barrier per tick)',
        unit='s',
        bounds=(0.0, 60.0),
        read_only=True,
    ),
    ParamSpec(
        'clock',
        'lockstep',
        'lockstep: wait for every participant each tick; wall: pace by the wall clock and count late participants',
        choices=CLOCK_MODES,
        read_only=True,
    ),
    ParamSpec(
        'participants',
        ','.join(DEFAULT_PARTICIPANTS),
        f'Comma-separated nodes that acknowledge every tick (of {", ".join(KNOWN_PARTICIPANTS)})',
        read_only=True,
    ),
    ParamSpec('start_time', 0.0, 'Simulated time at start', unit='s', bounds=(0.0, DURATION.hi), read_only=True),
    ParamSpec(
        'duration',
        0.0,
        'Simulated time to run for after start_time; 0 runs until interrupted',
        unit='s',
        bounds=(0.0, DURATION.hi),
        read_only=True,
    ),
    ParamSpec(
        'lost_timeout',
        3.0,
        'Wall time a tick waits for a participant before it is declared lost',
        unit='s',
        bounds=LOST_TIMEOUT.bounds,
        read_only=True,
    ),
    ParamSpec(
        'startup_timeout',
        60.0,
        'Wall time the first tick waits for every participant',
        unit='s',
        bounds=(1.0, 3600.0),
        read_only=True,
    ),
)


def _few(topics: set[str], most: int = 3) -> str:
    """``'/a, /b, /c and 24 more topics'``: a log line's worth of ``topics``."""
    listed = sorted(topics)
    more = len(listed) - most
    return ', '.join(listed[:most]) + (f' and {more} more topics' if more > 0 else '')


def parse_participants(text: str) -> tuple[str, ...]:
    """``'crank_drive, supervisor'`` -> ``('crank_drive', 'supervisor')``; ParameterError naming ``participants``."""
    try:
        return participant_names(text)
    except ValueError as err:
        raise ParameterError('participants', text, str(err)) from None


#: why line_clock refuses simulated time
_WALL_CLOCK = 'line_clock publishes /clock and runs on the wall clock'


def _check(values: Mapping[str, Any]) -> None:
    if values.get('use_sim_time') is True:
        raise ParameterError('use_sim_time', True, _WALL_CLOCK)
    parse_participants(values['participants'])
    rtf = values['rtf']
    if 0.0 < rtf < MIN_RTF:
        raise ParameterError('rtf', rtf, f'must be 0 (no ceiling) or in {RTF.text()}')
    if rtf == 0.0 and values['clock'] == 'wall':
        raise ParameterError('rtf', rtf, 'must be > 0 with clock=wall (the wall clock paces the ticks)')


class LineClock(Node):
    """Grants simulated time and publishes it on ``/clock`` (see the module docstring).

    Attributes
    ----------
    done : rclpy.task.Future
        Completes with the last stamp (ns) once the last tick is answered.
    lost : dict of str to float
        Participants declared lost -> the tick (s) they did not answer.
    waiting : dict of str to float
        Participants waited for now -> wall time (monotonic s) of their latest answer.
    late : dict of str to int
        Wall mode: ticks each participant answered late.
    foreign_clock : int
        ``/clock`` messages not published by this node (refused).
    partition : str or None
        The line's DDS partition (:func:`folder_line.ros.dds_profile.line_partition`); None: an open line.
    strangers : dict of str to set of str
        Nodes not of the line seen publishing on its topics -> those topics.
    ticks : int
        Ticks granted (a repeated first tick counts once).
    """

    NODE_NAME = NODE_NAME

    def __init__(self, *, parameter_overrides: Iterable[Parameter[Any]] | None = None, **kwargs: Any) -> None:
        # use_sim_time is off by default; on, from the constructor or --ros-args, it is refused
        super().__init__(NODE_NAME, parameter_overrides=list(parameter_overrides or []), **kwargs)
        try:  # a node refused here is torn down at once, in order (not left to the garbage collector)
            self._make()
        except BaseException:
            self.destroy_node()
            raise

    @classmethod
    def refuse_start(cls, given: Mapping[str, object]) -> None:
        """Refuse, before any node is made, a start this node would refuse, with its own words.

        Parameters
        ----------
        given : mapping of str to object
            The starting values the command line gives (:func:`folder_line.ros.ros_args.command_line_values`).

        Raises
        ------
        ParameterError
            What the node's start would raise first: ``use_sim_time`` true, a value its spec refuses,
            values its cross-check refuses.
        """
        if given.get('use_sim_time') is True:
            raise ParameterError('use_sim_time', True, _WALL_CLOCK)
        _check(given_values(SPECS, given))

    def _make(self) -> None:
        """Check the parameters, then make the clock's entities (after ``Node.__init__``)."""
        if self.get_parameter('use_sim_time').value:
            raise ParameterError('use_sim_time', True, _WALL_CLOCK)
        v = self.values = declare_parameters(self, SPECS, cross_check=_check)
        self._init_state(v)
        self._pub = self.create_publisher(ClockMsg, CLOCK_TOPIC, CLOCK_QOS)
        self._grant_pub = self.create_publisher(TimeReference, GRANT_TOPIC, GRANT_QOS)
        self._diag = self.create_publisher(DiagnosticArray, DIAGNOSTICS_TOPIC, LINE_QOS)
        announce = self.create_publisher(String, PARTICIPANTS_TOPIC, PARTICIPANTS_QOS)
        self.announcement = Announcement(self.mode, self._end, self.participants)
        announce.publish(String(data=format_announcement(self.announcement)))
        for name in self.participants:
            self.create_subscription(TimeReference, progress_topic(name), self._on_ack(name), ACK_QOS, raw=True)
        self.create_subscription(ClockMsg, CLOCK_TOPIC, self._on_clock, CLOCK_SUB_QOS, raw=True)
        self._pacer = self.create_timer(1.0, self._pump, clock=self._wall)
        self._pacer.cancel()
        self._watch = self.create_timer(HEARTBEAT, self._on_watch, clock=self._wall)
        self._scan = self.create_timer(STRANGER_SCAN, self._look_for_strangers, clock=self._wall)
        self._next_lateness = self._start + NS_PER_S
        self.add_post_set_parameters_callback(self._apply)
        self.signatures = guard_changes(self)  # on a keyed line, a change at run time must be signed
        self._say_start(v)
        self._publish_tick(self._start)
        self._grant()

    def _init_state(self, v: Mapping[str, Any]) -> None:
        """The clock's state from its parameter values ``v``, before its first tick."""
        self._wall = Clock(clock_type=ClockType.STEADY_TIME)
        self.mode: str = v['clock']
        self.participants = parse_participants(v['participants'])
        self._start = seconds_to_ns(v['start_time'])
        self._end = self._start + seconds_to_ns(v['duration']) if v['duration'] > 0.0 else None
        self._step: int = round(NS_PER_S / v['rate'])
        self._first: int = self._start  # the first tick of the current step
        self._window = seconds_to_ns(v['window'])
        self._rtf: float = v['rtf']
        self.current: int | None = None  # the latest tick granted, ns
        self._origin: tuple[int, float] | None = None  # (sim ns, wall s) the rtf ceiling counts from
        self._granted_at = 0.0  # wall time of the latest grant (or its repeat)
        self._advanced_at = 0.0  # wall time of the latest tick granted
        self._slot = 0.0  # earliest wall time of the next grant (GRANT_PERIOD after the due time of the last)
        self.published_clock = 0
        self.published_statuses = 0  # on /diagnostics
        self.ticks = 0
        self.grants = 0  # grants published (repeats too)
        self.lost: dict[str, float] = {}
        self.waiting: dict[str, float] = {}
        self.late: dict[str, int] = dict.fromkeys(self.participants, 0)
        self.rejected = 0
        self.foreign_clock = 0
        self._foreign_named: set[str] = set()
        self.partition = line_partition()
        self.strangers: dict[str, set[str]] = {}
        self._own_clock: deque[bytes] = deque()  # /clock messages published, not yet seen back
        self.done: Future[int] = Future()
        self.first_done_wall: float | None = None
        self._finished_wall: float | None = None
        self._ledger = TickLedger(self.participants)
        self._heard: dict[str, float] = dict.fromkeys(self.participants, time.monotonic())
        self._reported: dict[str, float] = {}

    def _say_start(self, v: Mapping[str, Any]) -> None:
        """Log what the clock does, and warn if the line is open."""
        rtf_text = 'no rtf ceiling' if self._rtf == 0.0 else f'rtf {self._rtf:g}'
        self.get_logger().info(
            f'{self.mode} /clock at {v["rate"]:g} Hz of sim time, {rtf_text}, from {v["start_time"]:g} s'
            + (f' for {v["duration"]:g} s' if self._end is not None else '')
            + f'; participants {", ".join(self.participants)}'
        )
        if self.partition is None:
            self.get_logger().warning(
                f'an open line: any node on this ROS domain can feed it; start every node of the line with '
                f'the same {KEY_VARIABLE} (and no profiles file of your own) to close it'
            )

    # ------------------------------------------------------------------ state

    @property
    def rtf_achieved(self) -> float:
        """Sim seconds per wall second from the first tick answered by all to the last (0 before)."""
        if self.first_done_wall is None or self.current is None:
            return 0.0
        wall = (self._finished_wall or time.monotonic()) - self.first_done_wall
        return (self.current - self._start) / NS_PER_S / wall if wall > 0 else 0.0

    def published_counts(self) -> dict[str, int]:
        """Messages published so far, per topic (the recorder's loss accounting)."""
        return {CLOCK_TOPIC: self.published_clock, PARTICIPANTS_TOPIC: 1, DIAGNOSTICS_TOPIC: self.published_statuses}

    # ------------------------------------------------------------------ inputs

    def _apply(self, parameters: list[Parameter[Any]]) -> None:
        for p in parameters:
            if p.name == 'rtf':
                self._rtf = p.value
                if self.current is not None and self._origin is not None:
                    self._origin = (self.current, time.monotonic())
            elif p.name == 'rate':
                self._step = round(NS_PER_S / p.value)
                if self.current is not None:
                    self._first = self.current + self._step  # the new step starts with the next tick

    def _on_ack(self, name: str) -> Callable[[bytes], None]:
        def on_ack(data: bytes) -> None:
            try:
                frame_id, stamp, counts, promise = read_ack(data)
            except ValueError:
                self.rejected += 1
                return
            if frame_id != name or self._ledger.ack(name, stamp, counts, promise) is not None:
                self.rejected += 1
                return
            self._heard_from(name)
            if self.done.done() or self.current is None:
                return
            if self.first_done_wall is None:
                if self._all_answered(self._start):
                    self._first_done()
                return
            if self.mode == 'lockstep':
                self._pump()
            elif self._end is not None and self.current >= self._end and self._all_answered(self._end):
                self._finish('duration reached')

        return on_ack

    def _heard_from(self, name: str) -> None:
        now = time.monotonic()
        if name in self.waiting:
            waited = now - self.waiting.pop(name)
            self.get_logger().info(f'participant {name} answers again after {waited:.1f} s: taken back')
            self._status(
                'resumed',
                DiagnosticStatus.OK,
                f'{name} answers again after {waited:.1f} s',
                {'node': name, 'waited_wall_s': f'{waited:.3f}'},
            )
        self._heard[name] = now

    def _on_clock(self, data: bytes) -> None:
        """Every ``/clock`` message on the domain: this node's own come back in order; any other is foreign."""
        own = self._own_clock
        if own and data == own[0]:
            own.popleft()
            return
        self.foreign_clock += 1
        others = sorted(
            f'{info.node_namespace.rstrip("/")}/{info.node_name}'
            for info in self.get_publishers_info_by_topic(CLOCK_TOPIC)
            if info.node_name != NODE_NAME or info.node_namespace != self.get_namespace()
        )
        new = [n for n in others if n not in self._foreign_named] or ([] if others else ['an unknown publisher'])
        new = [n for n in new if n not in self._foreign_named]
        if not new:
            return
        self._foreign_named.update(new)
        self.get_logger().warning(
            f'refused a foreign /clock message from {", ".join(new)}: the line takes time only from its own '
            f'line_clock, and sim time goes on ({self.foreign_clock} refused so far)'
        )
        self._status(
            'foreign_clock',
            DiagnosticStatus.WARN,
            f'foreign /clock from {", ".join(new)} refused',
            {'publishers': ', '.join(sorted(self._foreign_named)), 'refused': str(self.foreign_clock)},
            stamp=self.current or self._start,
        )

    def _look_for_strangers(self) -> None:
        """Name, once per node and topic, the publishers on the line's topics that are not the line's nodes
        (while the line runs: the recorder takes the status into the bag)."""
        if self.done.done():
            return
        found = foreign_publishers(self)
        new = {who: topics - self.strangers.get(who, set()) for who, topics in found.items()}
        new = {who: topics for who, topics in new.items() if topics}
        if not new:
            return
        for who, topics in new.items():
            self.strangers.setdefault(who, set()).update(topics)
        effect = (
            "refused: they are not in the line's partition"
            if self.partition is not None
            else f'an open line hears them: start it with {KEY_VARIABLE} to refuse them'
        )
        named = '; '.join(f'{who} on {_few(topics)}' for who, topics in sorted(new.items()))
        self.get_logger().warning(f'publishers not of the line: {named}; {effect}')
        self._status(
            'foreign_publishers',
            DiagnosticStatus.WARN,
            f'{len(self.strangers)} node(s) not of the line publish on its topics: {effect}',
            {
                'publishers': '; '.join(f'{w}: {" ".join(sorted(t))}' for w, t in sorted(self.strangers.items())),
                'partition': self.partition or 'none (open line)',
            },
            stamp=self.current or self._start,
        )

    # ------------------------------------------------------------------ granting

    def _all_answered(self, stamp: int) -> bool:
        return all(
            p in self.lost or ((a := self._ledger.last_ack(p)) is not None and a >= stamp) for p in self.participants
        )

    def _first_done(self) -> None:
        self.first_done_wall = time.monotonic()
        assert self.current is not None
        self._origin = (self.current, self.first_done_wall)
        self.get_logger().info('every participant answered the first tick: sim time runs')
        self._pump()

    def _next_stamp(self) -> int | None:
        assert self.current is not None
        if self._end is not None and self.current >= self._end:
            return None
        nxt = self.current + self._step
        if self._end is not None:
            nxt = min(nxt, self._end)
        return min(nxt, TIME_MSG_MAX_NS)

    def _limit(self) -> int:
        """Lockstep: the last tick the window allows (one tick past the slowest answer at least)."""
        assert self.current is not None
        acks = [self._ledger.last_ack(p) for p in self.participants if p not in self.lost]
        if not acks:
            return TIME_MSG_MAX_NS
        if any(a is None for a in acks):
            return self.current
        slowest = min(a for a in acks if a is not None)
        return max(slowest + self._window, slowest + self._step if slowest >= self.current else slowest)

    def _due(self, stamp: int) -> float:
        """Wall time (monotonic s) at which ``stamp`` may be granted (the rtf ceiling)."""
        if self._rtf == 0.0 or self._origin is None:
            return 0.0
        sim0, wall0 = self._origin
        return wall0 + (stamp - sim0) / NS_PER_S / self._rtf

    def _pump(self) -> None:
        """Grant every tick that is due and that the window allows, at most once per :data:`GRANT_PERIOD`;
        then wait for the next due time, or finish once the last tick is answered."""
        self._pacer.cancel()
        if self.done.done() or self.current is None or self.first_done_wall is None:
            return
        now = time.monotonic()
        limit = self._limit() if self.mode == 'lockstep' else TIME_MSG_MAX_NS
        nxt = self._next_stamp()
        if nxt is not None and nxt <= limit:
            start = max(self._due(nxt), self._slot)
            if start > now:
                self._wake_at(start, now)
            else:
                self._grant_due(nxt, limit, start, now)
        if self._at_end(now):
            self._finish('duration reached')

    def _grant_due(self, nxt: int, limit: int, start: float, now: float) -> None:
        """Grant the ticks from ``nxt`` that are due by ``now`` and within ``limit``, in one grant."""
        if self.mode == 'lockstep' and now - self._due(nxt) > MAX_BURST:
            # late (a stall): the ceiling counts afresh, with at most MAX_BURST to catch up
            self._origin = (nxt, now - MAX_BURST)
        stamp: int | None = nxt
        while stamp is not None and stamp <= limit and self._due(stamp) <= now:
            if self.mode == 'wall':
                self._count_late()
            self._publish_tick(stamp)
            stamp = self._next_stamp()
        self._grant()
        # the next grant's earliest time counts from this one's due time, not from when the executor ran it:
        # a late wake-up does not push every later grant back
        self._slot = max(start, now - GRANT_PERIOD) + GRANT_PERIOD
        if stamp is not None and stamp <= limit:
            self._wake_at(max(self._due(stamp), self._slot), now)

    def _wake_at(self, when: float, now: float) -> None:
        self._pacer.timer_period_ns = max(int((when - now) * NS_PER_S), 1)
        self._pacer.reset()

    def _at_end(self, now: float) -> bool:
        """The last tick is granted and answered (wall mode: or unanswered for ``lost_timeout``)."""
        assert self.current is not None
        if self._end is None or self.current < self._end:
            return False
        return self._all_answered(self._end) or (
            self.mode == 'wall' and now - self._advanced_at > self.values['lost_timeout']
        )

    def _count_late(self) -> None:
        assert self.current is not None
        for p in self.participants:
            a = self._ledger.last_ack(p)
            if p not in self.lost and (a is None or a < self.current):
                self.late[p] += 1

    def _publish_tick(self, stamp: int) -> None:
        self.current = stamp
        self._advanced_at = time.monotonic()
        msg = ClockMsg(clock=ns_to_time_msg(stamp))
        self._pub.publish(msg)
        self._own_clock.append(serialize_message(msg))
        while len(self._own_clock) > PUBLISH_DEPTH:  # never seen back (no matching subscription): forget
            self._own_clock.popleft()
        self.published_clock += 1
        self.ticks += 1
        if self.mode == 'wall' and stamp >= self._next_lateness:
            self._next_lateness = stamp + NS_PER_S
            self._report_lateness(stamp)

    def _grant(self) -> None:
        assert self.current is not None
        first = self._first if self._first <= self.current else self.current
        self._grant_pub.publish(format_grant(self.current, first, self._step))
        self.grants += 1
        self._granted_at = time.monotonic()

    def _on_watch(self) -> None:
        """Repeat the latest grant when nothing was granted for a while (the first tick until everyone
        answered it); name the participants waited for; declare lost the silent ones that left the graph."""
        if self.current is None or self.done.done():
            return
        now = time.monotonic()
        first = self.first_done_wall is None
        if now - self._granted_at >= (REPEAT_FIRST if first else HEARTBEAT):
            self._grant()
        if not first and self.mode == 'lockstep' and not self._pacer.is_canceled():
            return  # pacing: nobody is waited for
        for p in self.participants:
            if p not in self.lost and not self._answered_latest(p):
                self._judge(p, now, first)
        if not first:
            self._pump()
        elif self._all_answered(self._start):
            self._first_done()

    def _answered_latest(self, p: str) -> bool:
        a = self._ledger.last_ack(p)
        return a is not None and self.current is not None and a >= self.current

    def _judge(self, p: str, now: float, first: bool) -> None:
        limit = self.values['startup_timeout'] if first else self.values['lost_timeout']
        silent = now - self._heard[p]
        if silent <= limit:
            return
        present = self.count_publishers(progress_topic(p)) > 0
        if first or not present:
            self._lose(p, silent, limit, 'no answer to the first tick' if first else 'gone from the graph')
            return
        self.waiting.setdefault(p, self._heard[p])
        if now - self._reported.get(p, -math.inf) < WAIT_REPORT:
            return
        self._reported[p] = now
        assert self.current is not None
        self.get_logger().warning(
            f'waiting for {p}: silent for {silent:.1f} s of wall time, still in the graph (slow or cut off, not lost)'
        )
        self._status(
            'waiting',
            DiagnosticStatus.WARN,
            f'waiting for {p}: silent for {silent:.1f} s',
            {'node': p, 'silent_wall_s': f'{silent:.3f}', 'tick': repr(self.current / NS_PER_S)},
            stamp=self.current,
        )

    def _lose(self, p: str, waited: float, limit: float, why: str) -> None:
        assert self.current is not None
        a = self._ledger.last_ack(p)
        tick = self._start if a is None else min(self.current, a + self._step)
        self.lost[p] = tick / NS_PER_S
        self.waiting.pop(p, None)
        self._ledger.lose(p)
        self.get_logger().error(
            f'participant {p} lost: no answer to tick {tick / NS_PER_S:.9f} s in '
            f'{waited:.1f} s of wall time (limit {limit:g} s; {why})'
        )
        self._status(
            'lost',
            DiagnosticStatus.ERROR,
            f'participant {p} lost at {tick / NS_PER_S:.9f} s',
            {'node': p, 'tick': repr(tick / NS_PER_S), 'waited_wall_s': f'{waited:.3f}', 'limit_s': repr(limit)},
            stamp=self.current,
        )

    def _report_lateness(self, stamp: int) -> None:
        worst = max(self.late.values(), default=0)
        level = DiagnosticStatus.WARN if worst else DiagnosticStatus.OK
        text = ', '.join(f'{p} {n}' for p, n in self.late.items() if n) or 'none'
        self._status('lateness', level, f'late ticks: {text}', {p: str(n) for p, n in self.late.items()}, stamp=stamp)

    def _status(
        self, what: str, level: bytes, message: str, values: Mapping[str, str], stamp: int | None = None
    ) -> None:
        arr = DiagnosticArray()
        arr.header.stamp = ns_to_time_msg(self._start if stamp is None else stamp)
        arr.header.frame_id = NODE_NAME
        st = DiagnosticStatus(
            name=f'folder_line/line_clock/{what}', hardware_id=NODE_NAME, level=level, message=message
        )
        st.values = [KeyValue(key=k, value=v) for k, v in values.items()]
        arr.status.append(st)
        self._diag.publish(arr)
        self.published_statuses += 1

    def _finish(self, why: str) -> None:
        self._pacer.cancel()
        if self.done.done():
            return
        self._finished_wall = time.monotonic()
        assert self.current is not None
        if self.mode == 'wall':
            self._report_lateness(self.current)
        seconds, nanoseconds = divmod(self.current, NS_PER_S)
        lost = f'; lost: {", ".join(self.lost)}' if self.lost else ''
        self.get_logger().info(
            f'stopped at sim time {seconds}.{nanoseconds:09d} s: {why} '
            f'({self.ticks} ticks, rtf {self.rtf_achieved:.2f}){lost}'
        )
        self.done.set_result(self.current)


def main(args: list[str] | None = None) -> int:
    """Run ``line_clock`` until Ctrl-C or the end of ``duration``; exit 0, 2 on a bad parameter, 3 if a
    participant was lost."""
    return run_node(LineClock, args, exit_code=lambda node: EXIT_LOST if getattr(node, 'lost', None) else 0)


if __name__ == '__main__':
    sys.exit(main())
