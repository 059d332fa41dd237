"""folder_line.ros.parameters, .topics, .time_msg, .runtime: parameter specs and validation, topics, time, run_node."""

from __future__ import annotations

import importlib
import math
from collections.abc import Mapping
from decimal import ROUND_HALF_EVEN, Decimal
from fractions import Fraction
from typing import TYPE_CHECKING, Any

import pytest
from hypothesis import given
from hypothesis import strategies as st
from rcl_interfaces.msg import ParameterType
from rclpy.exceptions import InvalidNodeNameException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.task import Future
from rclpy.validate_full_topic_name import validate_full_topic_name

from folder_line import interfaces
from folder_line.errors import AssemblyError, ParameterError
from folder_line.interfaces import NS_PER_S, TIME_MSG_MAX_NS, TOPICS, seconds_to_ns
from folder_line.ros.parameters import (
    ParamSpec,
    declare_parameters,
    make_screen,
    make_validator,
    parameter_values,
    sim_time_overrides,
)
from folder_line.ros.runtime import EXIT_BAD_PARAMETER, EXIT_OK, TEARDOWN_TIMEOUT, run_node
from folder_line.ros.time_msg import ns_to_time_msg, time_msg_to_ns
from folder_line.ros.topics import joint_states_topic

if TYPE_CHECKING:
    from .conftest import Ros

# --------------------------------------------------------------------------- specs (no graph)

GAIN = ParamSpec('gain', 1.0, 'Gain of the probe', bounds=(0.0, 10.0), low_open=True)
OFFSET = ParamSpec('offset', 0.0, 'Unbounded offset', unit='m')
COUNT = ParamSpec('count', 3, 'Number of things', bounds=(1, 100))
MODE = ParamSpec('mode', 'slow', 'Operating mode', choices=('slow', 'normal'))
ENABLED = ParamSpec('enabled', True, 'Switch')
FIXED = ParamSpec('fixed', 0.5, 'Set at start only', unit='s', bounds=(0.0, 1.0), read_only=True)
LO = ParamSpec('lo', 0.0, 'Lower end', unit='m', bounds=(-100.0, 100.0))
HI = ParamSpec('hi', 1.0, 'Upper end', unit='m', bounds=(-100.0, 100.0))
SPECS = (GAIN, OFFSET, COUNT, MODE, ENABLED, FIXED, LO, HI)


def ordered(values: Mapping[str, Any]) -> None:
    """Cross-check of the probe: the core would refuse lo >= hi (as a FolderLineError)."""
    if values['lo'] >= values['hi']:
        raise AssemblyError('probe loop', 0.0, f'lo={values["lo"]!r} m must be below hi={values["hi"]!r} m')


@pytest.mark.parametrize(
    ('spec', 'value'),
    [
        (GAIN, 2.5),
        (GAIN, 10.0),
        (GAIN, 1e-300),
        (OFFSET, -1e300),
        (COUNT, 1),
        (COUNT, 100),
        (MODE, 'normal'),
        (ENABLED, False),
        (FIXED, 0.0),
    ],
)
def test_check_accepts_and_returns_the_value_itself(spec: ParamSpec, value: object) -> None:
    out = spec.check(value)
    assert out == value and type(out) is type(value)


@pytest.mark.parametrize(('spec', 'value'), [(GAIN, 5), (GAIN, 10), (OFFSET, -(2**63)), (FIXED, 0), (FIXED, 1)])
def test_check_takes_an_integer_for_a_float_and_returns_the_float(spec: ParamSpec, value: int) -> None:
    out = spec.check(value)
    assert out == float(value) and type(out) is float


def test_an_integer_beyond_any_float_is_not_finite() -> None:
    with pytest.raises(ParameterError, match='must be finite'):
        OFFSET.check(10**400)


@pytest.mark.parametrize(
    ('spec', 'value', 'words'),
    [
        (GAIN, math.nan, 'finite'),
        (GAIN, math.inf, 'finite'),
        (OFFSET, -math.inf, 'finite'),
        (GAIN, 0.0, '(0, 10]'),
        (GAIN, 10.000001, '(0, 10]'),
        (GAIN, 'abc', 'must be a float, got str'),
        (GAIN, True, 'got bool'),
        (GAIN, None, 'unset'),
        (COUNT, 0, '[1, 100]'),
        (COUNT, 3.0, 'must be an integer, got float'),
        (COUNT, True, 'got bool'),
        (MODE, 'fast', 'one of slow, normal'),
        (MODE, 1, 'must be a string'),
        (ENABLED, 1, 'must be a bool, got int'),
        (FIXED, [0.5], 'got list'),
    ],
)
def test_check_rejects_naming_parameter_and_value(spec: ParamSpec, value: object, words: str) -> None:
    with pytest.raises(ParameterError) as info:
        spec.check(value)
    assert str(info.value).startswith(f'{spec.name}={value!r}: ')
    assert words in str(info.value)


@pytest.mark.parametrize(
    ('kwargs', 'words'),
    [
        ({'name': '', 'default': 1.0}, 'non-empty'),
        ({'name': 'x', 'default': [1.0]}, 'bool, int, float or str'),
        ({'name': 'x', 'default': 1.0, 'bounds': (2.0, 3.0)}, 'must be a float in [2, 3]'),
        ({'name': 'x', 'default': 1.0, 'bounds': (3.0, 2.0)}, 'lo < hi'),
        ({'name': 'x', 'default': 1.0, 'bounds': (math.nan, 2.0)}, 'lo < hi'),
        ({'name': 'x', 'default': 'a', 'bounds': (0.0, 1.0)}, 'int or float'),
        ({'name': 'x', 'default': 1.0, 'low_open': True}, 'need bounds'),
        ({'name': 'x', 'default': 1.0, 'choices': ('a',)}, 'string parameters'),
        ({'name': 'x', 'default': 'c', 'choices': ('a', 'b')}, 'one of a, b'),
        ({'name': 'x', 'default': 'a', 'choices': ('a', 'a')}, 'distinct'),
        ({'name': 'x', 'default': math.nan}, 'finite'),
    ],
)
def test_an_inconsistent_spec_is_refused(kwargs: dict[str, Any], words: str) -> None:
    with pytest.raises(ParameterError) as info:
        ParamSpec(description='d', **kwargs)
    assert words in str(info.value)


def test_descriptor_carries_description_unit_range_and_read_only() -> None:
    d = FIXED.descriptor()
    assert d.description == 'Set at start only [s]'
    assert d.additional_constraints == 'a float in [0, 1] s'
    assert d.read_only is True
    assert [(r.from_value, r.to_value, r.step) for r in d.floating_point_range] == [(0.0, 1.0, 0.0)]
    assert list(d.integer_range) == []
    g = GAIN.descriptor()
    assert g.additional_constraints == 'a float in (0, 10]' and g.read_only is False
    c = COUNT.descriptor()
    assert [(r.from_value, r.to_value, r.step) for r in c.integer_range] == [(1, 100, 0)]
    assert list(c.floating_point_range) == []
    o = OFFSET.descriptor()  # no finite range: none advertised
    assert list(o.floating_point_range) == [] and o.additional_constraints == 'a float m'
    assert MODE.descriptor().additional_constraints == 'a string one of slow, normal'
    assert GAIN.descriptor() is not GAIN.descriptor()  # rclpy keeps and mutates the one it gets
    half_open = ParamSpec('h', 1.0, 'd', bounds=(0.0, math.inf), low_open=True)
    assert list(half_open.descriptor().floating_point_range) == []
    assert half_open.constraint_text() == 'a float in (0, inf]'


def test_types_follow_the_default() -> None:
    assert [s.type for s in (GAIN, COUNT, MODE, ENABLED)] == [
        Parameter.Type.DOUBLE,
        Parameter.Type.INTEGER,
        Parameter.Type.STRING,
        Parameter.Type.BOOL,
    ]


def test_screen_replaces_refused_values_by_valid_stand_ins_that_the_validator_refuses() -> None:
    screen = make_screen(SPECS)
    proposed = [Parameter('gain', value='5'), Parameter('offset', value=2.0), Parameter('use_sim_time', value=True)]
    screened = screen(proposed)
    assert [p.name for p in screened] == ['gain', 'offset', 'use_sim_time']
    assert screened[1:] == proposed[1:]  # accepted values pass unchanged
    stand_in = screened[0]
    assert (stand_in.type_, stand_in.value) == (Parameter.Type.DOUBLE, GAIN.default)  # passes rclpy's checks
    assert screen(screened)[0] is stand_in
    validate = make_validator(SPECS, lambda: {s.name: s.default for s in SPECS})
    result = validate(screened)
    assert not result.successful and result.reason == "gain='5': must be a float, got str"


def test_screen_turns_an_integer_for_a_float_into_the_float() -> None:
    [gain, count] = make_screen(SPECS)([Parameter('gain', value=5), Parameter('count', value=5)])
    assert (gain.type_, gain.value) == (Parameter.Type.DOUBLE, 5.0) and type(gain.value) is float
    assert (count.type_, count.value) == (Parameter.Type.INTEGER, 5)  # an integer parameter keeps its integer


def test_validator_reports_the_first_bad_parameter_and_runs_the_cross_check() -> None:
    current = {s.name: s.default for s in SPECS}
    validate = make_validator(SPECS, lambda: current, ordered)
    ok = validate([Parameter('gain', value=2.0), Parameter('use_sim_time', value=True)])
    assert ok.successful, ok.reason  # parameters without a spec pass
    bad = validate([Parameter('gain', value=2.0), Parameter('offset', value=math.nan)])
    assert not bad.successful and bad.reason == 'offset=nan: must be finite (not NaN or inf)'
    wrong_type = validate([Parameter('gain', value=True)])
    assert not wrong_type.successful and wrong_type.reason == 'gain=True: must be a float, got bool'
    crossed = validate([Parameter('lo', value=2.0)])
    assert not crossed.successful
    assert crossed.reason.startswith('lo=2.0 rejected: probe loop cannot be assembled')
    assert 'lo=2.0 m must be below hi=1.0 m' in crossed.reason
    both = validate([Parameter('lo', value=2.0), Parameter('hi', value=3.0)])
    assert both.successful, both.reason


# --------------------------------------------------------------------------- time (no graph)


def test_seconds_to_ns_is_exact() -> None:
    assert seconds_to_ns(0.1) == 100_000_000
    assert seconds_to_ns(1e9) == 10**18
    assert seconds_to_ns(0.0) == 0
    assert seconds_to_ns(0.3) == 300_000_000
    assert seconds_to_ns(123456.789) == 123_456_789_000_000  # 123456.789 * 1e9 is 123456788999999.98 in floats
    for bad in (math.nan, math.inf, -math.inf):
        with pytest.raises(ValueError, match='seconds='):
            seconds_to_ns(bad)


@given(st.floats(min_value=0.0, max_value=2e9, allow_nan=False))
def test_seconds_to_ns_matches_decimal_rounding(seconds: float) -> None:
    expected = int((Decimal(seconds) * NS_PER_S).quantize(Decimal(1), rounding=ROUND_HALF_EVEN))
    assert seconds_to_ns(seconds) == expected
    assert abs(seconds_to_ns(seconds) - Fraction(seconds) * NS_PER_S) <= Fraction(1, 2)


@given(st.integers(min_value=0, max_value=TIME_MSG_MAX_NS))
def test_time_msg_round_trip(ns: int) -> None:
    msg = ns_to_time_msg(ns)
    assert 0 <= msg.nanosec < NS_PER_S
    assert time_msg_to_ns(msg) == ns


def test_time_msg_out_of_range() -> None:
    assert ns_to_time_msg(TIME_MSG_MAX_NS).sec == 2**31 - 1
    for bad in (-1, TIME_MSG_MAX_NS + 1):
        with pytest.raises(ValueError, match='builtin_interfaces'):
            ns_to_time_msg(bad)


# --------------------------------------------------------------------------- topics (no graph)


def test_topics_are_valid_names_of_existing_message_types() -> None:
    names = [t.name for t in TOPICS]
    assert len(set(names)) == len(names)
    for topic in TOPICS:
        validate_full_topic_name(topic.name.format(node='knife'))
        package, kind, name = topic.type.split('/')
        assert kind == 'msg'
        assert hasattr(importlib.import_module(f'{package}.msg'), name), topic.type
        # documented in the module docstring table, under the same name
        assert f'``{topic.name.replace("{node}", "<node>")}``' in interfaces.__doc__


def test_topic_constants() -> None:
    assert interfaces.CLOCK_TOPIC == '/clock'
    assert interfaces.EVENTS_TOPIC == '/line/events'
    assert interfaces.DIAGNOSTICS_TOPIC == '/diagnostics'
    assert interfaces.SUPERVISOR_STATE_TOPIC == '/line/supervisor/state'
    assert interfaces.SHEET_COUNT_TOPIC == '/line/sheet_counter/count'
    assert joint_states_topic('knife') == '/line/knife/joint_states'
    with pytest.raises(InvalidNodeNameException):
        joint_states_topic('bad/name')


def test_sim_time_overrides() -> None:
    given_overrides = [Parameter('rtf', value=2.0)]
    out = sim_time_overrides(given_overrides)
    assert [(p.name, p.value) for p in out] == [('rtf', 2.0), ('use_sim_time', True)]
    assert len(given_overrides) == 1  # not mutated
    explicit = sim_time_overrides([Parameter('use_sim_time', value=False)])
    assert [(p.name, p.value) for p in explicit] == [('use_sim_time', False)]
    assert [(p.name, p.value) for p in sim_time_overrides(None, use_sim_time=False)] == [('use_sim_time', False)]


# --------------------------------------------------------------------------- parameters on a node (real DDS)


class Probe(Node):
    """A minimal line-style node: parameters from SPECS with the `ordered` cross-check."""

    def __init__(self, **kwargs: Any) -> None:
        overrides = kwargs.pop('parameter_overrides', None)
        super().__init__('probe', parameter_overrides=sim_time_overrides(overrides), **kwargs)
        self.start = declare_parameters(self, SPECS, cross_check=ordered)


def _set(node: Node, name: str, value: object) -> tuple[bool, str]:
    [result] = node.set_parameters([Parameter(name, value=value)])
    return result.successful, result.reason


def test_declared_parameters_start_from_defaults_and_use_sim_time(ros: Ros) -> None:
    probe = ros.add(Probe(context=ros.context))
    assert probe.start == {s.name: s.default for s in SPECS}
    assert probe.get_parameter('use_sim_time').value is True
    [descriptor] = probe.describe_parameters(['gain'])
    assert descriptor.type == ParameterType.PARAMETER_DOUBLE
    assert descriptor.description == 'Gain of the probe'
    assert descriptor.floating_point_range[0].to_value == 10.0


@pytest.mark.parametrize(
    ('name', 'value', 'reason'),
    [
        ('gain', math.nan, 'gain=nan: must be finite (not NaN or inf)'),
        ('gain', math.inf, 'gain=inf: must be finite (not NaN or inf)'),
        ('gain', 11.0, 'gain=11.0: must be a float in (0, 10]'),
        ('gain', 0.0, 'gain=0.0: must be a float in (0, 10]'),
        ('gain', 10.000001, 'gain=10.000001: must be a float in (0, 10]'),  # inside rclpy's own 1e-6 slack
        ('offset', -math.inf, 'offset=-inf: must be finite (not NaN or inf)'),
        ('count', 101, 'count=101: must be an integer in [1, 100]'),
        ('mode', 'fast', "mode='fast': must be one of slow, normal"),
        ('gain', 0, 'gain=0: must be a float in (0, 10]'),  # an integer is taken as a float, and checked
        ('gain', 'abc', "gain='abc': must be a float, got str"),
        ('count', 3.0, 'count=3.0: must be an integer, got float'),
        ('enabled', 'yes', "enabled='yes': must be a bool, got str"),
        (
            'lo',
            5.0,
            'lo=5.0 rejected: probe loop cannot be assembled at phi=0.0 rad (0.000 deg): '
            'lo=5.0 m must be below hi=1.0 m',
        ),
    ],
)
def test_bad_values_are_rejected_naming_parameter_and_value_and_the_old_value_kept(
    ros: Ros, name: str, value: object, reason: str
) -> None:
    probe = ros.add(Probe(context=ros.context))
    before = parameter_values(probe, SPECS)
    assert _set(probe, name, value) == (False, reason)
    assert parameter_values(probe, SPECS) == before
    [descriptor] = probe.describe_parameters([name])  # the stand-in left the declared type alone
    assert (
        descriptor.type
        == {
            float: ParameterType.PARAMETER_DOUBLE,
            int: ParameterType.PARAMETER_INTEGER,
            str: ParameterType.PARAMETER_STRING,
            bool: ParameterType.PARAMETER_BOOL,
        }[type(before[name])]
    )


def test_read_only_is_refused_and_valid_values_are_accepted(ros: Ros) -> None:
    probe = ros.add(Probe(context=ros.context))
    ok, reason = _set(probe, 'fixed', 0.25)
    assert not ok and 'read-only' in reason and 'fixed' in reason
    for name, value in (
        ('gain', 10.0),
        ('gain', 2.5),
        ('count', 100),
        ('mode', 'normal'),
        ('enabled', False),
        ('offset', -3.0),
        ('lo', 0.5),
    ):
        ok, reason = _set(probe, name, value)
        assert ok, reason
        assert probe.get_parameter(name).value == value
    # a change the cross-check refuses one at a time passes atomically
    result = probe.set_parameters_atomically([Parameter('lo', value=7.0), Parameter('hi', value=8.0)])
    assert result.successful, result.reason
    assert (probe.get_parameter('lo').value, probe.get_parameter('hi').value) == (7.0, 8.0)


def test_rejection_through_the_parameter_service(ros: Ros) -> None:
    probe = ros.add(Probe(context=ros.context))
    caller = ros.node('caller')
    client = AsyncParameterClient(caller, probe.get_name())
    assert ros.spin_until(client.services_are_ready, timeout=20.0)
    future = client.set_parameters([Parameter('offset', value=math.inf), Parameter('gain', value=4.0)])
    assert ros.spin_until(future.done, timeout=20.0)
    bad, good = future.result().results
    assert not bad.successful and bad.reason == 'offset=inf: must be finite (not NaN or inf)'
    assert good.successful
    assert probe.get_parameter('offset').value == 0.0
    assert probe.get_parameter('gain').value == 4.0


@pytest.mark.parametrize(
    ('override', 'error', 'words'),
    [
        (Parameter('offset', value=math.nan), ParameterError, 'offset=nan: must be finite'),
        (Parameter('gain', value=0.0), ParameterError, 'gain=0.0: must be a float in (0, 10]'),
        (Parameter('mode', value='fast'), ParameterError, "mode='fast'"),
        (Parameter('lo', value=3.0), AssemblyError, 'lo=3.0 m must be below hi=1.0 m'),
        (Parameter('gain', value=20.0), ParameterError, 'gain=20.0: must be a float in (0, 10]'),
        (Parameter('gain', value='2'), ParameterError, "gain='2': must be a float, got str"),
        (Parameter('count', value=2.0), ParameterError, 'count=2.0: must be an integer, got float'),
    ],
)
def test_bad_starting_values_stop_the_node(ros: Ros, override: Parameter, error: type, words: str) -> None:
    with pytest.raises(error) as info:
        Probe(context=ros.context, parameter_overrides=[override])
    assert words in str(info.value)


def test_starting_values_come_from_overrides(ros: Ros) -> None:
    probe = ros.add(
        Probe(
            context=ros.context,
            parameter_overrides=[
                Parameter('gain', value=3.0),
                Parameter('fixed', value=0.75),
                Parameter('use_sim_time', value=False),
            ],
        )
    )
    assert probe.start['gain'] == 3.0 and probe.start['fixed'] == 0.75
    assert probe.get_parameter('use_sim_time').value is False


def test_duplicate_spec_names_are_refused(ros: Ros) -> None:
    node = ros.node('dupe')
    with pytest.raises(ParameterError, match='distinct'):
        declare_parameters(node, (GAIN, GAIN))


# --------------------------------------------------------------------------- run_node (default context)


class Finishing(Node):
    """Finishes after three timer ticks, through the `done` convention of run_node."""

    NODE_NAME = 'finishing'

    def __init__(self) -> None:
        super().__init__(self.NODE_NAME, parameter_overrides=sim_time_overrides(use_sim_time=False))
        self.done: Future = Future()
        self.ticks = 0
        self.create_timer(0.01, self._tick)

    def _tick(self) -> None:
        self.ticks += 1
        if self.ticks == 3:
            self.done.set_result(self.ticks)


def test_run_node_returns_0_when_the_node_is_done() -> None:
    built: list[Finishing] = []

    def factory() -> Finishing:
        built.append(Finishing())
        return built[-1]

    assert run_node(factory, args=[]) == EXIT_OK
    assert built[0].done.result() == 3


def test_run_node_returns_the_exit_code_the_node_asks_for() -> None:
    """As ``line_clock`` exits 3 after it lost a participant: ``exit_code(node)`` once the node is done."""
    seen: list[Any] = []

    def code(node: Node) -> int:
        seen.append(node.done.result())  # type: ignore[attr-defined]
        return 3

    assert run_node(Finishing, args=[], exit_code=code) == 3
    assert seen == [3]


def test_run_node_returns_2_with_one_line_naming_the_parameter(capsys: pytest.CaptureFixture[str]) -> None:
    def factory() -> Node:
        return Probe(parameter_overrides=[Parameter('offset', value=math.inf)])

    assert run_node(factory, args=['--ros-args', '-p', 'gain:=2.0']) == EXIT_BAD_PARAMETER
    err = capsys.readouterr().err
    assert err == 'factory: error: offset=inf: must be finite (not NaN or inf)\n'


def test_run_node_lets_other_errors_through() -> None:
    def factory() -> Node:
        raise RuntimeError('a bug')

    with pytest.raises(RuntimeError, match='a bug'):
        run_node(factory, args=[])


_HANGING_TEARDOWN = '''
import sys, time
sys.path.insert(0, {repo!r})
from rclpy.node import Node
from rclpy.task import Future
from folder_line.ros.runtime import run_node

class Hanging(Node):
    """Done at once; its teardown hangs as the middleware's sometimes does."""
    NODE_NAME = 'hanging'

    def __init__(self):
        super().__init__(self.NODE_NAME)
        self.done = Future()
        self.done.set_result(True)

    def destroy_node(self):
        time.sleep(30.0)

sys.exit(run_node(Hanging, teardown_timeout={timeout!r}))
'''


_GIL_HOLDING_TEARDOWN = '''
import re, sys
sys.path.insert(0, {repo!r})
from rclpy.node import Node
from rclpy.task import Future
from folder_line.ros.runtime import run_node

class Holding(Node):
    """Done at once, with exit code 3; its teardown hangs in a C call that holds the GIL."""
    NODE_NAME = 'holding'

    def __init__(self):
        super().__init__(self.NODE_NAME)
        self.done = Future()
        self.done.set_result(True)

    def exit_code(self):
        return 3

    def destroy_node(self):
        re.match(r'(a+)+$', 'a' * 60 + 'b')

sys.exit(run_node(Holding, teardown_timeout=0.5))
'''


def test_a_node_process_whose_teardown_hangs_holding_the_gil_exits_with_its_own_code() -> None:
    """No Python thread runs, so the Python watchdog cannot: faulthandler prints the stacks, and the C
    timer ends the process with the node's code (3), not faulthandler's 1 (seen once in CI)."""
    import subprocess
    import sys
    from pathlib import Path

    repo = str(Path(__file__).resolve().parents[2])
    proc = subprocess.run(
        [sys.executable, '-c', _GIL_HOLDING_TEARDOWN.format(repo=repo)], capture_output=True, text=True, timeout=60
    )
    assert proc.returncode == 3, (proc.returncode, proc.stderr[-2000:])
    assert 'Timeout (0:00:' in proc.stderr, proc.stderr[-2000:]  # faulthandler's report
    assert 'in destroy_node' in proc.stderr  # the stacks say where it hung
    assert 'did not finish tearing the node down' not in proc.stderr  # the Python watchdog never ran


@pytest.mark.parametrize('timeout', [0.5, None])
def test_a_node_process_whose_teardown_hangs_exits_after_the_timeout(timeout: float | None) -> None:
    """A node process (args from sys.argv) whose destroy_node hangs exits with 0 and one warning
    after the teardown timeout (given, or the default TEARDOWN_TIMEOUT), not after the hang's 30 s."""
    import subprocess
    import sys
    import time
    from pathlib import Path

    repo = str(Path(__file__).resolve().parents[2])
    t0 = time.monotonic()
    proc = subprocess.run(
        [sys.executable, '-c', _HANGING_TEARDOWN.format(repo=repo, timeout=timeout)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    elapsed = time.monotonic() - t0
    limit = TEARDOWN_TIMEOUT if timeout is None else timeout
    assert proc.returncode == 0, proc.stderr
    assert (
        proc.stderr.count(
            f'hanging: the middleware did not finish tearing the node down in {limit:g} s; exiting anyway'
        )
        == 1
    ), proc.stderr
    assert limit <= elapsed < limit + 10.0
