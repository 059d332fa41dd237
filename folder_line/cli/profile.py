"""``folder-line profile``: the path of the line's Fast DDS profile, for ros2 tools that must reach a closed line."""

from __future__ import annotations

import argparse
import os

from folder_line.cli.verb_options import Subparsers
from folder_line.errors import FolderLineError

__all__ = ['add_parser', 'run']


def add_parser(subparsers: Subparsers) -> argparse.ArgumentParser:
    """Add the ``profile`` verb to ``folder-line``'s sub-parsers."""
    parser: argparse.ArgumentParser = subparsers.add_parser(
        'profile',
        help="print the path of the line's Fast DDS profile for FOLDER_LINE_KEY (writing it if needed), for ros2 "
        'tools that must reach a closed line: FASTDDS_DEFAULT_PROFILES_FILE=$(folder-line profile) ros2 param set ...',
    )
    parser.set_defaults(func=run, output_option='stdout')
    return parser


def run(args: argparse.Namespace) -> int:
    """Print the profile's path (FolderLineError without a line key, or with an RMW that cannot take it)."""
    from folder_line.ros.dds_profile import line_partition, use_line_profile
    from folder_line.ros.line_key import KEY_VARIABLE

    env = dict(os.environ)
    if not env.get(KEY_VARIABLE, '').strip():
        raise FolderLineError(f'{KEY_VARIABLE} is not set: give the key of the line (folder-line run prints it)')
    env.pop('FASTDDS_DEFAULT_PROFILES_FILE', None)  # the line's own, not the one this shell may name
    env.pop('FASTRTPS_DEFAULT_PROFILES_FILE', None)
    path = use_line_profile(env)
    if path is None or line_partition(env) is None:
        raise FolderLineError(
            f'RMW_IMPLEMENTATION={env.get("RMW_IMPLEMENTATION")}: the line key needs rmw_fastrtps_cpp'
        )
    print(path)
    return 0
