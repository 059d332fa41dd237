"""``folder-line run``: the line as ROS 2 nodes over DDS for a while, then its report."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from folder_line.cli.exits import EXIT_RUN_FAILED
from folder_line.cli.study_options import NAMES, add_scene_arguments
from folder_line.cli.verb_options import (
    Subparsers,
    add_bag_split,
    add_limited,
    add_marker_rate,
    add_out,
    rtf_ceiling,
)
from folder_line.config.run_config import BAG_DIR, SCENE_FILE, RunConfig
from folder_line.core.limits import LOST_TIMEOUT
from folder_line.errors import ParameterError
from folder_line.files.atomic import claim_output_dir

__all__ = ['add_parser', 'run']


def add_parser(subparsers: Subparsers) -> argparse.ArgumentParser:
    """Add the ``run`` verb to ``folder-line``'s sub-parsers."""
    parser: argparse.ArgumentParser = subparsers.add_parser(
        'run', help='run the line as ROS 2 nodes over DDS for a while, then report'
    )
    add_scene_arguments(parser, 20.0)
    parser.add_argument(
        '--rtf',
        type=rtf_ceiling,
        default=1.0,
        metavar='X|max',
        help='real-time factor ceiling (default 1); max: as fast as the slowest node allows',
    )
    parser.add_argument(
        '--clock',
        choices=('lockstep', 'wall'),
        default='lockstep',
        help='lockstep: sim time waits for every node, the answer never depends on load (default); '
        'wall: paced by the wall clock for hardware in the loop, late ticks counted',
    )
    add_limited(
        parser,
        '--lost-timeout',
        LOST_TIMEOUT,
        3.0,
        'S',
        'wall time a tick waits for a node before the node is declared lost',
    )
    add_out(parser, 'out')
    where = parser.add_mutually_exclusive_group()
    where.add_argument('--processes', action='store_true', help='one process per node, as a launch file would')
    where.add_argument(
        '--external-nodes',
        action='store_true',
        help='the machine nodes run elsewhere (each on its own host): start only line_clock and the recorder '
        'here, print the command for each node, and wait for them',
    )
    add_marker_rate(parser, '')
    add_bag_split(parser, '')
    parser.set_defaults(func=run, output_option='--out')
    return parser


def _config(args: argparse.Namespace) -> RunConfig:
    """The run the options ask for (ParameterError for ``--rtf max`` on the wall clock)."""
    if args.clock == 'wall' and args.rtf == 0.0:
        raise ParameterError('--rtf', 'max', 'needs --clock lockstep (the wall clock paces a wall run)')
    return RunConfig(
        scene=args.scene,
        duration=args.duration,
        overrides=tuple(args.overrides),
        rtf=args.rtf,
        out=Path(args.out),
        processes=args.processes,
        external=args.external_nodes,
        clock=args.clock,
        lost_timeout=args.lost_timeout,
        marker_rate=args.marker_rate,
        max_bag_duration=args.max_bag_duration or 0.0,
        max_bag_size=int(args.max_bag_size or 0),
    )


def run(args: argparse.Namespace) -> int:
    """Run the line into ``--out``, print its summary; exit 1 if the run failed."""
    cfg = _config(args)
    from folder_line.ros import run as ros_run  # loads rclpy: only the run and monitor verbs need DDS
    from folder_line.ros import run_summary

    with claim_output_dir(cfg.out, '--out', files=('run.json', SCENE_FILE), dirs=(BAG_DIR, 'logs')):
        result = ros_run.run_line(cfg, sys.stdout, NAMES)
    run_summary.print_run_summary(result.summary, cfg.out, sys.stdout)
    verdict = result.summary.outcome
    if not verdict.ok:
        print(f'folder-line: run failed: {verdict.message}', file=sys.stderr)
        return EXIT_RUN_FAILED
    return 0
