"""The operator's commands without the ``ros2`` CLI: one call of a supervisor service.

``folder-line hold`` (and ``unhold``, ``stop``, ``start``, ``suspend``, ``unsuspend``,
``reset``, ``clear``, ``abort``) calls ``/line/supervisor/<command>``
(``std_srvs/Trigger``) on the current ROS domain, as ``ros2 service call
/line/supervisor/hold std_srvs/srv/Trigger`` would, and returns the supervisor's answer:
accepted or refused, with its message (the state, and for a drive command when it takes
effect; or why the command is illegal now).

``folder-line tune KEY=VALUE`` sets the node parameter that tunes ``KEY``
(:data:`folder_line.interfaces.TUNABLE_PARAMETERS`), as ``ros2 param set`` would.

On a keyed line (``FOLDER_LINE_KEY``) both sign their request with the key
(:mod:`folder_line.ros.signing`): the tuning is set together with its ``line_signature``, and a
command's call is preceded by the supervisor's ``operator_command`` set so.
"""

from __future__ import annotations

import contextlib
import os
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import rclpy
from rclpy.client import Client
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.signals import SignalHandlerOptions
from std_srvs.srv import Trigger

from folder_line.core.line.tuning import TUNABLES
from folder_line.errors import ParameterError
from folder_line.interfaces import OPERATOR_COMMANDS, TUNABLE_PARAMETERS
from folder_line.ros.dds_profile import use_line_profile
from folder_line.ros.parameters import signed_change
from folder_line.ros.signing import SIGNATURE_PARAMETER, line_signer

__all__ = ['COMMANDS', 'Answer', 'call_command', 'call_tune', 'service_name', 'tunable_parameter']

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


@contextlib.contextmanager
def _session() -> Iterator[tuple[Node, SingleThreadedExecutor]]:
    """A node of its own (``folder_line_operator_<pid>``) in a context of its own, spun by its executor;
    rclpy's signal handlers are not installed, so Ctrl-C raises ``KeyboardInterrupt`` in the caller."""
    context = rclpy.Context()
    use_line_profile()  # before this process's first participant
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    try:
        node = Node(f'folder_line_operator_{os.getpid()}', context=context)
        executor = SingleThreadedExecutor(context=context)
        try:
            executor.add_node(node)
            yield node, executor
        finally:
            executor.shutdown()
            node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)


#: wall time a request waits once its service is found, s: the server must also have found this process's
#: reply reader by the time it answers, or the answer is lost (rmw_fastrtps waits only 100 ms for it,
#: ros2/rmw_fastrtps#467); discovery finds both sides at about the same time, but not at once on a busy host
REPLY_MATCH_WAIT = 0.5


def _until(executor: SingleThreadedExecutor, ready: Callable[[], bool], timeout: float) -> bool:
    """Spin until ``ready()`` (discovery runs while the executor spins), then :data:`REPLY_MATCH_WAIT` more;
    False after ``timeout`` s."""
    deadline = time.monotonic() + timeout
    while not ready():
        if time.monotonic() >= deadline:
            return False
        executor.spin_once(timeout_sec=0.05)
    settled = time.monotonic() + REPLY_MATCH_WAIT
    while time.monotonic() < settled:
        executor.spin_once(timeout_sec=max(0.0, min(0.05, settled - time.monotonic())))
    return True


def _check_timeout(timeout: float) -> None:
    if not timeout > 0.0:
        raise ParameterError('--timeout', timeout, 'must be > 0 s')


def _set_signed(
    node: Node, executor: SingleThreadedExecutor, target: str, parameters: list[Parameter[Any]], timeout: float
) -> Answer | None:
    """Set ``parameters`` of node ``target`` at once, signed on a keyed line
    (:func:`folder_line.ros.signing.sign_request`): None when accepted, else the refusal (an empty
    message: ``target`` did not answer within ``timeout``)."""
    client = AsyncParameterClient(node, target)
    if not _until(executor, client.services_are_ready, timeout):
        return Answer(False, '')
    parameters = signed_change(target, parameters)
    future = client.set_parameters_atomically(parameters)
    executor.spin_until_future_complete(future, timeout_sec=timeout)
    if not future.done():
        return Answer(False, '')
    response = future.result()
    assert response is not None
    if not response.result.successful:
        change = ', '.join(f'{p.name}={p.value!r}' for p in parameters if p.name != SIGNATURE_PARAMETER)
        return Answer(False, f'/{target} {change}: {response.result.reason}')
    return None


def call_command(command: str, timeout: float = 5.0) -> Answer | None:
    """Call the supervisor's service ``command`` once; None if no supervisor answered within ``timeout``.

    A node of its own in a context of its own (:func:`_session`): it waits for the service
    to be discovered, sends one request, waits for the answer, and is destroyed.

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
    _check_timeout(timeout)
    with _session() as (node, executor):
        client: Client[Trigger.Request, Trigger.Response] = node.create_client(Trigger, service_name(command))
        if not _until(executor, client.service_is_ready, timeout):
            return None
        if line_signer().keyed:  # a keyed line takes a command whose request is signed first
            refused = _set_signed(node, executor, 'supervisor', [Parameter('operator_command', value=command)], timeout)
            if refused is not None:
                return refused if refused.message else None
        future = client.call_async(Trigger.Request())
        executor.spin_until_future_complete(future, timeout_sec=timeout)
        if not future.done():
            return None
        response = future.result()
        assert response is not None
        return Answer(bool(response.success), str(response.message))


def tunable_parameter(key: str) -> tuple[str, str]:
    """``(node, parameter)`` that tunes ``key`` (:data:`folder_line.interfaces.TUNABLE_PARAMETERS`)."""
    for node, params in TUNABLE_PARAMETERS.items():
        for param, tuned in params.items():
            if tuned == key:
                return node, param
    raise ParameterError('KEY', key, f'is not tunable; tunable: {", ".join(TUNABLES)}')


def call_tune(key: str, value: float, timeout: float = 5.0) -> Answer | None:
    """Set the node parameter that tunes ``key`` to ``value``, as ``ros2 param set /<node> <param> <value>``
    would; None if the node did not answer within ``timeout``.

    The node checks the value as any parameter (range, the scene) and forwards it to the
    supervisor, which times it at the next machine cycle boundary and publishes it on
    ``/line/supervisor/commands`` with its effective time.

    Raises
    ------
    ParameterError
        ``key`` is not tunable, or ``timeout`` is not > 0.
    """
    _check_timeout(timeout)
    target, param = tunable_parameter(key)
    with _session() as (node, executor):
        refused = _set_signed(node, executor, target, [Parameter(param, value=float(value))], timeout)
        if refused is not None:
            return None if not refused.message else refused
        unit = TUNABLES[key].unit
        return Answer(
            True,
            f'/{target} {param} = {float(value)!r} {unit}: the supervisor times it at the next machine cycle '
            'boundary (its effective time is on /line/supervisor/commands and in the run log)',
        )
