"""The lockstep protocol of the live line, on standard messages.

``line_clock`` owns simulated time and publishes it tick by tick on ``/clock``
(``rosgraph_msgs/Clock``). In ``lockstep`` mode (the default) it publishes tick
``k + 1`` only once every *participant* has finished tick ``k``; when the machine
cannot keep up, simulated time slows down instead of dropping a tick (Gazebo's
lockstep, CARLA's synchronous mode). In ``wall`` mode (hardware in the loop) it
paces ticks by the wall clock and counts the late participants instead.

Topics
------
``/line/participants`` (``std_msgs/String``, reliable, transient-local)
    Published once by ``line_clock`` before its first tick:
    ``'clock=lockstep end=<ns or none> participants=crank_drive,...,line_recorder'``
    (:func:`format_announcement`). Every participant waits for it, so the set of
    participants has one source: ``line_clock``'s ``participants`` parameter.
``/line/<node>/tick_done`` (``sensor_msgs/TimeReference``)
    A participant's acknowledgement of a tick, published after all that tick's
    messages: ``header.stamp`` = ``time_ref`` = the tick, ``header.frame_id`` = the
    participant, ``source`` = its cumulative published counts
    (:func:`folder_line.core.supervision.lockstep.format_counts`). Consumers that must not act on
    missing input (the supervisor, the machine nodes for the supervisor's commands,
    the recorder) count what they received from each producer and wait until the
    counts reach the acknowledged ones (:class:`folder_line.core.supervision.lockstep.TickLedger`).
    Acknowledgements are taken raw and decoded by ``rosbags``' CDR deserializer
    (:func:`read_ack`), three times cheaper than rclpy's message conversion; a tick
    has about twenty of them.

Data publishers of the line are reliable and transient-local with a deep history,
so a subscriber that matches late (discovery between processes takes up to seconds)
still gets every message of the first ticks.

A participant that stops answering (killed, crashed, SIGSTOP) is declared *lost*
after ``lost_timeout`` s of wall time (``startup_timeout`` for the first tick) by
whoever waits for it; it is named in the log and in ``/diagnostics``, and the
others go on without it. A participant that is only slow is waited for. One that
waits, for the clock's next tick or for another participant, repeats its latest
acknowledgement every ``HEARTBEAT`` s (before its first, it acknowledges the instant
before the tick it waits on), so that only the silent one is declared lost, not those
held up by it; so does one that works at length on a tick (a node that
joins the line far into it and fast-forwards there: before its first acknowledgement
it acknowledges the instant before the tick, :meth:`Participant.working`). One that
answers but whose counted messages never arrive (a consumer that does not count
what the producer counts, a broken link) is declared lost too, after
``MISSING_FACTOR`` times the limit, naming what is missing: a tick is never waited
for for ever.
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from rclpy.clock import Clock
from rclpy.clock_type import ClockType
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosbags.typesys import Stores, get_typestore
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import TimeReference
from std_msgs.msg import String

from folder_line.core.supervision.lockstep import TickLedger, format_counts, parse_counts
from folder_line.interfaces import (
    CLOCK_TOPIC,
    KNOWN_PARTICIPANTS,
    MACHINE_NODES,
    NS_PER_S,
    PARTICIPANTS_TOPIC,
    tick_done_topic,
)
from folder_line.ros.time_msg import ns_to_time_msg, time_msg_to_ns
from folder_line.ros.topics import PUBLISH_DEPTH

__all__ = [
    'CLOCK_MODES',
    'DEFAULT_PARTICIPANTS',
    'LINE_QOS',
    'PARTICIPANTS_QOS',
    'TICK_QOS',
    'Announcement',
    'Participant',
    'format_announcement',
    'parse_announcement',
    'participant_names',
    'read_ack',
]

HEARTBEAT = 0.1  # wall s: a participant that waits repeats its latest acknowledgement this often
#: a producer that acknowledged a tick whose counted messages have not all arrived after this many times the
#: lost limit is lost too: a reliable writer repairs a dropped sample at its next heartbeat (Fast DDS: up to
#: ~3 s), so this is far longer than any repair, yet a consumer never waits for ever on messages that never come
MISSING_FACTOR = 3.0

#: what ``line_clock`` waits for when started by hand with no ``participants``
DEFAULT_PARTICIPANTS: tuple[str, ...] = MACHINE_NODES
CLOCK_MODES: tuple[str, ...] = ('lockstep', 'wall')

LINE_QOS = QoSProfile(
    depth=PUBLISH_DEPTH,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
    history=HistoryPolicy.KEEP_LAST,
)
"""QoS of every data publisher and subscription of the line: reliable, transient-local, 1000 deep."""
TICK_QOS = LINE_QOS
PARTICIPANTS_QOS = QoSProfile(
    depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
)
CLOCK_SUB_QOS = QoSProfile(depth=PUBLISH_DEPTH, reliability=ReliabilityPolicy.RELIABLE)


@dataclass(frozen=True)
class Announcement:
    """What ``line_clock`` announces on :data:`PARTICIPANTS_TOPIC`."""

    clock: str
    end_ns: int | None
    participants: tuple[str, ...]


def format_announcement(a: Announcement) -> str:
    """``'clock=lockstep end=20000000000 participants=crank_drive,supervisor'``."""
    end = 'none' if a.end_ns is None else str(a.end_ns)
    return f'clock={a.clock} end={end} participants={",".join(a.participants)}'


def parse_announcement(text: str) -> Announcement:
    """Inverse of :func:`format_announcement`; ``ValueError`` with the reason on anything else."""
    if len(text) > 1000:
        raise ValueError(f'announcement of {len(text)} characters (at most 1000)')
    fields = dict(item.partition('=')[::2] for item in text.split())
    if set(fields) != {'clock', 'end', 'participants'}:
        raise ValueError(f'announcement {text[:80]!r}: needs exactly clock=, end= and participants=')
    if fields['clock'] not in CLOCK_MODES:
        raise ValueError(f'clock={fields["clock"][:20]!r}: must be one of {", ".join(CLOCK_MODES)}')
    end = None if fields['end'] == 'none' else fields['end']
    if end is not None and not (end.isdigit() and len(end) <= 19):
        raise ValueError(f'end={end[:25]!r}: must be none or integer ns')
    try:
        names = participant_names(fields['participants'])
    except ValueError:
        raise ValueError(
            f'participants={fields["participants"][:80]!r}: must be distinct names among '
            f'{", ".join(KNOWN_PARTICIPANTS)}'
        ) from None
    return Announcement(fields['clock'], None if end is None else int(end), names)


def participant_names(text: str) -> tuple[str, ...]:
    """``'crank_drive, supervisor'`` -> ``('crank_drive', 'supervisor')``: distinct known participants, at
    least one; ``ValueError`` with the reason otherwise (``line_clock`` names its parameter in it)."""
    names = tuple(n.strip() for n in text.split(',') if n.strip())
    bad = [n for n in names if n not in KNOWN_PARTICIPANTS]
    if bad:
        raise ValueError(
            f'unknown node(s) {", ".join(b[:40] for b in bad[:5])}; known: {", ".join(KNOWN_PARTICIPANTS)}'
        )
    if len(set(names)) != len(names):
        raise ValueError('names a node twice')
    if not names:
        raise ValueError('names no node: the clock would have nobody to wait for')
    return names


@functools.cache
def _typestore() -> Any:
    return get_typestore(Stores.ROS2_KILTED)


#: the counts of an acknowledgement are parsed once, not once per consumer (the result is not mutated)
_cached_counts = functools.lru_cache(maxsize=256)(parse_counts)


def read_ack(data: bytes) -> tuple[str, int, dict[str, int]]:
    """``(frame_id, stamp ns, counts)`` of a ``tick_done`` message as published (CDR bytes).

    Raises ``ValueError`` with the reason for bytes that are not a ``sensor_msgs/TimeReference``
    or whose ``source`` is not counts (:func:`folder_line.core.supervision.lockstep.parse_counts`). The
    counts mapping may be shared between calls: read it, do not change it.
    """
    try:
        msg = _typestore().deserialize_cdr(data, 'sensor_msgs/msg/TimeReference')
    except Exception as err:  # noqa: BLE001 - any decoding failure of foreign bytes is a rejection
        raise ValueError(f'not a sensor_msgs/TimeReference ({type(err).__name__}: {str(err)[:80]})') from None
    return msg.header.frame_id, time_msg_to_ns(msg.header.stamp), _cached_counts(msg.source)


Depends = Callable[[Announcement], Mapping[str, tuple[str, ...]]]
"""A participant's dependencies once the participants are known: producer -> counted streams."""


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
        ``needs(stamp_ns, previous_ns) -> ns``: the producers' tick that must be
        complete before this tick may run (default: ``previous_ns``, the tick before).
    on_lost : callable, optional
        ``on_lost(producer, waited_s, stamp_ns)`` when a producer is declared lost.
    on_reject : callable, optional
        ``on_reject(kind, reason)`` for a malformed, foreign or out-of-order input.
    on_end : callable, optional
        ``on_end(stamp_ns)`` once the announced last tick is done (after its acknowledgement).
    lost_timeout, startup_timeout : float
        Wall seconds a tick may wait for a producer before it is declared lost (the first tick).
    clock_subscription : bool
        Subscribe to ``/clock`` (default). A node that takes ``/clock`` itself passes False and
        hands every message to :meth:`on_clock`: one delivery per tick instead of two.
    """

    def __init__(
        self,
        node: Node,
        depends: Depends,
        on_tick: Callable[[int], None],
        *,
        needs: Callable[[int, int | None], int | None] | None = None,
        on_lost: Callable[[str, float, int], None] | None = None,
        on_reject: Callable[[str, str], None] | None = None,
        on_end: Callable[[int], None] | None = None,
        lost_timeout: float = 3.0,
        startup_timeout: float = 60.0,
        clock_subscription: bool = True,
    ) -> None:
        self.node = node
        self.name = node.get_name()
        self._depends = depends
        self._on_tick = on_tick
        self._needs = needs or (lambda stamp, previous: previous)
        self._on_lost = on_lost
        self._on_reject = on_reject
        self._on_end = on_end
        self.lost_timeout = lost_timeout
        self.startup_timeout = startup_timeout
        self.announcement: Announcement | None = None
        self.ledger: TickLedger | None = None
        self.counts: dict[str, int] = {'messages': 0, 'events': 0, 'commands': 0}
        self.pending: list[int] = []
        self.last_done: int | None = None
        self.ticks = 0
        self.ended = False
        self._waiting_since: float | None = None
        # counted before the announcement (discovery between processes orders nothing): applied to the ledger
        self._early: dict[tuple[str, str], int] = {}
        self._heard: dict[str, float] = {}  # producer -> wall time of its latest acknowledgement (a repeat too)
        self._last_ack: TimeReference | None = None
        self._acked_at = 0.0  # wall time (monotonic) the latest acknowledgement was sent or repeated
        self._ack_pub = node.create_publisher(TimeReference, tick_done_topic(self.name), TICK_QOS)
        # a deep queue (compatible with the depth-1 publisher): a malformed or foreign announcement arriving
        # right after line_clock's must not push it out of the queue before it is taken
        node.create_subscription(String, PARTICIPANTS_TOPIC, self._on_announcement, LINE_QOS)
        if clock_subscription:
            node.create_subscription(ClockMsg, CLOCK_TOPIC, self.on_clock, CLOCK_SUB_QOS)
        # the node's sim clock (use_sim_time) is fed from this subscription: rclpy's TimeSource would take
        # every /clock message a second time through a subscription of its own
        time_source = getattr(node, '_time_source', None)
        own = getattr(time_source, '_clock_sub', None)
        if time_source is not None and own is not None:
            node.destroy_subscription(own)
            time_source._clock_sub = None
            self._time_source = time_source
        else:
            self._time_source = None
        self._timer = node.create_timer(HEARTBEAT, self._check_lost, clock=_steady(node))

    # ------------------------------------------------------------------ publishing

    def publish(self, publisher: Any, msg: Any, stream: str | None = None) -> None:
        """Publish ``msg`` and count it (``messages``, and ``stream`` if given)."""
        publisher.publish(msg)
        self.counts['messages'] += 1
        if stream is not None:
            self.counts[stream] += 1

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
        deps = {p: s for p, s in self._depends(a).items() if p in a.participants and p != self.name}
        self.ledger = TickLedger(deps, {s for streams in deps.values() for s in streams})
        self._streams = deps
        self._heard = dict.fromkeys(deps, time.monotonic())
        for (producer, stream), n in self._early.items():
            self.ledger.received(producer, stream, n)
        self._early.clear()
        for producer in deps:
            self.node.create_subscription(
                TimeReference, tick_done_topic(producer), self._on_ack(producer), TICK_QOS, raw=True
            )
        self.advance()

    def _on_ack(self, producer: str) -> Callable[[bytes], None]:
        def on_ack(data: bytes) -> None:
            try:
                frame_id, stamp, counts = read_ack(data)
            except ValueError as err:
                self._reject('tick_done', str(err))
                return
            if frame_id != producer:
                self._reject('tick_done', f"frame_id {frame_id[:40]!r} on {producer}'s topic")
                return
            assert self.ledger is not None
            refused = self.ledger.ack(producer, stamp, counts)
            if refused is not None:
                self._reject('tick_done', refused)
                return
            self._heard[producer] = time.monotonic()
            if self.pending:
                self.advance()

        return on_ack

    def on_clock(self, msg: ClockMsg) -> None:
        """A ``/clock`` tick (from the participant's own subscription, or handed on by its node)."""
        if self._time_source is not None:
            self._time_source.clock_callback(msg)
        stamp = time_msg_to_ns(msg.clock)
        if self.last_done is not None and stamp <= self.last_done:
            if stamp == self.last_done:
                self._ack(stamp)  # line_clock repeats a tick until everyone answered it
            else:
                self._reject('clock', f'tick {stamp} ns is older than the last tick done {self.last_done} ns')
            return
        if self.pending and stamp <= self.pending[-1]:
            return  # a repeated tick still pending
        self.pending.append(stamp)
        if self._waiting_since is None:
            self._waiting_since = time.monotonic()
        self.advance()

    # ------------------------------------------------------------------ ticks

    def required(self, stamp: int) -> int | None:
        """The producers' tick that must be complete before tick ``stamp`` runs."""
        return self._needs(stamp, self.last_done)

    def advance(self) -> None:
        """Run every pending tick whose inputs are complete, in order."""
        if self.ledger is None or self.ended:
            return
        while self.pending:
            stamp = self.pending[0]
            need = self.required(stamp)
            if need is not None and not self.ledger.complete_through(need):
                return
            self.pending.pop(0)
            self._on_tick(stamp)
            self.last_done = stamp
            self.ticks += 1
            self._ack(stamp)
            self._waiting_since = time.monotonic() if self.pending else None
            a = self.announcement
            if a is not None and a.end_ns is not None and stamp >= a.end_ns:
                self.ended = True
                self.pending.clear()
                if self._on_end is not None:
                    self._on_end(stamp)
                return

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
        else:
            self._ack_pub.publish(self._last_ack)
            self._acked_at = now

    def _ack(self, stamp: int) -> None:
        # one message object, refilled: publishing serializes it at once, and the heartbeat repeats the latest
        ack = self._last_ack
        if ack is None:
            ack = TimeReference()
            ack.header.frame_id = self.name
        ack.header.stamp = ack.time_ref = ns_to_time_msg(stamp)
        ack.source = format_counts(self.counts)
        self._ack_pub.publish(ack)
        self._last_ack = ack
        self._acked_at = time.monotonic()

    def _check_lost(self) -> None:
        """While a tick waits: repeat the latest acknowledgement (alive, waiting), and declare lost the producers
        it waits for that acknowledged nothing, not even a repeat, for the limit: a producer that waits for
        a lost one itself is not lost."""
        if self.ledger is None or self.ended:
            return
        now = time.monotonic()
        if self._last_ack is not None and now - self._acked_at >= HEARTBEAT:
            # waiting, for the clock's next tick or for a producer: say so. This also stands in for an
            # acknowledgement lost on the way, which a reliable writer sends again only at its next
            # heartbeat (seconds): those waiting for this participant must not take it for lost.
            self._ack_pub.publish(self._last_ack)
            self._acked_at = now
        elif self._last_ack is None and self.pending and self.pending[0] > 0 and now - self._acked_at >= HEARTBEAT:
            # waiting for a producer before the first tick is done (the producers of a line joined far into
            # it fast-forward first, at length): alive, at the instant before the tick, as working() says.
            # A line that starts at 0 has no instant before it, and its producers start at once.
            self._ack(self.pending[0] - 1)
        if not self.pending or self._waiting_since is None:
            return
        waited = now - self._waiting_since
        limit = self.startup_timeout if self.last_done is None else self.lost_timeout
        if waited <= limit:
            return
        need = self.required(self.pending[0])
        if need is None:
            return
        for producer in self.ledger.waiting_for(need):
            why = f'limit {limit:g} s'
            if now - self._heard.get(producer, -math.inf) <= limit:
                # it answers: lost only if it acknowledged the tick and its counted messages do not come
                acked = self.ledger.last_ack(producer)
                missing = self.ledger.missing(producer)
                if acked is None or acked < need or not missing or waited <= MISSING_FACTOR * limit:
                    continue
                shortfall = ', '.join(f'{n} {stream}' for stream, n in sorted(missing.items()))
                why = f'acknowledged, but {shortfall} it counted never arrived within {MISSING_FACTOR:g} x {limit:g} s'
            self.ledger.lose(producer)
            self.node.get_logger().error(
                f'participant {producer} lost: tick {need / NS_PER_S:.9f} s not complete after {waited:.1f} s of '
                f'wall time ({why}); going on without it'
            )
            if self._on_lost is not None:
                self._on_lost(producer, waited, need)
        self.advance()

    def destroy(self) -> None:
        """Cancel the wall timer (the node destroys its entities)."""
        self._timer.cancel()


def _steady(node: Node) -> Any:
    return Clock(clock_type=ClockType.STEADY_TIME)
