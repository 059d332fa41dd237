"""``folder-line analyze``: the replay analysis of a recorded run, report.md and plots (no ROS needed)."""

from __future__ import annotations

import argparse
import sys

from folder_line.analysis.report import analyze, print_analysis
from folder_line.cli import animate as animate_cli
from folder_line.cli.arg_types import limited
from folder_line.cli.verb_options import BAG_TIME, Subparsers

__all__ = ['add_parser', 'run']


def add_parser(subparsers: Subparsers) -> argparse.ArgumentParser:
    """Add the ``analyze`` verb to ``folder-line``'s sub-parsers."""
    ana: argparse.ArgumentParser = subparsers.add_parser(
        'analyze', help='replay analysis of a recorded run: report.md and plots (no ROS needed)'
    )
    ana.add_argument('path', metavar='RUN_DIR|BAG', help='a run directory (run.json, bag/) or a bag directory')
    ana.add_argument('--out', metavar='DIR', help='output directory (default RUN_DIR/analysis)')
    ana.add_argument('--csv', action='store_true', help='also write one CSV per topic to DIR/csv/')
    ana.add_argument(
        '--from', dest='t_from', type=limited('--from', BAG_TIME), metavar='S', help='analyse line time from S s on'
    )
    ana.add_argument(
        '--to', dest='t_to', type=limited('--to', BAG_TIME), metavar='S', help='analyse line time up to S s'
    )
    ana.add_argument(
        '--animate',
        metavar='FILE.mp4|FILE.gif',
        help='also write a video of the recorded run over the window --from .. --to (its recorded states and '
        'violations written on it; see folder-line animate --help for the time scale)',
    )
    animate_cli.add_animation_options(ana, defaults=False)
    ana.set_defaults(func=run, output_option='--out')
    return ana


def run(args: argparse.Namespace) -> int:
    """Analyse the recording into ``--out``; print the analysis; with ``--animate`` write its video."""
    animate_cli.check_animation_options(args)  # before any work: the video's target and options
    result = analyze(
        args.path,
        args.out,
        csv=args.csv,
        t_from=args.t_from,
        t_to=args.t_to,
        before_writing=lambda rec: animate_cli.check_recording_window(args, rec),
    )
    print_analysis(result, sys.stdout)
    if args.animate is not None:
        animate_cli.animate_recording(args, result.recording)
    return 0
