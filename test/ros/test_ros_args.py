"""The values ``--ros-args`` give a node, read as rcl reads them, or None where this reading is not sure."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from folder_line.ros.ros_args import command_line_values


def values(*words: str, node: str = 'crank_drive') -> dict[str, object] | None:
    return command_line_values(list(words), node)


def test_rules_are_read_as_rcl_reads_a_value() -> None:
    got = values(
        *('prog', '--ros-args', '-p', 'a:=5', '-p', 'b:=-2.5e3', '--param', 'c:=true', '-p', 'd:=FALSE'),
        *('-p', 'e:=nan', '-p', 'f:=-.inf', '-p', 'g:="7"', '-p', 'h:=feed_transporter.V_tr=-1', '-p', 'i:=1_000'),
    )
    assert got is not None
    assert {k: v for k, v in got.items() if k != 'e'} == {
        'a': 5,
        'b': -2500.0,
        'c': True,
        'd': False,
        'f': -math.inf,
        'g': '7',
        'h': 'feed_transporter.V_tr=-1',
        'i': '1_000',
    }
    assert isinstance(got['e'], float) and math.isnan(got['e'])
    assert type(got['a']) is int


def test_only_this_nodes_rules_and_only_inside_ros_args() -> None:
    got = values('-p', 'x:=1', '--ros-args', '-p', 'other:a:=1', '-p', 'crank_drive:b:=2', '-p', '/**:c:=3')
    assert got == {'b': 2, 'c': 3}
    assert values('--ros-args', '-p', 'a:=1', '--', '-p', 'b:=2') == {'a': 1}
    assert values('--ros-args', '--log-level', 'debug', '--disable-rosout-logs', '-p', 'a:=1') == {'a': 1}
    # ros2 launch names the node by its own name and passes its parameters in a file
    assert values('--ros-args', '-r', '__node:=crank_drive', '-p', 'a:=1') == {'a': 1}
    assert values() == {}


@pytest.mark.parametrize(
    'words',
    [
        ('--ros-args', '-r', '__node:=other', '-p', 'a:=1'),  # another name
        ('--ros-args', '-r', '__ns:=/plant', '-p', 'a:=1'),  # a namespace
        ('--ros-args', '-p', 'a:=[1, 2]'),  # a list
        ('--ros-args', '-p', 'a:=0x10'),  # strtol's base 16
        ('--ros-args', '-p', 'a:=010'),  # strtol's base 8
        ('--ros-args', '-p', 'a:=yes'),  # a YAML 1.1 bool word
        ('--ros-args', '-p', 'a'),  # no :=
        ('--ros-args', '-p'),  # nothing after -p
        ('--ros-args', '--unknown-option'),
    ],
)
def test_what_is_not_read_for_sure_leaves_the_reading_to_rcl(words: tuple[str, ...]) -> None:
    assert values(*words) is None


def test_a_parameter_file_is_read_with_rclpys_reader_and_the_last_setting_wins(tmp_path: Path) -> None:
    """As with rcl (tried with rclpy: ``-p rate:=50.0 --params-file F`` gives F's 100.0, the other order 50.0)."""
    params = tmp_path / 'params.yaml'
    params.write_text('crank_drive:\n  ros__parameters:\n    scene: line\n    rate: 100.0\n')
    got = values('--ros-args', '--params-file', str(params), '-p', 'rate:=50.0')
    assert got == {'scene': 'line', 'rate': 50.0}
    assert values('--ros-args', '-p', 'rate:=50.0', '--params-file', str(params)) == {'scene': 'line', 'rate': 100.0}
    later = tmp_path / 'later.yaml'
    later.write_text('/**:\n  ros__parameters:\n    scene: folder\n')
    assert values('--ros-args', '--params-file', str(params), '--params-file', str(later)) == {
        'scene': 'folder',
        'rate': 100.0,
    }
    (tmp_path / 'broken.yaml').write_text('crank_drive: [unclosed\n')
    assert values('--ros-args', '--params-file', str(tmp_path / 'broken.yaml')) is None
    assert values('--ros-args', '--params-file', str(tmp_path / 'missing.yaml')) is None
