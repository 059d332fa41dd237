"""The construction steps of :class:`~folder_line.core.line.folder_sim.FolderLine`, one function each.

:func:`setup` reads the scene's folder on one drive; :func:`hand_overs` draws the
hand-over slots and the signatures fed, :func:`belt_phase` and :func:`feed` carry them
to the stops, :func:`knife_cycles` and :func:`fates` fold, jam and release them,
:func:`bounces`, :func:`fault_events` and :func:`sheet_events` make the event tables and
:func:`summary` the figures (:class:`~folder_line.core.line.folder_figures.FolderFigures`). The
timeline they follow is in :mod:`folder_line.core.line.folder_sim`'s docstring.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, SupportsFloat

import numpy as np

from folder_line.core.effects import (
    arrival_jitter,
    chain_friction,
    faults,
    feed_slip,
    length_scatter,
    property_scatter,
    stop_bounce,
)
from folder_line.core.line.delivery_plan import DeliveryPlan, delivery_plan
from folder_line.core.line.folder_figures import (
    BounceFigures,
    CycleTimes,
    DeliveryFigures,
    FaultCounts,
    FolderFigures,
    ReleaseFigures,
    Slack,
    SlipFigures,
)
from folder_line.core.mechanisms.belt import BeltPhase, belt_intervals
from folder_line.core.mechanisms.cyclogram import CycleTiming, cycle_timing
from folder_line.core.mechanisms.delivery import stroke_minimum
from folder_line.core.mechanisms.drive import Drive
from folder_line.core.numerics.rng import stream
from folder_line.core.types.events import event_kind, make_events
from folder_line.errors import ParameterError

if TYPE_CHECKING:
    from folder_line.core.line.scene import Scene

__all__ = [
    'Fates',
    'KnifeCycles',
    'Setup',
    'Sheets',
    'Stream',
    'belt_phase',
    'bounces',
    'fates',
    'fault_events',
    'feed',
    'friction',
    'hand_overs',
    'knife_cycles',
    'restitution',
    'setup',
    'sheet_events',
    'summary',
    'travel',
]

#: smallest speed factor used to freeze the slip speeds at a hand-over (a drive at a standstill)
_LAMBDA_FLOOR = 1e-9


# --------------------------------------------------------------------------- helpers


def _indices(first: float, step: float, last: float) -> np.ndarray:
    """k = 0, 1, ... with ``k step + first <= last`` (empty if first > last)."""
    if first > last:
        return np.zeros(0, dtype=np.int64)
    n = math.floor((last - first) / step) + 2
    k = np.arange(n, dtype=np.int64)
    return k[k * step + first <= last]


def _json_float(x: SupportsFloat) -> float:
    x = float(x)
    if not math.isfinite(x):  # never expected; keep the summary JSON-clean
        raise ValueError(f'non-finite summary figure {x!r}')
    return x


@dataclass(frozen=True, eq=False)
class Sheets:
    """Per-signature arrays (only signatures handed over by the end)."""

    sheet: np.ndarray  # ids
    cycle: np.ndarray  # handover cycle
    t_h: np.ndarray
    arrived: np.ndarray  # at the stops by the end
    t_a: np.ndarray  # valid where arrived
    v_imp: np.ndarray  # valid where arrived


@dataclass(frozen=True, eq=False)
class Setup:
    """What every step of :class:`FolderLine`'s construction reads: the scene's folder on one drive."""

    scene: Scene
    drive: Drive
    duration: float
    theta_end: float  # Θ at ``duration``, nominal s
    timing: CycleTiming
    V_tr: float
    phase: float  # ``sheets.phase``, nominal s
    plan: DeliveryPlan | None
    slip: feed_slip.Params | None  # the listed effects' parameters, or None
    bounce: stop_bounce.Params | None
    faults: faults.Params | None
    jitter: arrival_jitter.Params | None
    length: length_scatter.Params | None
    scatter: property_scatter.Params | None


@dataclass(frozen=True, eq=False)
class Stream:
    """The hand-over slots and the signatures fed by the end (:func:`hand_overs`)."""

    slots: np.ndarray  # hand-over slot (cycle) indices with a nominal hand-over by the end
    theta_nom: np.ndarray  # nominal hand-over phase of each slot
    sheet_faults: faults.SheetFaults | None  # of the slots, or None without ``faults``
    slowdowns: faults.Slowdowns | None  # faults' belt slow-downs, or None
    missing: np.ndarray  # per slot
    double: np.ndarray
    delay: np.ndarray  # per slot, nominal s
    cycle: np.ndarray  # per signature fed: its slot
    theta_h: np.ndarray  # per signature fed: hand-over phase
    ids: np.ndarray  # per signature fed: sheet id
    t_h: np.ndarray  # per signature fed: hand-over time, s


@dataclass(frozen=True, eq=False)
class KnifeCycles:
    """Knife contacts and exits by the end: cycle indices and times (:func:`knife_cycles`)."""

    k_c: np.ndarray
    t_c: np.ndarray
    k_x: np.ndarray
    t_x: np.ndarray


@dataclass(frozen=True, eq=False)
class Fates:
    """What became of each signature fed (:func:`fates`)."""

    folded: np.ndarray  # at the stops by its cycle's knife contact
    jammed: np.ndarray  # its cycle's knife came first
    released: np.ndarray  # released on the pile by the end (with a delivery)
    t_rel: np.ndarray  # valid where released
    counted: np.ndarray  # released (with a delivery), else folded


def setup(scene: Scene, drive: Drive, duration: float) -> Setup:
    timing = cycle_timing(scene.machine('cyclogram'), scene.machine('knife'))
    duration = float(duration)
    return Setup(
        scene=scene,
        drive=drive,
        duration=duration,
        theta_end=float(np.asarray(drive.theta(duration))) if math.isfinite(duration) else math.inf,
        timing=timing,
        V_tr=float(scene.machine('feed_transporter').V_tr),
        phase=float(scene.sheets.phase),
        plan=delivery_plan(scene, timing),
        slip=scene.effect_params('feed_slip') if scene.has('feed_slip') else None,
        bounce=scene.effect_params('stop_bounce') if scene.has('stop_bounce') else None,
        faults=scene.effect_params('faults') if scene.has('faults') else None,
        jitter=_jitter(scene, timing.L_feed),
        length=_length(scene, timing.L_feed),
        scatter=_scatter(scene),
    )


def _jitter(scene: Scene, L_feed: float) -> arrival_jitter.Params | None:
    if not scene.has('arrival_jitter'):
        return None
    p: arrival_jitter.Params = scene.effect_params('arrival_jitter')
    arrival_jitter.check_travel(p, L_feed)
    return p


def _length(scene: Scene, L_feed: float) -> length_scatter.Params | None:
    if not scene.has('length_scatter'):
        return None
    p: length_scatter.Params = scene.effect_params('length_scatter')
    # with arrival_jitter the shortest travel is L_feed - its largest offset - the largest excess
    back = (
        arrival_jitter.half_width(scene.effect_params('arrival_jitter')) * 1e-3 if scene.has('arrival_jitter') else 0.0
    )
    length_scatter.check_travel(p, L_feed - back)
    return p


def _scatter(scene: Scene) -> property_scatter.Params | None:
    if not scene.has('property_scatter'):
        return None
    p: property_scatter.Params = scene.effect_params('property_scatter')
    property_scatter.check_listed(p, scene.effects)
    return p


def travel(s: Setup, n: int) -> float | np.ndarray:
    """Feed travel of signatures 0 .. n-1 to the stops, m: ``L_feed + δ_k - ΔL_k``
    (``arrival_jitter``, ``length_scatter``; the scalar ``L_feed`` without either)."""
    L = s.timing.L_feed
    if s.jitter is None and s.length is None:
        return L
    out = np.full(n, L)
    if s.jitter is not None:
        out = out + arrival_jitter.draw_offsets(s.jitter, s.scene.seed, n)
    if s.length is not None:
        out = out - length_scatter.draw_excess(s.length, s.scene.seed, n)
    return out


def friction(s: Setup, n: int) -> np.ndarray | None:
    """``feed_slip``'s mu of signatures 0 .. n-1 with ``property_scatter`` (None: the nominal mu for all)."""
    if s.scatter is None or s.slip is None or s.scatter.mu_sigma == 0.0:
        return None
    return property_scatter.friction(s.scatter, s.slip.mu, s.scene.seed, n)


def restitution(s: Setup, n: int) -> np.ndarray | None:
    """``stop_bounce``'s e of signatures 0 .. n-1 with ``property_scatter`` (None: the nominal e for all)."""
    if s.scatter is None or s.bounce is None or s.scatter.e_sigma == 0.0:
        return None
    return property_scatter.restitution(s.scatter, s.bounce.e, s.scene.seed, n)


def hand_overs(s: Setup) -> Stream:
    """Hand-over slots, the faults drawn for them and the signatures fed by the end."""
    T, t_out = s.timing.T, s.timing.knife.t_out
    slots = _indices(t_out + s.phase, T, s.theta_end)
    theta_nom = slots * T + (t_out + s.phase)
    sf = slowdowns = None
    if s.faults is not None:
        sf = faults.draw_sheet_faults(s.faults, slots.size, stream(s.scene.seed, 'folder.faults'))
        slowdowns = faults.draw_slowdowns(s.faults, s.duration, T, stream(s.scene.seed, 'folder.slowdowns'))
        missing, double, delay = sf.missing, sf.double, np.asarray(sf.delay, dtype=float)
    else:
        missing = np.zeros(slots.size, dtype=bool)
        double = np.zeros(slots.size, dtype=bool)
        delay = np.zeros(slots.size)
    mult = np.where(missing, 0, np.where(double, 2, 1))
    # a slot before the line starts (a knife whose exit phase t_out + phase is negative) feeds nothing:
    # the line starts at Θ = 0, and its first cycle then runs empty (one_per_cycle flags it)
    mult = np.where(theta_nom + delay < 0.0, 0, mult)
    cyc_all = np.repeat(slots, mult)
    theta_h_all = np.repeat(theta_nom + delay, mult)
    fed = theta_h_all <= s.theta_end
    cyc = cyc_all[fed]
    theta_h = theta_h_all[fed]
    return Stream(
        slots=slots,
        theta_nom=theta_nom,
        sheet_faults=sf,
        slowdowns=slowdowns,
        missing=missing,
        double=double,
        delay=delay,
        cycle=cyc,
        theta_h=theta_h,
        ids=np.arange(cyc.size, dtype=np.int64),
        t_h=np.asarray(s.drive.time_of(theta_h), dtype=float) if cyc.size else np.zeros(0),
    )


def belt_phase(s: Setup, st: Stream, steps: list[tuple[float, float]] | None = None) -> BeltPhase:
    """The feed belt's travel in master phase, with the faults' slow-downs and the operator's speed
    ``steps`` (``(t, factor)`` from ``t`` on, :func:`folder_line.core.line.tuning.belt_steps`)."""
    return BeltPhase(s.drive, s.duration, *belt_intervals(st.slowdowns, steps or []))


def feed(
    drive: Drive,
    duration: float,
    belt: BeltPhase,
    st: Stream,
    V_d: float,
    V_tr: float,
    L: float | np.ndarray,
    slip: feed_slip.Params | None,
    mu: np.ndarray | None = None,
) -> Sheets:
    """Arrival at the stops of every signature handed over (exact, vectorised).

    ``L`` is the travel to the stops, m: one for all, or one per signature (:func:`travel`);
    ``mu`` a friction coefficient per signature with ``feed_slip`` (:func:`friction`), or None.
    """
    ids, cyc, theta_h, t_h = st.ids, st.cycle, st.theta_h, st.t_h
    n = ids.size
    arrived = np.zeros(n, dtype=bool)
    t_a = np.zeros(n)
    v_imp = np.zeros(n)
    if n == 0:
        return Sheets(ids, cyc, t_h, arrived, t_a, v_imp)
    b_end = float(belt.at(np.asarray(duration)))
    if slip is None:
        b_h = theta_h if belt.plain else belt.at(t_h, theta_h)
        b_a = b_h + L / V_tr
        ride = b_a <= b_end
        idx = np.flatnonzero(ride)
    else:
        lam = np.maximum(np.asarray(drive.rate(t_h), dtype=float), _LAMBDA_FLOOR)
        f_h = belt.factor(t_h)
        sa = feed_slip.arrival(slip, lam * V_d, lam * f_h * V_tr, L, mu)
        # slides all the way to the stops: closed form in line time
        slide = ~sa.reached
        t_slide = t_h + sa.t
        ok = slide & (t_slide <= duration)
        arrived[ok] = True
        t_a[ok] = t_slide[ok]
        v_imp[ok] = sa.v_impact[ok]
        # reaches belt speed at t_m, then rides the belt for L - d1
        t_m = t_h + sa.t_slip
        cand = np.flatnonzero(sa.reached & (t_m <= duration))
        b_a = np.zeros(n)
        L_c = L[cand] if isinstance(L, np.ndarray) else L
        b_a[cand] = belt.at(t_m[cand]) + (L_c - sa.d_slip[cand]) / V_tr
        idx = cand[b_a[cand] <= b_end]
    if idx.size:
        th = belt.theta_of(b_a[idx])
        t = np.asarray(drive.time_of(th), dtype=float)
        keep = t <= duration  # b_a <= B(duration): drops only a rounding-level overshoot
        idx, t = idx[keep], t[keep]
        arrived[idx] = True
        t_a[idx] = t
        v_imp[idx] = V_tr * np.asarray(drive.rate(t), dtype=float) * belt.factor(t)
    return Sheets(ids, cyc, t_h, arrived, t_a, v_imp)


def fault_events(s: Setup, st: Stream) -> list[np.ndarray]:
    """The ``fault_*`` and ``belt_slowdown_*`` events (none without ``faults``)."""
    if s.faults is None or st.sheet_faults is None or st.slowdowns is None:  # all three drawn with ``faults``
        return []
    slots, cyc, ids = st.slots, st.cycle, st.ids
    first_id = np.full(slots.size, -1, dtype=np.int64)
    fed_slot = np.zeros(slots.size, dtype=bool)
    fed_slot[cyc] = True
    # id of the first signature of each slot (ids are in slot order)
    starts = np.searchsorted(cyc, slots, side='left')
    first_id[fed_slot] = ids[starts[fed_slot]]
    t_nom = np.asarray(s.drive.time_of(st.theta_nom), dtype=float) if slots.size else np.zeros(0)
    table = faults.fault_events(st.sheet_faults, t_nom, first_id, slots, st.slowdowns, s.duration)
    return [table[table['t'] >= 0.0]]  # a slot before the line starts has no fault either


def knife_cycles(s: Setup) -> KnifeCycles:
    """Knife contact of cycle k at Θ = (k+1)T + t_in, exit at (k+1)T + t_out (those by the end)."""
    T, t_in, t_out, drive = s.timing.T, s.timing.knife.t_in, s.timing.knife.t_out, s.drive
    k_c = _indices(T + t_in, T, s.theta_end)
    t_c = np.asarray(drive.time_of(k_c * T + (T + t_in)), dtype=float) if k_c.size else np.zeros(0)
    k_x = _indices(T + t_out, T, s.theta_end)
    t_x = np.asarray(drive.time_of(k_x * T + (T + t_out)), dtype=float) if k_x.size else np.zeros(0)
    return KnifeCycles(k_c, t_c, k_x, t_x)


def fates(s: Setup, sheets: Sheets, knife: KnifeCycles) -> Fates:
    """Folded or jammed at the knife; released on the pile (with a delivery); counted."""
    n = sheets.sheet.size
    # folded: at the stops by its cycle's knife contact (cycle k's contact is t_c[k])
    has_contact = sheets.cycle < knife.k_c.size
    t_contact = np.zeros(n)
    t_contact[has_contact] = knife.t_c[sheets.cycle[has_contact]]
    folded = has_contact & sheets.arrived & (sheets.t_a <= t_contact)
    jammed = has_contact & ~folded
    released = np.zeros(n, dtype=bool)
    t_rel = np.zeros(n)
    if s.plan is None:
        return Fates(folded, jammed, released, t_rel, folded)
    theta_rel = s.plan.release_phase(sheets.cycle)
    released = folded & (theta_rel <= s.theta_end)
    if released.any():
        t_rel[released] = np.asarray(s.drive.time_of(theta_rel[released]), dtype=float)
    released &= t_rel <= s.duration
    return Fates(folded, jammed, released, t_rel, released)


def bounces(s: Setup, sheets: Sheets) -> tuple[list[np.ndarray], BounceFigures | None]:
    """``bounce`` and ``settled`` events and the summary's ``stop_bounce`` figures (none without it)."""
    if s.bounce is None:
        return [], None
    ids = sheets.sheet
    arr = np.flatnonzero(sheets.arrived)
    e = restitution(s, ids.size)
    sched = stop_bounce.bounce_schedule(s.bounce, sheets.v_imp[arr], e=None if e is None else e[arr])
    t_settled = sheets.t_a.copy()
    t_settled[arr] = sheets.t_a[arr] + sched.settle
    tb = sheets.t_a[arr][sched.index] + sched.dt
    keep = tb <= s.duration
    tables = [
        make_events(
            'bounce',
            tb[keep],
            sheet=ids[arr][sched.index][keep],
            cycle=sheets.cycle[arr][sched.index][keep],
            value=sched.rebound[keep],
        )
    ]
    sk = arr[t_settled[arr] <= s.duration]
    tables.append(make_events('settled', t_settled[sk], sheet=ids[sk], cycle=sheets.cycle[sk]))
    info = _bounce_info(
        s.bounce,
        float(s.V_tr),
        int(sched.count.max()) if sched.count.size else 0,
        _json_float(sched.settle.max()) if sched.settle.size else 0.0,
    )
    return tables, info


def sheet_events(s: Setup, sheets: Sheets, knife: KnifeCycles, fates: Fates) -> list[np.ndarray]:
    """``sheet_handover``, ``at_stops``, ``knife_contact``, ``knife_exit`` and ``released_on_pile``."""
    ids, cyc, arrived = sheets.sheet, sheets.cycle, sheets.arrived
    tables = [
        make_events('sheet_handover', sheets.t_h, sheet=ids, cycle=cyc),
        make_events(
            'at_stops', sheets.t_a[arrived], sheet=ids[arrived], cycle=cyc[arrived], value=sheets.v_imp[arrived]
        ),
        make_events('knife_contact', knife.t_c, cycle=knife.k_c),
        make_events('knife_exit', knife.t_x, cycle=knife.k_x),
    ]
    if s.plan is not None:
        rel = fates.released
        tables.append(make_events('released_on_pile', fates.t_rel[rel], sheet=ids[rel], cycle=cyc[rel]))
    return tables


def summary(
    s: Setup,
    st: Stream,
    sheets: Sheets,
    knife: KnifeCycles,
    fates: Fates,
    events: np.ndarray,
    bounce_info: BounceFigures | None,
) -> FolderFigures:
    """The folder's figures (see the ``simulate`` verb of the CLI): :func:`static_summary` with the run's counts."""
    timing, plan = s.timing, s.plan
    ids = sheets.sheet
    n_fed = int(ids.size)
    n_counted = int(np.count_nonzero(fates.counted))
    # in the machine, from the event table: handed over, but no pile release (or not folded) by the end
    gone = events['sheet'][events['kind'] == event_kind('released_on_pile')] if plan is not None else ids[fates.folded]
    handed = events['sheet'][events['kind'] == event_kind('sheet_handover')]
    in_machine = int(np.count_nonzero(~np.isin(handed, gone)))
    fault_counts = None
    if s.faults is not None:
        fault_counts = FaultCounts(
            missing=int(np.count_nonzero(st.missing)),
            double=int(np.count_nonzero(st.double)),
            late=int(np.count_nonzero(st.delay > 0.0)),
            slowdowns=int(np.asarray(st.slowdowns.t_start).size) if st.slowdowns is not None else 0,
        )
    return replace(
        static_summary(s),
        cycles=int(knife.k_c.size),
        cycles_started=int(_indices(timing.knife.t_out, timing.T, s.theta_end).size),
        sheets_fed=n_fed,
        sheets_at_stops=int(np.count_nonzero(sheets.arrived)),
        sheets_folded=int(np.count_nonzero(fates.folded)),
        sheets_jammed=int(np.count_nonzero(fates.jammed)),
        sheets_counted=n_counted,
        sheets_in_machine=in_machine,
        sheets_balance_ok=bool(handed.size == n_fed and n_fed == n_counted + in_machine),
        stop_bounce=bounce_info,
        faults=fault_counts,
    )


def static_summary(s: Setup) -> FolderFigures:
    """The folder's figures that do not depend on the run (the counts left at 0 for the caller)."""
    timing, V_tr, plan = s.timing, s.V_tr, s.plan
    V_d = timing.V_d
    release = None
    if plan is not None:
        release = ReleaseFigures(
            u_rel=_json_float(plan.u_rel),
            K_v=_json_float(plan.K_v_rel),
            chain_travel=_json_float(plan.travel_rel),
            v_A=_json_float(plan.v_A),
            carriage_speed=_json_float(plan.K_v_rel * plan.v_A),
        )
    return FolderFigures(
        cycles=0,
        cycles_started=0,
        sheets_fed=0,
        sheets_at_stops=0,
        sheets_folded=0,
        sheets_jammed=0,
        sheets_counted=0,
        sheets_in_machine=0,
        sheets_balance_ok=True,
        V_d=_json_float(V_d),
        V_tr=_json_float(V_tr),
        v_tr_over_v_d=_json_float(V_tr / V_d),
        V_tr_min=_json_float(timing.V_tr_min),
        V_tr_min_over_V_d=_json_float(timing.ratio_min),
        # the knife's table-occupation window: its duration and its crank angles
        knife_window_s=_json_float(timing.t_knife),
        knife_window_deg=_json_float(math.degrees(timing.knife.phi_out - timing.knife.phi_in)),
        knife_in_deg=_json_float(math.degrees(timing.knife.phi_in)),
        knife_out_deg=_json_float(math.degrees(timing.knife.phi_out)),
        timing=CycleTimes(
            T=_json_float(timing.T),
            t_in=_json_float(timing.knife.t_in),
            t_out=_json_float(timing.knife.t_out),
            t_knife=_json_float(timing.t_knife),
            t_dwell=_json_float(timing.t_dwell),
            t_fw=_json_float(timing.t_fw),
            t_allowed=_json_float(timing.t_allowed),
        ),
        slack=_slack(s),
        feed_slip=None if s.slip is None else _slip_info(s, s.slip, _slip_cost(s, s.slip)),
        stop_bounce=None if s.bounce is None else _bounce_info(s.bounce, float(V_tr)),
        release=release,
        delivery=_delivery_info(s, plan) if plan is not None and s.scene.has('chain_friction') else None,
    )


def _slip_cost(s: Setup, slip: feed_slip.Params) -> float:
    """The feed time the slip costs at nominal speed, s."""
    return float(feed_slip.slip_cost(slip, s.timing.V_d, s.V_tr, s.timing.L_feed))


def _slack(s: Setup) -> Slack:
    """What each part of the cycle leaves over at nominal speed, no faults, s."""
    timing, phase = s.timing, s.phase
    t_feed = timing.L_feed / s.V_tr
    ideal = _json_float(timing.t_allowed - phase - t_feed)
    cost = None
    if s.slip is not None:
        cost = _slip_cost(s, s.slip)
        t_feed += cost
    rest = (timing.T - timing.t_knife) - phase - t_feed
    settle = None if s.bounce is None else _json_float(stop_bounce.settle_time(s.bounce, float(s.V_tr)))
    return Slack(
        feed_margin_ideal=ideal,
        feed_margin=_json_float(timing.t_allowed - phase - t_feed),
        rest_at_stops=_json_float(rest),
        slip_cost=None if cost is None else _json_float(cost),
        settle_time=settle,
        settled_margin=None if settle is None else _json_float(rest - settle),
    )


def _bounce_info(bounce: stop_bounce.Params, nominal: float, count: int = 0, settle: float = 0.0) -> BounceFigures:
    """``stop_bounce``'s figures at the nominal belt speed ``nominal`` (m/s), with the run's largest."""
    return BounceFigures(
        bounces_at_V_tr=int(stop_bounce.bounce_count(bounce, nominal)),
        settle_time_at_V_tr=_json_float(stop_bounce.settle_time(bounce, nominal)),
        first_rebound_at_V_tr=_json_float(stop_bounce.first_rebound(bounce, nominal)),
        bounces_max=count,
        settle_time_max=settle,
    )


def _delivery_info(s: Setup, plan: DeliveryPlan) -> DeliveryFigures:
    """The summary's ``delivery`` figures with ``chain_friction``: the stroke's efficiency minimum and
    where it is, and the sprocket torque over a cycle.

    ``eta_min_u`` is the stroke position u in [0, 2] (0..1 the deceleration section, 1..2 the
    acceleration section; :mod:`folder_line.core.mechanisms.delivery`), ``eta_min_travel_m`` the chain
    travel from the start of the stroke to it, m. The torques are the sprocket's M_1 summed over the
    carriages on the stroke, peak and mean over a cycle, N m
    (:class:`folder_line.core.effects.chain_friction.MasterLoad` with a unit gear ratio).
    """
    cf = s.scene.effect_params('chain_friction')
    u, eta = stroke_minimum(plan.params, 'eta', return_section=cf.return_section)
    load = chain_friction.master_load(s.scene, 1.0)  # omega_nom 1 rad/s: torque x ratio, divided back (cached)
    torque = (load.peak / load.ratio, load.mean / load.ratio)
    return DeliveryFigures(
        eta_min=_json_float(eta),
        eta_min_u=_json_float(u),
        eta_min_travel_m=_json_float(float(plan.path.arc(u))),
        sprocket_torque_peak_Nm=_json_float(torque[0]),
        sprocket_torque_mean_Nm=_json_float(torque[1]),
    )


def _slip_info(s: Setup, slip: feed_slip.Params, cost: float) -> SlipFigures:
    """The summary's ``feed_slip`` figures (``slip``: the scene's, ``s.slip``)."""
    timing, L = s.timing, s.timing.L_feed
    try:
        v_min: float | None = _json_float(feed_slip.min_belt_speed(slip, timing.V_d, L, timing.t_allowed))
    except ParameterError:
        v_min = None
    return SlipFigures(
        accel=_json_float(slip.accel),
        slip_cost=_json_float(cost),
        feed_margin_with_slip=_json_float(timing.t_allowed - L / s.V_tr - cost),
        V_tr_min_with_slip=v_min,
    )
