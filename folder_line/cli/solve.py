"""``folder-line solve``: the value of a scene key where a condition on a metric starts to hold."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable

from folder_line.cli.study_options import (
    add_cluster_arguments,
    add_scene_arguments,
    cluster_from,
    scheduler_reached,
    source_from,
)
from folder_line.cli.verb_options import Subparsers
from folder_line.errors import bounded_repr
from folder_line.files.atomic import check_output_file, write_json_atomic
from folder_line.studies.grid import parse_bounds
from folder_line.studies.solve import DEFAULT_SCAN, parse_condition, solve_boundary

__all__ = ['add_parser', 'run']


def _positive(option: str) -> Callable[[str], float]:
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = float('nan')
        if not 0.0 < value < float('inf'):
            raise argparse.ArgumentTypeError(f'{option}={bounded_repr(text)}: must be a finite number > 0')
        return value

    return parse


def _scan(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = 0
    if not 2 <= value <= 10_000:
        raise argparse.ArgumentTypeError(f'--scan={bounded_repr(text)}: must be a whole number in [2, 10000]')
    return value


def add_parser(subparsers: Subparsers) -> argparse.ArgumentParser:
    """Add the ``solve`` verb to ``folder-line``'s sub-parsers."""
    parser: argparse.ArgumentParser = subparsers.add_parser(
        'solve', help='the value of a scene key where a condition on a metric starts to hold (scan, then brentq)'
    )
    add_scene_arguments(parser, 2.0, per='at every point')
    parser.add_argument('--find', required=True, metavar='KEY', help='the scene key to solve for')
    parser.add_argument(
        '--where',
        required=True,
        metavar="'METRIC>=X'",
        help='the condition: a metric, one of >=, >, <=, <, and a number in its unit',
    )
    parser.add_argument(
        '--between', metavar='LO:HI', help="the key's range (default: half to twice the scene's own value)"
    )
    parser.add_argument(
        '--tol',
        type=_positive('--tol'),
        metavar='X',
        help="absolute tolerance of the answer, in the key's unit (default 1e-6 of the range)",
    )
    parser.add_argument(
        '--scan',
        type=_scan,
        default=DEFAULT_SCAN,
        metavar='N',
        help=f'values of the bracketing scan (default {DEFAULT_SCAN})',
    )
    parser.add_argument('--json', metavar='PATH', help='write the answer as JSON ({"value": ..., ...})')
    add_cluster_arguments(parser)
    parser.set_defaults(func=run, output_option='--json')
    return parser


def run(args: argparse.Namespace) -> int:
    """Run ``folder-line solve``; returns the exit code."""
    if args.json:
        check_output_file(args.json, '--json')
    condition = parse_condition(args.where)
    between = parse_bounds(args.between, '--between') if args.between is not None else None
    cluster = cluster_from(args)
    with scheduler_reached(cluster):
        result = solve_boundary(
            source_from(args),
            args.find,
            condition,
            args.duration,
            cluster,
            between=between,
            tol=args.tol,
            scan=args.scan,
            progress=sys.stderr,
        )
    unit = f' {result.unit}' if result.unit else ''
    side = 'above it (fails below)' if result.holds == 'above' else 'below it (fails above)'
    print(
        f'{result.key} = {result.value:.9g}{unit} (+- {result.tolerance:.3g}{unit}): '
        f'{result.condition.text} holds {side}; {result.evaluations} simulations of {args.duration:g} s'
    )
    if args.json:
        print(f'wrote {write_json_atomic(args.json, result.document())}')
    return 0
