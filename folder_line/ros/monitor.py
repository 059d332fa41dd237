"""The monitor's side of the ROS graph: subscriptions to every topic of the line, fed into a callable.

:class:`MonitorNode` subscribes to every topic of :data:`folder_line.ros.recorder.LINE_TOPICS`
and hands each message, with the wall time its publisher wrote it, to a ``sink(topic,
msg, wall)`` it is given (``folder-line monitor`` gives
:meth:`folder_line.cli.monitor_view.MonitorState.ingest`); it keeps nothing of the
messages but their counts. :func:`monitor_session` runs it in a private context on a
``SingleThreadedExecutor``, with SIGINT and SIGTERM turned into a stop request, and
yields a :class:`MonitorSession` that runs the ready callbacks in batches
(:meth:`~MonitorSession.drain`) or collects for a while (:meth:`~MonitorSession.collect`).

What is shown, and how, is the CLI's (:mod:`folder_line.cli.monitor`); this module
does not import it. The monitor takes no part in the lockstep: it never holds the line up.
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from typing import Any

import rclpy
from rclpy.client import Client
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rclpy.subscription import MessageInfo
from std_srvs.srv import Trigger

from folder_line.interfaces import (
    COMMANDS_TOPIC,
    EVENTS_TOPIC,
    LANDING_TOPIC,
    NS_PER_S,
    PARTICIPANTS_TOPIC,
    SUPERVISOR_STATE_TOPIC,
)
from folder_line.ros.dds_profile import use_line_profile
from folder_line.ros.parameters import signed_change
from folder_line.ros.player import line_qos
from folder_line.ros.recorder import LINE_TOPICS
from folder_line.ros.runtime import SignalHandler
from folder_line.ros.signing import line_signer
from folder_line.ros.topics import COMMANDS_QOS

__all__ = [
    'ALWAYS_HELD',
    'BATCH',
    'INTERMITTENT',
    'KEY_PERIOD',
    'LATCHED',
    'QUEUE_DEPTH',
    'MessageSink',
    'MonitorNode',
    'MonitorSession',
    'monitor_session',
]

MessageSink = Callable[[str, object, float], None]
"""``sink(topic, msg, wall)``: takes one message of ``topic`` written at wall time ``wall``, s."""

QUEUE_DEPTH = 200
"""Depth of the monitor's subscriptions: a second of a 200 Hz topic, ten rounds of :data:`BATCH`
at ten times that rate."""

BATCH = 0.02
"""Wall time, s, the monitor sleeps between two rounds of callbacks. Messages queue up
meanwhile (their reception times are kept by the middleware), so one wait of the
executor finds many ready at once: about a third of the CPU time of waking up for
every single message (the executor rebuilds its wait set on each wake-up)."""

KEY_PERIOD = 0.05
"""Longest wall time, s, between two looks at the keyboard (and at a stop request)."""

ALWAYS_HELD = (PARTICIPANTS_TOPIC, SUPERVISOR_STATE_TOPIC)
"""Latched topics whose publisher always holds a message (the announcement, the state; the commands may
hold none): a snapshot waits for them (:meth:`MonitorSession.missing_history`)."""

INTERMITTENT = (PARTICIPANTS_TOPIC, COMMANDS_TOPIC, EVENTS_TOPIC, LANDING_TOPIC)
"""Topics that may be silent for long while the line runs (no command, a held line's events, no leaves):
a snapshot does not wait for them to flow (:meth:`MonitorSession.not_flowing`)."""

LATCHED = (PARTICIPANTS_TOPIC, SUPERVISOR_STATE_TOPIC, COMMANDS_TOPIC)
"""Topics whose history (what their publishers held when the monitor joined) is shown: the current state,
the participants, the commands so far. They do not show that the line runs."""


def _subscription_qos(topic: str) -> QoSProfile:
    """Reliable, :data:`QUEUE_DEPTH` deep, with the durability of the line's publisher of ``topic``.

    Transient-local wherever that publisher is (every topic but ``/clock``), not only on the
    :data:`LATCHED` topics: a volatile reliable reader that joins a transient-local publisher
    holding a history gets, with Fast DDS, nothing until that publisher's next heartbeat (up to
    seconds between processes; between two contexts of one process, nothing at all in our runs), so
    a topic could show 0 for a whole ``--once`` window while it was being published. The history
    that comes instead is dropped by :class:`MonitorNode`, except on the latched topics.
    """
    if topic == COMMANDS_TOPIC:  # every command so far, late joiner too
        return COMMANDS_QOS
    return QoSProfile(depth=QUEUE_DEPTH, reliability=ReliabilityPolicy.RELIABLE, durability=line_qos(topic).durability)


class MonitorNode(Node):
    """Subscribes to every topic of the line and feeds each message to ``sink``.

    Reliable subscriptions keeping the last :data:`QUEUE_DEPTH` messages (a monitor
    that falls further behind loses old ones, it never holds the line up),
    transient-local where the line's publisher is (every topic but ``/clock``; see
    :func:`_subscription_qos`); the drive commands with the commands' own QoS, so every
    command so far shows. What a transient-local publisher held from before the monitor
    started (its source timestamp earlier than :attr:`since_ns`) is dropped, so the
    counts are those of messages written since the monitor started, except on the
    :data:`LATCHED` topics, whose history shows at once (the current state, the
    participants, the commands so far). Source timestamps are the publisher's system
    clock: on another host, it must agree with this one (as the rates need too).

    Parameters
    ----------
    sink : MessageSink
        Gets ``sink(topic, msg, wall)`` for every message, ``wall`` being the
        message's source timestamp (system clock, s: when the publisher wrote it,
        which on one host is when it arrived here to within the transport's
        latency). So the rates are those the line publishes at, not the bursts in
        which a monitor busy drawing, starved of CPU or just joined (the state's
        history) takes the messages. Failing that, the middleware's reception time,
        failing that ``time.time()``.
    topics : mapping of str to type, optional
        Topic -> message class (default :data:`folder_line.ros.recorder.LINE_TOPICS`).
    **kwargs
        Passed to ``rclpy.node.Node`` (``context`` ...).

    Attributes
    ----------
    received : dict of str to int
        Messages handed to ``sink`` so far, per topic (every subscribed topic, from 0).
    total : int
        Their sum.
    since_ns : int
        System time the subscriptions were made at, ns.
    history : dict of str to int
        Messages dropped so far, per topic: written before :attr:`since_ns`.
    """

    def __init__(self, sink: MessageSink, topics: dict[str, type] | None = None, **kwargs: Any) -> None:
        super().__init__(f'line_monitor_{os.getpid()}', **kwargs)
        self.sink = sink
        self.total = 0
        topics = LINE_TOPICS if topics is None else topics
        self.received: dict[str, int] = dict.fromkeys(topics, 0)
        self.history: dict[str, int] = dict.fromkeys(topics, 0)
        self.since_ns = time.time_ns()
        self.subscription_of = {
            topic: self.create_subscription(cls, topic, self._callback(topic), _subscription_qos(topic))
            for topic, cls in topics.items()
        }

    def _callback(self, topic: str) -> Callable[[object, MessageInfo], None]:
        keep_history = topic in LATCHED

        def on_message(msg: object, info: MessageInfo) -> None:
            written = info.get('source_timestamp', 0)
            if 0 < written < self.since_ns and not keep_history:
                self.history[topic] += 1
                return
            stamp = written or info.get('received_timestamp', 0)
            self.received[topic] += 1
            self.total += 1
            self.sink(topic, msg, stamp / NS_PER_S if stamp > 0 else time.time())

        return on_message


class _Stop:
    """SIGINT/SIGTERM -> a flag (checked between callbacks); a second SIGINT raises KeyboardInterrupt."""

    def __init__(self) -> None:
        self.event = threading.Event()
        self._previous: dict[int, SignalHandler] = {}

    def __enter__(self) -> _Stop:
        if threading.current_thread() is threading.main_thread():
            for signum in (signal.SIGINT, signal.SIGTERM):
                self._previous[signum] = signal.signal(signum, self._on_signal)
        return self

    def _on_signal(self, signum: int, frame: object) -> None:
        if self.event.is_set() and signum == signal.SIGINT:
            raise KeyboardInterrupt
        self.event.set()

    def __exit__(self, *exc: object) -> None:
        for signum, handler in self._previous.items():
            signal.signal(signum, signal.SIG_DFL if handler is None else handler)


class MonitorSession:
    """A running :class:`MonitorNode` and its executor (see :func:`monitor_session`).

    Attributes
    ----------
    node : MonitorNode
        The node (its ``received`` counts).
    stop : threading.Event
        Set by SIGINT or SIGTERM.
    """

    def __init__(self, executor: SingleThreadedExecutor, node: MonitorNode, stop: threading.Event) -> None:
        self.executor = executor
        self.node = node
        self.stop = stop
        self.clients: dict[str, Client[Trigger.Request, Trigger.Response]] = {}
        self._parameters: AsyncParameterClient | None = None  # the supervisor's, to sign a command

    def command(self, name: str, on_answer: Callable[[bool, str], None]) -> bool:
        """Call the supervisor's operator service ``name`` without waiting; False if no supervisor offers it.

        ``on_answer(accepted, message)`` runs in a later :meth:`drain` when the answer
        arrives (``std_srvs/Trigger``: ``success`` and ``message``).
        """
        client = self.clients.get(name)
        if client is None:
            client = self.clients[name] = self.node.create_client(Trigger, f'/line/supervisor/{name}')
        if not client.service_is_ready():
            return False

        def answered(f: Any) -> None:  # Any: a done future (rclpy types its result Optional)
            response = f.result()
            on_answer(bool(response.success), str(response.message))

        def call() -> None:
            client.call_async(Trigger.Request()).add_done_callback(answered)

        if not line_signer().keyed:
            call()
            return True
        # a keyed line takes a command whose request is signed first (as folder-line hold does)
        if self._parameters is None:
            self._parameters = AsyncParameterClient(self.node, 'supervisor')
        request = signed_change('supervisor', [Parameter('operator_command', value=name)])

        def signed(f: Any) -> None:
            result = f.result().result
            if result.successful:
                call()
            else:
                on_answer(False, f'operator_command={name!r}: {result.reason}')

        self._parameters.set_parameters_atomically(request).add_done_callback(signed)
        return True

    @property
    def stopped(self) -> bool:
        """A stop was requested (SIGINT or SIGTERM)."""
        return self.stop.is_set()

    def live(self) -> bool:
        """A message of the running line arrived, not only one a transient-local topic kept for late joiners."""
        return any(n for topic, n in self.node.received.items() if topic not in LATCHED)

    def drain(self, budget: float) -> None:
        """Run the callbacks that are ready, until none is or ``budget`` s of wall time have passed.

        ``spin_once`` gets the same (zero) timeout every time, so that the executor keeps
        the ready callbacks of one wait and hands them out without waiting again. It
        runs no message callback once per wait (at the end of the ready list), so the
        queues are empty only after two such calls in a row.
        """
        end = time.monotonic() + budget
        idle = 0
        while idle < 2 and time.monotonic() < end:
            before = self.node.total
            self.executor.spin_once(timeout_sec=0.0)
            idle = idle + 1 if self.node.total == before else 0

    def collect(self, timeout: float, window: float) -> None:
        """Wait up to ``timeout`` s of wall time for the line (:meth:`live`), then take its messages for ``window`` s.

        Returns at once on a stop request, and after the wait if nothing at all arrived. The window
        starts once every topic that flows steadily has delivered (:meth:`not_flowing`). After the
        window it waits on (up to ``timeout`` from the start) for the held message of every
        :data:`ALWAYS_HELD` topic whose publisher is matched (:meth:`missing_history`).
        """
        deadline = time.monotonic() + timeout
        while not self.stopped and not self.live() and time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.05)
        if self.node.total == 0:
            return
        # the window starts once every steady topic with a matched publisher flows: under load a process
        # discovers, or gets the first data of, some of a line's publishers seconds after the others
        while not self.stopped and self.not_flowing() and time.monotonic() < deadline:
            self.drain(KEY_PERIOD)
            time.sleep(BATCH)
        end = time.monotonic() + window
        while not self.stopped and time.monotonic() < end:
            self.drain(KEY_PERIOD)
            time.sleep(max(min(BATCH, end - time.monotonic()), 0.0))
        self.drain(KEY_PERIOD)
        # a held message of a matched publisher comes with its heartbeat, which may be seconds away: wait for it
        while not self.stopped and self.missing_history() and time.monotonic() < deadline:
            self.drain(KEY_PERIOD)
            time.sleep(BATCH)

    def not_flowing(self) -> list[str]:
        """Topics not in :data:`INTERMITTENT` with a matched publisher and no message received yet."""
        return [
            topic
            for topic, sub in self.node.subscription_of.items()
            if topic not in INTERMITTENT and self.node.received[topic] == 0 and sub.get_publisher_count() > 0
        ]

    def missing_history(self) -> list[str]:
        """Topics of :data:`ALWAYS_HELD` with a matched publisher whose held message has not arrived yet.

        A reliable transient-local writer sends what it holds to a new reader after an exchange of
        heartbeat and acknowledgement; when the first heartbeat finds the reader not yet ready, the
        next one comes a heartbeat period later (3 s with Fast DDS), so a snapshot's window can end
        before the announcement or the state arrives although their publisher is known.
        """
        return [
            topic
            for topic in ALWAYS_HELD
            if topic in self.node.subscription_of
            and self.node.received[topic] == 0
            and self.node.subscription_of[topic].get_publisher_count() > 0
        ]


@contextlib.contextmanager
def monitor_session(
    sink: MessageSink, argv: Sequence[str] | None = None, topics: dict[str, type] | None = None
) -> Iterator[MonitorSession]:
    """A :class:`MonitorNode` feeding ``sink``, in a context and on an executor of its own, for a ``with`` block.

    rclpy's signal handlers are not installed: in the main thread SIGINT and SIGTERM set
    :attr:`MonitorSession.stop` (checked between callbacks) and a second SIGINT raises
    ``KeyboardInterrupt``; the previous handlers are back, the node destroyed and the
    context shut down when the block ends, however it ends.

    Parameters
    ----------
    sink : MessageSink
        See :class:`MonitorNode`.
    argv : sequence of str, optional
        ``rclpy.init`` arguments (default none).
    topics : mapping of str to type, optional
        See :class:`MonitorNode`.
    """
    context = rclpy.Context()
    try:
        with _Stop() as stop:
            use_line_profile()  # before this process's first participant
            rclpy.init(args=list(argv or []), context=context, signal_handler_options=SignalHandlerOptions.NO)
            executor = SingleThreadedExecutor(context=context)
            node = MonitorNode(sink, topics, context=context)
            try:
                executor.add_node(node)
                yield MonitorSession(executor, node, stop.event)
            finally:
                executor.shutdown()
                node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)
