"""A stranger on the line's ROS domain, without the line's key: it attacks every input of the line.

Run as a process (``python test/ros/_stranger.py REPORT``) with
:func:`_ros_env.stranger_environment`. Two nodes, ``stranger`` and one that takes the name
``supervisor``, publish as fast as they can, with the line's own QoS, on every topic a node
of the line reads or the recorder records: NaN joint states and rates, forged
``tick_done``/``progress`` of every participant stamped 100 s ahead (and out of order), a
grant and a ``/clock`` far ahead, a participants announcement, a ``stop`` command, a retune of
``feed_transporter``, bogus events, and calls ``/line/supervisor/abort``. It also listens on
the line's topics, as ``ros2 topic echo`` would. It creates ``REPORT.ready`` once it has
published every attack once; when ``REPORT.stop`` appears it writes its counts as JSON to
``REPORT``: what it published, what it heard of the line, and the answers to its service calls.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path
from typing import Any

import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.publisher import Publisher
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState, TimeReference
from std_msgs.msg import Float64, String, UInt64
from std_srvs.srv import Trigger

from folder_line.interfaces import (
    COMMANDS_TOPIC,
    DIAGNOSTICS_TOPIC,
    EVENTS_TOPIC,
    GRANT_TOPIC,
    JOINT_NODES,
    KNOWN_PARTICIPANTS,
    LANDING_TOPIC,
    PARTICIPANTS_TOPIC,
    SHEET_COUNT_TOPIC,
    SHEET_RATE_TOPIC,
    SUPERVISOR_STATE_TOPIC,
    TUNE_TOPIC,
    joint_states_topic,
    progress_topic,
    tick_done_topic,
)
from folder_line.ros.lockstep import ACK_QOS, CLOCK_SUB_QOS, GRANT_QOS, LINE_QOS, PARTICIPANTS_QOS, TICK_QOS
from folder_line.ros.time_msg import ns_to_time_msg
from folder_line.ros.topics import CLOCK_QOS, COMMANDS_QOS, TUNE_QOS

AHEAD_NS = 100 * 10**9  # forged stamps: 100 s of line time ahead


def _time_ref(frame: str, stamp_ns: int, source: str) -> TimeReference:
    msg = TimeReference(source=source)
    msg.header.frame_id = frame
    msg.header.stamp = ns_to_time_msg(stamp_ns)
    msg.time_ref = ns_to_time_msg(stamp_ns)
    return msg


def _attacks(node: Node) -> list[tuple[Publisher[Any], object]]:
    """``(publisher, message)`` of every attack published by ``node``: NaN data, a retune, forged state,
    announcement, command, event, grant, clock, diagnostics and acknowledgements (ahead, then out of order)."""
    nan = float('nan')
    joint = JointState(name=['q'], position=[nan], velocity=[nan], effort=[nan])
    pub = node.create_publisher
    attacks: list[tuple[Publisher[Any], object]] = [
        (pub(JointState, joint_states_topic(name), LINE_QOS), joint) for name in JOINT_NODES
    ]
    attacks += [
        (pub(Float64, SHEET_RATE_TOPIC, LINE_QOS), Float64(data=nan)),
        (pub(Float64, LANDING_TOPIC, LINE_QOS), Float64(data=nan)),
        (pub(UInt64, SHEET_COUNT_TOPIC, LINE_QOS), UInt64(data=2**63)),
        (pub(String, TUNE_TOPIC, TUNE_QOS), String(data='feed_transporter feed_transporter.V_tr=6.0')),
        (pub(String, SUPERVISOR_STATE_TOPIC, LINE_QOS), String(data='ABORTED')),
        (pub(String, PARTICIPANTS_TOPIC, PARTICIPANTS_QOS), String(data='clock=lockstep end=none participants=x')),
        (pub(TimeReference, COMMANDS_TOPIC, COMMANDS_QOS), _time_ref('supervisor', 10**9, 'stop')),
        (pub(TimeReference, EVENTS_TOPIC, LINE_QOS), _time_ref('knife', 10**9, 'jam sheet=1 cycle=1 value=nan')),
        (pub(TimeReference, GRANT_TOPIC, GRANT_QOS), _time_ref('line_clock', AHEAD_NS, 'step=5000000')),
        (pub(Clock, '/clock', CLOCK_QOS), Clock(clock=ns_to_time_msg(AHEAD_NS))),
        (
            pub(DiagnosticArray, DIAGNOSTICS_TOPIC, LINE_QOS),
            DiagnosticArray(status=[DiagnosticStatus(level=DiagnosticStatus.ERROR, name='forged')]),
        ),
    ]
    for p in KNOWN_PARTICIPANTS:
        for k, when in enumerate((AHEAD_NS, AHEAD_NS // 2, 1)):  # ahead, then out of order
            forged = _time_ref(p, when, 'messages=9999 events=0 commands=0')
            attacks.append((pub(TimeReference, tick_done_topic(p), TICK_QOS), forged))
            if k == 0:
                attacks.append((pub(TimeReference, progress_topic(p), ACK_QOS), forged))
    return attacks


def main(report: Path) -> None:
    rclpy.init()
    stranger = rclpy.create_node('stranger')
    impostor = rclpy.create_node('supervisor')  # a node named as one of the line's
    attacks = _attacks(stranger) + _attacks(impostor)
    heard: dict[str, int] = {}
    for topic, cls, qos in (('/clock', Clock, CLOCK_SUB_QOS), (SUPERVISOR_STATE_TOPIC, String, LINE_QOS)):
        stranger.create_subscription(cls, topic, lambda _m, t=topic: heard.__setitem__(t, heard.get(t, 0) + 1), qos)
    abort = stranger.create_client(Trigger, '/line/supervisor/abort')
    answered: list[bool] = []
    executor = SingleThreadedExecutor()
    executor.add_node(stranger)
    executor.add_node(impostor)
    published = 0
    calls = 0
    next_call = 0.0
    ready, stop = report.with_suffix('.ready'), report.with_suffix('.stop')
    while not stop.exists():
        for publisher, msg in attacks:
            publisher.publish(msg)
        published += len(attacks)
        if not ready.exists():
            ready.touch()
        if time.monotonic() >= next_call:
            abort.call_async(Trigger.Request()).add_done_callback(lambda f: answered.append(f.result().success))
            calls += 1
            next_call = time.monotonic() + 0.5
        executor.spin_once(timeout_sec=0.0)
    report.write_text(
        json.dumps(
            {'published': published, 'topics': len(attacks), 'heard': heard, 'calls': calls, 'answers': answered}
        )
    )
    executor.shutdown()
    rclpy.try_shutdown()


if __name__ == '__main__':
    main(Path(sys.argv[1]))
