"""Argument types of the command line: numbers in a range, refused in one line naming the option.

Each returns an ``argparse`` type function; a refusal is an ``ArgumentTypeError`` whose text
is ``OPTION=VALUE: reason`` (the value cut to 80 characters), which the parser prints as one
line and exits 2 (:class:`folder_line.cli.main._Parser`).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable

from folder_line.core.limits import Limit
from folder_line.core.line.scene import Scene
from folder_line.core.line.tuning import SCENE_KEYS, TUNABLES, Tuning, check_tuning
from folder_line.errors import FolderLineError, ParameterError, bounded_repr

__all__ = ['add_tune_argument', 'check_tunings', 'limited', 'number', 'split_limit', 'tuning', 'tuning_change']


def limited(option: str, limit: Limit, *, also: str = '') -> Callable[[str], float]:
    """A value in the physical range ``limit`` (:mod:`folder_line.core.limits`: the same bounds as the scene
    loader's and the node parameters'); ``also``: one word that is also accepted, returned as 0.0 (``max``),
    as is 0 itself (the node parameters' spelling of it)."""
    extra = f', or 0 or {also}' if also else ''

    def parse(text: str) -> float:
        if also and text.strip().lower() == also:
            return 0.0
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f'{option}={bounded_repr(text)}: must be a number in {limit.text()}{extra}'
            ) from None
        if also and value == 0.0:
            return 0.0
        if not limit.lo <= value <= limit.hi:  # NaN fails too
            raise argparse.ArgumentTypeError(f'{option}={bounded_repr(text)}: must be in {limit.text()}{extra}')
        return value

    return parse


def number(
    option: str, lo: float | None = None, hi: float | None = None, *, whole: bool = False, open_lo: bool = False
) -> Callable[[str], float]:
    """A number (``whole``: an int) in ``[lo, hi]`` (``(lo, hi]`` with ``open_lo``); without bounds any number,
    for the value's user to judge (e.g. :class:`folder_line.studies.runner.Cluster`)."""
    left = '(' if open_lo else '['
    kind = 'a whole number' if whole else 'a number'
    bounds = '' if lo is None or hi is None else f' in {left}{lo:g}, {hi:g}]'

    def parse(text: str) -> float:
        try:
            value: float = int(text) if whole else float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f'{option}={bounded_repr(text)}: must be {kind}{bounds}') from None
        if lo is not None and hi is not None:
            inside = (lo < value) if open_lo else (lo <= value)
            if not inside or not value <= hi:  # NaN fails too
                raise argparse.ArgumentTypeError(f'{option}={bounded_repr(text)}: must be in {left}{lo:g}, {hi:g}]')
        return value

    return parse


def split_limit(option: str, lo: float, hi: float, unit: str, *, whole: bool = False) -> Callable[[str], float]:
    """0 (no split) or a number in ``[lo, hi]`` ``unit`` (``whole``: an int): ``--max-bag-duration`` and
    ``--max-bag-size``, which mean what rosbag2's options of those names mean."""
    kind = 'a whole number' if whole else 'a number'

    def parse(text: str) -> float:
        try:
            value: float = int(text) if whole else float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f'{option}={bounded_repr(text)}: must be {kind}: 0 (no split) or in [{lo:g}, {hi:g}] {unit}'
            ) from None
        if value != 0 and not lo <= value <= hi:  # NaN fails too
            raise argparse.ArgumentTypeError(
                f'{option}={bounded_repr(text)}: must be 0 (no split) or in [{lo:g}, {hi:g}] {unit}'
            )
        return value

    return parse


def tuning_change(text: str, shown: str = '') -> tuple[str, float]:
    """``KEY=VALUE`` of ``folder-line tune``: a tunable key and a value in its range (``shown``: how the
    refusal names the argument, default ``KEY=VALUE`` itself)."""
    key, eq, value = text.partition('=')
    shown = shown or bounded_repr(text)
    if not eq:
        raise argparse.ArgumentTypeError(f'{shown}: must read KEY=VALUE, e.g. feed_transporter.V_tr=9.0')
    if key not in TUNABLES:
        raise argparse.ArgumentTypeError(f'{shown}: {key!r} is not tunable; tunable: {", ".join(TUNABLES)}')
    try:
        number = float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f'{shown}: {key}={bounded_repr(value)} must be a number') from None
    try:
        return key, TUNABLES[key].limit.check(key, number)
    except FolderLineError as err:
        raise argparse.ArgumentTypeError(f'{shown}: {err}') from None


def tuning(text: str) -> Tuning:
    """``--tune T:KEY=VALUE``: a :class:`~folder_line.core.line.tuning.Tuning` of ``KEY`` to ``VALUE`` effective
    at ``T`` s (> 0); whether the scene can take it is checked once the scene is known."""
    when, colon, change = text.partition(':')
    shown = f'--tune={bounded_repr(text)}'
    if not colon:
        raise argparse.ArgumentTypeError(f'{shown}: must read T:KEY=VALUE, e.g. 5.0:feed_transporter.V_tr=9.0')
    try:
        t = float(when)
    except ValueError:
        raise argparse.ArgumentTypeError(f'{shown}: T must be a number of seconds, the effective time') from None
    key, value = tuning_change(change, shown)
    if not 0.0 < t < float('inf'):
        start = f'a start value is set with --set {key}=...' if key in SCENE_KEYS else 'it starts at the model value'
        raise argparse.ArgumentTypeError(f'{shown}: T must be > 0 s ({start})')
    return Tuning(t, key, value)


def add_tune_argument(parser: argparse.ArgumentParser) -> None:
    """The repeatable ``--tune T:KEY=VALUE`` of the batch verbs (``simulate``, ``animate``)."""
    parser.add_argument(
        '--tune',
        action='append',
        default=[],
        type=tuning,
        metavar='T:KEY=VALUE',
        help='an operator change effective at T s, as on the running line (repeatable; '
        f'KEY one of {", ".join(TUNABLES)}), e.g. 5.0:feed_transporter.V_tr=9.0',
    )


def check_tunings(scene: Scene, given: list[Tuning], duration: float) -> tuple[Tuning, ...]:
    """``--tune``s sorted by time, each one the scene can take and inside the run (ParameterError naming it)."""
    for tu in given:
        check_tuning(scene, tu.key, tu.value)
        if tu.t >= duration:
            raise ParameterError(
                '--tune', f'{tu.t!r}:{tu.key}={tu.value!r}', f'T must be before --duration {duration:g} s'
            )
    return tuple(sorted(given, key=lambda tu: tu.t))
