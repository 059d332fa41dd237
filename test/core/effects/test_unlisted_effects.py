"""An effect the scene does not list costs nothing: none of its code runs.

Every Python function call of a simulation is traced (``sys.setprofile``); an effect's code is its
module and every core module only it imports (found from the package's imports, those inside
functions included). The same tracer must see that code run when the scene lists the effect.
"""

from __future__ import annotations

import ast
import sys
from collections.abc import Mapping
from pathlib import Path
from types import FrameType

import pytest

import folder_line
from folder_line.config.scenes import load_scene
from folder_line.core.effects import EFFECTS
from folder_line.core.line.model import simulate
from folder_line.core.line.scene import Scene, parse_scene

from .._scenes import FAULTS

PACKAGE = Path(folder_line.__file__).resolve().parent

#: the effects the shipped ``line`` scene does not list, with parameters that make each do something
EXTRA: dict[str, Mapping[str, object]] = {
    'faults': FAULTS,
    'speed_ripple': {'amplitude': 0.05, 'frequency': 3.0},
    'arrival_jitter': {'distribution': 'uniform', 'sigma': 0.3},
    'length_scatter': {'sigma': 0.2},
    'property_scatter': {'e_sigma': 0.2, 'mu_sigma': 0.1},
    'guide_friction': {'mu': 0.5, 's0': 0.0, 'v0': 1.0, 'h': 0.002},
}


def _module_name(path: Path) -> str:
    return '.'.join(path.relative_to(PACKAGE.parent).with_suffix('').parts).removesuffix('.__init__')


def _imports() -> dict[str, set[str]]:
    """Module -> the package's modules it imports anywhere in its text."""
    files = {_module_name(p): p for p in PACKAGE.rglob('*.py')}
    out: dict[str, set[str]] = {m: set() for m in files}
    for module, path in files.items():
        for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'))):
            if isinstance(node, ast.Import):
                out[module] |= {a.name for a in node.names if a.name in files}
            elif isinstance(node, ast.ImportFrom) and node.module:
                named = {f'{node.module}.{a.name}' for a in node.names}
                out[module] |= ({node.module} | named) & files.keys()
    return out


IMPORTS = _imports()


def effect_code(effect: str) -> set[Path]:
    """The files of ``effect``'s code: its module and the core modules imported by its code alone."""
    group = {f'folder_line.core.effects.{effect}'}
    grown = True
    while grown:
        grown = False
        for module in IMPORTS:
            if module in group or not module.startswith('folder_line.core.'):
                continue
            importers = {m for m, deps in IMPORTS.items() if module in deps}
            if importers and importers <= group:
                group.add(module)
                grown = True
    return {PACKAGE.parent.joinpath(*m.split('.')).with_suffix('.py') for m in group}


def _scene(effects: Mapping[str, object]) -> Scene:
    """The ``line`` scene with ``effects``; guide_friction gives way to chute_belts (one excludes the other),
    and property_scatter scatters only what is listed."""
    effects = dict(effects)
    if 'chute_belts' in effects:
        effects.pop('guide_friction', None)
    if 'property_scatter' in effects:
        effects['property_scatter'] = {
            'e_sigma': 0.2 if 'stop_bounce' in effects else 0.0,
            'mu_sigma': 0.1 if 'feed_slip' in effects else 0.0,
        }
    data = dict(load_scene('line').source)
    data['effects'] = effects
    return parse_scene(data)


def _every_effect() -> dict[str, object]:
    listed = load_scene('line').source['effects']
    assert isinstance(listed, Mapping)
    return {**listed, **EXTRA}


def _files_run(scene: Scene) -> tuple[set[Path], int]:
    """The files whose functions ran in 3 s of the line (module bodies of late imports aside), and the events."""
    seen: set[str] = set()

    def profile(frame: FrameType, event: str, arg: object) -> None:
        if event == 'call' and frame.f_code.co_name != '<module>':
            seen.add(frame.f_code.co_filename)

    sys.setprofile(profile)
    try:
        result = simulate(scene, 3.0, sample_rate=100.0)
    finally:
        sys.setprofile(None)
    return {Path(f).resolve() for f in seen}, int(result.events.size)


def test_every_effect_has_parameters_here() -> None:
    assert set(_every_effect()) == set(EFFECTS)


@pytest.mark.parametrize('effect', sorted(EFFECTS))
def test_an_unlisted_effect_never_runs(effect: str) -> None:
    scene = _scene({k: v for k, v in _every_effect().items() if k != effect})
    assert effect not in scene.effects
    ran, events = _files_run(scene)
    assert events > 0
    assert not {p.name for p in ran & effect_code(effect)}


@pytest.mark.parametrize('effect', sorted(EFFECTS))
def test_a_listed_effect_is_seen_running(effect: str) -> None:
    effects = _every_effect()
    if effect == 'guide_friction':
        effects.pop('chute_belts')
    scene = _scene(effects)
    assert effect in scene.effects
    ran, _ = _files_run(scene)
    assert PACKAGE / 'core' / 'effects' / f'{effect}.py' in ran


def test_code_an_effect_shares_is_not_its_own() -> None:
    # the seeded draws serve two effects: they live in numerics, not in either effect's module
    assert PACKAGE / 'core' / 'numerics' / 'rng.py' not in effect_code('length_scatter')
    assert PACKAGE / 'core' / 'effects' / 'motor_segment.py' in effect_code('motor_dynamics')
    assert PACKAGE / 'core' / 'numerics' / 'hermite.py' in effect_code('guide_friction')
