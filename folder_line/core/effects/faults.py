"""``faults`` — seeded fault injection (all machines).

Per sheet (or leaf), independently: missing with probability ``p_missing``; else
doubled (two sheets arrive together) with ``p_double``; and, if it is not missing,
late by ``late_delay`` s with ``p_late``. Per machine cycle, a belt slow-down starts
with probability ``p_slowdown`` at a uniformly drawn time in the cycle, scales the
belt speed by ``slowdown_factor`` for ``slowdown_duration`` s; overlapping
slow-downs are merged. Draws come from the scene seed's named streams
(:func:`folder_line.core.numerics.rng.stream`), so the same scene and seed give the same
faults, and listing or removing another effect does not change them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from folder_line.core.line.events import make_events, merge_events
from folder_line.core.numerics.validate import check_fields, non_negative, within

__all__ = ['Params', 'SheetFaults', 'Slowdowns', 'belt_factor', 'draw_sheet_faults', 'draw_slowdowns', 'fault_events']


@dataclass(frozen=True)
class Params:
    """Fault rates and sizes.

    Attributes
    ----------
    p_missing, p_double, p_late : float
        Per-sheet probabilities in [0, 1].
    late_delay : float
        Delay of a late sheet, s (>= 0).
    p_slowdown : float
        Per-cycle probability that a belt slow-down starts, in [0, 1].
    slowdown_factor : float
        Belt speed factor during a slow-down, in (0, 1].
    slowdown_duration : float
        Length of a slow-down, s (>= 0).
    """

    p_missing: float
    p_double: float
    p_late: float
    late_delay: float
    p_slowdown: float
    slowdown_factor: float
    slowdown_duration: float

    def __post_init__(self) -> None:
        check_fields(
            self,
            'effects.faults',
            **dict.fromkeys(('p_missing', 'p_double', 'p_late', 'p_slowdown'), within(0.0, 1.0)),
            late_delay=non_negative,
            slowdown_factor=within(0.0, 1.0, lo_open=True),
            slowdown_duration=non_negative,
        )


@dataclass(frozen=True, eq=False)
class SheetFaults:
    """Per-sheet faults: boolean masks and delays (s), each of length n."""

    missing: np.ndarray
    double: np.ndarray
    delay: np.ndarray


@dataclass(frozen=True, eq=False)
class Slowdowns:
    """Non-overlapping belt slow-downs sorted by start: [t_start, t_end) with a speed factor."""

    t_start: np.ndarray
    t_end: np.ndarray
    factor: np.ndarray


def draw_sheet_faults(params: Params, n: int, rng: np.random.Generator) -> SheetFaults:
    """Faults of ``n`` consecutive sheets. Three uniform draws per sheet, always, taken
    sheet by sheet, so sheet j's faults depend neither on the probabilities nor on n."""
    u = rng.random((n, 3)).T if n else np.zeros((3, 0))
    missing = u[0] < params.p_missing
    double = ~missing & (u[1] < params.p_double)
    late = ~missing & (u[2] < params.p_late)
    return SheetFaults(missing, double, np.where(late, params.late_delay, 0.0))


def draw_slowdowns(params: Params, duration: float, period: float, rng: np.random.Generator) -> Slowdowns:
    """Belt slow-downs over [0, duration] for machine cycles of ``period`` s."""
    n = int(np.ceil(duration / period)) if period > 0 else 0
    u = rng.random((n, 2)).T if n else np.zeros((2, 0))  # cycle by cycle: a longer run extends, never reshuffles
    starts = (np.arange(n) + u[1]) * period
    starts = starts[(u[0] < params.p_slowdown) & (starts < duration)]
    if starts.size == 0 or params.slowdown_duration == 0.0 or params.slowdown_factor == 1.0:
        empty = np.zeros(0)
        return Slowdowns(empty, empty, empty)
    ends = starts + params.slowdown_duration
    # merge overlaps: a new interval starts where a start exceeds every previous end
    run_end = np.maximum.accumulate(ends)
    new = np.ones(starts.size, dtype=bool)
    new[1:] = starts[1:] > run_end[:-1]
    first = np.flatnonzero(new)
    last = np.append(first[1:], starts.size) - 1
    return Slowdowns(starts[first], run_end[last], np.full(first.size, params.slowdown_factor))


def belt_factor(slowdowns: Slowdowns, t: npt.ArrayLike) -> np.ndarray:
    """Belt speed factor at times ``t`` (1 outside every slow-down)."""
    t = np.asarray(t, dtype=float)
    if slowdowns.t_start.size == 0:
        return np.ones_like(t)
    i = np.searchsorted(slowdowns.t_start, t, side='right') - 1
    ic = np.clip(i, 0, None)
    inside = (i >= 0) & (t < slowdowns.t_end[ic])
    return np.where(inside, slowdowns.factor[ic], 1.0)


def fault_events(
    faults: SheetFaults,
    t_nominal: npt.ArrayLike,
    sheet: npt.ArrayLike,
    cycle: npt.ArrayLike,
    slowdowns: Slowdowns,
    duration: float,
) -> np.ndarray:
    """Events for the drawn faults: ``fault_missing``/``fault_double``/``fault_late`` at the
    sheet's nominal time, ``belt_slowdown_start``/``_end`` at the slow-down's ends (only
    those within ``duration``)."""
    t_nominal = np.asarray(t_nominal, dtype=float)
    sheet = np.asarray(sheet)
    cycle = np.asarray(cycle)
    late = faults.delay > 0.0
    tables = [
        make_events(
            'fault_missing', t_nominal[faults.missing], sheet=sheet[faults.missing], cycle=cycle[faults.missing]
        ),
        make_events('fault_double', t_nominal[faults.double], sheet=sheet[faults.double], cycle=cycle[faults.double]),
        make_events('fault_late', t_nominal[late], sheet=sheet[late], cycle=cycle[late], value=faults.delay[late]),
        make_events('belt_slowdown_start', slowdowns.t_start, value=slowdowns.factor),
        make_events('belt_slowdown_end', slowdowns.t_end[slowdowns.t_end <= duration]),
    ]
    return merge_events(tables)
