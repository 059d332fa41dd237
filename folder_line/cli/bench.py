"""``folder-line bench accuracy``: what accuracy costs in CPU time (:mod:`folder_line.accuracy`)."""

from __future__ import annotations

import argparse
import sys

from folder_line.accuracy.bench import STUDIES, run_benchmark
from folder_line.accuracy.output import write_outputs
from folder_line.cli.verb_options import Subparsers, add_out
from folder_line.files.atomic import claim_output_dir

__all__ = ['add_parser', 'run']


def add_parser(subparsers: Subparsers) -> argparse.ArgumentParser:
    """Add the ``bench`` verb and its ``accuracy`` to ``folder-line``'s sub-parsers."""
    bench: argparse.ArgumentParser = subparsers.add_parser('bench', help='benchmarks: what accuracy costs in CPU time')
    bench_sub = bench.add_subparsers(dest='bench_verb', required=True, metavar='BENCH_VERB')
    acc = bench_sub.add_parser(
        'accuracy',
        help='error against CPU time per simulated second for every accuracy knob: CSV, markdown, Pareto plot',
    )
    add_out(acc, 'out/accuracy')
    acc.add_argument('--quick', action='store_true', help='fewer knob settings, shorter spans (under a minute)')
    acc.add_argument(
        '--only',
        action='append',
        metavar='STUDY',
        default=[],
        choices=STUDIES,
        help=f'run only this study (repeatable): {", ".join(STUDIES)}',
    )
    acc.set_defaults(func=run, output_option='--out')
    return bench


def run(args: argparse.Namespace) -> int:
    """Run the accuracy benchmark into ``--out`` (claimed before any work); print each file written."""
    files = ('accuracy.csv', 'accuracy.md', 'accuracy.png', 'accuracy.json')
    with claim_output_dir(args.out, '--out', files) as out:  # before any work: the results need a place
        result = run_benchmark(quick=args.quick, only=args.only, stream=sys.stdout)
        command = (
            'folder-line bench accuracy'
            + (' --quick' if args.quick else '')
            + ''.join(f' --only {s}' for s in args.only)
        )
        for path in write_outputs(result, out, command):
            print(f'wrote {path}')
    return 0
