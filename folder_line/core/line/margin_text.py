"""Constraint margins as people read them: one unit per kind, what a margin means, cycle or leaf.

The summaries, the JSON and the CSV keep every margin in SI (``s``, ``m``, ``m/s``, ``sheets``,
``1``: :mod:`folder_line.core.line.constraints`); the human text — ``simulate``'s table, the
Monte Carlo table, ``analyze``'s lines and ``report.md``, the figures — shows them through
this module only:

* times in ms, lengths in mm, speeds in m/s, ratios plain (:func:`shown_unit`,
  :func:`format_margin`);
* ``one_per_cycle`` as what it counts (``1 sheet per cycle``, ``1 sheet off``), and a margin at
  the best value its constraint allows marked as such (:func:`best_possible`, :func:`margin_text`);
* a short phrase per constraint saying what its margin is (:data:`MARGIN_MEANINGS`,
  :func:`margin_legend`);
* the index a margin belongs to as ``cycle k`` or, for the per-leaf ``chute_speed``,
  ``leaf k`` (:func:`margin_at`).
"""

from __future__ import annotations

from collections.abc import Iterable

from folder_line.core.line.constraints import LAYUP_CONSTRAINTS, RELEASE_KV_TOL

__all__ = [
    'CONSTRAINT_UNITS',
    'MARGIN_AXIS_NOTES',
    'MARGIN_LABELS',
    'MARGIN_MEANINGS',
    'PER_LEAF',
    'best_possible',
    'format_margin',
    'margin_at',
    'margin_constraint',
    'margin_legend',
    'margin_text',
    'shown_unit',
]

#: SI unit of a margin -> (factor, unit shown): times in ms, lengths in mm, the rest as they are
_SHOWN: dict[str, tuple[float, str]] = {
    's': (1e3, 'ms'),
    'm': (1e3, 'mm'),
    'm/s': (1.0, 'm/s'),
    'sheets': (1.0, 'sheets'),
    '1': (1.0, ''),
    '': (1.0, ''),
}

#: SI unit of each constraint's margin (as :mod:`folder_line.core.line.constraints` reports it)
CONSTRAINT_UNITS: dict[str, str] = {
    'feed_window': 's',
    'settled_before_knife': 's',
    'one_per_cycle': 'sheets',
    'rebound': 'm',
    'release_at_min_speed': '1',
    'chute_speed': 'm/s',
}

#: constraints judged once per leaf (their ``cycle`` column holds the leaf id), the others once per cycle
PER_LEAF: frozenset[str] = frozenset(LAYUP_CONSTRAINTS)

#: short names of the margins, for the figures' labels
MARGIN_LABELS: dict[str, str] = {
    'feed_window': 'feed',
    'settled_before_knife': 'settled',
    'one_per_cycle': 'sheets',
    'rebound': 'rebound',
    'release_at_min_speed': 'K_v at release',
    'chute_speed': 'exit speed',
}

#: what each constraint's margin is, and what its best possible value is (>= 0 always passes)
MARGIN_MEANINGS: dict[str, str] = {
    'feed_window': 'time to spare before the feed deadline (t_allowed after the knife left the table); more is better',
    'settled_before_knife': 'time the signature rests at the front stops before the knife contact; more is better',
    'one_per_cycle': (
        'sheets at the stops at the knife contact: 1 per cycle is the best possible; "k off" = missing or double'
    ),
    'rebound': (
        'fold tolerance minus the largest rebound off the stops; the whole tolerance (no rebound) is the best possible'
    ),
    'release_at_min_speed': (
        f'tolerance minus how far K_v (carriage speed ratio) at the release is above its minimum; '
        f'{RELEASE_KV_TOL:+g} (released at the slowest point) is the best possible'
    ),
    'chute_speed': "distance of a leaf's exit speed to the nearer end of the allowed [v_min, v_damage); per leaf",
}

#: a short note for a margin's axis, where its numbers alone mislead (a count, a tolerance)
MARGIN_AXIS_NOTES: dict[str, str] = {
    'one_per_cycle': '0: 1 sheet per cycle, the best possible',
    'release_at_min_speed': f'{RELEASE_KV_TOL:+g}: released at the slowest point (best)',
}

#: the best value a margin can take, where the constraint has one
_BEST: dict[str, float] = {'one_per_cycle': 0.0, 'release_at_min_speed': RELEASE_KV_TOL}


def shown_unit(unit: str) -> tuple[float, str]:
    """``(factor, unit shown)`` of a margin in the SI ``unit``: ``s`` -> (1e3, 'ms'), ``m`` -> (1e3, 'mm'),
    ``1`` -> (1, ''); any other unit is shown as it is."""
    return _SHOWN.get(unit, (1.0, unit))


def _number(value: float, precision: int, fixed: bool) -> str:
    if not fixed or (value != 0.0 and abs(value) < 0.5 * 10.0**-precision):  # too small for the decimals
        return f'{value:+.{precision}g}'
    return f'{value:+.{precision}f}'


def _sheets_text(value: float, precision: int, short: bool) -> str:
    if value == 0.0:
        return '1 sheet' if short else '1 sheet per cycle'
    off = f'{-value:.{precision}g}'
    return f'{off} sheet off' if off == '1' else f'{off} sheets off'


def format_margin(
    value: float, unit: str, constraint: str = '', *, precision: int = 4, fixed: bool = True, short: bool = False
) -> str:
    """A margin as the text shows it: the value in its display unit (:func:`shown_unit`).

    Parameters
    ----------
    value : float
        The margin in the SI ``unit`` (s, m, m/s, sheets or 1).
    unit : str
        Its SI unit, as the summaries give it.
    constraint : str, optional
        The constraint's name: ``one_per_cycle`` is shown as the sheets it counts
        (``1 sheet per cycle``, ``1 sheet off``); others by value and unit.
    precision : int, optional
        Decimals of ms, mm and m/s (fixed point, so a column lines up); significant digits
        of a ratio, a count, or a value too small for the fixed decimals.
    fixed : bool, optional
        False: significant digits for every unit (``+0.1 ms``; for a figure's label, not a column).
    short : bool, optional
        ``one_per_cycle`` at 0 as ``1 sheet`` (where the context says "of the cycle").

    Returns
    -------
    str
        E.g. ``+0.1000 ms``, ``+0.9189 mm``, ``+0.4246 m/s``, ``+1e-06``, ``1 sheet per cycle``.
    """
    value = float(value)
    if constraint == 'one_per_cycle' and value <= 0.0:
        return _sheets_text(value, precision, short)
    factor, shown = shown_unit(unit)
    text = _number(value * factor, precision, fixed and shown not in ('', 'sheets'))
    return f'{text} {shown}' if shown else text


def best_possible(constraint: str, value: float, *, precision: int = 4) -> bool:
    """Whether ``value`` shows as the best margin ``constraint`` allows (``one_per_cycle`` 0,
    ``release_at_min_speed`` the K_v tolerance); False for a constraint with no fixed best."""
    best = _BEST.get(constraint)
    if best is None:
        return False
    return f'{float(value):+.{precision}g}' == f'{best:+.{precision}g}'


def margin_text(value: float, unit: str, constraint: str = '', *, precision: int = 4) -> str:
    """:func:`format_margin`, with `` (best possible)`` where :func:`best_possible`."""
    text = format_margin(value, unit, constraint, precision=precision)
    return text + ' (best possible)' if best_possible(constraint, value, precision=precision) else text


def margin_constraint(path: str) -> str:
    """The constraint of a metric path: ``min_margin.rebound.margin`` and ``min_margin_s.feed_window``
    -> ``rebound``, ``feed_window``; '' for a path that is not a margin."""
    parts = path.split('.')
    for i, part in enumerate(parts[:-1]):
        if part in ('min_margin', 'min_margin_s'):
            return parts[i + 1]
    return ''


def margin_at(constraint: str, index: int) -> str:
    """Where a margin was judged: ``leaf k`` for a per-leaf constraint (``chute_speed``), else ``cycle k``."""
    return f'{"leaf" if constraint in PER_LEAF else "cycle"} {int(index)}'


def margin_legend(constraints: Iterable[str], indent: str = '  ') -> list[str]:
    """One line per constraint (known ones, in the order given): its name and what its margin means."""
    names = [c for c in constraints if c in MARGIN_MEANINGS]
    width = max((len(c) for c in names), default=0)
    return [f'{indent}{c:<{width}}  {MARGIN_MEANINGS[c]}' for c in names]
