"""The package's architecture, checked: parts import only what lies below them, no import cycles.

The parts of ``folder_line`` and what each may import (besides itself)::

    core        numpy-only physics and timing (errors only; test_core_boundary.py)
    interfaces  names of topics, nodes, events, time (core)
    files       writing that never destroys, bounded reading (errors)
    config      defaults, scenes, run settings (core, interfaces, files)
    bag         rosbag2/MCAP (core, interfaces, files, config)
    ros         nodes, lockstep, run, recorder (all of the above)
    analysis    a recorded run (all but ros: a bag is analysed without ROS)
    accuracy    what accuracy costs (all but cli)
    studies     sweeps, solves, optimisation, Monte Carlo on Dask (all but ros, accuracy and cli)
    cli         the command line (everything)

Imports inside functions count too: a dependency hidden in a function is still one.

Inside ``core`` the layers run one way too, imports for annotations only (``if TYPE_CHECKING``)
included, since a type named is a dependency of the design::

    numerics     integrators, roots, validation, arrays (nothing of the core)
    limits       the table of physical ranges (numerics)
    types        events and joint samples, machine sections of no mechanism (the above)
    mechanisms   the papers' machines; SceneView, what they read of a scene (the above)
    effects      one module per effect (the above)
    line         scenes, simulators, the streamed line, the batch model (the above)
    supervision  the supervisor's logic (the above)
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest
from _loaded import ros_modules_loaded

PACKAGE = Path(__file__).resolve().parent.parent / 'folder_line'

_BASE = {'errors', 'progress', '__init__'}
#: part of folder_line -> the parts it may import
MAY_IMPORT: dict[str, set[str]] = {
    'errors': set(),
    'progress': set(),
    '__init__': set(),
    'core': {'errors'},
    'interfaces': {'core', *_BASE},
    'files': set(_BASE),
}
MAY_IMPORT['config'] = {'core', 'interfaces', 'files', *_BASE}
MAY_IMPORT['bag'] = {'config', *MAY_IMPORT['config']}
MAY_IMPORT['ros'] = {'bag', *MAY_IMPORT['bag']}
MAY_IMPORT['analysis'] = {'bag', *MAY_IMPORT['bag']}
MAY_IMPORT['accuracy'] = {'ros', 'analysis', *MAY_IMPORT['ros']}
MAY_IMPORT['studies'] = {'analysis', *MAY_IMPORT['analysis']}
MAY_IMPORT['cli'] = {'accuracy', 'studies', *MAY_IMPORT['accuracy']}


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix('').parts
    return '.'.join(parts[:-1] if parts[-1] == '__init__' else parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted(PACKAGE.rglob('*.py'))}


def _imports(path: Path, annotations: bool = False) -> set[str]:
    """folder_line modules imported by ``path``, inside functions too; under ``if TYPE_CHECKING`` only with
    ``annotations``."""
    tree = ast.parse(path.read_text(encoding='utf-8'))
    known = _modules()
    found: set[str] = set()

    def visit(node: ast.AST) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.Import | ast.ImportFrom):
                if isinstance(child, ast.Import):
                    names = [a.name for a in child.names]
                else:
                    assert child.level == 0, f'{path}: relative import'
                    base = child.module or ''
                    names = [f'{base}.{a.name}' if f'{base}.{a.name}' in known else base for a in child.names]
                found.update(n for n in names if n.split('.')[0] == 'folder_line')
            elif (
                isinstance(child, ast.If)
                and isinstance(child.test, ast.Name)
                and child.test.id == 'TYPE_CHECKING'
                and not annotations
            ):
                continue  # annotations only: no import at run time
            visit(child)

    visit(tree)
    return found


def _part(module: str) -> str:
    return module.split('.')[1] if '.' in module else '__init__'


def test_every_part_is_placed() -> None:
    parts = {_part(m) for m in _modules()}
    assert parts <= set(MAY_IMPORT), sorted(parts - set(MAY_IMPORT))


def test_parts_import_only_what_lies_below() -> None:
    wrong = sorted(
        f'{m} imports {dep}'
        for m, p in _modules().items()
        for dep in _imports(p)
        if _part(dep) != _part(m) and _part(dep) not in MAY_IMPORT[_part(m)]
    )
    assert wrong == []


class _Tarjan:
    """Tarjan's strongly connected components of ``graph``, those of more than one module in :attr:`out`."""

    def __init__(self, graph: dict[str, set[str]]) -> None:
        self.graph = graph
        self.index: dict[str, int] = {}
        self.low: dict[str, int] = {}
        self.stack: list[str] = []
        self.on_stack: set[str] = set()
        self.out: list[list[str]] = []
        for v in sorted(graph):
            if v not in self.index:
                self.strong(v)

    def strong(self, v: str) -> None:
        index, low = self.index, self.low
        index[v] = low[v] = len(index)
        self.stack.append(v)
        self.on_stack.add(v)
        for w in self.graph.get(v, ()):
            if w not in index:
                self.strong(w)
                low[v] = min(low[v], low[w])
            elif w in self.on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            self.pop_component(v)

    def pop_component(self, v: str) -> None:
        comp = []
        while True:
            w = self.stack.pop()
            self.on_stack.discard(w)
            comp.append(w)
            if w == v:
                break
        if len(comp) > 1:
            self.out.append(sorted(comp))


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    return _Tarjan(graph).out


def test_no_import_cycles() -> None:
    modules = _modules()
    graph = {m: {d for d in _imports(p) if d in modules and d != m} for m, p in modules.items()}
    # a package's __init__ importing its own modules is not a cycle of the design
    graph = {m: {d for d in deps if not m.startswith(d + '.')} for m, deps in graph.items()}
    assert _cycles(graph) == []


#: layer of folder_line.core -> the layers it may import
CORE_LAYERS = ('numerics', 'limits', 'types', 'mechanisms', 'effects', 'line', 'supervision')
CORE_MAY_IMPORT = {layer: set(CORE_LAYERS[:i]) for i, layer in enumerate(CORE_LAYERS)}


def _core_layer(module: str) -> str:
    """``folder_line.core.line.scene`` -> ``line``; the package ``folder_line.core`` itself -> ``''``."""
    parts = module.split('.')
    return parts[2] if len(parts) > 2 else ''


def test_the_core_layers_run_one_way() -> None:
    """Within ``core``, each layer imports only the layers below it, for annotations too."""
    core = {m: p for m, p in _modules().items() if m.startswith('folder_line.core.')}
    assert {_core_layer(m) for m in core} == set(CORE_LAYERS)
    wrong = sorted(
        f'{m} imports {dep}'
        for m, p in core.items()
        for dep in _imports(p, annotations=True)
        if dep.startswith('folder_line.core')
        and _core_layer(dep) != _core_layer(m)
        and _core_layer(dep) not in CORE_MAY_IMPORT[_core_layer(m)]
    )
    assert wrong == []


def test_the_core_has_no_import_cycle_even_for_annotations() -> None:
    core = {m: p for m, p in _modules().items() if m.startswith('folder_line.core')}
    graph = {m: {d for d in _imports(p, annotations=True) if d in core and d != m} for m, p in core.items()}
    graph = {m: {d for d in deps if not m.startswith(d + '.')} for m, deps in graph.items()}
    assert _cycles(graph) == []


def test_the_cycle_check_finds_a_cycle() -> None:
    assert _cycles({'a': {'b'}, 'b': {'c'}, 'c': {'a'}, 'd': {'a'}}) == [['a', 'b', 'c']]


@pytest.mark.parametrize(
    'module', ['folder_line.interfaces', 'folder_line.config', 'folder_line.bag', 'folder_line.analysis']
)
def test_layers_below_ros_do_not_load_rclpy(module: str) -> None:
    names = sorted(m for m in _modules() if m == module or m.startswith(module + '.'))
    assert ros_modules_loaded(''.join(f'import {m}\n' for m in names)) == ('', [])


#: (module file, imported module) -> why that import stands inside a function (every other import is at the top)
FUNCTION_LEVEL_IMPORTS: dict[tuple[str, str], str] = {
    ('cli/run.py', 'folder_line.ros'): 'loads rclpy: only `folder-line run` and `bag play` need DDS',
    ('cli/bag.py', 'folder_line.ros'): 'loads rclpy: only `folder-line run` and `bag play` need DDS',
    ('cli/monitor_verb.py', 'folder_line.cli.monitor'): 'loads rclpy: only `folder-line monitor` needs DDS',
    ('cli/operator.py', 'folder_line.ros.operator'): 'loads rclpy: only the operator commands need DDS',
    ('cli/tune.py', 'folder_line.ros.operator'): 'loads rclpy: only the operator commands need DDS',
    ('cli/profile.py', 'folder_line.ros.dds_profile'): 'the ros package: only `folder-line profile` needs it',
    ('cli/profile.py', 'folder_line.ros.line_key'): 'the ros package: only `profile` and the operators need it',
    ('cli/operator.py', 'folder_line.ros.line_key'): 'the ros package: only `profile` and the operators need it',
    ('cli/simulate.py', 'folder_line.cli.plots'): 'the figures and the batch bag writer: only `simulate --plots` draws',
    ('analysis/figures.py', 'matplotlib'): 'slow to import, and the back end must be chosen before pyplot',
    ('analysis/figures.py', 'matplotlib.pyplot'): 'imported after matplotlib.use("Agg")',
    ('analysis/animation/frames.py', 'matplotlib.collections'): 'imported after pyplot() chose the Agg back end',
    ('analysis/animation/frames.py', 'matplotlib.patches'): 'imported after pyplot() chose the Agg back end',
    ('analysis/landing_drawing.py', 'matplotlib.ticker'): 'matplotlib loads on use, after pyplot() chose the back end',
    ('accuracy/output.py', 'matplotlib'): 'matplotlib loads on use, after pyplot() chose the back end',
    ('config/params.py', 'ament_index_python.packages'): 'present only on a ROS 2 install: tried, not required',
    ('studies/runner.py', 'dask.distributed'): 'slow to import (~0.5 s): only the verbs that fan out load it',
    ('studies/runner.py', 'dask'): 'its configuration, with dask.distributed',
    ('studies/runner.py', 'distributed.comm.addressing'): 'the scheduler address checked as Dask reads it',
    ('studies/runner.py', 'distributed.comm.registry'): 'the scheduler address checked as Dask reads it',
    ('studies/montecarlo.py', 'scipy.special'): 'scipy is slow to import: `folder-line --help` does not need it',
    ('studies/optimize.py', 'scipy.optimize'): 'scipy is slow to import: `folder-line --help` does not need it',
    ('studies/solve.py', 'scipy.optimize'): 'scipy is slow to import: `folder-line --help` does not need it',
}


def _function_level_imports(path: Path) -> set[tuple[str, str]]:
    tree = ast.parse(path.read_text(encoding='utf-8'))
    rel = path.relative_to(PACKAGE).as_posix()
    found: set[tuple[str, str]] = set()
    for fn in ast.walk(tree):
        if isinstance(fn, ast.FunctionDef | ast.AsyncFunctionDef):
            for n in ast.walk(fn):
                if isinstance(n, ast.Import):
                    found.update((rel, a.name) for a in n.names)
                elif isinstance(n, ast.ImportFrom):
                    found.add((rel, n.module or ''))
    return found


def test_imports_inside_functions_are_few_and_explained() -> None:
    found = set().union(*(_function_level_imports(p) for p in _modules().values()))
    assert found == set(FUNCTION_LEVEL_IMPORTS)
