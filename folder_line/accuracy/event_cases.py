"""The cases of study ``events`` (:mod:`folder_line.accuracy.events`): the objects, their event
function and the reference event times.

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
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import mpmath as mp
import numpy as np

from folder_line.config.scenes import load_scene
from folder_line.core.effects import chute_belts, leaf_flight
from folder_line.core.line.drives import make_drive
from folder_line.core.line.folder_sim import FolderLine
from folder_line.core.line.layup_sim import LayupLine
from folder_line.core.mechanisms.drive import RampDrive
from folder_line.core.numerics.arrays import BoolArray, FloatArray, IntArray
from folder_line.core.numerics.constants import G
from folder_line.core.types.events import event_kind
from folder_line.errors import MeasurementError

__all__ = [
    'DPS',
    'DRAG',
    'SPAN_FOLDER',
    'SPAN_LAYUP',
    'T_RAMP',
    'EventCase',
    'build_case',
    'exit_states',
    'front_stops_case',
    'leaf_landing_case',
    'reference_roots',
]

#: decimal digits of the reference
DPS = 30
#: ramp time of the folder case's master drive, s
T_RAMP = 2.0
#: simulated spans, s (the folder's: the ramp and 1 s of steady running)
SPAN_FOLDER = 3.0
SPAN_LAYUP = 3.0
#: linear drag of the leaf flight, 1/s (terminal speed G/DRAG = 3.3 m/s)
DRAG = 3.0


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
