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

import math
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from folder_line.core.numerics.validate import check_fields, non_negative, within
from folder_line.core.types.events import make_events, merge_events

__all__ = [
    'Params',
    'SheetFaults',
    'SlowdownStream',
    'Slowdowns',
    'belt_factor',
    'draw_sheet_faults',
    'draw_slowdowns',
    'fault_events',
]


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


@dataclass
class SlowdownStream:
    """The belt slow-downs of :func:`draw_slowdowns`, drawn as the line runs (the same draws, in order).

    :meth:`advance` draws the machine cycles that start by a line time; a slow-down is
    known from its start on, and its end once no later draw can extend it (every cycle
    that starts before that end is drawn). Overlapping slow-downs merge as in
    :func:`draw_slowdowns`.

    Parameters
    ----------
    params : Params
        Fault rates and sizes.
    period : float
        Machine cycle, s (> 0).
    rng : numpy.random.Generator
        The seed's stream (taken over: it is advanced here).

    Attributes
    ----------
    t : float
        Line time drawn to, s.
    running : bool
        A slow-down is on whose end is not known yet (``run_end`` its end so far, s).
    started : int
        Slow-downs started so far (merged ones count once).
    """

    params: Params
    period: float
    rng: np.random.Generator
    t: float = -math.inf
    next_cycle: int = 0
    running: bool = False
    run_end: float = 0.0
    started: int = 0
    _breaks: list[tuple[float, float]] = field(default_factory=list)
    _events: list[tuple[float, bool]] = field(default_factory=list)

    @property
    def enabled(self) -> bool:
        """Whether any slow-down can happen (a zero length or a factor of 1 changes nothing)."""
        p = self.params
        return p.p_slowdown > 0.0 and p.slowdown_duration > 0.0 and p.slowdown_factor != 1.0

    def advance(self, t: float) -> None:
        """Draw every cycle that starts at or before ``t`` (s)."""
        if t <= self.t:
            return
        self.t = t
        if not self.enabled:
            return
        p, period = self.params, self.period
        last = math.floor(t / period) if t >= 0.0 else -1
        n = last + 1 - self.next_cycle
        if n > 0:
            u = self.rng.random((n, 2)).T  # cycle by cycle, as draw_slowdowns draws them
            starts = (np.arange(self.next_cycle, last + 1) + u[1]) * period
            self.next_cycle = last + 1
            for s in starts[u[0] < p.p_slowdown].tolist():
                if self.running and s <= self.run_end:  # overlaps the running one: merged
                    self.run_end = max(self.run_end, s + p.slowdown_duration)
                    continue
                self._close()
                self.running, self.run_end = True, s + p.slowdown_duration
                self._breaks.append((s, p.slowdown_factor))
                self._events.append((s, True))
                self.started += 1
        if self.running and self.run_end <= t:  # no later cycle starts before its end: it ends there
            self._close()

    def _close(self) -> None:
        if self.running:
            self._breaks.append((self.run_end, 1.0))
            self._events.append((self.run_end, False))
            self.running = False

    def breaks(self, t0: float, t1: float) -> list[tuple[float, float]]:
        """``(t, factor from t on)`` of the changes in ``(t0, t1]`` (``t1`` at most the time drawn to)."""
        out = [b for b in self._breaks if t0 < b[0] <= t1]
        self._breaks = [b for b in self._breaks if b[0] > t1]
        return out

    def take_events(self) -> list[tuple[float, bool]]:
        """``(t, True)`` for each start and ``(t, False)`` for each end learnt since the last call."""
        out, self._events = self._events, []
        return out


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
