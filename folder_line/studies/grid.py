"""The points of a sweep: ``--vary KEY=START:STOP:N`` parsed, and the grid they span; and
``LO:HI`` ranges (:func:`parse_bounds`, for ``solve --between`` and ``optimize --vary``).

Each ``--vary`` gives one scene key and ``N`` linearly spaced values from ``START`` to
``STOP`` (both included; ``N = 1`` is the single value ``START``, and then ``STOP`` must
equal it). Several keys span their product, the first key varying slowest, so that the
points are in the same order whatever runs them.
"""

from __future__ import annotations

import itertools
import math
import re
from dataclasses import dataclass

import numpy as np

from folder_line.errors import ParameterError

__all__ = ['MAX_POINTS', 'MAX_VALUES', 'Vary', 'grid_points', 'parse_bounds', 'parse_vary']

#: most values of one ``--vary``
MAX_VALUES = 10_000
#: most points of a sweep (the product of every ``--vary``)
MAX_POINTS = 1_000_000
#: a number written as a whole number (no point, no exponent): a key varied over such numbers gets ints
_WHOLE = re.compile(r'^[+-]?\d+$')


@dataclass(frozen=True)
class Vary:
    """One varied key and its values.

    Attributes
    ----------
    key : str
        The scene key, as ``--set`` takes it (``feed_transporter.V_tr``).
    start, stop : float
        First and last value, in the key's unit.
    n : int
        Number of values (>= 1).
    whole : bool
        START and STOP were written as whole numbers and every value is one: the values are ints
        (a seed, a bin count).
    """

    key: str
    start: float
    stop: float
    n: int
    whole: bool = False

    @property
    def values(self) -> tuple[float | int, ...]:
        """The ``n`` values, linearly spaced from ``start`` to ``stop`` (both included), in the key's unit."""
        raw = np.array([self.start]) if self.n == 1 else np.linspace(self.start, self.stop, self.n)
        if self.whole:
            return tuple(round(v) for v in raw)
        return tuple(float(v) for v in raw)


def parse_vary(text: str, option: str = '--vary') -> Vary:
    """``'feed_transporter.V_tr=8:11:7'`` -> :class:`Vary`.

    Parameters
    ----------
    text : str
        ``KEY=START:STOP:N``: a scene key, two finite numbers in the key's unit and a whole number
        ``N`` in [1, :data:`MAX_VALUES`] (``N = 1``: START and STOP equal).
    option : str
        The option that gave it, for the message.

    Returns
    -------
    Vary

    Raises
    ------
    ParameterError
        One line naming ``option`` and ``text`` and what is wrong.
    """
    key, sep, spec = text.partition('=')
    key = key.strip()
    parts = spec.split(':')
    if not sep or not key or len(parts) != 3:
        raise ParameterError(option, text, 'must be KEY=START:STOP:N, e.g. feed_transporter.V_tr=8:11:7')
    start_text, stop_text, n_text = (p.strip() for p in parts)
    try:
        start, stop = float(start_text), float(stop_text)
    except ValueError:
        raise ParameterError(option, text, 'START and STOP must be numbers (in the unit of the key)') from None
    if not (math.isfinite(start) and math.isfinite(stop)):
        raise ParameterError(option, text, 'START and STOP must be finite numbers')
    if not _WHOLE.match(n_text) or not 1 <= int(n_text) <= MAX_VALUES:
        raise ParameterError(option, text, f'N must be a whole number in [1, {MAX_VALUES}]')
    n = int(n_text)
    if n == 1 and start != stop:
        raise ParameterError(option, text, 'N=1 is one value: give it as START:START:1')
    if n > 1 and start == stop:
        raise ParameterError(option, text, f'START equals STOP: {n} equal values (give START:START:1 for one)')
    whole = bool(_WHOLE.match(start_text) and _WHOLE.match(stop_text))
    if whole and n > 1:
        step = (stop - start) / (n - 1)
        whole = step == round(step)
    return Vary(key, start, stop, n, whole)


def parse_bounds(
    text: str,
    option: str = '--between',
    *,
    item: str | None = None,
    form: str = 'LO:HI, two finite numbers in the unit of the key',
) -> tuple[float, float]:
    """``'5:15'`` -> ``(5.0, 15.0)``: two finite numbers, the first below the second.

    Parameters
    ----------
    text : str
        ``LO:HI``.
    option : str
        The option that gave it, for the message.
    item : str, optional
        What the message shows as the option's value (default ``text``), e.g. the whole
        ``layup.l4=0.55:0.7`` that ``text`` came from.
    form : str
        What ``text`` must be, for the message when it is not two numbers split by ``:``.

    Raises
    ------
    ParameterError
        One line naming ``option`` and ``item``: not ``LO:HI``, a bound not a number or not
        finite, or ``LO >= HI``.
    """
    shown = text if item is None else item
    parts = text.split(':')
    if len(parts) != 2:
        raise ParameterError(option, shown, f'must be {form}')
    bounds = []
    for part in parts:
        try:
            bounds.append(float(part))
        except ValueError:
            raise ParameterError(option, shown, f'{part.strip()!r} is not a number (must be {form})') from None
    lo, hi = bounds
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise ParameterError(option, shown, 'LO and HI must be finite numbers')
    if not lo < hi:
        raise ParameterError(option, shown, f'LO must be below HI (need LO < HI, got {lo:g}:{hi:g})')
    return lo, hi


def grid_points(varies: tuple[Vary, ...] | list[Vary]) -> list[dict[str, float | int]]:
    """Every point of the product of ``varies``, the first key slowest: ``[{key: value, ...}, ...]``.

    Raises
    ------
    ParameterError
        A key varied twice (naming ``--vary``), or more than :data:`MAX_POINTS` points.
    """
    keys = [v.key for v in varies]
    for key in keys:
        if keys.count(key) > 1:
            raise ParameterError('--vary', key, 'is varied twice; give each key once')
    total = math.prod(v.n for v in varies)
    if total > MAX_POINTS:
        raise ParameterError('--vary', ' x '.join(str(v.n) for v in varies), f'{total} points; at most {MAX_POINTS}')
    return [dict(zip(keys, combo, strict=True)) for combo in itertools.product(*(v.values for v in varies))]
