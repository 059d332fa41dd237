"""Someone who learnt the line's partition but not its key: it attacks every signed input of the line.

Run as a process (``python test/ros/_sniffer.py REPORT``) with :func:`_ros_env.sniffer_environment`:
the line's DDS profile (its partition), no ``FOLDER_LINE_KEY``. So the line's readers hear it, as they
would someone who read the partition's name off the network. Ten times a second it publishes:

* forged grants, ``progress`` and ``tick_done`` of every participant (stamped 100 s ahead), an
  announcement, a ``stop`` command and a retune of ``feed_transporter``, each once unsigned and once
  with a made-up signature;
* and, as it hears them, it plays again every grant, acknowledgement, command, tuning and announcement
  of the line.

It does not flood: a writer in the partition can fill the line's readers' histories, which DDS shares
between writers, and so slow or stall the line (the docs say so); what is tested is that nothing it
sends is taken.

Twice a second it asks, through the parameter services: ``V_tr=6.0`` of ``feed_transporter`` and
``rtf=0.25`` of ``line_clock``, unsigned and with a made-up signature; ``operator_command=abort`` of the
supervisor with a made-up signature, then the service ``/line/supervisor/abort``. It creates
``REPORT.ready`` once it has published every forgery once; when ``REPORT.stop`` appears it writes JSON
to ``REPORT``: how much it published and replayed, and every answer it got.
"""

from __future__ import annotations

import json
import secrets
import sys
import time
from pathlib import Path
from typing import Any

import rclpy
from _stranger import AHEAD_NS, _time_ref  # (run as a script: its folder is on the path)
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from sensor_msgs.msg import TimeReference
from std_msgs.msg import String
from std_srvs.srv import Trigger

from folder_line.interfaces import (
    COMMANDS_TOPIC,
    GRANT_TOPIC,
    KNOWN_PARTICIPANTS,
    PARTICIPANTS_TOPIC,
    TUNE_TOPIC,
    progress_topic,
    tick_done_topic,
)
from folder_line.ros.lockstep import ACK_QOS, GRANT_QOS, PARTICIPANTS_QOS, TICK_QOS
from folder_line.ros.signing import SIGNATURE_FIELD, SIGNATURE_PARAMETER
from folder_line.ros.topics import COMMANDS_QOS, TUNE_QOS

RETUNE = 'feed_transporter.V_tr=6.0'
ROUND = 0.1  # wall s between two rounds of forgeries


def _made_up(text: str) -> str:
    return f'{text}{SIGNATURE_FIELD}{secrets.token_hex(16)}'


def _signature() -> str:
    return f'{time.time_ns()}.{secrets.token_hex(8)}.{secrets.token_hex(16)}'


def _forgeries(node: Any) -> list[tuple[Any, Any]]:
    """``(publisher, message)`` of every forgery, once unsigned and once with a made-up signature."""
    pub = node.create_publisher
    forged: list[tuple[Any, Any]] = []
    for sign in (str, _made_up):
        forged += [
            (pub(TimeReference, GRANT_TOPIC, GRANT_QOS), _time_ref('line_clock', AHEAD_NS, sign('step=5000000'))),
            (pub(TimeReference, COMMANDS_TOPIC, COMMANDS_QOS), _time_ref('supervisor', 10**9, sign('stop'))),
            (pub(String, TUNE_TOPIC, TUNE_QOS), String(data=sign(f'feed_transporter {RETUNE} #{2**62}'))),
            (
                pub(String, PARTICIPANTS_TOPIC, PARTICIPANTS_QOS),
                String(data=sign('clock=lockstep end=none participants=crank_drive')),
            ),
        ]
        for p in KNOWN_PARTICIPANTS:
            ack = _time_ref(p, AHEAD_NS, sign('messages=9999 events=0 commands=0'))
            forged += [(pub(TimeReference, tick_done_topic(p), TICK_QOS), ack)]
            forged += [(pub(TimeReference, progress_topic(p), ACK_QOS), ack)]
    return forged


class _Requests:
    """The parameter requests and the abort call, each answer noted in :attr:`answers`."""

    def __init__(self, node: Any) -> None:
        self.feed = AsyncParameterClient(node, 'feed_transporter')
        self.clock = AsyncParameterClient(node, 'line_clock')
        self.supervisor = AsyncParameterClient(node, 'supervisor')
        self.abort = node.create_client(Trigger, '/line/supervisor/abort')
        self.answers: list[list[object]] = []
        self.calls = 0

    def ready(self) -> bool:
        return bool(self.abort.service_is_ready() and self.feed.services_are_ready())

    def answer(self, what: str) -> Any:
        def done(future: Any) -> None:
            result = future.result()
            if hasattr(result, 'results'):  # set_parameters: one result per parameter
                self.answers.extend([what, r.successful, r.reason] for r in result.results)
            elif hasattr(result, 'result'):  # set_parameters_atomically
                self.answers.append([what, result.result.successful, result.result.reason])
            else:  # Trigger
                self.answers.append([what, result.success, result.message])

        return done

    def send(self) -> None:
        v_tr = Parameter('V_tr', value=6.0)
        self.feed.set_parameters([v_tr]).add_done_callback(self.answer('V_tr unsigned'))
        signed = [v_tr, Parameter(SIGNATURE_PARAMETER, value=_signature())]
        self.feed.set_parameters_atomically(signed).add_done_callback(self.answer('V_tr made-up'))
        self.clock.set_parameters([Parameter('rtf', value=0.25)]).add_done_callback(self.answer('rtf unsigned'))
        command = [Parameter('operator_command', value='abort'), Parameter(SIGNATURE_PARAMETER, value=_signature())]
        self.supervisor.set_parameters_atomically(command).add_done_callback(self.answer('operator_command made-up'))
        self.abort.call_async(Trigger.Request()).add_done_callback(self.answer('abort'))
        self.calls += 1


def _listen_for_replays(node: Any, forged: list[tuple[Any, Any]], replays: list[tuple[Any, Any]]) -> None:
    """Subscribe to what the line publishes: each message heard goes to ``replays`` with the sniffer's own
    publisher of its topic (it hears the line's writers)."""

    def replay(publisher: Any) -> Any:
        def again(msg: Any) -> None:
            replays.append((publisher, msg))

        return again

    for cls, topic, qos in (
        (TimeReference, GRANT_TOPIC, GRANT_QOS),
        (TimeReference, COMMANDS_TOPIC, COMMANDS_QOS),
        (String, TUNE_TOPIC, TUNE_QOS),
        (String, PARTICIPANTS_TOPIC, PARTICIPANTS_QOS),
        *((TimeReference, progress_topic(p), ACK_QOS) for p in KNOWN_PARTICIPANTS),
        *((TimeReference, tick_done_topic(p), TICK_QOS) for p in KNOWN_PARTICIPANTS),
    ):
        again = next((p for p, _ in forged if p.topic_name == topic), None) or node.create_publisher(cls, topic, qos)
        node.create_subscription(cls, topic, replay(again), qos)


def main(report: Path) -> None:
    rclpy.init()
    node = rclpy.create_node('sniffer')
    forged = _forgeries(node)
    replays: list[tuple[Any, Any]] = []
    replayed = 0
    _listen_for_replays(node, forged, replays)
    requests = _Requests(node)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    published = 0
    next_call = 0.0
    ready, stop = report.with_suffix('.ready'), report.with_suffix('.stop')
    next_round = 0.0
    while not stop.exists():
        if time.monotonic() >= next_round:  # not a flood: the line must refuse each, not outlast a flood
            for publisher, msg in forged:
                publisher.publish(msg)
            published += len(forged)
            next_round = time.monotonic() + ROUND
        for publisher, msg in replays:
            publisher.publish(msg)
        replayed += len(replays)
        replays.clear()
        if not ready.exists():
            ready.touch()
        if time.monotonic() >= next_call and requests.ready():
            requests.send()
            next_call = time.monotonic() + 0.5
        executor.spin_once(timeout_sec=0.01)
    summary = {'published': published, 'topics': len(forged), 'calls': requests.calls, 'answers': requests.answers}
    report.write_text(json.dumps({**summary, 'replayed': replayed}))
    executor.shutdown()
    rclpy.try_shutdown()


if __name__ == '__main__':
    main(Path(sys.argv[1]))
