"""folder_line/core is numpy-only physics: no ROS, no bag code, no scipy, no plotting; no ROS node names;
its imports at module level."""

from __future__ import annotations

import ast
import sys
from pathlib import Path

from folder_line.config.scenes import load_scene
from folder_line.core.line.stream import UNITS
from folder_line.interfaces import (
    EVENT_KINDS,
    EVENT_OWNER,
    JOINT_NODES,
    KNOWN_PARTICIPANTS,
    LINE_CLOCK,
    NODE_OF_UNIT,
    UNIT_OF_NODE,
)

CORE = Path(__file__).resolve().parent.parent / 'folder_line' / 'core'


def _imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding='utf-8'), filename=str(path))
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # relative import stays inside the core
                names.add('folder_line.core')
            elif node.module:
                names.add(node.module)
    return names


def _allowed(name: str) -> bool:
    top = name.split('.')[0]
    if top in sys.stdlib_module_names or top == '__future__':
        return True
    if top == 'numpy':
        return True
    return name == 'folder_line.errors' or name == 'folder_line.core' or name.startswith('folder_line.core.')


def test_core_modules_exist() -> None:
    assert len(list(CORE.rglob('*.py'))) >= 5


def test_core_imports_numpy_and_stdlib_only() -> None:
    offenders = {
        str(p.relative_to(CORE.parent.parent)): sorted(n for n in _imports(p) if not _allowed(n))
        for p in sorted(CORE.rglob('*.py'))
    }
    offenders = {k: v for k, v in offenders.items() if v}
    assert offenders == {}


def test_the_check_catches_a_forbidden_import(tmp_path: Path) -> None:
    bad = tmp_path / 'bad.py'
    bad.write_text('import rclpy\nfrom sensor_msgs.msg import JointState\nimport scipy.integrate\n')
    assert sorted(n for n in _imports(bad) if not _allowed(n)) == ['rclpy', 'scipy.integrate', 'sensor_msgs.msg']


# --------------------------------------------------------------------------- units, not ROS node names

#: every ROS node name of the line; the core names its machine units instead (core.line.stream.UNITS)
NODE_NAMES = frozenset({*KNOWN_PARTICIPANTS, LINE_CLOCK})
#: node names that are also the name of a scene's machine section (user input: ``--set
#: feed_transporter.V_tr=...``); the core may use them where they name that section
SECTION_NAMES = frozenset({'feed_transporter'})


def _names_a_section(node: ast.Constant, parents: dict[ast.AST, ast.AST], tables: set[int]) -> bool:
    """``node`` is used as a scene's machine section: ``x.machines[...]``, ``x.machine(...)``, ``Literal[...]``,
    or a key or an element of a module-level table (the registry of sections and of what the effects need)."""
    parent = parents.get(node)
    if isinstance(parent, ast.Subscript) and parent.slice is node:
        if isinstance(parent.value, ast.Name) and parent.value.id == 'Literal':  # Scene.machine's typed overloads
            return True
        return isinstance(parent.value, ast.Attribute) and parent.value.attr == 'machines'
    if isinstance(parent, ast.Call) and any(a is node for a in parent.args):
        return isinstance(parent.func, ast.Attribute) and parent.func.attr == 'machine'
    if isinstance(parent, ast.Dict):
        return id(node) in tables and any(k is node for k in parent.keys)
    return isinstance(parent, (ast.Tuple, ast.List, ast.Set)) and id(node) in tables


def _node_names(path: Path) -> list[tuple[int, str]]:
    """(line, literal) of each string literal in ``path`` equal to a node name (see :data:`SECTION_NAMES`)."""
    tree = ast.parse(path.read_text(encoding='utf-8'), filename=str(path))
    parents = {child: node for node in ast.walk(tree) for child in ast.iter_child_nodes(node)}
    tables = {id(n) for stmt in tree.body if isinstance(stmt, (ast.Assign, ast.AnnAssign)) for n in ast.walk(stmt)}
    return sorted(
        (n.lineno, n.value)
        for n in ast.walk(tree)
        if isinstance(n, ast.Constant)
        and isinstance(n.value, str)
        and n.value in NODE_NAMES
        and not (n.value in SECTION_NAMES and _names_a_section(n, parents, tables))
    )


def test_core_string_literals_name_no_ros_node() -> None:
    offenders = {str(p.relative_to(CORE.parent.parent)): _node_names(p) for p in sorted(CORE.rglob('*.py'))}
    assert {k: v for k, v in offenders.items() if v} == {}


def test_the_node_name_check_catches_a_node_name(tmp_path: Path) -> None:
    bad = tmp_path / 'bad.py'
    bad.write_text(
        "UNITS = ('crank_drive', 'drive')\n"  # 1: a node name in a table
        "SOURCE = 'feed_transporter'\n"  # 2: a section's name, but not used as one
        "SECTIONS = {'feed_transporter': ('knife',)}\n"  # 3: the section registry: allowed
        'def f(scene, res):\n'
        "    v = scene.machines['feed_transporter'].V_tr\n"  # 5: allowed
        "    w = scene.machine('feed_transporter')\n"  # 6: allowed
        "    return res.samples['feed_transporter'], {'x': 'line_clock'}, f'the {w} supervisor'\n"  # 7: two
    )
    assert _node_names(bad) == [(1, 'crank_drive'), (2, 'feed_transporter'), (7, 'feed_transporter'), (7, 'line_clock')]


def test_the_section_names_are_sections_and_the_units_map_to_the_nodes() -> None:
    scene = load_scene('folder', {f'{name}.V_tr': 5.0 for name in SECTION_NAMES})  # a section of the scene files
    assert scene.name == 'folder'
    assert tuple(NODE_OF_UNIT) == UNITS and tuple(NODE_OF_UNIT.values()) == JOINT_NODES
    assert {node: unit for unit, node in NODE_OF_UNIT.items()} == UNIT_OF_NODE
    assert not set(UNITS) & NODE_NAMES
    assert set(EVENT_OWNER) == set(EVENT_KINDS) and set(EVENT_OWNER.values()) <= set(JOINT_NODES)


# --------------------------------------------------------------------------- imports at module level

#: ``path:line`` -> why an import inside a function must stay there (none do)
FUNCTION_LEVEL_IMPORTS: dict[str, str] = {}


def _function_level_imports(path: Path, root: Path) -> list[str]:
    """``<path relative to root>:<line>`` of each import statement inside a function of ``path``."""
    tree = ast.parse(path.read_text(encoding='utf-8'), filename=str(path))
    found = {
        n.lineno
        for fn in ast.walk(tree)
        if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef))
        for n in ast.walk(fn)
        if isinstance(n, (ast.Import, ast.ImportFrom))
    }
    return [f'{path.relative_to(root).as_posix()}:{line}' for line in sorted(found)]


def test_core_imports_at_module_level() -> None:
    """An import inside a function hides a dependency (and, here once, an import cycle)."""
    found = [s for p in sorted(CORE.rglob('*.py')) for s in _function_level_imports(p, CORE.parent.parent)]
    assert [s for s in found if s not in FUNCTION_LEVEL_IMPORTS] == []


def test_the_import_check_catches_an_import_in_a_function(tmp_path: Path) -> None:
    bad = tmp_path / 'pkg' / 'bad.py'
    bad.parent.mkdir()
    bad.write_text('import math\n\n\ndef f():\n    from folder_line.core.line import model\n\n    return model\n')
    assert _function_level_imports(bad, tmp_path) == ['pkg/bad.py:5']
