"""Pareto curves of the accuracy benchmark: cheapest setting for an error, ratio at equal error."""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from folder_line.accuracy.measure import Row

__all__ = ['Choice', 'EqualErrorRatio', 'cheapest', 'curves', 'equal_error_ratio', 'pareto_front']


def curves(rows: Iterable[Row]) -> dict[tuple[str, str], list[Row]]:
    """Rows grouped by ``(study, method)``, each curve sorted by CPU time (cheapest first)."""
    out: dict[tuple[str, str], list[Row]] = {}
    for r in rows:
        out.setdefault((r.study, r.method), []).append(r)
    for v in out.values():
        v.sort(key=lambda r: (r.cpu_s_per_sim_s, r.error))
    return out


def pareto_front(rows: Iterable[Row]) -> list[Row]:
    """The non-dominated rows (no other row is both cheaper and at least as accurate), cheapest first."""
    front: list[Row] = []
    for r in sorted(rows, key=lambda r: (r.cpu_s_per_sim_s, r.error)):
        if not front or r.error < front[-1].error:
            front.append(r)
    return front


@dataclass(frozen=True)
class Choice:
    """The cheapest row of a study whose error is at or below ``target`` (``row`` None: none reaches it)."""

    study: str
    target: float
    row: Row | None


def cheapest(rows: Iterable[Row], study: str, target: float, *, quantity: str | None = None) -> Choice:
    """The cheapest measured setting of ``study`` (optionally of one ``quantity``) with error <= ``target``."""
    ok = [r for r in rows if r.study == study and (quantity is None or r.quantity == quantity) and r.error <= target]
    return Choice(study, target, min(ok, key=lambda r: r.cpu_s_per_sim_s) if ok else None)


@dataclass(frozen=True)
class EqualErrorRatio:
    """CPU of method ``b`` over method ``a`` where both reach the same error.

    Attributes
    ----------
    error : float
        The error level compared at (the unit of the study's rows).
    cpu_a, cpu_b : float
        CPU s per simulated s of each method at that error: the cheapest measured point
        of ``a`` reaching it, and ``b`` interpolated log-log between its measured points.
    ratio : float
        ``cpu_b / cpu_a``.
    reached : bool
        False if ``b`` never got down to ``error``: then ``error`` is ``b``'s best error,
        ``cpu_b`` the cost of that point, and the ratio a lower bound.
    """

    method_a: str
    method_b: str
    error: float
    cpu_a: float
    cpu_b: float
    ratio: float
    reached: bool


def _loglog_cost(front: Sequence[Row], error: float) -> float:
    """CPU at ``error`` on a Pareto front (errors falling as cost rises), log-log interpolated."""
    for lo, hi in itertools.pairwise(front):
        if hi.error <= error <= lo.error:
            if hi.error == lo.error or hi.error <= 0.0:
                return hi.cpu_s_per_sim_s
            w = (math.log(lo.error) - math.log(error)) / (math.log(lo.error) - math.log(hi.error))
            return math.exp(
                math.log(lo.cpu_s_per_sim_s) + w * (math.log(hi.cpu_s_per_sim_s) - math.log(lo.cpu_s_per_sim_s))
            )
    return front[0].cpu_s_per_sim_s  # error above the cheapest point: that point already reaches it


def equal_error_ratio(
    rows: Iterable[Row], study: str, method_a: str, method_b: str, error: float | None = None
) -> EqualErrorRatio:
    """How much more CPU method ``b`` needs than method ``a`` for the same error.

    Parameters
    ----------
    rows : iterable of Row
    study : str
    method_a, method_b : str
        Methods of ``study``; ``a`` is the reference (usually folder_line's own).
    error : float, optional
        Error level to compare at; default: the error of ``a``'s most accurate point,
        floored at ``b``'s best error (see :attr:`EqualErrorRatio.reached`).

    Raises
    ------
    KeyError
        A method has no rows.
    ValueError
        ``a`` never reaches the given ``error``.
    """
    rows = list(rows)
    fa = pareto_front(r for r in rows if r.study == study and r.method == method_a)
    fb = pareto_front(r for r in rows if r.study == study and r.method == method_b)
    if not fa or not fb:
        raise KeyError(f'no rows of {study}/{method_a if not fa else method_b}')
    if error is not None and not fa[-1].error <= error:
        raise ValueError(f'{study}/{method_a} never reaches error {error!r} (best {fa[-1].error!r})')
    target = fa[-1].error if error is None else error
    reached = fb[-1].error <= target
    if not reached:
        target = fb[-1].error
    a_ok = [r for r in fa if r.error <= target]
    cpu_a = a_ok[0].cpu_s_per_sim_s if a_ok else _loglog_cost(fa, target)
    cpu_b = _loglog_cost(fb, target) if reached else fb[-1].cpu_s_per_sim_s
    return EqualErrorRatio(method_a, method_b, target, cpu_a, cpu_b, cpu_b / cpu_a, reached)
