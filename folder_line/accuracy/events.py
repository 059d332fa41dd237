"""Study ``events``: event times by sampling at a rate, by root finding, and the core's own.

What is measured
----------------
Two kinds of event of the line, each a case (a group of curves; the case is part of
the method name), each over a span of line time with many events:

``front stops``   ``at_stops`` of the ``folder`` scene (``config/scenes/folder.yaml``)
                  with the master drive spinning up, ``drive.profile: ramp``,
                  ``t_ramp = T_RAMP`` s, over ``SPAN_FOLDER`` s (28 signatures, half of
                  them during the ramp). Signature k is handed to the feed belt at the
                  master phase ``Θ_h,k = k T + t_out + phase`` and is at the stops when the
                  belt has carried it ``L_feed`` (:mod:`folder_line.core.line.folder_sim`)::

                      g_k(t) = V_tr (Θ(t) − Θ_h,k) − L_feed            (m)

                  with Θ(t) the core's ``RampDrive.theta`` (``t²/(2 t_ramp)`` during the
                  ramp: g is quadratic in t there, linear after it).
``leaf landing``  ``leaf_landed``/``leaf_spilled`` of the ``layup`` scene with linear air
                  drag ``leaf_flight.drag = DRAG`` 1/s, over ``SPAN_LAYUP`` s (41 leaves).
                  Leaf j leaves its chute exit at ``t_x,j`` (the core's ``leaf_exit`` event)
                  with the exit state of :mod:`folder_line.core.line.layup_sim` and flies
                  (:func:`folder_line.core.effects.leaf_flight.state`)::

                      g_j(t) = y_floor − y_j(t − t_x,j)                (m)

                  a transcendental function of t (exponentials of the drag); the core
                  finds its zero by safeguarded Newton.

The event of object k is the zero of g_k; g_k < 0 before it. Every method evaluates
the core's own g (the functions above call ``drive.theta`` and ``leaf_flight.state``);
no physics is re-implemented. The objects' starting data (hand-over phase Θ_h, exit
state) are read from the core and are given to every method: the cost measured is the
cost of *finding the event times*, not of the line simulation.

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

Reference and how it is checked
-------------------------------
Each event time is the root of the same g written in mpmath at ``DPS`` = 30 digits
(:func:`g_mp` of the case: the ramp's quadratic phase, resp. the flight's closed form
with ``expm1``; the float inputs taken exactly), found by ``mpmath.findroot``
(Anderson–Björck on a bracket ``[t_start, t_start + s]``, s doubled until g > 0). The
tests check (``test/accuracy/test_events.py``): ``|g(t_ref)| < 1e-25`` m and g changes
sign across t_ref; t_ref agrees with the core's event table (``FolderLine`` /
``LayupLine`` events) to 1e-12 s; and it agrees to 1e-25 s with an independent closed
form: ``t = sqrt(2 t_ramp Θ_a)`` (during the ramp) or ``Θ_a + t_ramp/2``,
``Θ_a = Θ_h + L_feed/V_tr``; for the flight ``τ = D + W₀(−(k c/G) e^{−k D})/k``
(Lambert W, ``c = v_y + G/k``, ``D = (k H + c)/G``).

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

import mpmath as mp
import numpy as np

from folder_line.accuracy.measure import Row, cpu_budget, cpu_per_call
from folder_line.config.scenes import load_scene
from folder_line.core.effects import chute_belts, leaf_flight
from folder_line.core.line.drives import make_drive
from folder_line.core.line.folder_sim import FolderLine
from folder_line.core.line.layup_sim import LayupLine
from folder_line.core.mechanisms.drive import RampDrive
from folder_line.core.numerics import roots
from folder_line.core.numerics.arrays import BoolArray, FloatArray, IntArray
from folder_line.core.numerics.constants import G
from folder_line.core.types.events import event_kind
from folder_line.errors import MeasurementError, ParameterError

__all__ = [
    'BATCH',
    'CASES',
    'CHUNK_S',
    'COARSE_RATE',
    'DPS',
    'DRAG',
    'EXACT',
    'INTERP',
    'METHODS',
    'ROOT',
    'SAMPLING',
    'SPAN_FOLDER',
    'SPAN_LAYUP',
    'STUDY',
    'T_RAMP',
    'Detection',
    'EventCase',
    'build_case',
    'check_counts',
    'detect',
    'detect_exact',
    'detect_root',
    'detect_sampling',
    'errors',
    'exit_states',
    'front_stops_case',
    'knob_settings',
    'leaf_landing_case',
    'max_error',
    'measure_rows',
    'reference_roots',
    'run',
]


STUDY = 'events'
#: decimal digits of the reference
DPS = 30
#: ramp time of the folder case's master drive, s
T_RAMP = 2.0
#: simulated spans, s (the folder's: the ramp and 1 s of steady running)
SPAN_FOLDER = 3.0
SPAN_LAYUP = 3.0
#: linear drag of the leaf flight, 1/s (terminal speed G/DRAG = 3.3 m/s)
DRAG = 3.0
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


# ------------------------------------------------------------------------------ cases


@dataclass(frozen=True, eq=False)
class EventCase:
    """The objects of one case, their event function and the reference event times.

    Attributes
    ----------
    name : str
        ``'front stops'`` or ``'leaf landing'``.
    span : float
        Simulated line time, s; events in ``[0, span]`` count.
    ids : ndarray of int64, shape (n,)
        Sheet / leaf id of every watched object (handed over / exited within the span).
    t_start : ndarray, shape (n,)
        Start of the watch: hand-over resp. chute exit time, s (g < 0 there).
    expected : ndarray of bool, shape (n,)
        The object's event lies in the span (per the core's event table).
    t_core : ndarray, shape (n,)
        The core's event time, s (NaN where not expected).
    g : callable ``g(idx, t) -> ndarray``
        Event function of objects ``idx`` (int array broadcast against ``t``) at line
        times ``t``, m; vectorised, the core's functions.
    g_scalar : callable ``g_scalar(k, t) -> float``
        The same for one object at one time (what Brent calls), m.
    g_mp : callable ``g_mp(k, t) -> mpf``
        The same function in mpmath (float inputs taken exactly), m.
    exact : callable ``exact(idx) -> ndarray``
        The core's own event time computation for objects ``idx``, s.
    closed_form_mp : callable ``closed_form_mp(k) -> mpf``
        An independent mpmath closed form of the event time, s (for the checks).
    ref_mp : tuple of mpf
        Reference event time of every object (``mpmath.findroot``), s.
    ref_hi, ref_lo : ndarray, shape (n,)
        The reference as a float pair ``hi + lo``, s.
    """

    name: str
    span: float
    ids: IntArray
    t_start: FloatArray
    expected: BoolArray
    t_core: FloatArray
    g: Callable[[IntArray, FloatArray], FloatArray]
    g_scalar: Callable[[int, float], float]
    g_mp: Callable[[int, mp.mpf], mp.mpf]
    exact: Callable[[IntArray], FloatArray]
    closed_form_mp: Callable[[int], mp.mpf]
    ref_mp: tuple[mp.mpf, ...]
    ref_hi: FloatArray
    ref_lo: FloatArray

    @property
    def n_events(self) -> int:
        """Events in the span."""
        return int(np.count_nonzero(self.expected))


def _bracket(g_mp: Callable[[int, mp.mpf], mp.mpf], k: int, a: float) -> tuple[mp.mpf, mp.mpf]:
    """``[a, a + s]`` with ``g(a) < 0 < g(a + s)``, s = 0.05 s doubled as needed."""
    lo = mp.mpf(a)
    if not g_mp(k, lo) < 0:
        raise MeasurementError(f'events reference: g({a!r}) of object {k} is not negative')
    step = mp.mpf('0.05')
    for _ in range(12):
        hi = lo + step
        if g_mp(k, hi) > 0:
            return lo, hi
        step *= 2
    raise MeasurementError(f'events reference: no sign change of g within {float(step)} s after {a!r} (object {k})')


def reference_roots(g_mp: Callable[[int, mp.mpf], mp.mpf], t_start: Sequence[float]) -> tuple[mp.mpf, ...]:
    """Root of each object's ``g_mp`` after its ``t_start`` by ``mpmath.findroot`` at :data:`DPS` digits.

    Parameters
    ----------
    g_mp : callable ``g_mp(k, t) -> mpf``
        Event function of object k in mpmath, m.
    t_start : sequence of float
        Start of each object's watch, s (g < 0 there).

    Returns
    -------
    tuple of mpf
        The roots, s (Anderson–Björck on a bracket, see :func:`_bracket`).
    """
    out = []
    with mp.workdps(DPS):
        for k, a in enumerate(t_start):
            lo, hi = _bracket(g_mp, k, float(a))
            out.append(mp.findroot(lambda t, k=k: g_mp(k, t), (lo, hi), solver='anderson'))
    return tuple(out)


def build_case(
    name: str,
    span: float,
    ids: IntArray,
    t_start: FloatArray,
    t_core: FloatArray,
    g: Callable[[IntArray, FloatArray], FloatArray],
    g_scalar: Callable[[int, float], float],
    g_mp: Callable[[int, mp.mpf], mp.mpf],
    exact: Callable[[IntArray], FloatArray],
    closed_form_mp: Callable[[int], mp.mpf],
) -> EventCase:
    """An :class:`EventCase` with its references computed (:func:`reference_roots`).

    ``t_core`` is the core's event time per object (NaN where the event is beyond the span).
    """
    ref = reference_roots(g_mp, t_start.tolist())
    with mp.workdps(DPS):
        hi = np.array([float(r) for r in ref])
        lo = np.array([float(r - mp.mpf(h)) for r, h in zip(ref, hi.tolist(), strict=True)])
    return EventCase(
        name=name,
        span=float(span),
        ids=ids,
        t_start=t_start,
        expected=np.isfinite(t_core),
        t_core=t_core,
        g=g,
        g_scalar=g_scalar,
        g_mp=g_mp,
        exact=exact,
        closed_form_mp=closed_form_mp,
        ref_mp=ref,
        ref_hi=hi,
        ref_lo=lo,
    )


def front_stops_case(span: float = SPAN_FOLDER, t_ramp: float = T_RAMP) -> EventCase:
    """The ``front stops`` case: ``at_stops`` of the ``folder`` scene on a ramp drive (module docstring).

    Parameters
    ----------
    span : float
        Line time, s.
    t_ramp : float
        Ramp time of the master drive, s.

    Returns
    -------
    EventCase
    """
    scene = load_scene('folder', {'drive.profile': 'ramp', 'drive.t_ramp': float(t_ramp)})
    drive = make_drive(scene)
    if not isinstance(drive, RampDrive):
        raise MeasurementError(f'events: the folder scene with a ramp profile gave a {type(drive).__name__}')
    fl = FolderLine(scene, drive, span)
    if not fl.belt.plain or scene.has('feed_slip'):
        raise MeasurementError('events: the front-stops case needs a plain feed belt without feed_slip')
    ev = fl.events
    hand = ev[ev['kind'] == event_kind('sheet_handover')]
    stops = ev[ev['kind'] == event_kind('at_stops')]
    timing = fl.timing
    V_tr, L = float(fl.V_tr), float(timing.L_feed)
    # the core's hand-over phase (folder_sim: slots * T + (t_out + phase)); the tests check
    # that drive.time_of of it is the sheet_handover time, bit for bit
    theta_h: FloatArray = hand['cycle'].astype(float) * timing.T + (timing.knife.t_out + float(scene.sheets.phase))
    ids = hand['sheet'].astype(np.int64)
    t_core = np.full(ids.size, np.nan)
    pos = {int(s): i for i, s in enumerate(ids.tolist())}
    for s, t in zip(stops['sheet'].tolist(), stops['t'].tolist(), strict=True):
        t_core[pos[int(s)]] = t
    th_list: list[float] = theta_h.tolist()
    tr = drive.t_ramp

    def g(idx: IntArray, t: FloatArray) -> FloatArray:
        return V_tr * (np.asarray(drive.theta(t), dtype=float) - theta_h[idx]) - L

    def g_scalar(k: int, t: float) -> float:
        return V_tr * (float(drive.theta(t)) - th_list[k]) - L

    def g_mp(k: int, t: mp.mpf) -> mp.mpf:
        trm = mp.mpf(tr)
        theta = t * t / (2 * trm) if t < trm else t - trm / 2
        return mp.mpf(V_tr) * (theta - mp.mpf(th_list[k])) - mp.mpf(L)

    def exact(idx: IntArray) -> FloatArray:
        # the core's closed form (folder_steps.feed): Θ at the stops, then the drive's inverse
        return np.asarray(drive.time_of(fl.belt.theta_of(theta_h[idx] + L / V_tr)), dtype=float)

    def closed_form_mp(k: int) -> mp.mpf:
        trm = mp.mpf(tr)
        theta_a = mp.mpf(th_list[k]) + mp.mpf(L) / mp.mpf(V_tr)
        return mp.sqrt(2 * trm * theta_a) if theta_a < trm / 2 else theta_a + trm / 2

    return build_case(
        'front stops', span, ids, hand['t'].astype(float), t_core, g, g_scalar, g_mp, exact, closed_form_mp
    )


@dataclass(frozen=True, eq=False)
class _Flight:
    """Exit states of the leaves (the core's, :mod:`folder_line.core.line.layup_sim`)."""

    t_x: FloatArray
    x0: FloatArray
    y0: FloatArray
    vx: FloatArray
    vy: FloatArray


def exit_states(line: LayupLine) -> tuple[IntArray, _Flight]:
    """Ids and exit states (t, x, y, vx, vy) of the leaves that left a chute, from the core.

    The exit velocity is assembled as in :class:`folder_line.core.line.layup_sim.LayupLine`
    (``v_C n̂ + v_belt t̂``, ``t̂ = (sin, −cos)``, ``n̂ = (cos, sin)``) from the core's
    chute kinematics and belt speed; the tests check that it reproduces the core's
    landing events.
    """
    if line.profile is None:
        raise MeasurementError('events: the leaf-landing case needs chute_belts')
    ev = line.events
    ex = ev[ev['kind'] == event_kind('leaf_exit')]
    ids = ex['sheet'].astype(np.int64)
    t_x = ex['t'].astype(float)
    q = line.kinematics.chute(t_x, ids % 2)
    u = np.asarray(chute_belts.belt_speed(line.profile, line.drive, t_x), dtype=float)
    vp = q['v_perp']
    vx = u * q['sin'] + vp * q['cos']
    vy = -u * q['cos'] + vp * q['sin']
    return ids, _Flight(t_x, np.asarray(q['x'], dtype=float), np.asarray(q['y'], dtype=float), vx, vy)


def leaf_landing_case(span: float = SPAN_LAYUP, drag: float = DRAG) -> EventCase:
    """The ``leaf landing`` case: the leaves of the ``layup`` scene hitting the floor (module docstring).

    Parameters
    ----------
    span : float
        Line time, s.
    drag : float
        Linear drag of the flight, 1/s (> 0 for the Lambert-W check; 0 allowed).

    Returns
    -------
    EventCase
    """
    scene = load_scene('layup', {'leaf_flight.drag': float(drag)})
    drive = make_drive(scene)
    line = LayupLine(scene, drive, span)
    params: leaf_flight.Params = scene.effect('leaf_flight')
    y_floor = float(scene.machine('container').y_floor)
    ids, fl = exit_states(line)
    ev = line.events
    landed = ev[(ev['kind'] == event_kind('leaf_landed')) | (ev['kind'] == event_kind('leaf_spilled'))]
    t_core = np.full(ids.size, np.nan)
    pos = {int(s): i for i, s in enumerate(ids.tolist())}
    for s, t in zip(landed['sheet'].tolist(), landed['t'].tolist(), strict=True):
        t_core[pos[int(s)]] = t
    t_x, x0, y0, vx, vy = fl.t_x, fl.x0, fl.y0, fl.vx, fl.vy
    lists = [a.tolist() for a in (t_x, x0, y0, vx, vy)]
    k = float(params.drag)

    def g(idx: IntArray, t: FloatArray) -> FloatArray:
        tau = np.maximum(t - t_x[idx], 0.0)
        return y_floor - leaf_flight.state(params, x0[idx], y0[idx], vx[idx], vy[idx], tau)[1]

    def g_scalar(j: int, t: float) -> float:
        tau = max(t - lists[0][j], 0.0)
        return y_floor - float(leaf_flight.state(params, lists[1][j], lists[2][j], lists[3][j], lists[4][j], tau)[1])

    def g_mp(j: int, t: mp.mpf) -> mp.mpf:
        tau = t - mp.mpf(lists[0][j])
        tau = tau if tau > 0 else mp.mpf(0)
        y0m, vym, Gm = mp.mpf(lists[2][j]), mp.mpf(lists[4][j]), mp.mpf(G)
        if k == 0.0:
            y = y0m + vym * tau - Gm * tau * tau / 2
        else:
            km = mp.mpf(k)
            e = -mp.expm1(-km * tau)
            y = y0m + vym * e / km - Gm / km * (tau - e / km)
        return mp.mpf(y_floor) - y

    def exact(idx: IntArray) -> FloatArray:
        landing: FloatArray = t_x[idx] + leaf_flight.landing_time(params, y0[idx], vy[idx], y_floor)
        return landing

    def closed_form_mp(j: int) -> mp.mpf:
        H = mp.mpf(lists[2][j]) - mp.mpf(y_floor)
        vym, Gm = mp.mpf(lists[4][j]), mp.mpf(G)
        if k == 0.0:
            tau = (vym + mp.sqrt(vym * vym + 2 * Gm * H)) / Gm
        else:
            km = mp.mpf(k)
            c = vym + Gm / km
            D = (km * H + c) / Gm
            tau = D + mp.lambertw(-(km * c / Gm) * mp.exp(-km * D), 0).real / km
        return mp.mpf(lists[0][j]) + tau

    return build_case('leaf landing', span, ids, t_x, t_core, g, g_scalar, g_mp, exact, closed_form_mp)


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
