"""Node tests over real DDS: one rclpy context per test (:func:`ros`).

The ROS domain (one per test process) and the discovery range are set for the whole test
process by ``test/conftest.py`` (:mod:`_ros_env`), before rclpy is imported here; so the
contexts of this process and the node processes it starts (``node_env``) share them and
nothing else does.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any, TypeVar

import pytest
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile

N = TypeVar('N', bound=Node)


@dataclass
class Received:
    """Messages of one subscription, with the steady wall time of their arrival (ns)."""

    messages: list[Any] = field(default_factory=list)
    arrival_ns: list[int] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.messages)


@dataclass
class Ros:
    """A private rclpy context with its executor, for one test.

    Attributes
    ----------
    context : rclpy.context.Context
        Initialised for this test only (no signal handlers).
    executor : rclpy.executors.SingleThreadedExecutor
        Spins every node added with :meth:`add` or :meth:`node`.
    """

    context: Context
    executor: SingleThreadedExecutor
    nodes: list[Node] = field(default_factory=list)

    def add(self, node: N) -> N:
        """Spin ``node`` (built with ``context=self.context``) and destroy it after the test."""
        self.nodes.append(node)
        self.executor.add_node(node)
        return node

    def remove(self, node: Node) -> None:
        """Stop spinning ``node`` and destroy it now (its endpoints leave the graph, as when its process ends)."""
        self.executor.remove_node(node)
        self.nodes.remove(node)
        node.destroy_node()

    def node(self, name: str, **kwargs: Any) -> Node:
        """A plain node in this context."""
        return self.add(rclpy.create_node(name, context=self.context, **kwargs))

    def subscribe(self, node: Node, msg_type: type, topic: str, qos: QoSProfile | int = 100) -> Received:
        """Collect every message of ``topic`` into a :class:`Received`."""
        received = Received()

        def on_message(msg: Any) -> None:
            received.arrival_ns.append(time.monotonic_ns())
            received.messages.append(msg)

        node.create_subscription(msg_type, topic, on_message, qos)
        return received

    def spin_until(self, predicate: Callable[[], bool], timeout: float) -> bool:
        """Spin until ``predicate()`` is true or ``timeout`` s of wall time have passed; return it."""
        deadline = time.monotonic() + timeout
        while not predicate():
            remaining = deadline - time.monotonic()
            if remaining <= 0.0:
                return predicate()
            self.executor.spin_once(timeout_sec=min(remaining, 0.05))
        return True

    def spin_for(self, seconds: float) -> None:
        """Spin for a measurement window of ``seconds`` of wall time."""
        self.spin_until(lambda: False, seconds)


@pytest.fixture
def ros() -> Iterator[Ros]:
    """A :class:`Ros` with its own context, shut down after the test."""
    context = Context()
    rclpy.init(context=context)
    harness = Ros(context, SingleThreadedExecutor(context=context))
    try:
        yield harness
    finally:
        harness.executor.shutdown()
        for node in harness.nodes:
            node.destroy_node()
        rclpy.try_shutdown(context=context)
