"""``folder-line start``, ``stop``, ... ``abort``: the operator commands, each a call of the supervisor's service."""

from __future__ import annotations

import argparse
import os

from folder_line.cli.exits import EXIT_NO_ANSWER, EXIT_REFUSED, print_error
from folder_line.cli.verb_options import Subparsers, add_limited
from folder_line.core.limits import Limit
from folder_line.interfaces import OPERATOR_COMMANDS

__all__ = ['OPERATOR_TIMEOUT', 'add_parsers', 'key_hint', 'run']

OPERATOR_TIMEOUT = Limit('operator wait for the supervisor', 0.1, 3600.0, 's', 'wall time')


def add_parsers(subparsers: Subparsers) -> None:
    """Add one verb per operator command (:data:`folder_line.interfaces.OPERATOR_COMMANDS`) to the sub-parsers."""
    for command in OPERATOR_COMMANDS:
        op: argparse.ArgumentParser = subparsers.add_parser(
            command,
            help=f'operator command: {command} the running line (its supervisor, on this ROS domain)',
            description=(
                f"Call the supervisor's {command} service (std_srvs/Trigger) on the current ROS domain and print "
                'its answer. Exit 0: accepted; 1: refused (the reason is printed); 3: no supervisor answered.'
            ),
        )
        add_limited(op, '--timeout', OPERATOR_TIMEOUT, 5.0, 'S', 'longest wait for the service, then its answer, s')
        op.set_defaults(func=run, output_option='stdout')


def key_hint() -> str:
    """Which line key this process has: a closed line answers only a caller with its own."""
    from folder_line.ros.line_key import KEY_VARIABLE

    if os.environ.get(KEY_VARIABLE, '').strip():
        return f'with this {KEY_VARIABLE}'
    return f'and open? A line started by folder-line run is closed: give its {KEY_VARIABLE}'


def run(args: argparse.Namespace) -> int:
    """Call the command ``args.verb``; print the answer. Exit 0: accepted, 1: refused, 3: no answer."""
    from folder_line.ros.operator import call_command  # loads rclpy: only the verbs that use DDS need it

    answer = call_command(args.verb, timeout=args.timeout)
    if answer is None:
        domain = os.environ.get('ROS_DOMAIN_ID', '0') or '0'
        print_error(
            f'{args.verb}: no supervisor answered /line/supervisor/{args.verb} on ROS domain {domain} within '
            f'{args.timeout:g} s (is the line running, on this domain, {key_hint()}? On a busy host an answer can '
            "also be lost, the command taken: the supervisor's state shows it, folder-line monitor)"
        )
        return EXIT_NO_ANSWER
    print(f'{args.verb}: {"accepted" if answer.accepted else "refused"}: {answer.message}')
    return 0 if answer.accepted else EXIT_REFUSED
