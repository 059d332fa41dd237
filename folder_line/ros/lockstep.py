"""The lockstep protocol of the live line, on standard messages.

``line_clock`` owns simulated time. It *grants* time to the participants on
``/line/grant`` and publishes every tick it grants on ``/clock`` for everyone else.
A participant runs the ticks granted to it, each once its inputs allow, and
says how far it got on ``/line/<node>/progress``. In ``lockstep`` mode (the default)
the clock grants ticks up to ``window`` s of sim time ahead of the slowest
participant's latest acknowledgement, and never faster than ``rtf``: when the
machine or the network cannot keep up, sim time slows down instead of dropping a
tick. In ``wall`` mode (hardware in the loop) it grants by the wall clock and counts
late participants instead. The protocol and its safety argument are in docs/lockstep.md
("The protocol: lookahead, not a barrier per tick").

The messages (what each topic carries, as text on standard messages) are in
:mod:`folder_line.ros.lockstep_messages`.

A participant that stops answering is first *waited for*: after ``lost_timeout`` s
of wall time whoever waits for it names it, and how long, at a bounded rate, and
takes it back when it answers. It is declared *lost* only once its DDS participant
has left the graph too (its process ended, or its lease ran out: killed, crashed,
stopped, or cut off for longer than the lease). A participant that waits repeats
its latest acknowledgement every ``HEARTBEAT`` s, so only the silent one is waited
for, not those held up by it. One that answers but whose counted messages never
arrive is declared lost after ``MISSING_FACTOR`` times the limit, naming what is
missing: a tick is never waited for for ever.
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable, Mapping
from typing import TypeVar

from rclpy.clock import Clock, ROSClock
from rclpy.clock_type import ClockType
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.time import Time
from rclpy.time_source import TimeSource
from rclpy.type_support import Msg
from sensor_msgs.msg import TimeReference
from std_msgs.msg import String

from folder_line.core.supervision.lockstep import TickLedger, format_counts, format_ticks
from folder_line.interfaces import (
    GRANT_TOPIC,
    KNOWN_PARTICIPANTS,
    MACHINE_NODES,
    NS_PER_S,
    PARTICIPANTS_TOPIC,
    RECORDER,
    progress_topic,
    tick_done_topic,
)
from folder_line.ros.lockstep_messages import (
    Announcement,
    grant_ticks,
    parse_announcement,
    read_ack,
    read_ticks,
    sign_ack,
)
from folder_line.ros.time_msg import ns_to_time_msg, time_msg_to_ns
from folder_line.ros.topics import PUBLISH_DEPTH

__all__ = [
    'ACK_QOS',
    'DEFAULT_PARTICIPANTS',
    'GRANT_QOS',
    'HEARTBEAT',
    'LINE_QOS',
    'PARTICIPANTS_QOS',
    'TICK_QOS',
    'WAIT_REPORT',
    'Participant',
]

#: a message type, as rclpy's ``Publisher`` takes it
_M = TypeVar('_M', bound=Msg)

HEARTBEAT = 0.05  # wall s: a participant that waits repeats its latest acknowledgement this often
#: a participant that runs ticks one after another says how far it got at least every this many ticks
PROGRESS_EVERY = 10
#: wall s between two reports of the same wait (a participant waited for, a silent clock)
WAIT_REPORT = 5.0
#: a producer that acknowledged a tick whose counted messages have not all arrived after this many times the
#: lost limit is lost too: a reliable writer repairs a dropped sample at its next heartbeat (the line's Fast
#: DDS profile: tens of ms), so this is far longer than any repair, yet a consumer never waits for ever
MISSING_FACTOR = 3.0

#: what ``line_clock`` waits for when started by hand with no ``participants``
DEFAULT_PARTICIPANTS: tuple[str, ...] = MACHINE_NODES

LINE_QOS = QoSProfile(
    depth=PUBLISH_DEPTH,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
    history=HistoryPolicy.KEEP_LAST,
)
"""QoS of every data publisher and subscription of the line: reliable, transient-local, 1000 deep."""
TICK_QOS = LINE_QOS
"""QoS of the acknowledgements of every tick (``tick_done``; the recorder needs every one, in order)."""
ACK_QOS = QoSProfile(
    depth=10,
    reliability=ReliabilityPolicy.BEST_EFFORT,
    durability=DurabilityPolicy.VOLATILE,
    history=HistoryPolicy.KEEP_LAST,
)
"""QoS of ``progress``, the latest acknowledgement (the clock and the nodes read it): cumulative, so
best-effort (a repeat stands in for a lost one at once, where a reliable reader would hold it back until the
repair)."""
GRANT_QOS = LINE_QOS
"""QoS of the grants: reliable and in order (a grant adds the ticks after the previous one)."""
PARTICIPANTS_QOS = QoSProfile(
    depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
)
CLOCK_SUB_QOS = QoSProfile(depth=PUBLISH_DEPTH, reliability=ReliabilityPolicy.RELIABLE)


Depends = Callable[[Announcement], Mapping[str, tuple[str, ...]]]
"""A participant's dependencies once the participants are known: producer -> counted streams."""
Needs = Callable[[int, 'int | None'], 'tuple[int, int | None] | None']
"""``needs(stamp, previous) -> (stamp_need, promise_need)``: the tick may run once every producer's ticks up to
``stamp_need`` are complete, or a complete tick of it promises ``promise_need`` (None: no condition)."""


class Participant:
    """The lockstep protocol of one participant node (composed into the node).

    Parameters
    ----------
    node : rclpy.node.Node
        The participant (its name is the participant's name).
    depends : callable
        Announcement -> the producers it waits for, with the streams it counts from each.
    on_tick : callable
        ``on_tick(stamp_ns)``: publish everything of that tick (through :meth:`publish`).
    needs : callable, optional
        :data:`Needs` (default: the producers' previous tick complete).
    promise : callable, optional
        ``promise(stamp_ns) -> ns``: the promise acknowledged with a tick (default: the tick).
    on_lost : callable, optional
        ``on_lost(producer, waited_s, stamp_ns)`` when a producer is declared lost.
    on_reject : callable, optional
        ``on_reject(kind, reason)`` for a malformed, foreign or out-of-order input.
    on_end : callable, optional
        ``on_end(stamp_ns)`` once the announced last tick is done (after its acknowledgement).
    on_ack : callable, optional
        ``on_ack(producer, stamp_ns, counts)`` for every acknowledgement taken (the recorder places messages).
    lost_timeout, startup_timeout : float
        Wall seconds a tick may wait for a producer before it is reported (the first tick: declared lost).
    every_tick : bool
        Read the producers' acknowledgements of every tick (``tick_done``, reliable; the recorder) instead
        of their ``progress`` (best-effort).
    prompt : bool
        Say how far it got (``progress``) whenever it stops to wait, not only every :data:`PROGRESS_EVERY`
        ticks and on the heartbeat: for a participant whose ticks others wait for (not the recorder).
    """

    def __init__(
        self,
        node: Node,
        depends: Depends,
        on_tick: Callable[[int], None],
        *,
        needs: Needs | None = None,
        promise: Callable[[int], int] | None = None,
        on_lost: Callable[[str, float, int], None] | None = None,
        on_reject: Callable[[str, str], None] | None = None,
        on_end: Callable[[int], None] | None = None,
        on_ack: Callable[[str, int, Mapping[str, int]], None] | None = None,
        lost_timeout: float = 3.0,
        startup_timeout: float = 60.0,
        every_tick: bool = False,
        prompt: bool = True,
    ) -> None:
        self.node = node
        self.name = node.get_name()
        self._depends = depends
        self._on_tick = on_tick
        self._needs: Needs = needs or (lambda stamp, previous: None if previous is None else (previous, None))
        self._promise = promise or (lambda stamp: stamp)
        self._on_lost = on_lost
        self._on_reject = on_reject
        self._on_end = on_end
        self._on_ack_taken = on_ack
        self._every_tick = every_tick
        self._prompt = prompt
        self.lost_timeout = lost_timeout
        self.startup_timeout = startup_timeout
        self.announcement: Announcement | None = None
        self.ledger: TickLedger | None = None
        self.counts: dict[str, int] = {'messages': 0, 'events': 0, 'commands': 0}
        self._topics: dict[int, str] = {}  # id(publisher) -> its topic, counted per topic too
        self.pending: deque[int] = deque()
        self.granted: int | None = None  # the latest tick granted, ns
        self.last_done: int | None = None
        self.ticks = 0
        self.ended = False
        self.clock_silent = 0.0  # wall s the clock has been silent, once reported (0: it speaks)
        self.lost: list[str] = []  # the producers declared lost
        self._waiting_since: float | None = None
        self._clock_heard = time.monotonic()
        self._reported: dict[str, float] = {}  # producer (or the clock) -> wall time of its latest wait report
        # counted before the announcement (discovery between processes orders nothing): applied to the ledger
        self._early: dict[tuple[str, str], int] = {}
        self._heard: dict[str, float] = {}  # producer -> wall time of its latest acknowledgement (a repeat too)
        self._last_ack: TimeReference | None = None
        self._acked_at = 0.0  # wall time (monotonic) the latest progress was sent or repeated
        self._unsaid = 0  # ticks done since the latest progress
        self._ticks: list[tuple[int, dict[str, int]]] = []  # ticks done since the latest tick_done: (stamp, counts)
        self.acknowledged = 0  # tick_done messages published
        self.said = 0  # progress messages published (repeats too)
        self._tick_pub = node.create_publisher(TimeReference, tick_done_topic(self.name), TICK_QOS)
        self._per_tick = False  # the recorder takes part: it reads every tick's acknowledgement
        self._ack_pub = node.create_publisher(TimeReference, progress_topic(self.name), ACK_QOS)
        # a deep queue (compatible with the depth-1 publisher): a malformed or foreign announcement arriving
        # right after line_clock's must not push it out of the queue before it is taken
        node.create_subscription(String, PARTICIPANTS_TOPIC, self._on_announcement, LINE_QOS)
        node.create_subscription(TimeReference, GRANT_TOPIC, self.on_grant, GRANT_QOS)
        # the node's sim clock (use_sim_time) is fed with the ticks it runs, never from /clock: rclpy's
        # TimeSource would take every /clock message, a foreign one too, through a subscription of its own
        self._sim_clock = _stop_time_source(node)
        self._timer = node.create_timer(HEARTBEAT, self._check_lost, clock=_steady(node))

    # ------------------------------------------------------------------ publishing

    def publish(self, publisher: Publisher[_M], msg: _M, stream: str | None = None) -> None:
        """Publish ``msg`` and count it (``messages``, its topic, and ``stream`` if given)."""
        publisher.publish(msg)
        counts = self.counts
        counts['messages'] += 1
        topic = self._topics.get(id(publisher))
        if topic is None:
            topic = self._topics[id(publisher)] = publisher.topic_name
            counts[topic] = 0
        counts[topic] += 1
        if stream is not None:
            counts[stream] += 1

    def received(self, producer: str, stream: str, n: int = 1) -> None:
        """Count a message of ``stream`` from ``producer`` (a no-op if not waited for), then advance.

        Before the announcement the count is kept (for known participants only) and given to the ledger
        when it is built: a producer's first messages may arrive before ``line_clock``'s announcement.
        """
        if self.ledger is None:
            if producer in KNOWN_PARTICIPANTS:
                self._early[producer, stream] = self._early.get((producer, stream), 0) + n
            return
        if self.ledger.received(producer, stream, n) and self.pending:
            self.advance()

    # ------------------------------------------------------------------ inputs

    def _reject(self, kind: str, reason: str) -> None:
        if self._on_reject is not None:
            self._on_reject(kind, reason)

    def _on_announcement(self, msg: String) -> None:
        try:
            a = parse_announcement(msg.data)
        except ValueError as err:
            self._reject('announcement', str(err))
            return
        if self.announcement is not None:
            if a != self.announcement:
                self._reject('announcement', 'a second, different announcement (another line_clock?)')
            return
        if self.name not in a.participants:
            self.node.get_logger().warning(
                f'{self.name} is not among the participants {",".join(a.participants)}: line_clock will not wait for it'
            )
        self.announcement = a
        self._per_tick = RECORDER in a.participants and self.name != RECORDER  # the recorder reads them
        deps = {p: s for p, s in self._depends(a).items() if p in a.participants and p != self.name}
        self.ledger = TickLedger(deps, {s for streams in deps.values() for s in streams})
        self._heard = dict.fromkeys(deps, time.monotonic())
        for (producer, stream), n in self._early.items():
            self.ledger.received(producer, stream, n)
        self._early.clear()
        topic, qos = (tick_done_topic, TICK_QOS) if self._every_tick else (progress_topic, ACK_QOS)
        for producer in deps:
            self.node.create_subscription(TimeReference, topic(producer), self._on_ack(producer), qos, raw=True)
        self.advance()

    def _on_ack(self, producer: str) -> Callable[[bytes], None]:
        def on_ack(data: bytes) -> None:
            try:
                if self._every_tick:
                    frame_id, ticks, promise = read_ticks(data)
                else:
                    frame_id, stamp, counts, promise = read_ack(data)
                    ticks = [(stamp, counts)]
            except ValueError as err:
                self._reject('tick_done', str(err))
                return
            if frame_id != producer:
                self._reject('tick_done', f"frame_id {frame_id[:40]!r} on {producer}'s topic")
                return
            assert self.ledger is not None
            last = ticks[-1][0]
            for stamp, counts in ticks:
                known = self.ledger.last_ack(producer)
                refused = self.ledger.ack(producer, stamp, counts, promise if stamp == last else stamp)
                if refused is not None:
                    self._reject('tick_done', refused)
                    return
                if self._on_ack_taken is not None and stamp != known:  # a repeat changes nothing
                    self._on_ack_taken(producer, stamp, counts)
            self._answered(producer)
            if self.pending:
                self.advance()

        return on_ack

    def _answered(self, producer: str) -> None:
        now = time.monotonic()
        if producer in self._reported:
            waited = now - self._heard.get(producer, now)
            del self._reported[producer]
            self.node.get_logger().info(f'participant {producer} answers again after {waited:.1f} s: taken back')
        self._heard[producer] = now

    def on_grant(self, msg: TimeReference) -> None:
        """A grant of ``line_clock`` (:data:`GRANT_TOPIC`): queue the ticks it adds."""
        try:
            ticks = grant_ticks(msg, self.granted)
        except ValueError as err:
            self._reject('grant', str(err))
            return
        now = time.monotonic()
        if self.clock_silent:
            self.node.get_logger().info(f'line_clock speaks again after {now - self._clock_heard:.1f} s')
            self.clock_silent = 0.0
        self._clock_heard = now
        if not ticks:
            last = time_msg_to_ns(msg.header.stamp)
            if last == self.last_done:
                self._say()  # the first tick is granted again until everyone answered it
            return
        self.granted = ticks[-1]
        self.pending.extend(ticks)
        if self._waiting_since is None:
            self._waiting_since = now
        self.advance()

    # ------------------------------------------------------------------ ticks

    def required(self, stamp: int) -> tuple[int, int | None] | None:
        """What tick ``stamp`` needs of the producers (:data:`Needs`)."""
        return self._needs(stamp, self.last_done)

    def advance(self) -> None:
        """Run every pending tick whose inputs are complete, in order."""
        ledger = self.ledger
        if ledger is None or self.ended:
            return
        pending = self.pending
        while pending:
            stamp = pending[0]
            need = self._needs(stamp, self.last_done)
            if need is not None and not ledger.ready(*need):
                break
            pending.popleft()
            self._on_tick(stamp)
            self.last_done = stamp
            self.ticks += 1
            self._ack(stamp)
            self._waiting_since = time.monotonic() if pending else None
            a = self.announcement
            if a is not None and a.end_ns is not None and stamp >= a.end_ns:
                self.ended = True
                pending.clear()
                self._say()
                if self._on_end is not None:
                    self._on_end(stamp)
                return
        if self._sim_clock is not None and self._unsaid:  # the node's sim clock: the latest tick it ran
            assert self.last_done is not None
            self._sim_clock.set_ros_time_override(Time(nanoseconds=self.last_done, clock_type=ClockType.ROS_TIME))
        if self._unsaid and self._prompt:
            self._say()  # waiting now: say how far it got

    def working(self, stamp: int) -> None:
        """Say that this participant is alive while it works at length on tick ``stamp`` (a node that joins
        a line far into it fast-forwards there first): at most every ``HEARTBEAT`` s, it repeats its latest
        acknowledgement, or, before its first, acknowledges the instant before the tick (nothing published).
        Whoever waits for it takes that for alive and waiting, not for the tick done."""
        now = time.monotonic()
        if now - self._acked_at < HEARTBEAT:
            return
        if self._last_ack is None:
            if stamp > 0:  # a line that starts at 0 has no instant before it (and nothing to fast-forward)
                self._ack(stamp - 1)
                self._say()
        else:
            self._say()

    def _ack(self, stamp: int) -> None:
        """Acknowledge tick ``stamp``: on ``progress`` every :data:`PROGRESS_EVERY` ticks (and when the
        participant waits, :meth:`advance`); on ``tick_done``, if the recorder takes part, with the ticks
        since the previous one (:meth:`_say`)."""
        # one message object, refilled: publishing serializes it at once, and the heartbeat repeats the latest
        ack = self._last_ack
        if ack is None:
            ack = TimeReference()
            ack.header.frame_id = self.name
        ack.header.stamp = ns_to_time_msg(stamp)
        ack.time_ref = ns_to_time_msg(max(stamp, self._promise(stamp)))
        ack.source = format_counts(self.counts)
        sign_ack(ack, 'progress')
        if self._per_tick:
            self._ticks.append((stamp, dict(self.counts)))
        self._last_ack = ack
        self._unsaid += 1
        if self._unsaid >= PROGRESS_EVERY:
            self._say()

    def _say(self) -> None:
        """Publish the ticks acknowledged since the previous call on ``tick_done`` (if the recorder takes
        part), then the latest acknowledgement on ``progress``."""
        if self._ticks:
            ack = self._last_ack
            assert ack is not None
            batch = TimeReference()
            batch.header.frame_id = self.name
            batch.header.stamp = ack.header.stamp
            batch.time_ref = ack.time_ref
            batch.source = format_ticks(self._ticks)
            sign_ack(batch, 'tick_done')
            self._ticks.clear()
            self._tick_pub.publish(batch)
            self.acknowledged += 1
        if self._last_ack is not None:
            self._ack_pub.publish(self._last_ack)
            self.said += 1
            self._unsaid = 0
            self._acked_at = time.monotonic()

    def _check_lost(self) -> None:
        """Every ``HEARTBEAT``: repeat the latest acknowledgement if nothing was sent since (alive, waiting;
        an ended participant too, until it is destroyed: its last one may have been lost); report the
        producers waited for and a silent clock; declare lost a silent producer that left the graph."""
        now = time.monotonic()
        if self._last_ack is not None and now - self._acked_at >= HEARTBEAT:
            self._say()
        elif self._last_ack is None and self.pending and self.pending[0] > 0 and now - self._acked_at >= HEARTBEAT:
            # waiting for a producer before the first tick is done (the producers of a line joined far into
            # it fast-forward first, at length): alive, at the instant before the tick, as working() says.
            # A line that starts at 0 has no instant before it, and its producers start at once.
            self._ack(self.pending[0] - 1)
            self._say()
        if self.ledger is None or self.ended:
            return
        # the clock first, pending ticks or not: a clock killed mid-grant leaves the ticks it granted to some
        # participants pending for ever at those that wait for the others (the supervisor), whose producers are
        # alive and waiting for the next grant themselves
        self._check_clock(now)
        if not self.pending:
            return
        if self._waiting_since is None:
            return
        waited = now - self._waiting_since
        limit = self.startup_timeout if self.last_done is None else self.lost_timeout
        if waited <= limit:
            return
        need = self.required(self.pending[0])
        if need is not None:
            for producer in self.ledger.waiting_for(*need):
                self._judge(producer, now, waited, limit, need[0])
        self.advance()

    def _check_clock(self, now: float) -> None:
        """A clock silent for ``lost_timeout`` is named, every :data:`WAIT_REPORT` s (a live clock repeats its
        latest grant while it grants nothing new, so silence means it is gone or cut off)."""
        silent = now - self._clock_heard
        if self.last_done is None or silent <= self.lost_timeout:
            return
        if now - self._reported.get('line_clock', -math.inf) < WAIT_REPORT:
            return
        self._reported['line_clock'] = now
        gone = self.node.count_publishers(GRANT_TOPIC) == 0
        self.clock_silent = silent
        self.node.get_logger().error(
            f'line_clock silent for {silent:.1f} s of wall time after tick {self.last_done / NS_PER_S:.9f} s'
            + (' and gone from the graph' if gone else '')
            + ': waiting for its next grant'
        )

    def _judge(self, producer: str, now: float, waited: float, limit: float, need: int) -> None:
        """``producer`` holds up a tick for longer than ``limit``: lost if it left the graph (or its counted
        messages never come); else waited for, and said so every :data:`WAIT_REPORT` s."""
        assert self.ledger is not None
        silent = now - self._heard.get(producer, -math.inf)
        present = self.node.count_publishers(progress_topic(producer)) > 0
        why = ''
        if silent > limit and not present:
            why = f'silent for {silent:.1f} s (limit {limit:g} s) and gone from the graph'
        elif silent <= limit:
            acked = self.ledger.last_ack(producer)
            missing = self.ledger.missing(producer)
            if acked is not None and acked >= need and missing and waited > MISSING_FACTOR * limit:
                shortfall = ', '.join(f'{n} {stream}' for stream, n in sorted(missing.items()))
                why = f'acknowledged, but {shortfall} it counted never arrived within {MISSING_FACTOR:g} x {limit:g} s'
        elif self.last_done is None and waited > self.startup_timeout:
            why = f'no answer to the first tick in {waited:.1f} s (startup_timeout {self.startup_timeout:g} s)'
        if why:
            self.ledger.lose(producer)
            self.lost.append(producer)
            self._reported.pop(producer, None)
            self.node.get_logger().error(
                f'participant {producer} lost: tick {need / NS_PER_S:.9f} s not complete after {waited:.1f} s of '
                f'wall time ({why}); going on without it'
            )
            if self._on_lost is not None:
                self._on_lost(producer, waited, need)
            return
        if silent > limit and now - self._reported.get(producer, -math.inf) >= WAIT_REPORT:
            self._reported[producer] = now
            self.node.get_logger().warning(
                f'waiting for {producer}: silent for {silent:.1f} s of wall time, still in the graph '
                f'(slow or cut off, not lost); tick {need / NS_PER_S:.9f} s waits'
            )

    def destroy(self) -> None:
        """Cancel the wall timer (the node destroys its entities)."""
        self._timer.cancel()


def _stop_time_source(node: Node) -> ROSClock | None:
    """The clock of ``node`` if it runs on sim time, after destroying the ``/clock`` subscription of the
    node's own ``TimeSource`` (found by its callback); None if it runs on the system clock."""
    clock = node.get_clock()
    if not (isinstance(clock, ROSClock) and clock.ros_time_is_active):
        return None
    for subscription in list(node.subscriptions):
        if isinstance(getattr(subscription.callback, '__self__', None), TimeSource):
            node.destroy_subscription(subscription)
    return clock


def _steady(node: Node) -> Clock:
    return Clock(clock_type=ClockType.STEADY_TIME)
