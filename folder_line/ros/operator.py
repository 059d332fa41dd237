"""The operator's commands without the ``ros2`` CLI: one call of a supervisor service.

``folder-line hold`` (and ``unhold``, ``stop``, ``start``, ``suspend``, ``unsuspend``,
``reset``, ``clear``, ``abort``) calls ``/line/supervisor/<command>``
(``std_srvs/Trigger``) on the current ROS domain, as ``ros2 service call
/line/supervisor/hold std_srvs/srv/Trigger`` would, and returns the supervisor's answer:
accepted or refused, with its message (the state, and for a drive command when it takes
effect; or why the command is illegal now).
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass

import rclpy
from rclpy.client import Client
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from std_srvs.srv import Trigger

from folder_line.errors import ParameterError
from folder_line.interfaces import OPERATOR_COMMANDS

__all__ = ['COMMANDS', 'Answer', 'call_command', 'service_name']

#: the operator commands (:data:`folder_line.interfaces.OPERATOR_COMMANDS`)
COMMANDS: tuple[str, ...] = OPERATOR_COMMANDS


def service_name(command: str) -> str:
    """``/line/supervisor/<command>``."""
    return f'/line/supervisor/{command}'


@dataclass(frozen=True)
class Answer:
    """The supervisor's answer to one command.

    Attributes
    ----------
    accepted : bool
        ``Trigger.Response.success``.
    message : str
        ``Trigger.Response.message``: the new state and the drive command's effective
        time, or the reason for a refusal.
    """

    accepted: bool
    message: str


def call_command(command: str, timeout: float = 5.0) -> Answer | None:
    """Call the supervisor's service ``command`` once; None if no supervisor answered within ``timeout``.

    A node of its own (``folder_line_operator_<pid>``) in a context of its own: it waits
    for the service to be discovered, sends one request, waits for the answer, and is
    destroyed. rclpy's signal handlers are not installed, so Ctrl-C raises
    ``KeyboardInterrupt`` in the caller as usual.

    Parameters
    ----------
    command : str
        One of :data:`COMMANDS`.
    timeout : float
        Wall time to wait for the service, then again for its answer, s (> 0).

    Raises
    ------
    ParameterError
        ``command`` is not an operator command, or ``timeout`` is not > 0.
    """
    if command not in COMMANDS:
        raise ParameterError('command', command, f'must be one of {", ".join(COMMANDS)}')
    if not timeout > 0.0:
        raise ParameterError('--timeout', timeout, 'must be > 0 s')
    context = rclpy.Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    try:
        node = Node(f'folder_line_operator_{os.getpid()}', context=context)
        executor = SingleThreadedExecutor(context=context)
        try:
            executor.add_node(node)
            client: Client[Trigger.Request, Trigger.Response] = node.create_client(Trigger, service_name(command))
            deadline = time.monotonic() + timeout
            while not client.service_is_ready():  # discovery runs while the executor spins
                if time.monotonic() >= deadline:
                    return None
                executor.spin_once(timeout_sec=0.05)
            future = client.call_async(Trigger.Request())
            executor.spin_until_future_complete(future, timeout_sec=timeout)
            if not future.done():
                return None
            response = future.result()
            assert response is not None
            return Answer(bool(response.success), str(response.message))
        finally:
            executor.shutdown()
            node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)
