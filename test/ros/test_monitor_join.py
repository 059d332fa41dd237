"""The monitor joining a line that already runs (``bag play --loop``), over real DDS: every topic at once.

The line's publishers (and ``bag play``'s) are reliable and transient-local, 1000 deep
(``LINE_QOS``). A *volatile* reliable reader that joins such a publisher once it holds a
history gets, with Fast DDS, nothing until the publisher's next heartbeat: up to seconds
between processes (``folder-line monitor --once`` then showed ``/line/events`` at 0 while
a bag played), and, between two contexts of one process as here, nothing at all. The
monitor's subscriptions are transient-local where the line's publisher is
(:func:`folder_line.ros.player.line_qos`), and it drops the history they bring (written
before it started) except on the topics whose history is the point
(:data:`folder_line.ros.monitor.LATCHED`).
"""

from __future__ import annotations

import threading
import time
from collections import defaultdict
from typing import Any

from _ros_env import REPO

from folder_line.interfaces import CLOCK_TOPIC, EVENTS_TOPIC, PARTICIPANTS_TOPIC
from folder_line.ros.monitor import LATCHED, monitor_session
from folder_line.ros.player import PlayResult, play_bag
from folder_line.ros.recorder import LINE_TOPICS
from folder_line.ros.topics import joint_states_topic

FOLDER_BAG = REPO / 'test' / 'data' / 'folder_run' / 'bag'

#: topics of the bag at 124 .. 200 messages per second of line time: in any window of a second
STEADY = [
    CLOCK_TOPIC,
    EVENTS_TOPIC,
    *(joint_states_topic(n) for n in ('crank_drive', 'belt_conveyor', 'feed_transporter', 'sheet_counter')),
    '/line/supervisor/state',
    '/line/sheet_counter/count',
    '/line/sheet_counter/rate',
]


def test_a_monitor_joining_a_playing_bag_gets_every_topic_at_once_and_no_history() -> None:
    assert set(STEADY) <= set(LINE_TOPICS)
    calls = [0]  # should_stop is polled before every message: messages published so far
    stop = threading.Event()

    def should_stop() -> bool:
        calls[0] += 1
        return stop.is_set()

    result: list[PlayResult] = []
    player = threading.Thread(
        target=lambda: result.append(play_bag(str(FOLDER_BAG), loop=True, should_stop=should_stop)), daemon=True
    )
    player.start()
    try:
        deadline = time.monotonic() + 30.0
        while calls[0] < 500 and time.monotonic() < deadline:  # ~0.3 s of line: every publisher holds a history
            time.sleep(0.01)
        assert calls[0] >= 500, calls[0]
        for join in range(3):  # each a new participant, as each `monitor --once` is
            walls: dict[str, list[float]] = defaultdict(list)

            def sink(topic: str, msg: Any, wall: float, walls: dict[str, list[float]] = walls) -> None:
                walls[topic].append(wall)

            since = time.time()
            with monitor_session(sink) as session:
                session.collect(timeout=10.0, window=1.5)
                received = dict(session.node.received)
            missing = {t: received[t] for t in STEADY if received[t] == 0}
            assert not missing, (join, received)
            assert received[PARTICIPANTS_TOPIC] >= 1  # latched: the announcement however late the monitor came
            for topic, stamps in walls.items():  # nothing the publishers held from before the monitor started
                if topic not in LATCHED:
                    assert min(stamps) >= since, (join, topic, since - min(stamps))
    finally:
        stop.set()
        player.join(10.0)
    assert not player.is_alive() and result and result[0].interrupted


def test_a_snapshot_waits_for_the_held_message_of_a_matched_publisher() -> None:
    """The announcement's publisher is matched but holds nothing yet (as when its first heartbeat found the
    monitor not ready): ``collect`` waits past its window, up to its timeout, and gets it. A steady topic
    whose publisher is matched but whose data comes only later (under load, seconds after the others'):
    the window starts once it flows."""
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rosgraph_msgs.msg import Clock
    from std_msgs.msg import String, UInt64

    from folder_line.interfaces import SHEET_COUNT_TOPIC
    from folder_line.ros.lockstep import LINE_QOS, PARTICIPANTS_QOS
    from folder_line.ros.topics import CLOCK_QOS

    context = Context()
    rclpy.init(context=context)
    node = rclpy.create_node('held_announcement', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    announce = node.create_publisher(String, PARTICIPANTS_TOPIC, PARTICIPANTS_QOS)
    clock = node.create_publisher(Clock, CLOCK_TOPIC, CLOCK_QOS)
    count = node.create_publisher(UInt64, SHEET_COUNT_TOPIC, LINE_QOS)
    stop = threading.Event()
    started = time.monotonic()

    def line() -> None:  # /clock at 100 Hz from the start; the announcement after 2 s; the count from 3 s on
        announced = False
        while not stop.is_set():
            clock.publish(Clock())
            if time.monotonic() - started > 3.0:
                count.publish(UInt64(data=1))
            if not announced and time.monotonic() - started > 2.0:
                announce.publish(String(data='lockstep clock, 5 participants'))
                announced = True
            executor.spin_once(timeout_sec=0.01)

    thread = threading.Thread(target=line, daemon=True)
    thread.start()
    try:
        with monitor_session(lambda topic, msg, wall: None) as session:
            t0 = time.monotonic()
            session.collect(timeout=20.0, window=0.2)
            waited = time.monotonic() - t0
            received = dict(session.node.received)
        assert received[CLOCK_TOPIC] > 0
        assert received[PARTICIPANTS_TOPIC] == 1, received
        assert received[SHEET_COUNT_TOPIC] > 0, received  # the window began once it flowed
        assert time.monotonic() - started > 2.0 and waited < 20.0  # it came, and ended the wait
    finally:
        stop.set()
        thread.join(5.0)
        node.destroy_node()
        rclpy.try_shutdown(context=context)
