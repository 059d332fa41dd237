"""``folder-line bag info|play|repair``: the rosbag2 bags of a run."""

from __future__ import annotations

import argparse
import contextlib
import sys
from pathlib import Path

from folder_line.bag.metadata import METADATA_FILE
from folder_line.bag.reader import bag_info_lines, read_bag
from folder_line.bag.repair import repair, repairable
from folder_line.cli.arg_types import limited
from folder_line.cli.verb_options import BAG_TIME, Subparsers, rtf_ceiling
from folder_line.config.run_config import BAG_DIR, bag_of
from folder_line.core.limits import Limit
from folder_line.files.atomic import check_output_dir, claim_output_dir

__all__ = ['add_parser', 'info', 'play', 'repair_bag']

_BAG_SPAN = Limit('line time to play', 1e-9, 604800.0, 's', 'a week of line time')
_DIR_HELP = 'a run folder (e.g. out) or its bag folder (out/bag)'


def add_parser(subparsers: Subparsers) -> argparse.ArgumentParser:
    """Add the ``bag`` verb and its ``info``, ``play`` and ``repair`` to ``folder-line``'s sub-parsers."""
    bag: argparse.ArgumentParser = subparsers.add_parser('bag', help='rosbag2 bags of a run: info, play, repair')
    bag_sub = bag.add_subparsers(dest='bag_verb', required=True, metavar='BAG_VERB')
    bag_info = bag_sub.add_parser('info', help='topics, counts, line time and custom data of a bag')
    bag_info.add_argument('dir', metavar='DIR', help=_DIR_HELP)
    bag_info.set_defaults(func=info, output_option='DIR')
    bag_play = bag_sub.add_parser(
        'play', help='republish a bag on its topics with /clock, as the line published it (Ctrl-C stops)'
    )
    bag_play.add_argument('dir', metavar='DIR', help=_DIR_HELP)
    bag_play.add_argument(
        '--rtf',
        type=rtf_ceiling,
        default=1.0,
        metavar='X|max',
        help='line seconds per wall second (default 1); max: no pacing',
    )
    bag_play.add_argument(
        '--start', type=limited('--start', BAG_TIME), default=0.0, metavar='S', help="begin S s after the bag's start"
    )
    bag_play.add_argument(
        '--duration', type=limited('--duration', _BAG_SPAN), metavar='S', help='play S s of line time (default: all)'
    )
    bag_play.add_argument('--topics', nargs='+', default=[], metavar='T', help='only these topics (/clock always)')
    bag_play.add_argument('--loop', action='store_true', help='play the window again and again until Ctrl-C')
    bag_play.set_defaults(func=play, output_option='DIR')
    bag_repair = bag_sub.add_parser(
        'repair', help='rebuild metadata.yaml from the MCAP files present, salvaging an unfinished last file'
    )
    bag_repair.add_argument('dir', metavar='DIR', help=_DIR_HELP)
    bag_repair.set_defaults(func=repair_bag, output_option='DIR')
    return bag


def info(args: argparse.Namespace) -> int:
    """``bag info``: print the bag's topics, counts, line time and custom data."""
    args.dir = str(bag_of(args.dir))  # a run folder stands for its bag
    for line in bag_info_lines(read_bag(args.dir)):
        print(line)
    return 0


def play(args: argparse.Namespace) -> int:
    """``bag play``: republish the bag (Ctrl-C stops); print what was played."""
    args.dir = str(bag_of(args.dir))
    from folder_line.ros import player  # loads rclpy: only the verbs that use DDS need it

    played = player.play_bag(
        args.dir,
        rtf=args.rtf,
        start=args.start,
        duration=args.duration,
        topics=args.topics,
        loop=args.loop,
        stream=sys.stdout,
    )
    total = sum(played.published.values())
    how = 'stopped by Ctrl-C' if played.interrupted else 'done'
    print(
        f'{how}: {total} messages on {len(played.published)} topics, {played.passes} pass(es), '
        f'line time {played.line_time:.9g} s in {played.wall_time:.3f} s of wall time'
    )
    return 0


def repair_bag(args: argparse.Namespace) -> int:
    """``bag repair``: rebuild the bag's metadata.yaml, the bag and its run folder claimed meanwhile."""
    args.dir = str(bag_of(args.dir))
    bag = Path(args.dir)
    check_output_dir(bag, 'DIR', files=(METADATA_FILE,))  # before any claim touches a folder
    if bag.is_dir():
        repairable(bag)  # a folder that is no bag is refused before the claim's write probe goes into it
    with contextlib.ExitStack() as claims:  # the bag, and the run folder holding it: a run may be writing
        if bag.is_dir() and bag.resolve().name == BAG_DIR:
            claims.enter_context(claim_output_dir(bag.resolve().parent, 'DIR', create=False))
        claims.enter_context(claim_output_dir(bag, 'DIR', files=(METADATA_FILE,), create=False))
        result = repair(args.dir)
    print(f'repaired {args.dir}: {result.describe()}')
    print(f'wrote {result.metadata}')
    return 0
