"""``folder-line monitor``'s options; the view itself is :mod:`folder_line.cli.monitor`, loaded on use (rclpy)."""

from __future__ import annotations

import argparse

from folder_line.cli.verb_options import Subparsers, add_limited
from folder_line.core.limits import Limit

__all__ = ['add_parser', 'run']

# the monitor's own knobs (display, not line physics)
_MONITOR_RATE = Limit('monitor refresh rate', 0.1, 60.0, 'Hz', 'a screen refresh')
_MONITOR_WINDOW = Limit('monitor rate window', 0.01, 600.0, 's', 'sim time the rates are counted over')
_MONITOR_TIMEOUT = Limit('monitor wait for the line', 0.1, 3600.0, 's', 'wall time')


def add_parser(subparsers: Subparsers) -> argparse.ArgumentParser:
    """Add the ``monitor`` verb to ``folder-line``'s sub-parsers."""
    mon: argparse.ArgumentParser = subparsers.add_parser(
        'monitor', help='live terminal view of the running line (q or Ctrl-C quits)'
    )
    add_limited(mon, '--rate', _MONITOR_RATE, 4.0, 'HZ', 'screen refreshes per second')
    mon.add_argument(
        '--once',
        action='store_true',
        help='print one plain-text snapshot after collecting for the rate window, then exit',
    )
    add_limited(mon, '--window', _MONITOR_WINDOW, 2.0, 'S', 'window of the topic rates, s of wall time')
    add_limited(mon, '--timeout', _MONITOR_TIMEOUT, 10.0, 'S', 'with --once: longest wait for the first message, s')
    mon.set_defaults(func=run, output_option='stdout')
    return mon


def run(args: argparse.Namespace) -> int:
    """Run the monitor (:func:`folder_line.cli.monitor.run_monitor`)."""
    from folder_line.cli.monitor import run_monitor  # loads rclpy: only this verb needs DDS

    return run_monitor(rate=args.rate, once=args.once, window=args.window, timeout=args.timeout)
