"""The line recorder: one node that subscribes to every topic of the line.

It counts the messages per topic, follows sim time, the supervisor's state and the
sheet count, and hands every message to an optional sink (the bag writer).
"""

from __future__ import annotations

import time
from collections import Counter
from typing import Any, Callable

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.executors import Executor
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState, TimeReference
from std_msgs.msg import Float64, String, UInt64

from folder_line.nodes.supervisor import STATE_QOS
from folder_line.nodes.common import (
    CLOCK_TOPIC,
    COMMANDS_QOS,
    COMMANDS_TOPIC,
    DIAGNOSTICS_TOPIC,
    EVENTS_TOPIC,
    LANDING_TOPIC,
    NS_PER_S,
    SHEET_COUNT_TOPIC,
    SHEET_RATE_TOPIC,
    SUPERVISOR_STATE_TOPIC,
    joint_states_topic,
    time_msg_to_ns,
)

__all__ = ['LINE_TOPICS', 'LineRecorder']

#: topic -> message class, every topic of the line
LINE_TOPICS: dict[str, type] = {
    CLOCK_TOPIC: Clock,
    joint_states_topic('crank_drive'): JointState,
    joint_states_topic('belt_conveyor'): JointState,
    joint_states_topic('feed_transporter'): JointState,
    joint_states_topic('sheet_counter'): JointState,
    EVENTS_TOPIC: TimeReference,
    DIAGNOSTICS_TOPIC: DiagnosticArray,
    SUPERVISOR_STATE_TOPIC: String,
    SHEET_COUNT_TOPIC: UInt64,
    SHEET_RATE_TOPIC: Float64,
    LANDING_TOPIC: Float64,
    COMMANDS_TOPIC: TimeReference,
}

Sink = Callable[[str, Any, int], None]


class LineRecorder(Node):
    """Subscribes to :data:`LINE_TOPICS` (reliable, deep queues).

    Parameters
    ----------
    sink : callable, optional
        ``sink(topic, msg, receive_time_ns)`` for every message.
    **kwargs
        Passed to ``rclpy.node.Node`` (``context`` ...).
    """

    def __init__(self, sink: Sink | None = None, **kwargs: Any) -> None:
        super().__init__('line_recorder', **kwargs)
        self.sink = sink
        self.counts: Counter[str] = Counter()
        self.event_counts: Counter[str] = Counter()
        self.sim_time = 0.0
        self.clock_wall: tuple[float, float] | None = None  # wall time (s) of the first and latest /clock
        self.state = ''
        self.sheet_count = 0
        qos = QoSProfile(depth=10000, reliability=ReliabilityPolicy.RELIABLE)
        for topic, cls in LINE_TOPICS.items():
            self.create_subscription(cls, topic, self._callback(topic),
                                     COMMANDS_QOS if topic == COMMANDS_TOPIC else
                                     STATE_QOS if topic == SUPERVISOR_STATE_TOPIC else qos)

    def _callback(self, topic: str) -> Callable[[Any], None]:
        def on_message(msg: Any) -> None:
            self.counts[topic] += 1
            if topic == CLOCK_TOPIC:
                self.sim_time = max(self.sim_time, time_msg_to_ns(msg.clock) / NS_PER_S)
                now = time.monotonic()
                self.clock_wall = (now, now) if self.clock_wall is None else (self.clock_wall[0], now)
            elif topic == EVENTS_TOPIC:
                self.event_counts[msg.source.split(' ', 1)[0]] += 1
            elif topic == SUPERVISOR_STATE_TOPIC:
                self.state = msg.data
            elif topic == SHEET_COUNT_TOPIC:
                self.sheet_count = msg.data
            if self.sink is not None:
                self.sink(topic, msg, time.time_ns())

        return on_message

    def wait_for_publishers(self, n_nodes: int, executor: Executor, timeout: float) -> bool:
        """Spin until ``n_nodes`` publishers of ``/line/events`` are matched (True) or ``timeout`` s pass."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.count_publishers(EVENTS_TOPIC) >= n_nodes:
                return True
            executor.spin_once(timeout_sec=0.1)
        return False
