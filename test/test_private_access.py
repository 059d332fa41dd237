"""No code of the project reaches into another library's private parts.

A name with a leading underscore (not a dunder) is private to whoever defines it. The product,
the benchmarks and the tests may use such names only where the project defines them itself:
an attribute ``x._name``, a ``getattr(x, '_name')``, an import from a private module of another
package (``rclpy._rclpy_pybind11``) or of a private name of it. A library that changes its
insides must not break the tool, and a reviewer must not have to ask whether it may.
"""

from __future__ import annotations

import ast
import functools
from collections.abc import Iterator
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
TREES = ('folder_line', 'bench', 'test')
OURS = {'folder_line', 'bench', 'test'}
#: names with a leading underscore that their library documents as public API
DOCUMENTED = {
    '_exit',  # os._exit
    '_asdict',  # namedtuple methods and attributes
    '_replace',
    '_fields',
    '_make',
    '_fields_',  # ctypes Structure and Union layouts
}


def sources() -> list[Path]:
    return sorted(p for tree in TREES for p in (REPO / tree).rglob('*.py'))


@functools.cache
def parsed() -> tuple[tuple[Path, ast.Module], ...]:
    """Every source with its syntax tree, parsed once for the whole module."""
    return tuple((path, ast.parse(path.read_text(encoding='utf-8'))) for path in sources())


def is_private(name: str) -> bool:
    return name.startswith('_') and not (name.startswith('__') and name.endswith('__'))


def defined_names(tree: ast.AST) -> Iterator[str]:
    """Every name a module binds: functions, classes, assignment targets, attributes set, arguments, imports."""
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            yield node.name
        elif isinstance(node, ast.Name) and isinstance(node.ctx, (ast.Store, ast.Del)):
            yield node.id
        elif isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store):
            yield node.attr
        elif isinstance(node, ast.arg):
            yield node.arg
        elif isinstance(node, ast.alias):
            yield (node.asname or node.name).split('.')[0]


def our_private_names() -> set[str]:
    names: set[str] = set()
    for _, tree in parsed():
        names.update(n for n in defined_names(tree) if is_private(n))
    return names


def our_modules() -> set[str]:
    """The project's packages, and the test and bench modules and folders imported by their own names."""
    names = set(OURS)
    for path in sources():
        names.update(path.relative_to(REPO).with_suffix('').parts[1:])
    return names


MODULES = our_modules()


def foreign(module: str | None, level: int) -> bool:
    return level == 0 and module is not None and module.split('.')[0] not in MODULES


def _reflective_use(node: ast.Call, ours: set[str]) -> str | None:
    """``getattr(x, '_name')`` and its kin with a private name the project does not define, in words."""
    if not (isinstance(node.func, ast.Name) and node.func.id in {'getattr', 'hasattr', 'setattr', 'delattr'}):
        return None
    if len(node.args) < 2 or not isinstance(node.args[1], ast.Constant) or not isinstance(node.args[1].value, str):
        return None
    name = node.args[1].value
    return f'{node.func.id}(..., {name!r})' if is_private(name) and name not in ours | DOCUMENTED else None


def _import_from_uses(node: ast.ImportFrom) -> Iterator[str]:
    """A private module or name imported from another library, in words."""
    if not foreign(node.module, node.level):
        return
    assert node.module is not None
    if any(is_private(part) for part in node.module.split('.')):
        yield f'from {node.module} import'
    for alias in node.names:
        if is_private(alias.name) and alias.name not in DOCUMENTED:
            yield f'from {node.module} import {alias.name}'


def private_uses(tree: ast.AST, ours: set[str]) -> Iterator[tuple[int, str]]:
    """``(line, what)`` of each use of a private name the project does not define."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and is_private(node.attr) and node.attr not in ours | DOCUMENTED:
            yield node.lineno, f'.{node.attr}'
        elif isinstance(node, ast.Call) and (what := _reflective_use(node, ours)) is not None:
            yield node.lineno, what
        elif isinstance(node, ast.ImportFrom):
            yield from ((node.lineno, what) for what in _import_from_uses(node))
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split('.')[0] not in MODULES and any(is_private(p) for p in alias.name.split('.')):
                    yield node.lineno, f'import {alias.name}'


def test_nothing_uses_another_librarys_private_names() -> None:
    ours = our_private_names()
    found = [
        f'{path.relative_to(REPO)}:{line}: {what}' for path, tree in parsed() for line, what in private_uses(tree, ours)
    ]
    assert not found, '\n'.join(found)


@pytest.mark.parametrize(
    'code',
    [
        'writer._Writer__finalize_chunk()',
        'node._parameter_overrides',
        "getattr(node, '_time_source', None)",
        'from rclpy._rclpy_pybind11 import RCLError',
        'from mcap.writer import _private',
        'import mcap._chunk_builder',
        'parser._actions',
    ],
)
def test_the_check_finds_each_kind_of_use(code: str) -> None:
    assert list(private_uses(ast.parse(code), ours=set())), code


@pytest.mark.parametrize(
    'code',
    [
        'self._x = 1\nself._x',
        'os._exit(3)',
        'point._replace(x=1)',
        'from folder_line.bag.writer import _Segment',
        'from ._line import run_line',
        'obj.__slots__',
    ],
)
def test_the_check_passes_what_is_ours_or_documented(code: str) -> None:
    tree = ast.parse(code)
    ours = {n for n in defined_names(tree) if is_private(n)}
    assert not list(private_uses(tree, ours)), code
