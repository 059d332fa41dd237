"""Options several verbs share: a number in a range, ``--out``, ``--rtf``, and the marker rate and split of a bag;
and what a verb's ``add_parser`` is given (:class:`Subparsers`)."""

from __future__ import annotations

import argparse
from typing import Protocol

from folder_line.cli.arg_types import limited, split_limit
from folder_line.config.run_config import MARKER_RATE, MARKER_RATES
from folder_line.core.limits import RTF, Limit

__all__ = [
    'BAG_DURATION',
    'BAG_SIZE',
    'BAG_TIME',
    'Subparsers',
    'add_bag_split',
    'add_limited',
    'add_marker_rate',
    'add_out',
    'rtf_ceiling',
]

#: what `bag play` and `analyze --from/--to` take from a bag: line time (a week at most)
BAG_TIME = Limit('line time in a bag', 0.0, 604800.0, 's', 'a week of line time')
#: bounds of --max-bag-duration (s) and --max-bag-size (bytes) when not 0
BAG_DURATION = (1e-3, 1e7)
BAG_SIZE = (1024, 10**15)
#: ``--rtf``: a ceiling in the RTF range, or ``max`` (0.0: as fast as the line allows)
rtf_ceiling = limited('--rtf', RTF, also='max')


class Subparsers(Protocol):
    """What a verb's ``add_parser`` uses of ``ArgumentParser.add_subparsers()``: adding a verb's parser."""

    def add_parser(
        self, name: str, *, help: str | None = ..., description: str | None = ..., epilog: str | None = ...
    ) -> argparse.ArgumentParser: ...


def add_limited(
    parser: argparse.ArgumentParser, option: str, limit: Limit, default: float, metavar: str, help: str
) -> None:
    """``option``: a number in ``limit`` (:func:`folder_line.cli.arg_types.limited`); ``help`` gets
    `` (default ...)`` appended."""
    parser.add_argument(
        option, type=limited(option, limit), default=default, metavar=metavar, help=f'{help} (default {default:g})'
    )


def add_out(parser: argparse.ArgumentParser, default: str) -> None:
    """``--out DIR``, the verb's output folder."""
    parser.add_argument('--out', default=default, metavar='DIR', help=f'output directory (default ./{default})')


def add_marker_rate(parser: argparse.ArgumentParser, when: str, *, given_only: bool = False) -> None:
    """``--marker-rate HZ``: ``/line/markers`` per second of line time (the machine for RViz/Foxglove);
    ``given_only``: None unless given (the verb refuses it where it does nothing), :data:`MARKER_RATE` meant."""
    if not given_only:
        add_limited(
            parser,
            '--marker-rate',
            MARKER_RATES,
            MARKER_RATE,
            'HZ',
            f'{when}/line/markers per second of line time, 0: none',
        )
        return
    parser.add_argument(
        '--marker-rate',
        type=limited('--marker-rate', MARKER_RATES),
        default=None,
        metavar='HZ',
        help=f'{when}/line/markers per second of line time, 0: none (default {MARKER_RATE:g})',
    )


def add_bag_split(parser: argparse.ArgumentParser, when: str) -> None:
    """``--max-bag-duration S`` and ``--max-bag-size BYTES``: split the bag, as ``ros2 bag record`` does; None
    unless given (a verb refuses them where they do nothing), 0 (one file) meant."""
    parser.add_argument(
        '--max-bag-duration',
        type=split_limit('--max-bag-duration', *BAG_DURATION, 's'),
        default=None,
        metavar='S',
        help=f'{when}start a new .mcap file every S s of line time (default 0: one file, as ros2 bag record)',
    )
    parser.add_argument(
        '--max-bag-size',
        type=split_limit('--max-bag-size', *BAG_SIZE, 'bytes', whole=True),
        default=None,
        metavar='BYTES',
        help=f'{when}start a new .mcap file once one has BYTES bytes, at its next flush (every 0.1 s of '
        'line time); with --max-bag-duration, whichever comes first (default 0: no split by size)',
    )
