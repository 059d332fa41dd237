"""Study ``events``: event times by sampling at a rate, by root finding, and the core's own.

The cases
---------
Two kinds of event of the line, each a case: ``front stops`` (``at_stops`` of the ``folder``
scene on a ramp drive) and ``leaf landing`` (the ``layup`` scene's leaves hitting the floor
with air drag); what each measures, its event function g and its reference are described in
:mod:`folder_line.accuracy.event_cases`. Every method evaluates the core's own g; no physics
is re-implemented.

Methods (one curve each, per case)
----------------------------------
``sampling``                        a polling node: ticks at ``i / rate`` (knob ``rate``,
                                    100 Hz … 100 kHz), the event reported at the first
                                    tick with ``g >= 0`` (so ``0 <= t_det − t_ref < 1/rate``)
``sampling + linear interpolation`` the same ticks; the secant between the two
                                    straddling ticks (error ~ rate⁻²)
``root finding (folder_line)``      the same poll at ``COARSE_RATE`` = 100 Hz, then the
                                    core's event detector
                                    :func:`folder_line.core.numerics.roots.find_sign_changes`
                                    (Brent) on each object's coarse samples, knob
                                    ``xtol`` 1e-3 … 1e-12 s
``exact (folder_line)``             the core's own event time computation: the closed
                                    form ``drive.time_of(Θ_h + L_feed / V_tr)`` (square
                                    root during the ramp), resp.
                                    ``leaf_flight.landing_time`` (vectorised Newton),
                                    called on batches of ``batch`` events (knob ``batch``)

The poller evaluates g only while the object is watched -- from the last tick before its
hand-over/exit to the end of the chunk of ticks (``CHUNK_S`` s, at least ``MIN_CHUNK``
ticks; vectorised over the objects) in which it is first detected -- as a node does
that drops a sheet once it has seen it arrive. At 100 Hz the chunk (0.16 s) is longer
than most watches, so the cheapest settings pay for some ticks they would not need.

Missed and double events are failures, not numbers: every method's detections are
counted per object (rising crossings of g between consecutive ticks; the core
detector's reported sign changes; exact times within the span) and
:func:`check_counts` raises :class:`~folder_line.errors.MeasurementError` unless each
object whose event lies in the span is detected exactly once and no other object at all.

Reference
---------
Each event time is the root of the same g written in mpmath at ``DPS`` = 30 digits, checked
against the core's event table and an independent closed form
(:mod:`folder_line.accuracy.event_cases`).

Error and units
---------------
``error`` is the largest ``|t_det − t_ref|`` over all events of the case's span, in
**seconds** (computed against the reference rounded to a float pair, so errors down to
1e-30 s are resolved). ``cpu_s_per_sim_s`` is the CPU time of finding all events of the
span (``time.process_time``, :func:`~folder_line.accuracy.measure.cpu_per_call`) divided
by the span, CPU s per simulated s.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from folder_line.accuracy.event_cases import DPS, EventCase, front_stops_case, leaf_landing_case
from folder_line.accuracy.measure import Row, cpu_budget, cpu_per_call
from folder_line.core.numerics import roots
from folder_line.core.numerics.arrays import FloatArray, IntArray
from folder_line.errors import MeasurementError, ParameterError

__all__ = [
    'BATCH',
    'CASES',
    'CHUNK_S',
    'COARSE_RATE',
    'EXACT',
    'INTERP',
    'METHODS',
    'ROOT',
    'SAMPLING',
    'STUDY',
    'Detection',
    'check_counts',
    'detect',
    'detect_exact',
    'detect_root',
    'detect_sampling',
    'errors',
    'knob_settings',
    'max_error',
    'measure_rows',
    'run',
]


STUDY = 'events'
#: the root finder's scan grid, Hz
COARSE_RATE = 100.0
#: ticks evaluated per watched object and pass of the poller, s (at least MIN_CHUNK ticks)
CHUNK_S = 0.02
MIN_CHUNK = 16
#: the cases, in row order
CASES = ('front stops', 'leaf landing')
#: the methods, by their name in the rows
SAMPLING = 'sampling'
INTERP = 'sampling + linear interpolation'
ROOT = 'root finding (folder_line)'
EXACT = 'exact (folder_line)'
METHODS = (SAMPLING, INTERP, ROOT, EXACT)
KNOBS = {SAMPLING: 'rate', INTERP: 'rate', ROOT: 'xtol', EXACT: 'batch'}
#: the 'exact' knob: events per call of the core's vectorised event time computation
BATCH = 'batch'

_SETTINGS: dict[tuple[str, bool], tuple[float, ...]] = {
    (SAMPLING, False): (100.0, 300.0, 1e3, 3e3, 1e4, 3e4, 1e5),
    (SAMPLING, True): (100.0, 1e3, 1e4, 1e5),
    (ROOT, False): tuple(10.0**-k for k in range(3, 13)),
    (ROOT, True): (1e-3, 1e-6, 1e-9, 1e-12),
    (EXACT, False): (1.0, 4.0, 16.0, 64.0),
    (EXACT, True): (1.0, 8.0, 64.0),
}
_SETTINGS[(INTERP, False)] = _SETTINGS[(SAMPLING, False)]
_SETTINGS[(INTERP, True)] = _SETTINGS[(SAMPLING, True)]

REFERENCE = (
    f'mpmath.findroot at {DPS} digits on the same g; checked: g(t_ref) = 0, the core event table '
    'to 1e-12 s, closed form (sqrt / Lambert W) to 1e-25 s'
)


def knob_settings(method: str, quick: bool = False) -> tuple[float, ...]:
    """Knob settings of one curve: ``rate`` (Hz), ``xtol`` (s) or ``batch`` (events per call)."""
    return _SETTINGS[(method, quick)]


# ------------------------------------------------------------------------------ detection


@dataclass(frozen=True, eq=False)
class Detection:
    """What one method found: per watched object, its first detection and how many.

    Attributes
    ----------
    t : ndarray, shape (n,)
        First detected event time of each object, s (NaN if none).
    count : ndarray of int64, shape (n,)
        Detections of each object (1 where the event is in the span, 0 elsewhere, if right).
    evaluations : int
        Evaluations of g (vectorised elements and scalar calls); 0 for ``exact``.
    """

    t: FloatArray
    count: IntArray
    evaluations: int


@dataclass
class _Poll:
    t_prev: FloatArray
    g_prev: FloatArray
    t_hit: FloatArray
    g_hit: FloatArray
    count: IntArray
    evaluations: int
    grids: list[list[FloatArray]] | None
    values: list[list[FloatArray]] | None


def _poll(case: EventCase, rate: float, keep: bool = False) -> _Poll:
    """Poll every object's g on the ticks ``i / rate`` from its watch start, vectorised over objects.

    The first tick polled is the last one before the watch start (g < 0 there), so the
    first detection always has a straddling pair. A rising crossing is
    ``g[i-1] < 0 <= g[i]``; an object is dropped after the chunk in which it is first
    detected, or at the span's end.
    """
    n = case.t_start.size
    i_last = math.floor(case.span * rate * (1.0 + 1e-15))
    i0 = np.maximum(np.ceil(case.t_start * rate).astype(np.int64) - 1, 0)
    chunk = max(MIN_CHUNK, round(CHUNK_S * rate))
    steps = np.arange(chunk + 1, dtype=np.int64)
    t_prev = np.full(n, np.nan)
    g_prev = np.full(n, np.nan)
    t_hit = np.full(n, np.nan)
    g_hit = np.full(n, np.nan)
    count = np.zeros(n, dtype=np.int64)
    grids: list[list[FloatArray]] | None = [[] for _ in range(n)] if keep else None
    values: list[list[FloatArray]] | None = [[] for _ in range(n)] if keep else None
    live = np.flatnonzero(i0 <= i_last)
    offset = 0
    evaluations = 0
    while live.size:
        ticks = i0[live, None] + (offset + steps)
        valid = ticks <= i_last
        t = np.minimum(ticks, i_last) / rate
        gv = np.asarray(case.g(live[:, None], t), dtype=float)
        evaluations += gv.size
        rise = (gv[:, :-1] < 0.0) & (gv[:, 1:] >= 0.0) & valid[:, 1:]
        hits = rise.sum(axis=1)
        if offset == 0:  # an object already at g >= 0 on its first tick: a detection without a pair
            start = gv[:, 0] >= 0.0
            hits = hits + start
        else:
            start = np.zeros(live.size, dtype=bool)
        new = (hits > 0) & (count[live] == 0)
        if new.any():
            rows = np.flatnonzero(new)
            j = np.argmax(rise[rows], axis=1)
            st = start[rows]
            obj = live[rows]
            t_hit[obj] = np.where(st, t[rows, 0], t[rows, j + 1])
            g_hit[obj] = np.where(st, gv[rows, 0], gv[rows, j + 1])
            t_prev[obj] = np.where(st, np.nan, t[rows, j])
            g_prev[obj] = np.where(st, np.nan, gv[rows, j])
        count[live] += hits
        if keep:
            assert grids is not None and values is not None
            first = 0 if offset == 0 else 1  # the chunks overlap by one tick
            for r, o in enumerate(live.tolist()):
                m = valid[r].copy()
                m[:first] = False
                grids[o].append(t[r, m])
                values[o].append(gv[r, m])
        done = (count[live] > 0) | ~valid[:, -1]
        live = live[~done]
        offset += chunk
    return _Poll(t_prev, g_prev, t_hit, g_hit, count, evaluations, grids, values)


def detect_sampling(case: EventCase, rate: float, interpolate: bool = False) -> Detection:
    """Polling at ``rate`` Hz: the first tick with g >= 0, or the secant through the straddling ticks.

    Parameters
    ----------
    case : EventCase
        The objects and their event function.
    rate : float
        Tick rate, Hz (> 0).
    interpolate : bool
        Report the zero of the line through the two straddling ticks instead of the tick.

    Returns
    -------
    Detection
    """
    p = _poll(case, float(rate))
    if not interpolate:
        return Detection(p.t_hit, p.count, p.evaluations)
    paired = np.isfinite(p.t_prev)
    t = p.t_hit.copy()
    d = np.where(paired, p.g_hit - p.g_prev, 1.0)
    t[paired] = (p.t_prev - p.g_prev * (p.t_hit - p.t_prev) / d)[paired]
    return Detection(t, p.count, p.evaluations)


def detect_root(case: EventCase, xtol: float, coarse_rate: float = COARSE_RATE) -> Detection:
    """Poll at ``coarse_rate``, then the core's detector :func:`~folder_line.core.numerics.roots.find_sign_changes`.

    Each watched object's coarse samples (its watch, up to the chunk of the first
    detection) go to ``find_sign_changes`` with their values; every sign change it
    reports counts as a detection, the first rising one is the event time.

    Parameters
    ----------
    case : EventCase
        The objects and their event function.
    xtol : float
        Absolute tolerance of the Brent refinement, s.
    coarse_rate : float
        Scan grid, Hz.

    Returns
    -------
    Detection
    """
    p = _poll(case, float(coarse_rate), keep=True)
    assert p.grids is not None and p.values is not None
    n = case.t_start.size
    t = np.full(n, np.nan)
    count = np.zeros(n, dtype=np.int64)
    evaluations = p.evaluations
    for k in range(n):
        if not p.grids[k]:  # watch starts after the span
            continue
        grid = np.concatenate(p.grids[k])
        if grid.size < 2:
            continue

        def g_k(x: float, k: int = k) -> float:
            return case.g_scalar(k, x)

        sc = roots.find_sign_changes(g_k, grid, values=np.concatenate(p.values[k]), xtol=xtol)
        evaluations += sc.function_calls
        count[k] = len(sc)
        up = sc.x[sc.direction > 0]
        if up.size:
            t[k] = up[0]
    return Detection(t, count, evaluations)


def detect_exact(case: EventCase, batch: int) -> Detection:
    """The core's own event time computation, ``batch`` objects per call.

    Parameters
    ----------
    case : EventCase
        The objects.
    batch : int
        Objects per vectorised call (>= 1).

    Returns
    -------
    Detection
        ``count`` is 1 where the computed time lies in the span.
    """
    b = int(batch)
    if b < 1:
        raise ParameterError('batch', batch, 'must be a whole number >= 1')
    n = case.t_start.size
    idx = np.arange(n, dtype=np.int64)
    t = np.concatenate([case.exact(idx[i : i + b]) for i in range(0, n, b)]) if n else np.zeros(0)
    inside = t <= case.span
    return Detection(np.where(inside, t, np.nan), inside.astype(np.int64), 0)


def detect(case: EventCase, method: str, value: float) -> Detection:
    """One method at one knob setting (:data:`METHODS`), with the counts checked (:func:`check_counts`)."""
    if method == SAMPLING:
        det = detect_sampling(case, value)
    elif method == INTERP:
        det = detect_sampling(case, value, interpolate=True)
    elif method == ROOT:
        det = detect_root(case, value)
    elif method == EXACT:
        det = detect_exact(case, int(value))
    else:
        raise ParameterError('method', method, f'unknown; known: {", ".join(METHODS)}')
    check_counts(case, det, f'{method} at {KNOBS[method]} {value:g}')
    return det


def check_counts(case: EventCase, det: Detection, label: str) -> None:
    """Raise unless each event in the span is detected once and nothing else at all.

    Raises
    ------
    MeasurementError
        Naming the missed, doubled and spurious objects (ids) and the method.
    """
    exp = case.expected
    missed = case.ids[exp & (det.count == 0)]
    double = case.ids[exp & (det.count > 1)]
    spurious = case.ids[~exp & (det.count > 0)]
    bad_time = case.ids[exp & (det.count == 1) & ~np.isfinite(det.t)]
    if missed.size or double.size or spurious.size or bad_time.size:
        raise MeasurementError(
            f'events [{case.name}] {label}: {missed.size} missed (ids {missed[:10].tolist()}), '
            f'{double.size} detected more than once (ids {double[:10].tolist()}), '
            f'{spurious.size} detected but not in the span (ids {spurious[:10].tolist()}), '
            f'{bad_time.size} without a time (ids {bad_time[:10].tolist()}); {case.n_events} events expected'
        )


def errors(case: EventCase, t: FloatArray) -> FloatArray:
    """Signed ``t − t_ref`` of the events in the span, s (against the float-pair reference)."""
    exp = case.expected
    return (t[exp] - case.ref_hi[exp]) - case.ref_lo[exp]


def max_error(case: EventCase, t: FloatArray) -> float:
    """Largest ``|t − t_ref|`` over the events in the span, s."""
    e = errors(case, t)
    if e.size == 0 or not np.all(np.isfinite(e)):
        raise MeasurementError(f'events [{case.name}]: no finite detection time for some event')
    return float(np.max(np.abs(e)))


# ------------------------------------------------------------------------------ rows


def measure_rows(
    cases: Sequence[EventCase], quick: bool = False, *, min_s: float = 0.05, repeats: int = 3
) -> list[Row]:
    """Rows of every method at every knob setting for the given cases.

    Parameters
    ----------
    cases : sequence of EventCase
        From :func:`front_stops_case`, :func:`leaf_landing_case`.
    quick : bool
        Fewer knob settings (:func:`knob_settings`).
    min_s, repeats : float, int
        Timing batches of :func:`~folder_line.accuracy.measure.cpu_per_call`.

    Returns
    -------
    list of Row
        ``error`` in s, ``cpu_s_per_sim_s`` in CPU s per simulated s.

    Raises
    ------
    MeasurementError
        A method missed or doubled an event (:func:`check_counts`).
    """
    rows: list[Row] = []
    for case in cases:
        for method in METHODS:
            for value in knob_settings(method, quick):
                det = detect(case, method, value)
                err = max_error(case, det.t)
                cpu = cpu_per_call(_timed(case, method, value), min_s=min_s, repeats=repeats)
                rows.append(
                    Row(
                        study=STUDY,
                        method=f'{method} [{case.name}]',
                        knob=KNOBS[method],
                        value=float(value),
                        error=err,
                        cpu_s_per_sim_s=cpu / case.span,
                        quantity=f'event time, {case.name} ({case.n_events} events)',
                        unit='s',
                        reference=REFERENCE,
                    )
                )
    return rows


def _timed(case: EventCase, method: str, value: float) -> Callable[[], object]:
    if method == SAMPLING:
        return lambda: detect_sampling(case, value)
    if method == INTERP:
        return lambda: detect_sampling(case, value, interpolate=True)
    if method == ROOT:
        return lambda: detect_root(case, value)
    return lambda: detect_exact(case, int(value))


def run(quick: bool = False) -> list[Row]:
    """Rows of the ``events`` study (module docstring): both cases, four methods each.

    Parameters
    ----------
    quick : bool
        Fewer knob settings (4 rates, 4 tolerances, 3 batch sizes) and shorter timing batches.

    Returns
    -------
    list of Row
        ``error`` in s (largest over the span's events), ``cpu_s_per_sim_s`` in CPU s per simulated s.
    """
    cases = (front_stops_case(), leaf_landing_case())
    min_s, repeats = cpu_budget(quick)
    return measure_rows(cases, quick, min_s=min_s, repeats=repeats)
