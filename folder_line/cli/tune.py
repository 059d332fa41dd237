"""``folder-line tune``: change a setting of the running line at its next machine cycle boundary."""

from __future__ import annotations

import argparse
import os

from folder_line.cli.arg_types import tuning_change
from folder_line.cli.exits import EXIT_NO_ANSWER, EXIT_REFUSED, print_error
from folder_line.cli.operator import OPERATOR_TIMEOUT, key_hint
from folder_line.cli.verb_options import Subparsers, add_limited
from folder_line.core.line.tuning import TUNABLES
from folder_line.interfaces import TUNABLE_PARAMETERS

__all__ = ['add_parser', 'run']


def add_parser(subparsers: Subparsers) -> argparse.ArgumentParser:
    """Add the ``tune`` verb to ``folder-line``'s sub-parsers."""
    tune: argparse.ArgumentParser = subparsers.add_parser(
        'tune',
        help='operator tuning: change a setting of the running line at its next machine cycle boundary',
        description=(
            'Set the node parameter that tunes KEY on the current ROS domain, as `ros2 param set` would '
            f'({", ".join(f"/{n} {p}" for n, ps in TUNABLE_PARAMETERS.items() for p in ps)}); the supervisor '
            'times the change at the next machine cycle boundary and records it. Exit 0: accepted; 1: refused '
            '(the reason is printed); 3: the node did not answer. `simulate --tune T:KEY=VALUE` runs the same '
            'change in the batch model.'
        ),
    )
    tune.add_argument('change', type=tuning_change, metavar='KEY=VALUE', help=f'KEY one of {", ".join(TUNABLES)}')
    add_limited(tune, '--timeout', OPERATOR_TIMEOUT, 5.0, 'S', 'longest wait for the node, then its answer, s')
    tune.set_defaults(func=run, output_option='stdout')
    return tune


def run(args: argparse.Namespace) -> int:
    """Set the parameter; print the answer. Exit 0: accepted, 1: refused, 3: the node did not answer."""
    from folder_line.ros.operator import call_tune, tunable_parameter  # loads rclpy: only the verbs that use DDS

    key, value = args.change
    answer = call_tune(key, value, timeout=args.timeout)
    if answer is None:
        domain = os.environ.get('ROS_DOMAIN_ID', '0') or '0'
        node, _ = tunable_parameter(key)
        print_error(
            f'tune: node /{node} did not answer on ROS domain {domain} within {args.timeout:g} s '
            f'(is the line running, on this domain, {key_hint()}?)'
        )
        return EXIT_NO_ANSWER
    print(f'tune: {"accepted" if answer.accepted else "refused"}: {answer.message}')
    return 0 if answer.accepted else EXIT_REFUSED
