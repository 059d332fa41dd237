"""``folder-line bag play``: a recorded bag republished on the line's topics, with ``/clock``.

One node, ``bag_player``, publishes every topic played on the QoS its publishers
offered when it was recorded (:func:`folder_line.bag.playback.recorded_qos`) or, where
the bag recorded none (the line's bags), on the QoS the line's own publisher of that
topic has (:func:`line_qos`). Messages go out as the CDR bytes the bag holds, never
deserialized, so a subscriber receives byte for byte what was recorded, stamps
included. ``/clock`` is the bag's own ``/clock`` where it has one (the line records
every tick, and every message is logged at a tick); a bag without one gets a
``rosgraph_msgs/Clock`` at each new log time. Messages are paced at ``rtf`` times real
time (0: as fast as DDS takes them). Ctrl-C stops playing; the node is destroyed and
:func:`play_bag` returns normally.
"""

from __future__ import annotations

import contextlib
import importlib
import signal
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import TextIO

import rclpy
from rclpy.context import Context
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rclpy.type_support import Msg
from rosgraph_msgs.msg import Clock

from folder_line.bag.playback import PlayPlan, QosSpec, play_plan, raw_messages, recorded_qos, wall_offset
from folder_line.interfaces import (
    CLOCK_TOPIC,
    COMMANDS_TOPIC,
    NS_PER_S,
    PARTICIPANTS_TOPIC,
    SUPERVISOR_STATE_TOPIC,
)
from folder_line.ros.dds_profile import use_line_profile
from folder_line.ros.lockstep import LINE_QOS, PARTICIPANTS_QOS
from folder_line.ros.nodes.supervisor import STATE_QOS
from folder_line.ros.topics import CLOCK_QOS, COMMANDS_QOS

__all__ = ['PLAYER', 'PlayResult', 'line_qos', 'message_class', 'play_bag']

#: the player's node name
PLAYER = 'bag_player'

#: wall time, s, the player waits at the end for reliable subscribers to acknowledge every message
ACK_TIMEOUT = 5.0

_LINE_QOS_OF: dict[str, QoSProfile] = {
    CLOCK_TOPIC: CLOCK_QOS,
    SUPERVISOR_STATE_TOPIC: STATE_QOS,
    COMMANDS_TOPIC: COMMANDS_QOS,
    PARTICIPANTS_TOPIC: PARTICIPANTS_QOS,
}


def line_qos(topic: str) -> QoSProfile:
    """The QoS the live line's publisher of ``topic`` has (:data:`LINE_QOS` for the data topics and any other)."""
    return _LINE_QOS_OF.get(topic, LINE_QOS)


def _profile(spec: QosSpec) -> QoSProfile:
    return QoSProfile(
        depth=spec.depth,
        reliability=ReliabilityPolicy.BEST_EFFORT if spec.reliability == 'best_effort' else ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL
        if spec.durability == 'transient_local'
        else DurabilityPolicy.VOLATILE,
        history=HistoryPolicy.KEEP_ALL if spec.history == 'keep_all' else HistoryPolicy.KEEP_LAST,
    )


def message_class(msgtype: str) -> type[Msg]:
    """The rclpy class of ``'pkg/msg/Type'``."""
    package, kind, name = msgtype.split('/')
    cls: type[Msg] = getattr(importlib.import_module(f'{package}.{kind}'), name)
    return cls


@dataclass(frozen=True)
class PlayResult:
    """What :func:`play_bag` played.

    Attributes
    ----------
    published : dict of str to int
        Topic -> messages published (``/clock`` made by the player included).
    passes : int
        Passes over the window begun (more than one with ``loop``).
    line_time : float
        Line time of the last message published, s.
    wall_time : float
        Wall time spent playing, s.
    interrupted : bool
        Stopped by Ctrl-C (or ``should_stop``).
    """

    published: dict[str, int]
    passes: int
    line_time: float
    wall_time: float
    interrupted: bool


class _Player:
    """The node and its publishers, one per topic played (raw CDR)."""

    def __init__(self, plan: PlayPlan, context: Context) -> None:
        self.node = Node(PLAYER, context=context)
        recorded = recorded_qos(plan.bag)
        self.pubs: dict[str, Publisher[Msg]] = {}
        for topic, msgtype in plan.topics.items():
            qos = _profile(recorded[topic]) if topic in recorded else line_qos(topic)
            self.pubs[topic] = self.node.create_publisher(message_class(msgtype), topic, qos)
        if not plan.has_clock:
            qos = _profile(recorded[CLOCK_TOPIC]) if CLOCK_TOPIC in recorded else CLOCK_QOS
            self.pubs[CLOCK_TOPIC] = self.node.create_publisher(Clock, CLOCK_TOPIC, qos)
        self.counts: dict[str, int] = dict.fromkeys(self.pubs, 0)
        self.clock_ns = -1
        self.last_ns = -1  # log time of the latest message published (what a Ctrl-C summary reports)

    def publish(self, topic: str, data: bytes) -> None:
        self.pubs[topic].publish(data)
        self.counts[topic] += 1

    def clock(self, t_ns: int) -> None:
        msg = Clock()
        msg.clock.sec, msg.clock.nanosec = divmod(t_ns, NS_PER_S)
        self.pubs[CLOCK_TOPIC].publish(msg)
        self.counts[CLOCK_TOPIC] += 1

    def wait_for_subscribers(self, timeout: float) -> None:
        """Wait up to ``timeout`` s of wall time until every publisher has a subscriber."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline and any(p.get_subscription_count() == 0 for p in self.pubs.values()):
            time.sleep(0.01)

    def drain(self) -> None:
        """Let reliable subscribers acknowledge what was published (bounded by :data:`ACK_TIMEOUT`)."""
        deadline = time.monotonic() + ACK_TIMEOUT
        for pub in self.pubs.values():
            left = max(deadline - time.monotonic(), 0.0)
            pub.wait_for_all_acked(Duration(nanoseconds=int(left * NS_PER_S)))


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


@contextlib.contextmanager
def _stop_on_signals() -> Iterator[None]:
    """SIGINT and SIGTERM raise ``KeyboardInterrupt`` while playing (in the main thread; a shell may have started
    the process with SIGINT ignored); the previous handlers come back afterwards."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {signum: signal.signal(signum, _interrupt) for signum in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, signal.SIG_DFL if handler is None else handler)


def _play_pass(player: _Player, plan: PlayPlan, rtf: float, should_stop: Callable[[], bool]) -> tuple[int, bool]:
    """One pass over the window; (log time of the last message or -1, stopped)."""
    wall0 = time.monotonic()
    first = -1
    last = -1
    for topic, t_ns, data in raw_messages(plan):
        if should_stop():
            return last, True
        if first < 0:
            first = t_ns
        due = wall0 + wall_offset(t_ns, first, rtf)
        wait = due - time.monotonic()
        if wait > 0:
            time.sleep(wait)
        if not plan.has_clock and t_ns != player.clock_ns:
            player.clock(t_ns)
            player.clock_ns = t_ns
        player.publish(topic, data)
        last = player.last_ns = t_ns
    return last, False


def play_bag(
    path: str,
    *,
    rtf: float = 1.0,
    start: float = 0.0,
    duration: float | None = None,
    topics: Sequence[str] = (),
    loop: bool = False,
    wait_for_subscribers: float = 0.0,
    should_stop: Callable[[], bool] = lambda: False,
    stream: TextIO | None = None,
    argv: Sequence[str] | None = None,
) -> PlayResult:
    """Republish the bag ``path`` on its topics with ``/clock`` (``folder-line bag play``).

    The bag and the options are checked (:func:`folder_line.bag.playback.play_plan`)
    before rclpy starts. Ctrl-C (``KeyboardInterrupt``) or ``should_stop()`` ends playing;
    the node is destroyed and the context shut down in every case.

    Parameters
    ----------
    path : str
        The bag directory.
    rtf : float, optional
        Line seconds played per wall second; 0: as fast as possible.
    start : float, optional
        Where to begin, s after the bag's first message.
    duration : float, optional
        How much to play, s of line time (default: to the end).
    topics : sequence of str, optional
        Only these topics (default all); ``/clock`` always.
    loop : bool, optional
        Play the window again and again until stopped.
    wait_for_subscribers : float, optional
        Before playing, wait up to this many s of wall time for every topic to have a subscriber.
    should_stop : callable, optional
        Polled before each message; True stops playing.
    stream : file, optional
        Where a line per pass goes (None: nowhere).
    argv : sequence of str, optional
        ``rclpy.init`` arguments.

    Raises
    ------
    BagError, ParameterError
        The bag cannot be opened; a topic or ``start`` it does not have.
    """
    plan = play_plan(path, start, duration, topics)
    context = Context()
    use_line_profile()  # before this process's first participant
    rclpy.init(
        args=None if argv is None else list(argv), context=context, signal_handler_options=SignalHandlerOptions.NO
    )
    wall0 = time.monotonic()
    passes, last, stopped = 0, -1, False
    player: _Player | None = None
    with _stop_on_signals():
        try:
            player = _Player(plan, context)
            player.wait_for_subscribers(wait_for_subscribers)
            wall0 = time.monotonic()
            while not stopped:
                passes += 1
                if stream is not None:
                    stream.write(
                        f'playing {plan.bag.path}: {plan.start_ns / NS_PER_S:.9g} .. {plan.end_ns / NS_PER_S:.9g} '
                        f's of line time, {len(plan.topics)} topics, pass {passes}\n'
                    )
                    stream.flush()
                t, stopped = _play_pass(player, plan, rtf, should_stop)
                last = max(last, t)
                if not loop or t < 0:
                    break
            player.drain()
        except KeyboardInterrupt:
            stopped = True
            if player is not None:  # stopped inside a pass: the line time played so far
                last = max(last, player.last_ns)
        finally:
            counts = dict(player.counts) if player is not None else {}
            if player is not None:
                player.node.destroy_node()
            context.try_shutdown()
    return PlayResult(
        published=counts,
        passes=passes,
        line_time=max(last, 0) / NS_PER_S,
        wall_time=time.monotonic() - wall0,
        interrupted=stopped,
    )
