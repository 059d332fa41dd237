"""F with D: the folder and its delivery over many cycles — exact events, samples, constraints.

:class:`FolderLine` (built once per scene, drive and duration; sampled at any times)
and its thin wrapper :func:`simulate_folder` turn a scene's folder (``knife``, ``cyclogram``,
``feed_transporter``) and, if present, its delivery (``delivery``,
``delivery_chain``) into the line's events, joint samples, per-cycle constraint
margins (:mod:`folder_line.core.line.constraints`) and summary figures. Every event time
is a closed form in the master phase Θ mapped through ``drive.time_of`` (or, with
``feed_slip``, a closed form in line time); nothing is read off the sample grid. All
cycles are handled at once with numpy (no per-cycle Python loop).

Timeline (one cycle, master phase Θ in nominal seconds)
-------------------------------------------------------
The knife crank turns at ``φ_k = ω_k Θ`` (``φ_k = 0`` at Θ = 0, the window is
centred on it for ``e = 0``), period ``T = 2π/ω_k``; the knife occupies the table
for ``Θ mod T`` in ``[t_in, t_out]`` (``t_in < 0 < t_out``,
:func:`folder_line.core.mechanisms.knife.window`). **Cycle k starts at the knife exit**
``kT + t_out`` (the feed window opens) and ends at the next exit::

    Θ ─► kT + t_out                                     (k+1)T + t_in    (k+1)T + t_out
             │                                                 │                │
    knife ███│                                                 │████████████████│
             │◄─────────── feed window t_fw ───────►│◄ t_dwell ►│◄── t_knife ───►│
             │◄────── t_allowed ───────►│◄ reserve ►│           │                │
             ▲          ▲     ▲     ▲   ▲                       ▲                ▲
        handover  at_stops bounce settled deadline         knife_contact     knife_exit
        (+phase)                                          (sheet k folded)  (carriage k takes it;
                                                                              cycle k+1 starts)

* ``sheet_handover`` of sheet k at ``Θ_h = kT + t_out + phase`` (``sheets.phase``;
  a late fault adds its delay, in nominal s); a slot with ``Θ_h < 0`` (before the
  line starts) feeds nothing;
* ``at_stops`` after ``L_feed`` of feed-belt travel: without ``feed_slip`` the
  signature rides the belt from the hand-over, ``ΔΘ = L_feed / V_tr`` (the belt
  moves ``V_tr dΘ``; a belt slow-down of factor f over ``[t_s, t_e)`` makes it
  ``f V_tr dΘ`` there, integrated exactly by :class:`folder_line.core.mechanisms.belt.BeltPhase`);
  with ``feed_slip`` see :mod:`folder_line.core.effects.feed_slip`. Value: the impact
  speed;
* ``bounce`` (value: rebound distance) and ``settled`` with ``stop_bounce``
  (:mod:`folder_line.core.effects.stop_bounce`);
* ``knife_contact`` of cycle k at ``(k+1)T + t_in``, ``knife_exit`` at
  ``(k+1)T + t_out`` (one each per cycle, ``sheet = -1``). The signature(s) of
  cycle k that are at the stops by the knife contact are folded; one that arrives
  later is *jammed* (it stays in the machine; the constraints flag the cycle);
* with a delivery, carriage k takes the folded signature k at the knife exit,
  ``Θ_pick(k) = (k+1)T + t_out`` (the line's one numbering, :mod:`folder_line.core.mechanisms.chain`),
  and the chain (speed ``v_A = pitch / T`` per unit Θ) carries it
  ``L_transfer + s(u_rel)`` to the release point, ``released_on_pile`` at
  ``Θ = Θ_pick(k) + (L_transfer + s(u_rel)) / v_A``. ``u_rel`` is where the
  carriage is slowest (``delivery.stroke_minimum(..., 'K_v', return_section=
  'geometric')``), ``s(u)`` the chain's arc length along the curved guide
  (:class:`folder_line.core.mechanisms.chain.ChainPath`).

A drive that the supervisor holds (:mod:`folder_line.core.mechanisms.drive`, "Supervisor
commands") stops Θ: the hand-over slots, knife and chain events are at fixed Θ, so
the sheet stream stops with the line and every signature stays where it is until
Θ moves again. What runs in line time goes on regardless: the bounce off the stops
and the settling (``stop_bounce``), belt slow-downs of ``faults``. With ``feed_slip``
the slip phase freezes the speeds at the hand-over (``feed_slip`` docstring), an
approximation while λ ramps.

Only events at ``t <= duration`` are returned; sheets handed over but not yet
counted are *in the machine* (``sheets_fed = sheets_counted + sheets_in_machine``,
checked in the summary). Sheets are numbered 0, 1, ... in cycle order over the
signatures actually fed (a double fault feeds two with consecutive ids; a missing
one takes no id).

Joint samples per unit (on ``t_samples``; λ = ``drive.rate``, f the belt slow-down factor)
----------------------------------------------------------------------------------------
* ``drive``: ``knife_crank`` (φ_k wrapped to [0, 2π), ω_k λ),
  ``knife`` (s(φ_k) m, v(φ_k) λ m/s);
* ``belts``: ``first_transporter`` (V_d Θ m, V_d λ m/s);
* ``feed`` (the feed transporter): ``feed_belt`` (its travel, V_tr λ f), and with a delivery
  ``chain`` (v_A Θ, v_A λ) and ``carriage``: the carriage on the stroke (the one
  that entered it last), its displacement from the stroke start
  ``u x_max + l (1 - cos α(u))`` (``= u x_max`` at both ends of the stroke; the
  rod's tilt makes the carriage lag or lead the pin: this keeps position and speed
  consistent) and speed ``K_v(u) v_A λ``; 0 and 0 while no carriage is on the
  stroke.
* efforts only with ``chain_friction``: the sprocket torque on ``chain`` (N m,
  :func:`folder_line.core.effects.chain_friction.sprocket_torque`), 0 on every
  other joint; without it ``effort`` is None.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, SupportsFloat

import numpy as np
import numpy.typing as npt

from folder_line.core.effects import chain_friction, faults, feed_slip, stop_bounce
from folder_line.core.line.constraints import evaluate_folder_constraints
from folder_line.core.line.delivery_plan import DeliveryPlan, delivery_plan
from folder_line.core.line.events import (
    JointSamples,
    LinePart,
    SubResult,
    event_kind,
    make_events,
    merge_events,
    stack_samples,
)
from folder_line.core.mechanisms import delivery as dlv
from folder_line.core.mechanisms import knife as knf
from folder_line.core.mechanisms.belt import BeltPhase
from folder_line.core.mechanisms.cyclogram import CycleTiming, cycle_timing
from folder_line.core.mechanisms.drive import Drive
from folder_line.core.numerics.rng import stream
from folder_line.errors import ParameterError

if TYPE_CHECKING:
    from folder_line.core.line.scene import Scene

__all__ = [
    'DeliveryPlan',  # re-exported: its home is folder_line.core.line.delivery_plan
    'FolderLine',
    'delivery_plan',
    'simulate_folder',
]

TWO_PI = 2.0 * math.pi
#: smallest speed factor used to freeze the slip speeds at a hand-over (a drive at a standstill)
_LAMBDA_FLOOR = 1e-9


# --------------------------------------------------------------------------- helpers


def _indices(first: float, step: float, last: float) -> np.ndarray:
    """k = 0, 1, ... with ``k step + first <= last`` (empty if first > last)."""
    if first > last:
        return np.zeros(0, dtype=np.int64)
    n = int(math.floor((last - first) / step)) + 2
    k = np.arange(n, dtype=np.int64)
    return k[k * step + first <= last]


def _json_float(x: SupportsFloat) -> float:
    x = float(x)
    if not math.isfinite(x):  # never expected; keep the summary JSON-clean
        raise ValueError(f'non-finite summary figure {x!r}')
    return x


@dataclass(frozen=True, eq=False)
class _Sheets:
    """Per-signature arrays (only signatures handed over by the end)."""

    sheet: np.ndarray  # ids
    cycle: np.ndarray  # handover cycle
    t_h: np.ndarray
    arrived: np.ndarray  # at the stops by the end
    t_a: np.ndarray  # valid where arrived
    v_imp: np.ndarray  # valid where arrived


# --------------------------------------------------------------------------- steps of FolderLine


@dataclass(frozen=True, eq=False)
class _Setup:
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


@dataclass(frozen=True, eq=False)
class _Stream:
    """The hand-over slots and the signatures fed by the end (:func:`_hand_overs`)."""

    slots: np.ndarray  # hand-over slot (cycle) indices with a nominal hand-over by the end
    theta_nom: np.ndarray  # nominal hand-over phase of each slot
    sheet_faults: Any  # faults.SheetFaults of the slots, or None without ``faults``
    slowdowns: Any  # faults' belt slow-downs, or None
    missing: np.ndarray  # per slot
    double: np.ndarray
    delay: np.ndarray  # per slot, nominal s
    cycle: np.ndarray  # per signature fed: its slot
    theta_h: np.ndarray  # per signature fed: hand-over phase
    ids: np.ndarray  # per signature fed: sheet id
    t_h: np.ndarray  # per signature fed: hand-over time, s


@dataclass(frozen=True, eq=False)
class _Knife:
    """Knife contacts and exits by the end: cycle indices and times (:func:`_knife_cycles`)."""

    k_c: np.ndarray
    t_c: np.ndarray
    k_x: np.ndarray
    t_x: np.ndarray


@dataclass(frozen=True, eq=False)
class _Fates:
    """What became of each signature fed (:func:`_fates`)."""

    folded: np.ndarray  # at the stops by its cycle's knife contact
    jammed: np.ndarray  # its cycle's knife came first
    released: np.ndarray  # released on the pile by the end (with a delivery)
    t_rel: np.ndarray  # valid where released
    counted: np.ndarray  # released (with a delivery), else folded


def _setup(scene: Scene, drive: Drive, duration: float) -> _Setup:
    timing = cycle_timing(scene.machine('cyclogram'), scene.machine('knife'))
    duration = float(duration)
    return _Setup(
        scene=scene,
        drive=drive,
        duration=duration,
        theta_end=float(np.asarray(drive.theta(duration))),
        timing=timing,
        V_tr=float(scene.machine('feed_transporter').V_tr),
        phase=float(scene.sheets.phase),
        plan=delivery_plan(scene, timing),
        slip=scene.effect_params('feed_slip') if scene.has('feed_slip') else None,
        bounce=scene.effect_params('stop_bounce') if scene.has('stop_bounce') else None,
        faults=scene.effect_params('faults') if scene.has('faults') else None,
    )


def _hand_overs(s: _Setup) -> _Stream:
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
    return _Stream(
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


def _belt_phase(s: _Setup, st: _Stream) -> BeltPhase:
    """The feed belt's travel in master phase, with the faults' slow-downs."""
    sd = st.slowdowns
    if sd is None:
        return BeltPhase(s.drive, s.duration)
    return BeltPhase(s.drive, s.duration, sd.t_start, sd.t_end, sd.factor)


def _fault_events(s: _Setup, st: _Stream) -> list[np.ndarray]:
    """The ``fault_*`` and ``belt_slowdown_*`` events (none without ``faults``)."""
    if s.faults is None:
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


def _knife_cycles(s: _Setup) -> _Knife:
    """Knife contact of cycle k at Θ = (k+1)T + t_in, exit at (k+1)T + t_out (those by the end)."""
    T, t_in, t_out, drive = s.timing.T, s.timing.knife.t_in, s.timing.knife.t_out, s.drive
    k_c = _indices(T + t_in, T, s.theta_end)
    t_c = np.asarray(drive.time_of(k_c * T + (T + t_in)), dtype=float) if k_c.size else np.zeros(0)
    k_x = _indices(T + t_out, T, s.theta_end)
    t_x = np.asarray(drive.time_of(k_x * T + (T + t_out)), dtype=float) if k_x.size else np.zeros(0)
    return _Knife(k_c, t_c, k_x, t_x)


def _fates(s: _Setup, sheets: _Sheets, knife: _Knife) -> _Fates:
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
        return _Fates(folded, jammed, released, t_rel, folded)
    theta_rel = s.plan.release_phase(sheets.cycle)
    released = folded & (theta_rel <= s.theta_end)
    if released.any():
        t_rel[released] = np.asarray(s.drive.time_of(theta_rel[released]), dtype=float)
    released &= t_rel <= s.duration
    return _Fates(folded, jammed, released, t_rel, released)


def _bounces(s: _Setup, sheets: _Sheets) -> tuple[list[np.ndarray], dict[str, Any]]:
    """``bounce`` and ``settled`` events and the summary's ``stop_bounce`` figures (none without it)."""
    if s.bounce is None:
        return [], {}
    ids = sheets.sheet
    arr = np.flatnonzero(sheets.arrived)
    sched = stop_bounce.bounce_schedule(s.bounce, sheets.v_imp[arr])
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
    nominal = float(s.V_tr)
    info = {
        'bounces_at_V_tr': int(stop_bounce.bounce_count(s.bounce, nominal)),
        'settle_time_at_V_tr': _json_float(stop_bounce.settle_time(s.bounce, nominal)),
        'first_rebound_at_V_tr': _json_float(stop_bounce.first_rebound(s.bounce, nominal)),
        'bounces_max': int(sched.count.max()) if sched.count.size else 0,
        'settle_time_max': _json_float(sched.settle.max()) if sched.settle.size else 0.0,
    }
    return tables, info


def _sheet_events(s: _Setup, sheets: _Sheets, knife: _Knife, fates: _Fates) -> list[np.ndarray]:
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


def _summary(
    s: _Setup,
    st: _Stream,
    sheets: _Sheets,
    knife: _Knife,
    fates: _Fates,
    events: np.ndarray,
    bounce_info: dict[str, Any],
) -> dict[str, Any]:
    """The JSON-ready figures of the folder (see the ``simulate`` verb of the CLI)."""
    timing, V_tr, phase, plan = s.timing, s.V_tr, s.phase, s.plan
    V_d, T, L = timing.V_d, timing.T, timing.L_feed
    ids = sheets.sheet
    n_fed = int(ids.size)
    n_counted = int(np.count_nonzero(fates.counted))
    # in the machine, from the event table: handed over, but no pile release (or not folded) by the end
    gone = events['sheet'][events['kind'] == event_kind('released_on_pile')] if plan is not None else ids[fates.folded]
    handed = events['sheet'][events['kind'] == event_kind('sheet_handover')]
    in_machine = int(np.count_nonzero(~np.isin(handed, gone)))
    t_feed = L / V_tr
    summary: dict[str, Any] = {
        'cycles': int(knife.k_c.size),
        'cycles_started': int(_indices(timing.knife.t_out, T, s.theta_end).size),
        'sheets_fed': n_fed,
        'sheets_at_stops': int(np.count_nonzero(sheets.arrived)),
        'sheets_folded': int(np.count_nonzero(fates.folded)),
        'sheets_jammed': int(np.count_nonzero(fates.jammed)),
        'sheets_counted': n_counted,
        'sheets_in_machine': in_machine,
        'sheets_balance_ok': bool(handed.size == n_fed and n_fed == n_counted + in_machine),
        'V_d': _json_float(V_d),
        'V_tr': _json_float(V_tr),
        'v_tr_over_v_d': _json_float(V_tr / V_d),
        'V_tr_min': _json_float(timing.V_tr_min),
        'timing': {
            'T': _json_float(T),
            't_in': _json_float(timing.knife.t_in),
            't_out': _json_float(timing.knife.t_out),
            't_knife': _json_float(timing.t_knife),
            't_dwell': _json_float(timing.t_dwell),
            't_fw': _json_float(timing.t_fw),
            't_allowed': _json_float(timing.t_allowed),
        },
        # nominal speed, no faults: what each part of the cycle leaves over (s)
        'slack': {'feed_margin_ideal': _json_float(timing.t_allowed - phase - t_feed)},
    }
    if s.slip is not None:
        cost = float(feed_slip.slip_cost(s.slip, V_d, V_tr, L))
        summary['feed_slip'] = _slip_info(s, s.slip, cost)
        summary['slack']['slip_cost'] = _json_float(cost)
        t_feed += cost
    summary['slack']['feed_margin'] = _json_float(timing.t_allowed - phase - t_feed)
    rest = (T - timing.t_knife) - phase - t_feed
    summary['slack']['rest_at_stops'] = _json_float(rest)
    if s.bounce is not None:
        settle = bounce_info['settle_time_at_V_tr']
        summary['slack']['settle_time'] = settle
        summary['slack']['settled_margin'] = _json_float(rest - settle)
        summary['stop_bounce'] = bounce_info
    if plan is not None:
        summary['release'] = {
            'u_rel': _json_float(plan.u_rel),
            'K_v': _json_float(plan.K_v_rel),
            'chain_travel': _json_float(plan.travel_rel),
            'v_A': _json_float(plan.v_A),
            'carriage_speed': _json_float(plan.K_v_rel * plan.v_A),
        }
    if s.faults is not None:
        summary['faults'] = {
            'missing': int(np.count_nonzero(st.missing)),
            'double': int(np.count_nonzero(st.double)),
            'late': int(np.count_nonzero(st.delay > 0.0)),
            'slowdowns': int(np.asarray(st.slowdowns.t_start).size) if st.slowdowns is not None else 0,
        }
    return summary


def _slip_info(s: _Setup, slip: feed_slip.Params, cost: float) -> dict[str, Any]:
    """The summary's ``feed_slip`` figures (``slip``: the scene's, ``s.slip``)."""
    timing, L = s.timing, s.timing.L_feed
    info: dict[str, Any] = {
        'accel': _json_float(slip.accel),
        'slip_cost': _json_float(cost),
        'feed_margin_with_slip': _json_float(timing.t_allowed - L / s.V_tr - cost),
    }
    try:
        info['V_tr_min_with_slip'] = _json_float(feed_slip.min_belt_speed(slip, timing.V_d, L, timing.t_allowed))
    except ParameterError:
        info['V_tr_min_with_slip'] = None
    return info


# --------------------------------------------------------------------------- simulation


class FolderLine(LinePart):
    """The folder (and its delivery) on a drive over ``[0, duration]``: built once, sampled anywhere.

    Construction computes everything that depends only on the scene, the drive and
    the duration -- the exact events, the per-cycle constraints and the summary (see
    the module docstring); :meth:`sample` then gives the joint states at any times
    cheaply (a node's tick calls it with one time).

    Parameters
    ----------
    scene : Scene
        Must have ``knife``, ``cyclogram`` and ``feed_transporter``; ``delivery`` and
        ``delivery_chain`` optional; effects ``feed_slip``, ``stop_bounce``,
        ``faults``, ``chain_friction`` run only if listed.
    drive : Drive
        Master drive (Θ(t), λ(t), and the exact inverse ``time_of``).
    duration : float
        Line time, s (> 0).

    Attributes
    ----------
    events : ndarray of EVENT_DTYPE
        Sorted by time (:func:`folder_line.core.line.events.merge_events`).
    constraints : list of ConstraintSeries
        :func:`folder_line.core.line.constraints.evaluate_folder_constraints`.
    summary : dict
        JSON-ready figures.
    timing : CycleTiming
        The cycle.
    plan : DeliveryPlan or None
        The delivery's derived figures.
    units : dict of str to tuple of str
        Unit (``drive``, ``belts``, ``feed``) -> its joint names.
    """

    def __init__(self, scene: Scene, drive: Drive, duration: float) -> None:
        s = _setup(scene, drive, duration)
        st = _hand_overs(s)
        belt = _belt_phase(s, st)
        sheets = _feed(drive, s.duration, belt, st, s.timing.V_d, s.V_tr, s.timing.L_feed, s.slip)
        knife = _knife_cycles(s)
        fates = _fates(s, sheets, knife)
        bounce_tables, bounce_info = _bounces(s, sheets)
        events = merge_events([*_fault_events(s, st), *bounce_tables, *_sheet_events(s, sheets, knife, fates)])

        self.scene = scene
        self.drive = drive
        self.duration = s.duration
        self.timing = s.timing
        self.V_tr = s.V_tr
        self.belt = belt
        self.plan = s.plan
        self.events = events
        self.constraints = evaluate_folder_constraints(events, s.timing, scene, drive, plan=s.plan)
        self.summary = _summary(s, st, sheets, knife, fates, events, bounce_info)
        self.knife: knf.KnifeParams = scene.machine('knife')
        self.with_torque = scene.has('chain_friction') and s.plan is not None
        self.torque_params = scene.effect_params('chain_friction') if self.with_torque else None
        self.units: dict[str, tuple[str, ...]] = {
            'drive': ('knife_crank', 'knife'),
            'belts': ('first_transporter',),
            'feed': ('feed_belt', 'chain', 'carriage') if s.plan is not None else ('feed_belt',),
        }

    # ------------------------------------------------------------------ joint states

    def sample_unit(
        self, unit: str, t: npt.ArrayLike, theta: np.ndarray | None = None, lam: np.ndarray | None = None
    ) -> JointSamples:
        """Joint states of one unit (``drive``, ``belts``, ``feed``) at ``t``."""
        t = np.asarray(t, dtype=float).reshape(-1)
        theta, lam = self._drive_state(t, theta, lam)
        timing = self.timing
        wt = self.with_torque
        if unit == 'drive':
            kp = self.knife
            phi = np.mod(timing.omega_k * theta, TWO_PI)
            s = knf.position(kp, phi)
            v = knf.velocity(kp, phi) * lam
            zeros = np.zeros(t.size)
            return stack_samples(
                'drive',
                ('knife_crank', 'knife'),
                t,
                [phi, s],
                [timing.omega_k * lam, v],
                [zeros, zeros] if wt else None,
            )
        if unit == 'belts':
            return stack_samples(
                'belts',
                ('first_transporter',),
                t,
                [timing.V_d * theta],
                [timing.V_d * lam],
                [np.zeros(t.size)] if wt else None,
            )
        if unit == 'feed':
            return self._feed_unit(t, theta, lam)
        raise KeyError(f'unit {unit!r} has no folder joints; units: {", ".join(self.units)}')

    def _feed_unit(self, t: np.ndarray, theta: np.ndarray, lam: np.ndarray) -> JointSamples:
        V_tr, belt, plan = self.V_tr, self.belt, self.plan
        zeros = np.zeros(t.size)
        b = belt.at(t, theta)
        names = ['feed_belt']
        pos = [V_tr * b]
        vel = [V_tr * lam * belt.factor(t)]
        eff: list[np.ndarray] | None = [zeros] if self.with_torque else None
        if plan is not None:
            chain_pos = plan.v_A * theta
            sch = plan.schedule
            a0, slack = sch.stroke_travel(theta)  # the carriage that entered the stroke last
            on = a0 <= sch.S + slack
            car_x = np.zeros(t.size)
            car_v = np.zeros(t.size)
            st = None
            u = None
            if on.any():
                u = plan.path.position(np.clip(a0[on], 0.0, sch.S))
                st = dlv.evaluate_stroke(plan.params, u, return_section='geometric')
                car_x[on] = u * plan.chain.x_max + plan.rod * (1.0 - np.cos(st.alpha))
                car_v[on] = st.K_v * plan.v_A * lam[on]
            names += ['chain', 'carriage']
            pos += [chain_pos, car_x]
            vel += [plan.v_A * lam, car_v]
            if eff is not None:
                if t.size == 1:  # a node's tick: reuse the carriage's stroke evaluation
                    torque = self._sprocket_torque(a0, slack, on, u, st)
                else:
                    torque = np.asarray(chain_friction.sprocket_torque(self.scene, theta), dtype=float)
                if torque.shape != t.shape or not np.all(np.isfinite(torque)):
                    raise ValueError('chain_friction.sprocket_torque must return finite values shaped like Θ')
                eff += [torque, zeros]
        return stack_samples('feed', tuple(names), t, pos, vel, eff)

    def _sprocket_torque(
        self, a0: np.ndarray, slack: np.ndarray, on0: np.ndarray, u0: np.ndarray | None, st0: Any
    ) -> np.ndarray:
        """:func:`folder_line.core.effects.chain_friction.sprocket_torque` at the same Θ, bit for bit.

        The fast path of a node's tick: the same operations in the same order as
        ``chain_friction._stroke_torque`` (a test compares the two bit for bit), but the
        newest carriage's stroke evaluation is the carriage joint's own where it is the
        same (geometric return section), which halves the cost of the tick."""
        p = self.torque_params
        plan = self.plan
        assert p is not None and plan is not None
        sch = plan.schedule
        total = np.zeros(a0.shape)
        for m in range(sch.max_on_stroke):  # carriages on the stroke at once
            a = a0 + m * sch.pitch
            on = (a >= -slack) & (a <= sch.S + slack)
            if np.any(on):
                if m == 0 and st0 is not None and p.return_section == 'geometric' and np.array_equal(on, on0):
                    total[on] += st0.forces(p.P_k, p.r).M_1
                else:
                    u = plan.path.position(np.clip(a[on], 0.0, sch.S))
                    total[on] += chain_friction.stroke_state(p, plan.params, u).M_1
        return total


def simulate_folder(scene: Scene, drive: Drive, duration: float, t_samples: np.ndarray) -> SubResult:
    """Simulate the folder (and its delivery) for ``duration`` seconds of line time.

    A thin wrapper: ``FolderLine(scene, drive, duration).result(t_samples)``.

    Parameters
    ----------
    scene : Scene
        As for :class:`FolderLine`.
    drive : Drive
        Master drive.
    duration : float
        Line time, s (> 0).
    t_samples : ndarray, shape (N,)
        Sample times in [0, duration], s (may be empty: events only).

    Returns
    -------
    SubResult
        Events (see the module docstring), samples per unit, constraints
        (:func:`folder_line.core.line.constraints.evaluate_folder_constraints`), summary.
    """
    return FolderLine(scene, drive, duration).result(t_samples)


def _feed(
    drive: Drive,
    duration: float,
    belt: BeltPhase,
    st: _Stream,
    V_d: float,
    V_tr: float,
    L: float,
    slip: Any,
) -> _Sheets:
    """Arrival at the stops of every signature handed over (exact, vectorised)."""
    ids, cyc, theta_h, t_h = st.ids, st.cycle, st.theta_h, st.t_h
    n = ids.size
    arrived = np.zeros(n, dtype=bool)
    t_a = np.zeros(n)
    v_imp = np.zeros(n)
    if n == 0:
        return _Sheets(ids, cyc, t_h, arrived, t_a, v_imp)
    b_end = float(belt.at(np.asarray(duration)))
    if slip is None:
        b_h = theta_h if belt.plain else belt.at(t_h, theta_h)
        b_a = b_h + L / V_tr
        ride = b_a <= b_end
        idx = np.flatnonzero(ride)
    else:
        lam = np.maximum(np.asarray(drive.rate(t_h), dtype=float), _LAMBDA_FLOOR)
        f_h = belt.factor(t_h)
        sa = feed_slip.arrival(slip, lam * V_d, lam * f_h * V_tr, L)
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
        b_a[cand] = belt.at(t_m[cand]) + (L - sa.d_slip[cand]) / V_tr
        idx = cand[b_a[cand] <= b_end]
    if idx.size:
        th = belt.theta_of(b_a[idx])
        t = np.asarray(drive.time_of(th), dtype=float)
        keep = t <= duration  # b_a <= B(duration): drops only a rounding-level overshoot
        idx, t = idx[keep], t[keep]
        arrived[idx] = True
        t_a[idx] = t
        v_imp[idx] = V_tr * np.asarray(drive.rate(t), dtype=float) * belt.factor(t)
    return _Sheets(ids, cyc, t_h, arrived, t_a, v_imp)
