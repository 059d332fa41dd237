"""``folder-line layout``: the Foxglove layout of a scene's line (:mod:`folder_line.analysis.foxglove`)."""

from __future__ import annotations

import argparse
import sys

from folder_line.analysis.foxglove import layout_text
from folder_line.cli.study_options import add_scene_arguments, source_from
from folder_line.cli.verb_options import Subparsers
from folder_line.core.line.scene import parse_scene
from folder_line.files.atomic import check_output_file, write_text_atomic

__all__ = ['HELP', 'add_arguments', 'add_parser', 'run']

HELP = "write a Foxglove layout of the scene's line: the machine in 3D, joint states, margins, state, events"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The verb's options on its parser."""
    add_scene_arguments(parser, None)
    parser.add_argument(
        '--out', metavar='FILE', help='write the layout (JSON) to FILE, replaced whole (default: print it)'
    )


def add_parser(subparsers: Subparsers) -> argparse.ArgumentParser:
    """Add the ``layout`` verb to ``folder-line``'s sub-parsers."""
    parser: argparse.ArgumentParser = subparsers.add_parser('layout', help=HELP)
    add_arguments(parser)
    parser.set_defaults(func=run, output_option='--out')
    return parser


def run(args: argparse.Namespace) -> int:
    """Print the layout, or write it to ``--out`` (its missing folders made, as every verb's output file)."""
    if args.out is not None:
        check_output_file(args.out, '--out')  # a FIFO, a folder or a dangling link is refused before any work
    text = layout_text(parse_scene(source_from(args)))
    if args.out is None:
        sys.stdout.write(text)
    else:
        print(f'wrote {write_text_atomic(args.out, text)}')
    return 0
