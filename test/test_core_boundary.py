"""folder_line/core is numpy-only physics: no ROS, no bag code, no scipy, no plotting."""

from __future__ import annotations

import ast
import sys
from pathlib import Path

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


def test_analysis_and_config_do_not_import_the_ros_layer() -> None:
    """What the analysis of a run needs (the run's parameters, its folder layout) is in folder_line/config."""
    package = CORE.parent
    offenders = {
        str(p.relative_to(package.parent)): sorted(n for n in _imports(p) if n.split('.')[:2] == ['folder_line', 'ros'])
        for folder in ('analysis', 'config')
        for p in sorted((package / folder).rglob('*.py'))
    }
    assert {k: v for k, v in offenders.items() if v} == {}
