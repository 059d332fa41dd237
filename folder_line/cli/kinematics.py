"""``folder-line kinematics``: the table of one mechanism over a crank turn (or the delivery stroke)."""

from __future__ import annotations

import argparse
import sys

from folder_line.cli import tables
from folder_line.cli.verb_options import Subparsers
from folder_line.errors import bounded_repr
from folder_line.files.atomic import check_output_file, write_csv_atomic

__all__ = ['add_parser', 'run']


def _samples(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'--samples={bounded_repr(text)}: must be a whole number >= 2') from None
    if n < 2 or n > 100_000_000:
        raise argparse.ArgumentTypeError(f'--samples={bounded_repr(text)}: must be in [2, 100000000]')
    return n


def add_parser(subparsers: Subparsers) -> argparse.ArgumentParser:
    """Add the ``kinematics`` verb to ``folder-line``'s sub-parsers."""
    kin: argparse.ArgumentParser = subparsers.add_parser(
        'kinematics', help='table of one mechanism over a crank turn (or the delivery stroke)'
    )
    kin.add_argument('mechanism', choices=('layup', 'knife', 'delivery'))
    kin.add_argument('--params', metavar='FILE.yaml', help='any subset of the parameters; the rest are the defaults')
    kin.add_argument('--samples', type=_samples, default=360, metavar='N', help='number of samples (default 360)')
    kin.add_argument('--csv', metavar='PATH', help='write the table as CSV (SI units, angles in rad)')
    kin.set_defaults(func=run, output_option='--csv')
    return kin


def run(args: argparse.Namespace) -> int:
    """Print the table's summary; write the table to ``--csv`` if given."""
    if args.csv:
        check_output_file(args.csv, '--csv')
    table = tables.kinematics_table(args.mechanism, args.params, args.samples)
    tables.print_summary(args.mechanism, table, sys.stdout)
    if args.csv:
        dest = write_csv_atomic(args.csv, table)
        print(f'wrote {dest} ({args.samples} rows, {len(table)} columns)')
    return 0
