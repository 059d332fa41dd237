"""``folder-line optimize``: the most even layup the design constraints allow (a thin verb over
:mod:`folder_line.studies.optimize`).

Writes ``DIR/scene.yaml`` (the scene with the best geometry, accepted by every verb),
``DIR/optimize.json`` (:func:`folder_line.studies.optimize_output.result_document`) and
``DIR/landing.png`` (the landing histograms before and after), and prints the verdict and
both histograms. Every output target is checked, and the folder claimed, before any work.
"""

from __future__ import annotations

import argparse
import sys

from folder_line.cli.arg_types import number
from folder_line.cli.study_options import add_scene_arguments
from folder_line.cli.verb_options import Subparsers
from folder_line.config.scenes import InputNames, parse_set, scene_mapping, write_scene
from folder_line.files.atomic import claim_output_dir, write_json_atomic
from folder_line.studies.optimize import (
    DEFAULT_KEYS,
    DEFAULT_SPAN,
    LINK_KEYS,
    OptimizeSettings,
    check_scene,
    default_bounds,
    optimize_layup,
    parse_design_vary,
)
from folder_line.studies.optimize_output import histogram_lines, landing_figure, result_document, verdict

__all__ = ['OUTPUT_FILES', 'add_parser', 'run']

#: what the verb writes into ``--out``
OUTPUT_FILES = ('scene.yaml', 'optimize.json', 'landing.png')
_DEFAULTS = OptimizeSettings()


def add_parser(subparsers: Subparsers) -> argparse.ArgumentParser:
    """Add the ``optimize`` verb to ``folder-line``'s subparsers; returns its parser."""
    opt: argparse.ArgumentParser = subparsers.add_parser(
        'optimize',
        help='optimise the layup geometry: smallest landing CV under the design constraints (scipy)',
        description='Minimise layup.landing_cv over link lengths of the layup six-bar within bounds, subject to: '
        'both loops assembled over the whole crank turn, loop O1-A-B-O2 a Grashof crank-rocker, a minimum '
        'transmission angle in both loops, both chute exits inside the container walls over the whole swing, '
        'and no leaf spilled or damaged (scipy.optimize.differential_evolution, seeded).',
    )
    add_scene_arguments(opt, _DEFAULTS.duration, scene='layup', per='for every candidate')
    opt.add_argument(
        '--vary',
        action='append',
        default=[],
        metavar='layup.KEY=LO:HI',
        help=f'a design variable and its bounds, m (repeatable; KEY one of {", ".join(LINK_KEYS)}); default: '
        f'{", ".join(DEFAULT_KEYS)} each within ±{100 * DEFAULT_SPAN:g} %% of the scene value',
    )
    opt.add_argument(
        '--min-transmission',
        type=number('--min-transmission', 0.0, 89.0, open_lo=True),
        default=_DEFAULTS.min_transmission_deg,
        metavar='DEG',
        help=f'smallest transmission angle allowed in either loop over the turn, deg '
        f'(default {_DEFAULTS.min_transmission_deg:g})',
    )
    opt.add_argument(
        '--seed',
        type=number('--seed', 0, 2**32 - 1, whole=True),
        default=_DEFAULTS.seed,
        metavar='N',
        help=f"the optimiser's seed (default {_DEFAULTS.seed})",
    )
    opt.add_argument(
        '--maxiter',
        type=number('--maxiter', 0, 100_000, whole=True),
        default=_DEFAULTS.maxiter,
        metavar='N',
        help=f'generations of differential evolution (default {_DEFAULTS.maxiter})',
    )
    opt.add_argument(
        '--popsize',
        type=number('--popsize', 1, 100_000, whole=True),
        default=_DEFAULTS.popsize,
        metavar='N',
        help=f'candidates per generation per design variable (default {_DEFAULTS.popsize})',
    )
    opt.add_argument('--out', default='out/optimize', metavar='DIR', help='output directory (default ./out/optimize)')
    opt.set_defaults(func=run, output_option='--out')
    return opt


def run(args: argparse.Namespace) -> int:
    """Run ``folder-line optimize``; returns the exit code (errors are raised for ``main`` to print)."""
    names = InputNames(scene='--scene', overrides='--set')
    settings = OptimizeSettings(
        min_transmission_deg=args.min_transmission,
        duration=args.duration,
        seed=args.seed,
        maxiter=args.maxiter,
        popsize=args.popsize,
    )
    mapping = scene_mapping(args.scene, parse_set(args.overrides, names), names=names)
    scene = check_scene(mapping)  # before the output folder is claimed
    bounds = parse_design_vary(args.vary) if args.vary else default_bounds(mapping['machines']['layup'])
    with claim_output_dir(args.out, '--out', OUTPUT_FILES) as out:
        print(
            f'optimising {", ".join(f"layup.{b.key} in [{b.lo:.4g}, {b.hi:.4g}]" for b in bounds)} '
            f'of scene {mapping.get("name")}: minimise landing_cv over {settings.duration:g} s, '
            f'transmission >= {settings.min_transmission_deg:g} deg',
            flush=True,
        )
        result = optimize_layup(mapping, bounds, settings, scene=scene, progress=sys.stdout)
        scene_path = out / 'scene.yaml'
        write_scene(scene_path, result.scene)
        cont = mapping['machines']['container']
        walls = (float(cont['x_left']), float(cont['x_right']))
        landing_figure(result, out / 'landing.png', walls)
        write_json_atomic(out / 'optimize.json', result_document(result, str(scene_path), walls))
    print(f'{result.message} ({result.nit} generations, {result.seconds:.1f} s)')
    width = max(len(k) for k in result.best.values)
    for key, value in result.best.values.items():
        start = result.start.values[key]
        change = f'  ({100.0 * (value - start) / abs(start):+.1f} %)' if start else ''
        print(f'  layup.{key:<{width}} {start:10.5f} -> {value:10.5f} m{change}')
    for line in histogram_lines(result):
        print(line)
    print(verdict(result, walls))
    for name in OUTPUT_FILES:
        print(f'wrote {out / name}')
    return 0
