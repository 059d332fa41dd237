"""``folder-line bag play`` over real DDS: play a bag, record the playback, compare; Ctrl-C stops it cleanly."""

from __future__ import annotations

import hashlib
import shutil
import signal
import subprocess
import sys
import threading
from collections import defaultdict
from pathlib import Path

import pytest
from _ros_env import REPO, node_environment
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from rosbags.rosbag2 import Reader
from rosgraph_msgs.msg import Clock

from folder_line.ros.player import PlayResult, message_class, play_bag

from .conftest import Ros

FOLDER_BAG = REPO / 'test' / 'data' / 'folder_run' / 'bag'

#: the recording side: every message kept, matches any reliable publisher
_RECORD_QOS = QoSProfile(
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
    history=HistoryPolicy.KEEP_ALL,
)


def _digest(path: Path) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(path.iterdir())}


def _bag_messages(path: Path) -> tuple[dict[str, str], dict[str, list[bytes]], dict[str, list[int]]]:
    """Topic -> type, topic -> CDR of each message, topic -> log times: read with rosbags, not with the player."""
    types: dict[str, str] = {}
    raw: dict[str, list[bytes]] = defaultdict(list)
    times: dict[str, list[int]] = defaultdict(list)
    with Reader(path) as reader:
        for conn in reader.connections:
            types[conn.topic] = conn.msgtype
        for conn, t_ns, data in reader.messages():
            raw[conn.topic].append(bytes(data))
            times[conn.topic].append(t_ns)
    return types, raw, times


def test_play_then_record_gives_the_bag_back(ros: Ros, tmp_path: Path) -> None:
    bag = tmp_path / 'bag'
    shutil.copytree(FOLDER_BAG, bag)
    before = _digest(bag)
    types, expected, times = _bag_messages(bag)
    node = ros.node('playback_recorder')
    got: dict[str, list[bytes]] = defaultdict(list)
    for topic, msgtype in types.items():
        node.create_subscription(
            message_class(msgtype), topic, lambda data, t=topic: got[t].append(bytes(data)), _RECORD_QOS, raw=True
        )
    result: list[PlayResult] = []
    # the player in a thread of its own (its own context): it waits for this recorder before playing
    player = threading.Thread(
        target=lambda: result.append(play_bag(str(bag), rtf=0.0, wait_for_subscribers=20.0)), daemon=True
    )
    player.start()
    total = sum(len(v) for v in expected.values())
    assert ros.spin_until(lambda: sum(len(v) for v in got.values()) >= total and not player.is_alive(), 60.0), {
        t: (len(got[t]), len(v)) for t, v in expected.items()
    }
    player.join(10.0)
    assert result and not result[0].interrupted
    assert {t: n for t, n in result[0].published.items() if n} == {t: len(v) for t, v in expected.items()}
    assert set(got) == set(expected)
    for topic, messages in expected.items():
        assert len(got[topic]) == len(messages), topic
        assert got[topic] == messages, f'{topic}: the content played differs from the bag'
    # the stamps: the /clock played is the bag's log times, tick for tick
    clock = [deserialize_message(m, Clock).clock for m in got['/clock']]
    assert [c.sec * 1_000_000_000 + c.nanosec for c in clock] == times['/clock']
    assert _digest(bag) == before


def test_play_a_window_of_some_topics(ros: Ros, tmp_path: Path) -> None:
    node = ros.node('window_recorder')
    got: dict[str, list[bytes]] = defaultdict(list)
    types, expected, times = _bag_messages(FOLDER_BAG)
    for topic in ('/clock', '/line/events', '/line/supervisor/state'):
        node.create_subscription(
            message_class(types[topic]), topic, lambda d, t=topic: got[t].append(bytes(d)), _RECORD_QOS, raw=True
        )
    result: list[PlayResult] = []
    player = threading.Thread(
        target=lambda: result.append(
            play_bag(
                str(FOLDER_BAG),
                rtf=0.0,
                start=0.5,
                duration=0.25,
                topics=['/line/events'],
                wait_for_subscribers=20.0,
            )
        ),
        daemon=True,
    )
    # no subscriber waits for /line/supervisor/state: the player must not publish it at all
    want = {
        t: [m for m, s in zip(expected[t], times[t], strict=True) if 500_000_000 <= s <= 750_000_000]
        for t in ('/clock', '/line/events')
    }
    assert want['/line/events'] and want['/clock']
    player.start()
    assert ros.spin_until(lambda: all(len(got[t]) >= len(v) for t, v in want.items()) and not player.is_alive(), 30.0)
    ros.spin_until(lambda: False, 0.3)
    assert got['/line/events'] == want['/line/events']
    assert got['/clock'] == want['/clock']
    assert not got['/line/supervisor/state']
    assert set(result[0].published) == {'/clock', '/line/events'}


def test_ctrl_c_stops_playing_cleanly(tmp_path: Path) -> None:
    bag = tmp_path / 'bag'
    shutil.copytree(FOLDER_BAG, bag)
    before = _digest(bag)
    proc = subprocess.Popen(
        [sys.executable, '-m', 'folder_line.cli.main', 'bag', 'play', str(bag), '--rtf', '0.5', '--loop'],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=node_environment(),
        cwd=REPO,
    )
    try:
        assert proc.stdout is not None
        first = proc.stdout.readline()  # printed once the node exists and playing begins
        assert first.startswith('playing ')
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, err
    assert 'Traceback' not in err
    assert 'stopped by Ctrl-C' in out
    assert _digest(bag) == before


@pytest.mark.parametrize(
    ('args', 'option'),
    [(['--topics', '/nope'], '--topics'), (['--start', '5'], '--start'), (['--rtf', 'fast'], '--rtf')],
)
def test_play_refuses_bad_options_in_one_line(args: list[str], option: str) -> None:
    proc = subprocess.run(
        [sys.executable, '-m', 'folder_line.cli.main', 'bag', 'play', str(FOLDER_BAG), *args],
        capture_output=True,
        text=True,
        env=node_environment(),
        cwd=REPO,
        timeout=60,
    )
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and option in lines[0], proc.stderr


def test_ctrl_c_inside_a_pass_reports_the_line_time_played_so_far(tmp_path: Path) -> None:
    """Ctrl-C arrives while a pass publishes (KeyboardInterrupt, here from the stop poll after 500 messages): the
    result counts what was published and says how far the line time got, not 0."""
    bag = tmp_path / 'bag'
    shutil.copytree(FOLDER_BAG, bag)
    _, _, times = _bag_messages(bag)
    polls = [0]

    def ctrl_c() -> bool:
        polls[0] += 1
        if polls[0] > 500:
            raise KeyboardInterrupt
        return False

    result = play_bag(str(bag), rtf=0.0, should_stop=ctrl_c)
    assert result.interrupted and sum(result.published.values()) >= 500
    ordered = sorted(t for ts in times.values() for t in ts)
    assert 0.0 < result.line_time == ordered[499] / 1e9  # the 500th message's log time
