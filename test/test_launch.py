"""launch/line.launch.py cannot run here (no launch_ros in the wheels); check what can be checked."""

from __future__ import annotations

import ast
import re
from pathlib import Path

from folder_line.interfaces import LINE_CLOCK, MACHINE_NODES

REPO = Path(__file__).resolve().parent.parent
LAUNCH = REPO / 'launch' / 'line.launch.py'


def _literal(tree: ast.Module, name: str) -> object:
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == name for t in node.targets):
            return ast.literal_eval(node.value)
    raise AssertionError(f'{name} not found')


def test_launch_file_starts_every_line_node_with_an_installed_executable() -> None:
    tree = ast.parse(LAUNCH.read_text())
    imported = {
        (node.module, alias.name) for node in tree.body if isinstance(node, ast.ImportFrom) for alias in node.names
    }
    assert ('folder_line.interfaces', 'MACHINE_NODES') in imported  # the node names are written once
    scripts = set(re.findall(r"'(\w+) = folder_line\.ros\.nodes\.\w+:main'", (REPO / 'setup.py').read_text()))
    assert set(MACHINE_NODES) | {LINE_CLOCK} <= scripts
    assert 'def generate_launch_description' in LAUNCH.read_text()


def test_launch_arguments_match_node_parameters() -> None:
    from folder_line.ros.nodes.machine import MACHINE_SPECS

    tree = ast.parse(LAUNCH.read_text())
    from folder_line.ros.nodes.line_clock import SPECS as CLOCK_SPECS

    args = {name for name, _, _ in _literal(tree, 'ARGUMENTS')}
    assert {spec.name for spec in MACHINE_SPECS} <= args
    clock = {spec.name for spec in CLOCK_SPECS}
    assert {'rtf', 'duration', 'rate', 'clock', 'lost_timeout'} <= args & clock


def test_launch_ends_the_whole_line_with_line_clock() -> None:
    text = LAUNCH.read_text()
    # the clock waits for exactly the machine nodes the file starts, and its exit shuts every node down
    assert "'participants': ','.join(MACHINE_NODES)" in text
    assert 'OnProcessExit' in text and 'Shutdown' in text


def test_launch_file_is_installed() -> None:
    assert "glob('launch/*.launch.py')" in (REPO / 'setup.py').read_text()


def test_launch_gives_the_drawing_node_its_marker_rate() -> None:
    from folder_line.ros.nodes.sheet_counter import SheetCounter

    args = {name for name, _, _ in _literal(ast.parse(LAUNCH.read_text()), 'ARGUMENTS')}
    assert 'marker_rate' in args and 'marker_rate' in {spec.name for spec in SheetCounter.EXTRA_SPECS}
    assert "if name == 'sheet_counter'" in LAUNCH.read_text()
