"""A float parameter takes an integer (``rate:=200``, ``ros2 param set /node rate 200``) and stores a float.

Real rclpy nodes over real DDS: in-process nodes declared with
:func:`folder_line.ros.parameters.declare_parameters` (overrides from ``--ros-args``, from the
constructor, changes through ``set_parameters`` and through the parameter service as the
``ros2 param`` command sends them), and node processes started as launch starts them. A bool
or a string for a float is still refused, with one line naming the parameter and the value.
"""

from __future__ import annotations

import signal
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest
import rclpy
from rcl_interfaces.msg import ParameterType
from rclpy.context import Context
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient

from folder_line.errors import AssemblyError, ParameterError
from folder_line.ros.parameters import ParamSpec, declare_parameters, parameter_values, sim_time_overrides

from ._node_process import assert_clean_exit, executable, send, start, unique_name
from ._signed import signed

if TYPE_CHECKING:
    from .conftest import Ros

GAIN = ParamSpec('gain', 1.0, 'Gain', bounds=(0.0, 10.0), low_open=True)
OFFSET = ParamSpec('offset', 0.0, 'Unbounded offset', unit='m')
COUNT = ParamSpec('count', 3, 'Number of things', bounds=(1, 100))
FIXED = ParamSpec('fixed', 0.5, 'Set at start only', unit='s', bounds=(0.0, 1.0), read_only=True)
LO = ParamSpec('lo', 0.0, 'Lower end', unit='m', bounds=(-100.0, 100.0))
HI = ParamSpec('hi', 1.0, 'Upper end', unit='m', bounds=(-100.0, 100.0))
SPECS = (GAIN, OFFSET, COUNT, FIXED, LO, HI)


def ordered(values: Mapping[str, Any]) -> None:
    if values['lo'] >= values['hi']:
        raise AssemblyError('probe', 0.0, f'lo={values["lo"]!r} m must be below hi={values["hi"]!r} m')


class Probe(Node):
    """Declares SPECS; records the type of every value its post-set callback sees."""

    def __init__(self, **kwargs: Any) -> None:
        overrides = kwargs.pop('parameter_overrides', None)
        super().__init__('int_probe', parameter_overrides=sim_time_overrides(overrides), **kwargs)
        self.start = declare_parameters(self, SPECS, cross_check=ordered)
        self.applied: list[tuple[str, object]] = []
        self.add_post_set_parameters_callback(lambda ps: self.applied.extend((p.name, p.value) for p in ps))


@pytest.fixture
def ros_args_context() -> Iterator[Context]:
    """A context whose command line sets integers for float parameters, as ``--ros-args -p`` does."""
    context = Context()
    rclpy.init(
        context=context,
        args=['--ros-args', '-p', 'gain:=2', '-p', 'fixed:=1', '-p', 'offset:=-3', '-p', 'count:=5', '-p', 'lo:=-7'],
    )
    try:
        yield context
    finally:
        rclpy.try_shutdown(context=context)


def _types(node: Node) -> dict[str, int]:
    names = [spec.name for spec in SPECS]
    return {d.name: d.type for d in node.describe_parameters(names)}


def test_integers_from_ros_args_start_float_parameters_as_floats(ros_args_context: Context) -> None:
    probe = Probe(context=ros_args_context)
    try:
        assert probe.start == {'gain': 2.0, 'offset': -3.0, 'count': 5, 'fixed': 1.0, 'lo': -7.0, 'hi': 1.0}
        values = parameter_values(probe, SPECS)
        assert values == probe.start
        assert {name: type(v) for name, v in values.items()} == {
            'gain': float,
            'offset': float,
            'count': int,
            'fixed': float,
            'lo': float,
            'hi': float,
        }
        assert _types(probe) == {
            'gain': ParameterType.PARAMETER_DOUBLE,
            'offset': ParameterType.PARAMETER_DOUBLE,
            'count': ParameterType.PARAMETER_INTEGER,
            'fixed': ParameterType.PARAMETER_DOUBLE,
            'lo': ParameterType.PARAMETER_DOUBLE,
            'hi': ParameterType.PARAMETER_DOUBLE,
        }
        [fixed] = probe.describe_parameters(['fixed'])
        assert fixed.read_only and not fixed.dynamic_typing  # the declaration the spec asks for
        assert fixed.floating_point_range[0].to_value == 1.0
        # nothing left of the probing declarations: the node has its parameters and those of any node
        plain = rclpy.create_node('int_plain', context=ros_args_context)
        try:
            rclpy_own = set(plain.list_parameters([], 0).names)
        finally:
            plain.destroy_node()
        assert set(probe.list_parameters([], 0).names) == {spec.name for spec in SPECS} | rclpy_own
    finally:
        probe.destroy_node()


def test_an_integer_override_from_the_constructor_is_a_float(ros: Ros) -> None:
    probe = ros.add(Probe(context=ros.context, parameter_overrides=[Parameter('gain', value=4)]))
    assert probe.get_parameter('gain').value == 4.0 and type(probe.get_parameter('gain').value) is float


@pytest.mark.parametrize(
    ('override', 'message'),
    [
        (Parameter('gain', value=0), 'gain=0: must be a float in (0, 10]'),  # the open end holds for integers
        (Parameter('gain', value=20), 'gain=20: must be a float in (0, 10]'),
        (Parameter('fixed', value=2), 'fixed=2: must be a float in [0, 1] s'),
        (Parameter('gain', value=True), 'gain=True: must be a float, got bool'),
        (Parameter('gain', value='2'), "gain='2': must be a float, got str"),
        (Parameter('count', value=2.0), 'count=2.0: must be an integer, got float'),  # no float for an integer
    ],
)
def test_a_bad_start_value_is_refused_in_one_line(ros: Ros, override: Parameter[Any], message: str) -> None:
    with pytest.raises(ParameterError) as info:
        Probe(context=ros.context, parameter_overrides=[override])
    assert str(info.value) == message


def test_an_integer_start_value_passes_the_cross_check_as_a_float(ros: Ros) -> None:
    with pytest.raises(AssemblyError, match=r'lo=5.0 m must be below hi=1.0 m'):
        Probe(context=ros.context, parameter_overrides=[Parameter('lo', value=5)])


def test_set_parameters_takes_an_integer_for_a_float(ros: Ros) -> None:
    probe = ros.add(Probe(context=ros.context))
    [result] = probe.set_parameters([Parameter('gain', value=10)])  # the closed upper end
    assert result.successful, result.reason
    assert probe.get_parameter('gain').value == 10.0 and type(probe.get_parameter('gain').value) is float
    assert probe.applied[-1] == ('gain', 10.0) and type(probe.applied[-1][1]) is float  # what the node applies
    [descriptor] = probe.describe_parameters(['gain'])
    assert descriptor.type == ParameterType.PARAMETER_DOUBLE and not descriptor.dynamic_typing
    atomic = probe.set_parameters_atomically([Parameter('lo', value=7), Parameter('hi', value=8)])
    assert atomic.successful, atomic.reason  # checked together, as floats
    assert (probe.get_parameter('lo').value, probe.get_parameter('hi').value) == (7.0, 8.0)
    [count] = probe.set_parameters([Parameter('count', value=7)])  # an integer parameter is untouched
    assert count.successful and probe.get_parameter('count').value == 7


@pytest.mark.parametrize(
    ('name', 'value', 'reason'),
    [
        ('gain', 0, 'gain=0: must be a float in (0, 10]'),
        ('gain', 11, 'gain=11: must be a float in (0, 10]'),
        ('gain', True, 'gain=True: must be a float, got bool'),
        ('gain', 'abc', "gain='abc': must be a float, got str"),
        (
            'lo',
            5,
            'lo=5.0 rejected: probe cannot be assembled at phi=0.0 rad (0.000 deg): lo=5.0 m must be below hi=1.0 m',
        ),
        ('fixed', 1, 'Trying to set a read-only parameter: fixed.'),
    ],
)
def test_a_bad_integer_bool_or_string_is_refused_and_the_old_value_kept(
    ros: Ros, name: str, value: object, reason: str
) -> None:
    probe = ros.add(Probe(context=ros.context))
    before = parameter_values(probe, SPECS)
    [result] = probe.set_parameters([Parameter(name, value=value)])
    assert (result.successful, result.reason) == (False, reason)
    assert parameter_values(probe, SPECS) == before
    assert _types(probe)['gain'] == ParameterType.PARAMETER_DOUBLE


def test_the_parameter_service_takes_an_integer_as_ros2_param_set_sends_it(ros: Ros) -> None:
    """``ros2 param set /int_probe gain 4`` sends an INTEGER value to the set_parameters service."""
    probe = ros.add(Probe(context=ros.context))
    caller = ros.node('int_caller')
    client = AsyncParameterClient(caller, probe.get_name())
    assert ros.spin_until(client.services_are_ready, timeout=20.0)
    future = client.set_parameters([Parameter('gain', value=4), Parameter('offset', value='x')])
    assert ros.spin_until(future.done, timeout=20.0)
    good, bad = future.result().results
    assert good.successful, good.reason
    assert not bad.successful and bad.reason == "offset='x': must be a float, got str"
    got = client.get_parameters(['gain'])
    assert ros.spin_until(got.done, timeout=20.0)
    [value] = got.result().values
    assert (value.type, value.double_value) == (ParameterType.PARAMETER_DOUBLE, 4.0)


# --------------------------------------------------------------------------- node processes


def _answer(ros: Ros, call: Any, attempts: int = 6, wait: float = 5.0) -> Any:
    """The answer of a service call to another process, asked again if none comes: a request sent before the
    server's response writer has matched this client's response reader (DDS discovery runs separately for
    the two directions) is answered to nobody, and the future never completes. Both calls here are
    idempotent."""
    for _ in range(attempts):
        future = call()
        if ros.spin_until(future.done, timeout=wait):
            return future.result()
    raise AssertionError(f'no answer in {attempts} calls of {wait:g} s')


def _parameter(ros: Ros, client: AsyncParameterClient, name: str) -> tuple[int, float]:
    [value] = _answer(ros, lambda: client.get_parameters([name])).values
    return value.type, value.double_value


@pytest.mark.parametrize(
    ('node', 'ros_args', 'expected'),
    [
        ('crank_drive', ('-p', 'rate:=200'), {'rate': 200.0}),
        ('line_clock', ('-p', 'duration:=10', '-p', 'rtf:=2', '-p', 'rate:=100'), {'duration': 10.0, 'rtf': 2.0}),
    ],
)
def test_a_node_process_started_with_integers_runs_on_floats(
    ros: Ros, node_env: dict[str, str], tmp_path: Path, node: str, ros_args: tuple[str, ...], expected: dict[str, float]
) -> None:
    """``ros2 run folder_line crank_drive --ros-args -p rate:=200``: the node runs, its rate 200.0; a
    ``ros2 param set`` with an integer works on the running process (signed with the line's key, as
    ``folder-line tune`` sends it; unsigned it is refused); SIGINT ends it with 0."""
    target = name = unique_name(node)
    proc = start([*executable(node), '--ros-args', '-r', f'__node:={name}', *ros_args], node_env, tmp_path, node)
    try:
        caller = ros.node('int_process_caller')
        client = AsyncParameterClient(caller, name)
        assert ros.spin_until(lambda: client.services_are_ready() or proc.proc.poll() is not None, timeout=60.0)
        assert proc.proc.poll() is None, proc.err()
        for name, value in expected.items():
            assert _parameter(ros, client, name) == (ParameterType.PARAMETER_DOUBLE, value)
        # as `ros2 param set /NODE rate 300`: refused on the keyed line (the test process's), for want of
        # the signature; taken with it, as `folder-line tune` sends a change (an integer still)
        [result] = _answer(ros, lambda: client.set_parameters([Parameter('rate', value=300)])).results
        assert not result.successful and 'must be signed with the line key' in result.reason
        change = [Parameter('rate', value=300)]
        result = _answer(ros, lambda: client.set_parameters_atomically(signed(target, change))).result
        assert result.successful, result.reason
        assert _parameter(ros, client, 'rate') == (ParameterType.PARAMETER_DOUBLE, 300.0)
        send(proc, signal.SIGINT)
        assert_clean_exit(proc, 0)
    finally:
        proc.close()


@pytest.mark.parametrize(
    ('value', 'line'),
    [
        ('true', 'crank_drive: error: rate=True: must be a float, got bool'),
        ('abc', "crank_drive: error: rate='abc': must be a float, got str"),
    ],
)
def test_a_node_process_refuses_a_bool_or_string_for_a_float_in_one_line(
    node_env: dict[str, str], tmp_path: Path, value: str, line: str
) -> None:
    proc = start([*executable('crank_drive'), '--ros-args', '-p', f'rate:={value}'], node_env, tmp_path)
    try:
        assert_clean_exit(proc, 2)
        assert proc.err().strip().splitlines() == [line]
    finally:
        proc.close()
