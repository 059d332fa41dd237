"""Node tests over real DDS: one ROS domain per test process, one rclpy context per test.

The domain id is derived from the pid (1..100, never 0, the default of any other ROS
graph on the machine) and discovery is kept to this host; both are set in
``os.environ`` before rclpy is imported, so the contexts of this process and the
node processes it starts share them and nothing else does.
"""

from __future__ import annotations

import os

# read by rclpy when it is imported; only os.environ changes here, so the imports below count as at the top
os.environ['ROS_DOMAIN_ID'] = str(1 + os.getpid() % 100)
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.pop('ROS_STATIC_PEERS', None)
os.environ.pop('ROS_LOCALHOST_ONLY', None)  # deprecated; would conflict with the range above

import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

import pytest
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile

DOMAIN_ID = int(os.environ['ROS_DOMAIN_ID'])  # 1..100 from the pid, set above

REPO = Path(__file__).resolve().parents[2]

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


def pytest_configure(config: pytest.Config) -> None:
    # rosidl_generator_py (imported by the first node) imports lark 0.12, which
    # imports the deprecated sre_parse/sre_constants: not ours, not actionable.
    for module in ('sre_parse', 'sre_constants'):
        config.addinivalue_line('filterwarnings', f"ignore:module '{module}' is deprecated:DeprecationWarning")


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


@pytest.fixture
def node_env() -> dict[str, str]:
    """Environment for a node process: this process's domain, and the repository importable."""
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join(p for p in (str(REPO), env.get('PYTHONPATH', '')) if p)
    env['PYTHONUNBUFFERED'] = '1'
    env['RCUTILS_COLORIZED_OUTPUT'] = '0'
    return env
