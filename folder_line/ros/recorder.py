"""The line recorder: one node that subscribes to every topic of the line.

It counts the messages per topic, follows sim time, the supervisor's state and the
sheet count, and hands every message to an optional sink (the bag writer) as the CDR
bytes it was published as: the subscriptions are raw, so a message is never turned into
Python objects and back to be recorded (only the few fields the recorder reads are
deserialized, by rclpy). It is a
lockstep participant (``line_recorder``, :mod:`folder_line.ros.lockstep`): it
runs tick ``t`` once every other participant's tick ``t`` is complete here, i.e.
every message they published up to ``t`` has arrived, so ``line_clock`` never runs
more than its window ahead of the bag. It reads every acknowledgement (reliably, in
order), whose per-topic counts say which of a producer's messages belong to which
tick; a producer's messages are held until their tick runs here, and written then at
that tick, after the tick's ``/clock``. So every message's log time in the bag is its
tick, whatever the order in which DDS delivers the topics and however far ahead the
producers run: the bag does not depend on the load. ``/clock`` is recorded as the
ticks ``line_clock`` granted (the same messages it publishes); a foreign ``/clock`` is
never recorded.
"""

from __future__ import annotations

import time
from collections import Counter, deque
from collections.abc import Callable, Mapping
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.node import Node
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState, TimeReference
from std_msgs.msg import Float64, Header, String, UInt64
from visualization_msgs.msg import MarkerArray

from folder_line.bag.statuses import TUNING_STATUS
from folder_line.interfaces import (
    CLOCK_TOPIC,
    COMMANDS_TOPIC,
    DIAGNOSTICS_TOPIC,
    EVENT_OWNER,
    EVENTS_TOPIC,
    JOINT_NODES,
    LANDING_TOPIC,
    MACHINE_NODES,
    MARKERS_TOPIC,
    NS_PER_S,
    PARTICIPANTS_TOPIC,
    RECORDER,
    SHEET_COUNT_TOPIC,
    SHEET_RATE_TOPIC,
    SUPERVISOR_STATE_TOPIC,
    is_command_source,
    parse_event_source,
)
from folder_line.ros.lockstep import LINE_QOS, Participant
from folder_line.ros.lockstep_messages import Announcement
from folder_line.ros.nodes.supervisor import STATE_QOS
from folder_line.ros.signing import open_text
from folder_line.ros.time_msg import ns_to_time_msg, time_msg_to_ns
from folder_line.ros.topics import COMMANDS_QOS, joint_states_topic

__all__ = ['LINE_TOPICS', 'LineRecorder']

#: topic -> message class, every topic of the line
LINE_TOPICS: dict[str, type] = {
    CLOCK_TOPIC: Clock,
    **{joint_states_topic(node): JointState for node in JOINT_NODES},
    EVENTS_TOPIC: TimeReference,
    DIAGNOSTICS_TOPIC: DiagnosticArray,
    SUPERVISOR_STATE_TOPIC: String,
    SHEET_COUNT_TOPIC: UInt64,
    SHEET_RATE_TOPIC: Float64,
    LANDING_TOPIC: Float64,
    COMMANDS_TOPIC: TimeReference,
    PARTICIPANTS_TOPIC: String,
    MARKERS_TOPIC: MarkerArray,
}

#: topic -> the participant that publishes it (None: the ``header.frame_id`` says; absent: not a participant's)
_PRODUCER: dict[str, str | None] = {
    **{joint_states_topic(n): None for n in MACHINE_NODES},
    EVENTS_TOPIC: None,
    DIAGNOSTICS_TOPIC: None,
    SUPERVISOR_STATE_TOPIC: 'supervisor',
    COMMANDS_TOPIC: None,
    SHEET_COUNT_TOPIC: 'sheet_counter',
    SHEET_RATE_TOPIC: 'sheet_counter',
    LANDING_TOPIC: 'sheet_counter',
    MARKERS_TOPIC: 'sheet_counter',
}

#: participant -> the topics it publishes, each counted in its acknowledgements (``/clock`` is line_clock's)
PRODUCER_TOPICS: dict[str, tuple[str, ...]] = {
    node: tuple(
        t
        for t, who in _PRODUCER.items()
        if who == node
        or (who is None and t == joint_states_topic(node))
        or (t == EVENTS_TOPIC and node in EVENT_OWNER.values())
        or (t in (DIAGNOSTICS_TOPIC, COMMANDS_TOPIC) and node == 'supervisor')
    )
    for node in MACHINE_NODES
}

#: ``sink(topic, cdr, log_ns, publish_ns)``: the message as published (CDR bytes), the tick it is
#: recorded at (the latest ``/clock``, ns) and its own stamp (``header.stamp``, else the tick), ns
Sink = Callable[[str, bytes, int, int], None]

#: topics whose messages the recorder reads whole (few per tick); of the others it reads only the
#: ``header`` (stamp and frame_id) if they have one, and nothing if not
_READ_WHOLE = frozenset(
    {CLOCK_TOPIC, EVENTS_TOPIC, DIAGNOSTICS_TOPIC, SUPERVISOR_STATE_TOPIC, SHEET_COUNT_TOPIC, COMMANDS_TOPIC}
)


#: topics whose messages are signed on a keyed line (:mod:`folder_line.ros.signing`)
_SIGNED = frozenset({COMMANDS_TOPIC, PARTICIPANTS_TOPIC})


def _could_publish(producer: str, topic: str, msg: Any) -> bool:
    """Whether ``producer`` could have published ``msg``: only such messages count towards its ticks.

    A malformed event or command that bears a participant's name (its consumers reject it) must
    not make the recorder believe that participant's tick is complete before it is.
    """
    if topic == EVENTS_TOPIC:
        try:
            kind = parse_event_source(msg.source)[0]
        except ValueError:
            return False
        return EVENT_OWNER.get(kind) == producer
    if topic == COMMANDS_TOPIC:
        return producer == 'supervisor' and is_command_source(msg.source)
    return True


class LineRecorder(Node):
    """Subscribes to :data:`LINE_TOPICS` (reliable, deep queues).

    Parameters
    ----------
    sink : callable, optional
        ``sink(topic, cdr, log_ns, publish_ns)`` for every message (:data:`Sink`).
    **kwargs
        Passed to ``rclpy.node.Node`` (``context`` ...).
    """

    def __init__(self, sink: Sink | None = None, *, lost_timeout: float = 3.0, **kwargs: Any) -> None:
        super().__init__(RECORDER, **kwargs)
        self.sink = sink
        self.counts: Counter[str] = Counter()
        self.event_counts: Counter[str] = Counter()
        self.sim_time = 0.0
        self.clock_wall: tuple[float, float] | None = None  # wall time (s) of the first and latest tick recorded
        self.state = ''
        self.sheet_count = 0
        self.lost: dict[str, float] = {}
        #: per topic, messages that arrived for ticks after the last one recorded (a stopped line), not recorded
        self.unrecorded: Counter[str] = Counter()
        #: per topic, messages refused as unsigned on a keyed line (:mod:`folder_line.ros.signing`), not recorded
        self.refused: Counter[str] = Counter()
        self._commands_at: tuple[int, set[tuple[int, str]]] = (-1, set())  # the latest stamp of a command, its own
        self._announced: str | None = None  # the announcement recorded
        #: the first error of the sink (a write the OS refused: disk full, ...); nothing is recorded after it
        self.write_error: OSError | None = None
        # the ERROR statuses seen (lost participants, violations, ...) and the operator's tunings
        self.diagnostics: list[DiagnosticStatus] = []
        self._last_clock = -1
        # per producer: its acknowledgements not yet recorded, and per topic its messages not yet recorded
        self._acks: dict[str, deque[tuple[int, Mapping[str, int]]]] = {n: deque() for n in PRODUCER_TOPICS}
        self._held: dict[str, dict[str, deque[tuple[bytes, int]]]] = {
            n: {t: deque() for t in topics} for n, topics in PRODUCER_TOPICS.items()
        }
        self._done: dict[tuple[str, str], int] = {}  # (producer, topic) -> its messages recorded (or counted)
        self._sim_origin = 0.0
        #: called with each tick's stamp (ns) once the tick is recorded, in tick order (a measurement's marks)
        self.tick_observer: Callable[[int], None] | None = None
        for topic, cls in LINE_TOPICS.items():
            if topic == CLOCK_TOPIC:
                continue  # recorded from the ticks line_clock grants
            qos = (
                COMMANDS_QOS if topic == COMMANDS_TOPIC else STATE_QOS if topic == SUPERVISOR_STATE_TOPIC else LINE_QOS
            )
            self.create_subscription(cls, topic, self._callback(topic, cls), qos, raw=True)
        self.lockstep = Participant(
            self,
            self._depends,
            self._on_tick,
            needs=lambda stamp, previous: (stamp, None),
            on_lost=self._on_lost,
            on_ack=self._on_ack,
            lost_timeout=lost_timeout,
            every_tick=True,
            prompt=False,  # only the clock reads its progress, within its window
        )

    def rtf_achieved(self) -> float:
        """Sim seconds per wall second between the first and the latest tick recorded (0 before two)."""
        if self.clock_wall is None or self.clock_wall[1] <= self.clock_wall[0]:
            return 0.0
        return (self.sim_time - self._sim_origin) / (self.clock_wall[1] - self.clock_wall[0])

    @staticmethod
    def _depends(a: Announcement) -> dict[str, tuple[str, ...]]:
        return dict(PRODUCER_TOPICS)

    def _on_lost(self, producer: str, waited: float, stamp: int) -> None:
        self.lost[producer] = stamp / NS_PER_S
        self._acks[producer].clear()
        for topic, queue in self._held[producer].items():  # no tick of it will place them: at the latest tick
            while queue:
                self._sink(topic, *queue.popleft())

    def _on_ack(self, producer: str, stamp: int, counts: Mapping[str, int]) -> None:
        acks = self._acks.get(producer)
        if acks is not None:
            acks.append((stamp, counts))

    def _on_tick(self, stamp: int) -> None:
        """Every producer's messages up to ``stamp`` are in: record the tick's ``/clock``, then its messages."""
        first = self._last_clock < 0
        self._last_clock = stamp
        self.sim_time = max(self.sim_time, stamp / NS_PER_S)
        now = time.monotonic()
        if first:  # the first tick waits for everyone to start: the rate counts from it
            self._sim_origin = self.sim_time
        self.clock_wall = (now, now) if self.clock_wall is None else (self.clock_wall[0], now)
        self.counts[CLOCK_TOPIC] += 1
        if self.sink is not None:
            self._sink(CLOCK_TOPIC, serialize_message(Clock(clock=ns_to_time_msg(stamp))), stamp)
        for producer, acks in self._acks.items():
            counts = None
            while acks and acks[0][0] <= stamp:
                counts = acks.popleft()[1]
            if counts is not None:
                self._place(producer, counts)
        if self.tick_observer is not None:
            self.tick_observer(stamp)

    def _place(self, producer: str, counts: Mapping[str, int]) -> None:
        """Record ``producer``'s messages that ``counts`` (its acknowledged per-topic totals) covers."""
        for topic, queue in self._held[producer].items():
            due = counts.get(topic, 0) - self._written(producer, topic)
            for _ in range(min(due, len(queue))):
                self._sink(topic, *queue.popleft())
                self._done[producer, topic] = self._written(producer, topic) + 1

    def _written(self, producer: str, topic: str) -> int:
        return self._done.get((producer, topic), 0)

    def _callback(self, topic: str, cls: type) -> Callable[[bytes], None]:
        producer = _PRODUCER.get(topic, '')
        whole = topic in _READ_WHOLE
        # CDR lays a struct's fields out in order, so a message whose first field is its std_msgs/Header
        # starts with that header's bytes: the header alone is read from them
        fields: Mapping[str, str] = getattr(cls, 'get_fields_and_field_types', dict)()
        has_header = not whole and 'header' in fields

        def on_message(data: bytes) -> None:
            msg: Any = deserialize_message(data, cls) if whole else None
            if topic in _SIGNED:  # recorded as what it says, without its signature (the bag is the key's)
                opened = self._opened(topic, data, msg)
                if opened is None:
                    return
                data = opened
            header = (
                msg.header
                if whole and hasattr(msg, 'header')
                else deserialize_message(data, Header)
                if has_header
                else None
            )
            if topic == EVENTS_TOPIC:
                self.event_counts[msg.source.split(' ', 1)[0]] += 1
            elif topic == SUPERVISOR_STATE_TOPIC:
                self.state = msg.data
            elif topic == SHEET_COUNT_TOPIC:
                self.sheet_count = msg.data
            elif topic == DIAGNOSTICS_TOPIC:
                self.diagnostics.extend(
                    st for st in msg.status if st.level == DiagnosticStatus.ERROR or st.name == TUNING_STATUS
                )
            self.counts[topic] += 1
            source = producer if producer else header.frame_id if producer is None and header is not None else ''
            publish_ns = time_msg_to_ns(header.stamp) if header is not None else -1
            counted = source in self._held and topic in self._held[source] and _could_publish(source, topic, msg)
            if not counted or (self.lockstep.ledger is not None and self.lockstep.ledger.is_lost(source)):
                self._sink(topic, data, publish_ns)  # not a participant's (line_clock's, a lost one's): as it comes
                return
            if self.sink is not None:
                self._held[source][topic].append((data, publish_ns))
            else:
                self._done[source, topic] = self._written(source, topic) + 1
            self.lockstep.received(source, topic)

        return on_message

    def _opened(self, topic: str, data: bytes, msg: Any) -> bytes | None:
        """``data`` (message ``msg``, deserialized if not None) without its signature; None, counted in
        :attr:`refused`, when the signature is missing or wrong on a keyed line."""
        try:
            if topic == COMMANDS_TOPIC:
                source = open_text(msg.source, 'command', msg.header.frame_id, msg.header.stamp, msg.time_ref)
                if not self._first_time(time_msg_to_ns(msg.header.stamp), (time_msg_to_ns(msg.time_ref), source)):
                    self.refused[topic] += 1  # a command played again: the supervisor publishes each once
                    return None
                if source == msg.source:
                    return data
                msg.source = source
                return bytes(serialize_message(msg))
            text = deserialize_message(data, String).data
            opened = open_text(text, 'announcement')
            if opened == self._announced:  # played again: line_clock announces once
                self.refused[topic] += 1
                return None
            self._announced = opened
            return data if opened == text else bytes(serialize_message(String(data=opened)))
        except ValueError:
            self.refused[topic] += 1
            return None

    def _first_time(self, stamp: int, command: tuple[int, str]) -> bool:
        """Whether ``command`` (effective ns, source), stamped ``stamp`` (ns), is new: the supervisor stamps
        its commands in order, so one stamped earlier than the latest, or seen at that stamp, is a copy."""
        latest, seen = self._commands_at
        if stamp < latest or (stamp == latest and command in seen):
            return False
        if stamp > latest:
            self._commands_at = (stamp, set())
        self._commands_at[1].add(command)
        return True

    def _sink(self, topic: str, data: bytes, publish_ns: int) -> None:
        """Record at the latest tick; a message without a stamp of its own is stamped with it. A write the
        OS refuses is kept in :attr:`write_error` (for ``run`` to end the line with it), not raised into
        the executor."""
        if self.sink is None or self.write_error is not None:
            return
        log_ns = max(self._last_clock, 0)
        try:
            self.sink(topic, data, log_ns, log_ns if publish_ns < 0 else publish_ns)
        except OSError as exc:
            self.write_error = exc

    def flush(self) -> None:
        """Before the bag is closed: the messages still held belong to ticks this recorder never completed
        (the line was stopped while producers ran ahead of it). They are not recorded at a tick that is not
        theirs: the bag ends with the last whole tick, and they are counted in :attr:`unrecorded`."""
        for topics in self._held.values():
            for topic, queue in topics.items():
                self.unrecorded[topic] += len(queue)
                queue.clear()
