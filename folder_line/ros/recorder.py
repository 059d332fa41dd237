"""The line recorder: one node that subscribes to every topic of the line.

It counts the messages per topic, follows sim time, the supervisor's state and the
sheet count, and hands every message to an optional sink (the bag writer) as the CDR
bytes it was published as: the subscriptions are raw, so a message is never turned into
Python objects and back to be recorded (only the few fields the recorder reads are
deserialized, by rclpy). It is a
lockstep participant (``line_recorder``, :mod:`folder_line.ros.lockstep`): it
acknowledges tick ``t`` once every other participant's tick ``t`` is complete here,
i.e. every message they published up to ``t`` has been recorded, so ``line_clock``
never runs ahead of the bag. A repeated ``/clock`` tick (the clock repeats its first
tick until every participant answered it) is recorded once. A message that arrives
before the ``/clock`` of its tick (DDS orders nothing across topics) is held until
that ``/clock`` is recorded (:meth:`LineRecorder.flush`), so every message's log time
in the bag is its tick: the bag does not depend on the load.
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Callable
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.node import Node
from rclpy.serialization import deserialize_message
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
from folder_line.ros.lockstep import CLOCK_SUB_QOS, LINE_QOS, Announcement, Participant
from folder_line.ros.nodes.supervisor import STATE_QOS
from folder_line.ros.time_msg import time_msg_to_ns
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

#: ``sink(topic, cdr, log_ns, publish_ns)``: the message as published (CDR bytes), the tick it is
#: recorded at (the latest ``/clock``, ns) and its own stamp (``header.stamp``, else the tick), ns
Sink = Callable[[str, bytes, int, int], None]

#: topics whose messages the recorder reads whole (few per tick); of the others it reads only the
#: ``header`` (stamp and frame_id) if they have one, and nothing if not
_READ_WHOLE = frozenset(
    {CLOCK_TOPIC, EVENTS_TOPIC, DIAGNOSTICS_TOPIC, SUPERVISOR_STATE_TOPIC, SHEET_COUNT_TOPIC, COMMANDS_TOPIC}
)


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
        self.clock_wall: tuple[float, float] | None = None  # wall time (s) of the first and latest /clock
        self.state = ''
        self.sheet_count = 0
        self.lost: dict[str, float] = {}
        #: the first error of the sink (a write the OS refused: disk full, ...); nothing is recorded after it
        self.write_error: OSError | None = None
        # the ERROR statuses seen (lost participants, violations, ...) and the operator's tunings
        self.diagnostics: list[Any] = []
        self._last_clock = -1
        self._held: list[tuple[str, bytes, int]] = []  # (topic, cdr, publish ns) of a tick whose /clock is not in
        self._sim_origin = 0.0
        for topic, cls in LINE_TOPICS.items():
            qos = (
                COMMANDS_QOS
                if topic == COMMANDS_TOPIC
                else STATE_QOS
                if topic == SUPERVISOR_STATE_TOPIC
                else CLOCK_SUB_QOS
                if topic == CLOCK_TOPIC
                else LINE_QOS
            )
            self.create_subscription(cls, topic, self._callback(topic, cls), qos, raw=True)
        # the participant takes /clock from this node's own subscription (after the tick is recorded)
        self.lockstep = Participant(
            self,
            self._depends,
            lambda stamp: None,
            needs=lambda stamp, previous: stamp,
            on_lost=self._on_lost,
            lost_timeout=lost_timeout,
            clock_subscription=False,
        )

    def rtf_achieved(self) -> float:
        """Sim seconds per wall second between the first and the latest tick recorded (0 before two)."""
        if self.clock_wall is None or self.clock_wall[1] <= self.clock_wall[0]:
            return 0.0
        return (self.sim_time - self._sim_origin) / (self.clock_wall[1] - self.clock_wall[0])

    @staticmethod
    def _depends(a: Announcement) -> dict[str, tuple[str, ...]]:
        return {n: ('messages',) for n in MACHINE_NODES}

    def _on_lost(self, producer: str, waited: float, stamp: int) -> None:
        self.lost[producer] = stamp / NS_PER_S

    def _callback(self, topic: str, cls: type) -> Callable[[bytes], None]:
        producer = _PRODUCER.get(topic, '')
        whole = topic in _READ_WHOLE
        # CDR lays a struct's fields out in order, so a message whose first field is its std_msgs/Header
        # starts with that header's bytes: the header alone is read from them
        has_header = not whole and 'header' in getattr(cls, '_fields_and_field_types', {})

        def on_message(data: bytes) -> None:
            msg: Any = deserialize_message(data, cls) if whole else None
            header = (
                msg.header
                if whole and hasattr(msg, 'header')
                else deserialize_message(data, Header)
                if has_header
                else None
            )
            if topic == CLOCK_TOPIC:
                stamp = time_msg_to_ns(msg.clock)
                if stamp <= self._last_clock:
                    self.lockstep.on_clock(msg)  # a repeated tick: recorded once, answered again
                    return
                first = self._last_clock < 0
                self._last_clock = stamp
                self.sim_time = max(self.sim_time, stamp / NS_PER_S)
                now = time.monotonic()
                if first:  # the first tick waits for everyone to start: the rate counts from it
                    self._sim_origin = self.sim_time
                self.clock_wall = (now, now) if self.clock_wall is None else (self.clock_wall[0], now)
            elif topic == EVENTS_TOPIC:
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
            source = (
                ''
                if producer == ''
                else producer
                if producer is not None
                else header.frame_id
                if header is not None
                else ''
            )
            if self.sink is not None:
                publish_ns = time_msg_to_ns(header.stamp) if header is not None else -1
                if source and self._ahead(source):
                    self._held.append((topic, data, publish_ns))
                else:
                    self._sink(topic, data, publish_ns)
                    if topic == CLOCK_TOPIC:
                        self.flush()
            if source and _could_publish(source, topic, msg):
                self.lockstep.received(source, 'messages')
            if topic == CLOCK_TOPIC:
                self.lockstep.on_clock(msg)

        return on_message

    def _sink(self, topic: str, data: bytes, publish_ns: int) -> None:
        """Record at the latest tick; a message without a stamp of its own is stamped with it. A write the
        OS refuses is kept in :attr:`write_error` (for ``run`` to end the line with it), not raised into
        the executor."""
        assert self.sink is not None
        if self.write_error is not None:
            return
        log_ns = max(self._last_clock, 0)
        try:
            self.sink(topic, data, log_ns, log_ns if publish_ns < 0 else publish_ns)
        except OSError as exc:
            self.write_error = exc

    def _ahead(self, producer: str) -> bool:
        """Whether a message of ``producer`` arriving now belongs to a tick whose ``/clock`` is not recorded yet.

        In lockstep a producer publishes tick ``t`` after ``/clock`` ``t``, which comes after this
        recorder completed the producer's tick before; so a message that arrives when the producer's
        latest complete tick is the latest ``/clock`` recorded here belongs to the next tick. It is held
        until that ``/clock`` is recorded, so that its log time in the bag is its tick whatever the order
        in which DDS delivers the topics (the bag does not depend on the load).
        """
        if self._last_clock < 0:
            return True
        a, ledger = self.lockstep.announcement, self.lockstep.ledger
        if (
            a is None
            or a.clock != 'lockstep'
            or ledger is None
            or not ledger.knows(producer)
            or ledger.is_lost(producer)
        ):
            return False
        complete = ledger.complete(producer)
        return complete is not None and complete >= self._last_clock

    def flush(self) -> None:
        """Hand the held messages to the sink (at a recorded ``/clock``, and before the bag is closed)."""
        held, self._held = self._held, []
        if self.sink is not None:
            for topic, data, publish_ns in held:
                self._sink(topic, data, publish_ns)
