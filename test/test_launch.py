"""launch/line.launch.py: launch_ros cannot be installed here (no wheel), so what it runs is checked without it.

The file is read as text and as a syntax tree; what it calls in the package, the arguments and
each node's parameters (:mod:`folder_line.ros.line_launch`), runs here in-process. The node
processes it starts are tested as launch runs them in test/ros/test_launch_process.py.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

from folder_line.errors import FolderLineError, ParameterError
from folder_line.interfaces import LINE_CLOCK, MACHINE_NODES
from folder_line.ros.line_key import KEY_VARIABLE, read_key

REPO = Path(__file__).resolve().parent.parent
LAUNCH = REPO / 'launch' / 'line.launch.py'


def _imports() -> set[tuple[str | None, str]]:
    tree = ast.parse(LAUNCH.read_text())
    return {(node.module, alias.name) for node in tree.body if isinstance(node, ast.ImportFrom) for alias in node.names}


def test_launch_file_starts_every_line_node_with_an_installed_executable() -> None:
    from folder_line.ros import entry

    imported = _imports()
    assert ('folder_line.interfaces', 'MACHINE_NODES') in imported  # the node names are written once
    assert ('folder_line.interfaces', 'LINE_CLOCK') in imported
    assert 'names = (*MACHINE_NODES, LINE_CLOCK)' in LAUNCH.read_text()
    scripts = dict(re.findall(r"'(\w+) = folder_line\.ros\.entry:(\w+)'", (REPO / 'setup.py').read_text()))
    assert set(MACHINE_NODES) | {LINE_CLOCK} <= set(scripts)
    assert all(scripts[name] == name for name in scripts)
    assert set(entry.NODE_MODULES) == set(MACHINE_NODES) | {LINE_CLOCK}
    assert 'def generate_launch_description' in LAUNCH.read_text()


def test_launch_arguments_match_node_parameters() -> None:
    from folder_line.ros.line_launch import ARGUMENTS
    from folder_line.ros.nodes.line_clock import SPECS as CLOCK_SPECS
    from folder_line.ros.nodes.machine import MACHINE_SPECS

    assert ('folder_line.ros.line_launch', 'ARGUMENTS') in _imports()
    args = {name for name, _, _ in ARGUMENTS}
    assert {spec.name for spec in MACHINE_SPECS} <= args
    clock = {spec.name for spec in CLOCK_SPECS}
    assert {'rtf', 'duration', 'rate', 'clock', 'lost_timeout', 'start_time'} <= args & clock


def test_every_argument_is_checked_before_any_node_is_started() -> None:
    text = LAUNCH.read_text()
    assert ('folder_line.ros.line_launch', 'line_parameters') in _imports()
    # the nodes are built by one function, after line_parameters has read every argument
    assert 'OpaqueFunction(function=start_line)' in text
    body = text[text.index('def start_line') :]
    assert body.index('line_parameters(given)') < body.index('Node(')
    assert 'ParameterValue' not in text  # no typed substitution left for launch_ros to fail on mid-start


def test_launch_ends_with_line_clock_and_fails_on_a_failed_node() -> None:
    text = LAUNCH.read_text()
    assert 'OnProcessExit(target_action=node, on_exit=on_exit)' in text and 'end = LineEnd(names)' in text
    # after the clock, the others are waited for; those still running END_GRACE s later are stopped
    assert "TimerAction(period=END_GRACE, actions=[EmitEvent(event=Shutdown(reason='the line ended'))])" in text
    body = text[text.index('def node_exited') :]
    assert 'step = end.exited(name, event.returncode)' in body
    assert 'if step is Step.FAIL:' in body and 'raise LineNodeFailed(failure_text(name, event.returncode))' in body
    assert 'actions.append(stragglers)' in body and 'stragglers.cancel()' in body


def test_launch_nodes_die_with_the_launch() -> None:
    assert ('folder_line.ros.entry', 'PARENT_PID_ENV') in _imports()
    text = LAUNCH.read_text()
    assert '{PARENT_PID_ENV: str(os.getpid()), **key_env}' in text and 'additional_env=parent' in text


def test_every_launched_node_gets_the_line_key() -> None:
    from folder_line.ros.line_launch import line_key_environment

    text = LAUNCH.read_text()
    assert 'key_env, told = line_key_environment(os.environ)' in text
    assert '[] if told is None else [LogInfo(msg=told)]' in text  # a new key is told to the operator
    env, told = line_key_environment({})
    key = env[KEY_VARIABLE]
    assert read_key(env) is not None and told is not None and f'{KEY_VARIABLE}={key}' in told
    assert line_key_environment({KEY_VARIABLE: f' {key} '}) == ({KEY_VARIABLE: key}, None)  # the caller's
    with pytest.raises(ParameterError, match=KEY_VARIABLE):
        line_key_environment({KEY_VARIABLE: 'not-a-key'})


def test_launch_file_is_installed() -> None:
    assert "glob('launch/*.launch.py')" in (REPO / 'setup.py').read_text()


# --------------------------------------------------------------------------- line_parameters (in-process)


def test_default_arguments_give_every_node_typed_parameters() -> None:
    from folder_line.ros.line_launch import line_parameters
    from folder_line.ros.nodes.sheet_counter import SheetCounter

    params = line_parameters({})
    assert set(params) == {*MACHINE_NODES, LINE_CLOCK}
    for name in MACHINE_NODES:
        assert params[name]['scene'] == 'folder' and params[name]['overrides'] == ''
        assert params[name]['rate'] == 200.0 and params[name]['use_sim_time'] is True
        assert ('marker_rate' in params[name]) == (name == 'sheet_counter')
    assert 'marker_rate' in {spec.name for spec in SheetCounter.EXTRA_SPECS}
    clock = params[LINE_CLOCK]
    assert clock['participants'] == ','.join(MACHINE_NODES)
    assert (clock['rtf'], clock['duration'], clock['start_time'], clock['clock']) == (1.0, 0.0, 0.0, 'lockstep')
    assert 'scene' not in clock and 'use_sim_time' not in clock


def test_integer_arguments_become_floats() -> None:
    from folder_line.ros.line_launch import line_parameters

    params = line_parameters({'rate': '200', 'duration': '10', 'rtf': '2', 'lost_timeout': '5', 'marker_rate': '0'})
    clock = params[LINE_CLOCK]
    for value in (clock['rate'], clock['duration'], clock['rtf'], clock['lost_timeout']):
        assert type(value) is float
    assert (clock['rate'], clock['duration'], clock['rtf']) == (200.0, 10.0, 2.0)
    assert params['sheet_counter']['marker_rate'] == 0.0 and type(params['crank_drive']['rate']) is float


@pytest.mark.parametrize(
    ('arguments', 'message'),
    [
        ({'rtf': 'fast'}, "rtf='fast': must be a float, got str"),
        ({'duration': 'abc'}, "duration='abc': must be a float, got str"),
        ({'rate': 'true'}, "rate='true': must be a float, got str"),
        ({'rate': 'nan'}, 'rate=nan: must be finite (not NaN or inf)'),
        ({'lost_timeout': '0.01'}, 'lost_timeout=0.01: must be a float in [0.1, 3600] s'),
        ({'clock': 'fast'}, "clock='fast': must be one of lockstep, wall"),
        ({'marker_rate': '-1'}, 'marker_rate=-1.0: must be a float in '),
    ],
)
def test_a_bad_argument_is_refused_naming_it(arguments: dict[str, str], message: str) -> None:
    from folder_line.ros.line_launch import line_parameters

    with pytest.raises(ParameterError) as info:
        line_parameters(arguments)
    assert str(info.value).startswith(message)
    assert '\n' not in str(info.value)


def test_a_scene_that_does_not_load_is_refused_before_any_node_starts() -> None:
    from folder_line.ros.line_launch import line_parameters

    with pytest.raises(FolderLineError, match="scene='nowhere': no such scene"):
        line_parameters({'scene': 'nowhere'})
    with pytest.raises(FolderLineError):
        line_parameters({'overrides': 'bogus.x=1'})


@pytest.mark.parametrize(
    ('name', 'code', 'text'),
    [
        ('line_clock', 3, 'line_clock exited with code 3 (a participant was lost)'),
        ('crank_drive', 2, 'crank_drive exited with code 2 (it refused its parameters)'),
        ('supervisor', 1, 'supervisor exited with code 1:'),
        ('crank_drive', 3, 'crank_drive exited with code 3 (it lost a producer, or its clock before the end)'),
        ('crank_drive', 4, 'crank_drive exited with code 4:'),
        ('belt_conveyor', -9, 'belt_conveyor was killed by SIGKILL'),
        ('belt_conveyor', -200, 'belt_conveyor was killed by signal 200'),
    ],
)
def test_failure_text_names_the_node_and_its_code(name: str, code: int, text: str) -> None:
    from folder_line.ros.line_launch import failure_text

    line = failure_text(name, code)
    assert line.startswith(text) and line.endswith('the line did not end as it should')


def test_arguments_are_the_parameters_as_the_nodes_read_them() -> None:
    """Each argument's default is a value its parameters accept, and reads back as their default."""
    from folder_line.ros.line_launch import ARGUMENTS
    from folder_line.ros.nodes.line_clock import SPECS as CLOCK_SPECS
    from folder_line.ros.nodes.machine import MACHINE_SPECS
    from folder_line.ros.nodes.sheet_counter import SheetCounter

    specs = {spec.name: spec for spec in (*MACHINE_SPECS, *SheetCounter.EXTRA_SPECS, *CLOCK_SPECS)}
    for name, default, description in ARGUMENTS:
        assert description and name in specs, name
        assert specs[name].from_text(default) == specs[name].default, name


# --------------------------------------------------------------------------- how the launch ends (LineEnd)


def _exits(*exits: tuple[str, int]) -> list[object]:
    from folder_line.ros.line_launch import LineEnd

    end = LineEnd((*MACHINE_NODES, LINE_CLOCK))
    return [end.exited(name, code) for name, code in exits]


def test_the_line_ends_with_its_clock_and_the_others_end_by_themselves() -> None:
    from folder_line.ros.line_launch import Step

    first, *rest = MACHINE_NODES
    # a machine node may end first (done at the last tick), then the clock: the rest are waited for
    steps = _exits((first, 0), (LINE_CLOCK, 0), *((name, 0) for name in rest))
    assert steps == [Step.GO_ON, Step.WAIT_FOR_THE_REST, *[Step.GO_ON] * (len(rest) - 1), Step.ENDED]
    # the clock last: nothing is left to stop
    assert _exits(*((name, 0) for name in MACHINE_NODES), (LINE_CLOCK, 0))[-1] == Step.ENDED


@pytest.mark.parametrize('code', [1, 2, 3, -2, -9, -15])
def test_a_node_that_exits_non_zero_fails_the_launch(code: int) -> None:
    from folder_line.ros.line_launch import Step

    assert _exits((MACHINE_NODES[0], code)) == [Step.FAIL]
    assert _exits((LINE_CLOCK, code)) == [Step.FAIL]
    assert _exits((LINE_CLOCK, 0), (MACHINE_NODES[0], code))[-1] == Step.FAIL  # after the end too


def test_an_exit_status_launch_lost_is_not_a_failure() -> None:
    from folder_line.ros.line_launch import STATUS_LOST, Step

    assert _exits((MACHINE_NODES[0], STATUS_LOST)) == [Step.GO_ON]
    assert _exits((LINE_CLOCK, STATUS_LOST)) == [Step.WAIT_FOR_THE_REST]


def test_the_launch_waits_longer_than_a_node_can_take_to_end() -> None:
    from folder_line.ros.line_launch import END_GRACE
    from folder_line.ros.runtime import HUNG_TEARDOWN_EXIT, LINGER, TEARDOWN_TIMEOUT

    assert END_GRACE > LINGER + TEARDOWN_TIMEOUT + HUNG_TEARDOWN_EXIT  # linger, teardown watchdog, the C timer
