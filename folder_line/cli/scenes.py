"""``folder-line scenes``: the shipped scenes with their machines, effects and descriptions."""

from __future__ import annotations

import argparse
import sys

from folder_line.cli import keys
from folder_line.cli.verb_options import Subparsers

__all__ = ['add_parser', 'run']


def add_parser(subparsers: Subparsers) -> argparse.ArgumentParser:
    """Add the ``scenes`` verb to ``folder-line``'s sub-parsers."""
    parser: argparse.ArgumentParser = subparsers.add_parser(
        'scenes', help='list the shipped scenes with their machines, effects and descriptions'
    )
    parser.set_defaults(func=run, output_option='stdout')
    return parser


def run(args: argparse.Namespace) -> int:
    """List the shipped scenes."""
    keys.print_scenes(sys.stdout)
    return 0
