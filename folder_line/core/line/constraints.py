"""F and D cyclogram constraints as pure functions of an event table.

:func:`evaluate_folder_constraints` reads only the events (any table with the
columns of :data:`folder_line.core.types.events.EVENT_DTYPE`; other kinds are ignored), the
cycle timing and the scene's parameters. It does not care where the events came
from, so the batch simulator (:func:`folder_line.core.line.folder_sim.simulate_folder`)
and a live supervisor fed by an event stream evaluate the same code; a supervisor
can call it on the events of the last cycles (a window that contains each judged
cycle's ``knife_contact`` and its sheets' events).

Which cycles are judged: those whose ``knife_contact`` is in the table. A sheet
belongs to the cycle its ``sheet_handover`` row names. Where a judged sheet's
``at_stops`` (or ``settled``) row is missing — it was still on its way when the
table ends — its time is bounded by the table's last time, which is after the
knife contact: the margin is then reported as that (negative) bound.

Causal evaluation (``causal=True``, what the live supervisor uses,
:mod:`folder_line.core.supervision`): each judged cycle sees only the rows at or
before its own knife contact — its decision time, the ``t`` of the series — as if
the table ended there. A sheet handed over after its cycle's knife contact is not
judged (the cycle had no sheet when it was decided); a sheet's ``at_stops``,
``settled`` or ``bounce`` after its cycle's knife contact is "still on its way" (bound ``-spacing(t_contact)``
instead of the actual lateness: the sign is the batch evaluation's, the size is what
is known at the decision). Each cycle's result then depends only on the rows up to
its decision time, so evaluating a stream cycle by cycle, in any batching, gives the
same margins as one causal call on the whole table. For every cycle whose sheets are
all at rest by the knife contact, the causal and the batch margins are equal.

Constraints (margin >= 0 passes; every margin finite)
-----------------------------------------------------
``feed_window`` (s), per cycle (worst sheet)
    ``(window start + t_allowed) - t_at_stops``: the feed, begun when the knife left
    the table (``kT + t_out``), must be done within ``t_allowed = (1 - reserve) t_fw``
    (paper 001: the feed time kept 10 % short as a reserve). In master phase the
    deadline is ``Θ(knife_contact) - (T - t_knife - t_allowed)``, mapped to time by
    the drive (Θ = t without one).
``settled_before_knife`` (s), per cycle (worst sheet)
    ``t_knife_contact - t_settled`` (``settled`` rows with ``stop_bounce``; without it
    the signature is at rest on arrival, ``t_settled = t_at_stops``).
``one_per_cycle`` (sheets), per cycle
    ``-|n - 1|`` with n the signatures of the cycle at the stops by the knife
    contact: 0 for exactly one, -1 for a missing (or jammed) one, -1 for a double.
``rebound`` (m), with ``stop_bounce``, per cycle (worst sheet that reached the stops)
    ``tolerance - first rebound distance`` (largest ``bounce`` value of the sheet; 0
    if it did not bounce).
``release_at_min_speed`` (dimensionless), with a delivery, per cycle
    ``RELEASE_KV_TOL - (K_v(u) - K_v,min)`` with u the carriage's stroke position at
    the ``released_on_pile`` time, recomputed from the chain's travel since the
    take-over (``v_A (Θ - Θ_take,k) - L_transfer`` inverted along the guide):
    the sheet must be let go where the carriage is slowest (paper 002).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from folder_line.core.effects import chute_belts, leaf_damage
from folder_line.core.line.delivery_plan import DeliveryPlan, delivery_plan
from folder_line.core.mechanisms.cyclogram import CycleTiming
from folder_line.core.mechanisms.delivery import evaluate_stroke
from folder_line.core.mechanisms.drive import Drive
from folder_line.core.types.events import ConstraintSeries, event_kind

if TYPE_CHECKING:
    from folder_line.core.line.scene import Scene

__all__ = [
    'FOLDER_CONSTRAINTS',
    'LAYUP_CONSTRAINTS',
    'RELEASE_KV_TOL',
    'FolderEvaluation',
    'chute_speed_series',
    'evaluate_folder_constraints',
    'evaluate_layup_constraints',
    'folder_evaluation',
]

#: names of the constraints :func:`evaluate_folder_constraints` may return, in order
FOLDER_CONSTRAINTS = ('feed_window', 'settled_before_knife', 'one_per_cycle', 'rebound', 'release_at_min_speed')
#: names of the constraints :func:`evaluate_layup_constraints` may return
LAYUP_CONSTRAINTS = ('chute_speed',)
#: how far above the stroke's minimum K_v a release may be, dimensionless
RELEASE_KV_TOL = 1e-6


def _rows(events: np.ndarray, kind: str) -> np.ndarray:
    rows: np.ndarray = events[events['kind'] == event_kind(kind)]  # a field of a structured array is typed Any
    return rows


def _lookup(
    keys: np.ndarray, values: np.ndarray, query: np.ndarray, reduce: str = 'first'
) -> tuple[np.ndarray, np.ndarray]:
    """values[keys == q] for each q: (value, found). ``reduce``: 'first' (first row in table order) or 'max'."""
    out = np.zeros(query.size)
    found = np.zeros(query.size, dtype=bool)
    if keys.size == 0 or query.size == 0:
        return out, found
    order = np.lexsort((-values, keys)) if reduce == 'max' else np.argsort(keys, kind='stable')
    k, v = keys[order], values[order]
    first = np.ones(k.size, dtype=bool)
    first[1:] = k[1:] != k[:-1]
    k, v = k[first], v[first]
    pos = np.minimum(np.searchsorted(k, query), k.size - 1)
    found = k[pos] == query
    out = np.where(found, v[pos], 0.0)
    return out, found


def _per_cycle_min(cycles: np.ndarray, margins: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    if cycles.size == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0)
    uc, inv = np.unique(cycles, return_inverse=True)
    m = np.full(uc.size, np.inf)
    np.minimum.at(m, inv, margins)
    return uc.astype(np.int64), m


def _contact_time(cc: np.ndarray, tc: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Knife-contact time of each cycle in ``c`` (all judged cycles are in ``cc``)."""
    if c.size == 0:
        return np.zeros(0)
    return tc[np.searchsorted(cc, c)]


@dataclass(frozen=True, eq=False)
class FolderEvaluation:
    """:func:`folder_evaluation`'s result: the constraints and the signature counts behind ``one_per_cycle``.

    Attributes
    ----------
    constraints : list of ConstraintSeries
        As :func:`evaluate_folder_constraints` returns them.
    cycle : ndarray of int64
        The judged cycles (those with a ``knife_contact`` row), ascending.
    signatures : ndarray of int64
        Signatures of each judged cycle at the front stops by its knife contact
        (1 nominal; 0 a missing or late one: starvation; 2 a double).
    t : ndarray of float64
        Knife contact (decision time) of each judged cycle, s.
    """

    constraints: list[ConstraintSeries]
    cycle: np.ndarray
    signatures: np.ndarray
    t: np.ndarray


def evaluate_folder_constraints(
    events: np.ndarray,
    timing: CycleTiming,
    scene: Scene,
    drive: Drive | None = None,
    *,
    plan: DeliveryPlan | None = None,
    causal: bool = False,
) -> list[ConstraintSeries]:
    """Per-cycle margins of the folder's (and delivery's) constraints.

    ``folder_evaluation(...).constraints`` (:func:`folder_evaluation`).
    """
    return folder_evaluation(events, timing, scene, drive, plan=plan, causal=causal).constraints


def folder_evaluation(
    events: np.ndarray,
    timing: CycleTiming,
    scene: Scene,
    drive: Drive | None = None,
    *,
    plan: DeliveryPlan | None = None,
    causal: bool = False,
    t_end: float | None = None,
) -> FolderEvaluation:
    """Per-cycle margins of the folder's (and delivery's) constraints, with the signature counts.

    Parameters
    ----------
    events : ndarray of EVENT_DTYPE
        Any event table (unsorted is fine).
    timing : CycleTiming
        The cycle (:func:`folder_line.core.mechanisms.cyclogram.cycle_timing`).
    scene : Scene
        For the listed effects (``stop_bounce`` tolerance) and the delivery.
    drive : Drive, optional
        Master drive, to map the deadline and the release phase between Θ and t;
        None means Θ = t (steady nominal speed).
    plan : DeliveryPlan, optional
        :func:`folder_line.core.line.delivery_plan.delivery_plan` of the scene, if already at
        hand (it is derived from the scene otherwise).
    causal : bool, optional
        Judge each cycle on the rows up to its knife contact only (module docstring);
        default False: on the whole table (the batch simulator's view).
    t_end : float, optional
        The time the table ends, s: a signature not at the stops by then arrives after it
        (default: the table's last time; the streamed line gives the last time it handed out).

    Returns
    -------
    FolderEvaluation
        ``constraints`` in the order of :data:`FOLDER_CONSTRAINTS`; ``rebound`` only
        with ``stop_bounce``, ``release_at_min_speed`` only with a delivery. Cycles in
        ascending order; margins finite.
    """
    ev = np.asarray(events)
    t_last = (float(ev['t'].max()) if ev.size else 0.0) if t_end is None else float(t_end)
    j = _judged(ev, causal, t_last)
    bouncing = scene.has('stop_bounce')
    per_cycle, counts = _one_per_cycle(j)
    out = [_feed_window(j, timing, drive), _settled_before_knife(ev, j, bouncing, causal), per_cycle]
    if bouncing:
        out.append(_rebound(ev, j, scene, causal))
    if 'delivery' in scene.machines:
        out.append(_release_at_min_speed(ev, timing, scene, drive, plan))
    return FolderEvaluation(constraints=out, cycle=j.cc.astype(np.int64), signatures=counts, t=j.tc.copy())


def _theta(drive: Drive | None, t: np.ndarray) -> np.ndarray:
    """Master phase Θ at line times ``t`` (Θ = t without a drive), nominal s."""
    return np.asarray(t, dtype=float) if drive is None else np.asarray(drive.theta(t), dtype=float)


def _time_of(drive: Drive | None, th: np.ndarray) -> np.ndarray:
    """Line time of the master phases ``th`` (t = Θ without a drive), s."""
    return np.asarray(th, dtype=float) if drive is None else np.asarray(drive.time_of(th), dtype=float)


class _Judged(NamedTuple):
    """The signatures judged in a table: those handed over in a cycle with a knife contact.

    ``cc``, ``tc``: the cycles with a knife contact (ascending) and its time, s; per judged
    signature: ``ic`` its cycle's index into them, ``sheet``, ``cyc``, ``t_contact`` (s),
    ``t_stop`` (s) and ``at_stops`` (known at the stops); ``late_bound``: the margin of one
    not at the stops (it arrives after the table ends), s.
    """

    cc: np.ndarray
    tc: np.ndarray
    ic: np.ndarray
    sheet: np.ndarray
    cyc: np.ndarray
    t_contact: np.ndarray
    t_stop: np.ndarray
    at_stops: np.ndarray
    late_bound: np.ndarray


def _judged(ev: np.ndarray, causal: bool, t_last: float) -> _Judged:
    """The judged signatures of ``ev`` (``causal``: as known at each knife contact; the table ends at ``t_last``, s)."""
    contact = _rows(ev, 'knife_contact')
    cc, first = np.unique(contact['cycle'], return_index=True)
    tc = contact['t'][first]
    hand = _rows(ev, 'sheet_handover')
    if cc.size:
        pos = np.minimum(np.searchsorted(cc, hand['cycle']), cc.size - 1)
        judged = cc[pos] == hand['cycle']
        if causal:  # a sheet handed over after its cycle's knife contact is not known there
            judged &= hand['t'] <= tc[pos]
    else:
        pos = np.zeros(hand.size, dtype=np.int64)
        judged = np.zeros(hand.size, dtype=bool)
    ic = pos[judged]  # index into (cc, tc) of each judged sheet's cycle
    sheet = hand['sheet'][judged]
    cyc = hand['cycle'][judged]
    t_contact = tc[ic]

    stops = _rows(ev, 'at_stops')
    t_stop, at_stops = _lookup(stops['sheet'], stops['t'], sheet)
    if causal:  # what is known at each cycle's knife contact
        at_stops &= t_stop <= t_contact
    # a sheet not yet at the stops when the table ends arrives after t_last (>= its knife contact)
    t_known = t_contact if causal else t_last
    late_bound = np.minimum(t_contact - t_known, -np.spacing(np.abs(t_contact) + 1.0))
    return _Judged(cc, tc, ic, sheet, cyc, t_contact, t_stop, at_stops, late_bound)


def _feed_window(j: _Judged, timing: CycleTiming, drive: Drive | None) -> ConstraintSeries:
    """``feed_window``: each signature at the stops by its cycle's feed deadline, margin in s."""
    if j.sheet.size:
        th_dead = _theta(drive, j.tc) - (timing.T - timing.t_knife - timing.t_allowed)
        t_dead = _time_of(drive, th_dead)[j.ic]
        margin = np.where(j.at_stops, t_dead - j.t_stop, (t_dead - j.t_contact) + j.late_bound)
    else:
        margin = np.zeros(0)
    c, m = _per_cycle_min(j.cyc, margin)
    return ConstraintSeries(
        'feed_window',
        's',
        c,
        m,
        'feed done within t_allowed of the knife exit: (window start + t_allowed) - t_at_stops',
        t=_contact_time(j.cc, j.tc, c),
    )


def _settled_before_knife(ev: np.ndarray, j: _Judged, bouncing: bool, causal: bool) -> ConstraintSeries:
    """``settled_before_knife``: each signature at rest (``settled`` with ``stop_bounce``) before the knife, s."""
    if bouncing:
        settled = _rows(ev, 'settled')
        t_set, is_set = _lookup(settled['sheet'], settled['t'], j.sheet)
        if causal:
            is_set &= t_set <= j.t_contact
    else:
        t_set, is_set = j.t_stop, j.at_stops
    margin = np.where(is_set, j.t_contact - t_set, j.late_bound)
    c, m = _per_cycle_min(j.cyc, margin)
    return ConstraintSeries(
        'settled_before_knife',
        's',
        c,
        m,
        'signature at rest at the front stops before the knife contact: t_contact - t_settled',
        t=_contact_time(j.cc, j.tc, c),
    )


def _one_per_cycle(j: _Judged) -> tuple[ConstraintSeries, np.ndarray]:
    """``one_per_cycle`` (margin ``-|count - 1|``), and the count of signatures at the stops per cycle."""
    in_time = j.at_stops & (j.t_stop <= j.t_contact)
    counts = np.zeros(j.cc.size, dtype=np.int64)
    if j.sheet.size:
        np.add.at(counts, j.ic[in_time], 1)
    series = ConstraintSeries(
        'one_per_cycle',
        'sheets',
        j.cc.astype(np.int64),
        0.0 - np.abs(counts - 1).astype(float),
        'exactly one signature at the stops at the knife contact: -|count - 1|',
        t=j.tc.copy(),
    )
    return series, counts


def _rebound(ev: np.ndarray, j: _Judged, scene: Scene, causal: bool) -> ConstraintSeries:
    """``rebound`` (with ``stop_bounce``): the first rebound off the stops within the fold tolerance, m."""
    tol = float(scene.effect_params('stop_bounce').tolerance)
    bounce = _rows(ev, 'bounce')
    if causal and bounce.size:  # only the rebounds before the sheet's knife contact
        t_cut, known = _lookup(j.sheet, j.t_contact, bounce['sheet'])
        bounce = bounce[known & (bounce['t'] <= t_cut)]
    rb, _ = _lookup(bounce['sheet'], bounce['value'], j.sheet, reduce='max')
    c, m = _per_cycle_min(j.cyc[j.at_stops], tol - rb[j.at_stops])
    return ConstraintSeries(
        'rebound',
        'm',
        c,
        m,
        'first rebound off the stops within the fold tolerance: tolerance - rebound',
        t=_contact_time(j.cc, j.tc, c),
    )


def _release_at_min_speed(
    ev: np.ndarray, timing: CycleTiming, scene: Scene, drive: Drive | None, plan: DeliveryPlan | None
) -> ConstraintSeries:
    """``release_at_min_speed`` (with a delivery): each release where the carriage is slowest, dimensionless."""
    if plan is None:
        plan = delivery_plan(scene, timing)
    assert plan is not None, 'delivery_plan is None only for a scene without a delivery'
    rel = _rows(ev, 'released_on_pile')
    if rel.size:
        travel = plan.schedule.travel(_theta(drive, rel['t']), rel['cycle'])
        u = plan.path.position(travel - plan.chain.L_transfer)
        kv = evaluate_stroke(plan.params, u, return_section='geometric').K_v
        c, m = _per_cycle_min(rel['cycle'], RELEASE_KV_TOL - (kv - plan.K_v_rel))
        uc, first_rel = np.unique(rel['cycle'], return_index=True)
        t_rel = rel['t'][first_rel][np.searchsorted(uc, c)]
    else:
        c, m, t_rel = np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0)
    return ConstraintSeries(
        'release_at_min_speed',
        '1',
        c,
        m,
        'sheet released where the carriage is slowest: tol - (K_v(u) - min K_v)',
        t=t_rel,
    )


def chute_speed_series(
    scene: Scene, leaf: np.ndarray, t_exit: np.ndarray, speed: np.ndarray
) -> ConstraintSeries | None:
    """The layup's ``chute_speed`` constraint per exited leaf, or None without ``chute_belts``.

    Margin ``speed - v_min`` (:func:`folder_line.core.effects.chute_belts.speed_margin`),
    with ``leaf_damage`` the smaller of it and ``nextafter(v_damage, 0) - speed``
    (:func:`folder_line.core.effects.leaf_damage.upper_margin`): the absolute exit
    speed must lie in ``[v_min, v_damage)``.

    Parameters
    ----------
    scene : Scene
        For ``chute_belts`` (``v_min``) and ``leaf_damage`` (``v_damage``).
    leaf, t_exit, speed : ndarray, shape (N,)
        Leaf ids, exit times (s, the decision times) and absolute exit speeds (m/s).

    Returns
    -------
    ConstraintSeries or None
        ``cycle`` = the leaf id, in the given order.
    """
    if not scene.has('chute_belts'):
        return None
    bp = scene.effect_params('chute_belts')
    speed = np.asarray(speed, dtype=float)
    upper = None
    desc = f'absolute exit speed >= v_min = {bp.v_min:g} m/s'
    if scene.has('leaf_damage'):
        dp = scene.effect_params('leaf_damage')
        upper = leaf_damage.upper_margin(dp, speed)
        desc += f' and < v_damage = {dp.v_damage:g} m/s'
    return ConstraintSeries(
        'chute_speed',
        'm/s',
        np.asarray(leaf, dtype=np.int64),
        chute_belts.speed_margin(bp, speed, upper),
        desc + ' (per leaf)',
        t=np.asarray(t_exit, dtype=float),
    )


def evaluate_layup_constraints(events: np.ndarray, scene: Scene) -> list[ConstraintSeries]:
    """The layup's constraints from any event table: ``chute_speed`` from the ``leaf_exit`` rows.

    A ``leaf_exit`` row carries the leaf's absolute exit speed (``value``), so the
    margin of each exited leaf is decided at its exit (the row's time), in the
    table's row order. Empty list without ``chute_belts``.
    """
    ex = _rows(np.asarray(events), 'leaf_exit')
    series = chute_speed_series(scene, ex['sheet'], ex['t'], ex['value'])
    return [] if series is None else [series]
