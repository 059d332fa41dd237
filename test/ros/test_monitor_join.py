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
