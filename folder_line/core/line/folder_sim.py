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

Joint samples (on ``t_samples``; λ = ``drive.rate``, f the belt slow-down factor)
-------------------------------------------------------------------------------
* ``crank_drive``: ``knife_crank`` (φ_k wrapped to [0, 2π), ω_k λ),
  ``knife`` (s(φ_k) m, v(φ_k) λ m/s);
* ``belt_conveyor``: ``first_transporter`` (V_d Θ m, V_d λ m/s);
* ``feed_transporter``: ``feed_belt`` (its travel, V_tr λ f), and with a delivery
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
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from folder_line.core.line.events import (
    JointSamples,
    LinePart,
    SubResult,
    event_kind,
    make_events,
    merge_events,
    stack_samples,
)
from folder_line.core.line.machines import ChainParams
from folder_line.core.mechanisms import chain
from folder_line.core.mechanisms import delivery as dlv
from folder_line.core.mechanisms import knife as knf
from folder_line.core.mechanisms.belt import BeltPhase
from folder_line.core.mechanisms.chain import ChainPath, ChainSchedule
from folder_line.core.mechanisms.cyclogram import CycleTiming, cycle_timing
from folder_line.core.mechanisms.drive import Drive
from folder_line.core.numerics.rng import stream
from folder_line.errors import ParameterError

if TYPE_CHECKING:
    from folder_line.core.line.scene import Scene

__all__ = [
    'DeliveryPlan',
    'FolderLine',
    'delivery_plan',
    'simulate_folder',
]

TWO_PI = 2.0 * math.pi
#: smallest speed factor used to freeze the slip speeds at a hand-over (a drive at a standstill)
_LAMBDA_FLOOR = 1e-9


# --------------------------------------------------------------------------- delivery


@dataclass(frozen=True, eq=False)
class DeliveryPlan:
    """What the folder simulation needs of the delivery (derived once per scene).

    Attributes
    ----------
    params : DeliveryParams
        The transporter.
    chain : ChainParams
        Chain geometry.
    path : ChainPath
        Arc length along the guide (:mod:`folder_line.core.mechanisms.chain`).
    schedule : ChainSchedule
        Where the carriages are; carriage k takes sheet k at ``schedule.pickup_phase(k)``.
    rod : float
        Rod length ``l``, m.
    u_rel : float
        Stroke position of the slowest carriage, where the sheet is released.
    K_v_rel : float
        ``K_v`` there (the stroke's minimum).
    s_rel : float
        Chain travel from the stroke start to ``u_rel``, m.
    travel_rel : float
        ``L_transfer + s_rel``: chain travel from the take-over at the folding
        rollers to the release, m.
    """

    params: dlv.DeliveryParams
    chain: ChainParams
    path: ChainPath
    schedule: ChainSchedule
    rod: float
    u_rel: float
    K_v_rel: float
    s_rel: float
    travel_rel: float

    @property
    def v_A(self) -> float:
        """Chain speed per unit master phase, ``pitch / T``, m/s at nominal speed."""
        return self.schedule.v_A

    def release_phase(self, cycle: npt.ArrayLike) -> np.ndarray:
        """Master phase Θ at which carriage ``cycle`` releases sheet ``cycle`` on the pile, nominal s."""
        return self.schedule.phase_of_travel(self.travel_rel, cycle)


def delivery_plan(scene: Scene, timing: CycleTiming) -> DeliveryPlan | None:
    """The delivery's derived figures, or None if the scene has no delivery.

    ``timing`` must be the scene's cycle timing: its ``T`` is the schedule's (checked).
    """
    if 'delivery' not in scene.machines:
        return None
    params: dlv.DeliveryParams = scene.machines['delivery']
    chain_p: ChainParams = scene.machines['delivery_chain']
    sch = chain.schedule(scene)
    if sch.T != timing.T or sch.theta_pick0 != timing.T + timing.knife.t_out:
        raise ValueError('delivery_plan: timing is not the cycle timing of this scene')
    path = chain.chain_path(scene)
    u_rel, kv_rel = dlv.stroke_minimum(params, 'K_v', return_section='geometric')
    s_rel = float(path.arc(u_rel))
    return DeliveryPlan(
        params=params,
        chain=chain_p,
        path=path,
        schedule=sch,
        rod=params.rod_length(chain_p.x_max),
        u_rel=float(u_rel),
        K_v_rel=float(kv_rel),
        s_rel=s_rel,
        travel_rel=chain_p.L_transfer + s_rel,
    )


# --------------------------------------------------------------------------- helpers


def _indices(first: float, step: float, last: float) -> np.ndarray:
    """k = 0, 1, ... with ``k step + first <= last`` (empty if first > last)."""
    if first > last:
        return np.zeros(0, dtype=np.int64)
    n = int(math.floor((last - first) / step)) + 2
    k = np.arange(n, dtype=np.int64)
    return k[k * step + first <= last]


def _json_float(x: float) -> float:
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
    """

    def __init__(self, scene: Scene, drive: Drive, duration: float) -> None:
        from folder_line.core.line.constraints import evaluate_folder_constraints

        knife_p: knf.KnifeParams = scene.machines['knife']
        timing = cycle_timing(scene.machines['cyclogram'], knife_p)
        V_tr = float(scene.machines['feed_transporter'].V_tr)
        V_d, T = timing.V_d, timing.T
        t_in, t_out = timing.knife.t_in, timing.knife.t_out
        L = timing.L_feed
        phase = float(scene.sheets.phase)
        duration = float(duration)
        theta_end = float(np.asarray(drive.theta(duration)))

        slip = scene.effect('feed_slip')
        bounce = scene.effect('stop_bounce')
        faults_p = scene.effect('faults')
        plan = delivery_plan(scene, timing)

        # ---- hand-over slots, faults and the signatures fed
        slots = _indices(t_out + phase, T, theta_end)
        theta_nom = slots * T + (t_out + phase)
        tables: list[np.ndarray] = []
        slowdowns = None
        if faults_p is not None:
            from folder_line.core.effects import faults

            sf = faults.draw_sheet_faults(faults_p, slots.size, stream(scene.seed, 'folder.faults'))
            slowdowns = faults.draw_slowdowns(faults_p, duration, T, stream(scene.seed, 'folder.slowdowns'))
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
        fed = theta_h_all <= theta_end
        cyc = cyc_all[fed]
        theta_h = theta_h_all[fed]
        ids = np.arange(cyc.size, dtype=np.int64)
        t_h = np.asarray(drive.time_of(theta_h), dtype=float) if cyc.size else np.zeros(0)
        belt = (
            BeltPhase(drive, duration)
            if slowdowns is None
            else BeltPhase(drive, duration, slowdowns.t_start, slowdowns.t_end, slowdowns.factor)
        )

        if faults_p is not None:
            from folder_line.core.effects import faults

            first_id = np.full(slots.size, -1, dtype=np.int64)
            fed_slot = np.zeros(slots.size, dtype=bool)
            fed_slot[cyc] = True
            # id of the first signature of each slot (ids are in slot order)
            starts = np.searchsorted(cyc, slots, side='left')
            first_id[fed_slot] = ids[starts[fed_slot]]
            t_nom = np.asarray(drive.time_of(theta_nom), dtype=float) if slots.size else np.zeros(0)
            table = faults.fault_events(sf, t_nom, first_id, slots, slowdowns, duration)
            tables.append(table[table['t'] >= 0.0])  # a slot before the line starts has no fault either

        sheets = _feed(drive, duration, belt, ids, cyc, theta_h, t_h, V_d, V_tr, L, slip)

        # ---- knife cycles
        k_c = _indices(T + t_in, T, theta_end)
        t_c = np.asarray(drive.time_of(k_c * T + (T + t_in)), dtype=float) if k_c.size else np.zeros(0)
        k_x = _indices(T + t_out, T, theta_end)
        t_x = np.asarray(drive.time_of(k_x * T + (T + t_out)), dtype=float) if k_x.size else np.zeros(0)

        # folded: at the stops by its cycle's knife contact (cycle k's contact is t_c[k])
        has_contact = sheets.cycle < k_c.size
        t_contact = np.zeros(ids.size)
        t_contact[has_contact] = t_c[sheets.cycle[has_contact]]
        folded = has_contact & sheets.arrived & (sheets.t_a <= t_contact)
        jammed = has_contact & ~folded

        # ---- stop bounce
        bounce_info: dict[str, Any] = {}
        if bounce is not None:
            from folder_line.core.effects import stop_bounce

            arr = np.flatnonzero(sheets.arrived)
            sched = stop_bounce.bounce_schedule(bounce, sheets.v_imp[arr])
            t_settled = sheets.t_a.copy()
            t_settled[arr] = sheets.t_a[arr] + sched.settle
            tb = sheets.t_a[arr][sched.index] + sched.dt
            keep = tb <= duration
            tables.append(
                make_events(
                    'bounce',
                    tb[keep],
                    sheet=ids[arr][sched.index][keep],
                    cycle=sheets.cycle[arr][sched.index][keep],
                    value=sched.rebound[keep],
                )
            )
            sk = arr[t_settled[arr] <= duration]
            tables.append(make_events('settled', t_settled[sk], sheet=ids[sk], cycle=sheets.cycle[sk]))
            nominal = float(V_tr)
            bounce_info = {
                'bounces_at_V_tr': int(stop_bounce.bounce_count(bounce, nominal)),
                'settle_time_at_V_tr': _json_float(stop_bounce.settle_time(bounce, nominal)),
                'first_rebound_at_V_tr': _json_float(stop_bounce.first_rebound(bounce, nominal)),
                'bounces_max': int(sched.count.max()) if sched.count.size else 0,
                'settle_time_max': _json_float(sched.settle.max()) if sched.settle.size else 0.0,
            }

        # ---- delivery
        released = np.zeros(ids.size, dtype=bool)
        t_rel = np.zeros(ids.size)
        if plan is not None:
            theta_rel = plan.release_phase(sheets.cycle)
            released = folded & (theta_rel <= theta_end)
            if released.any():
                t_rel[released] = np.asarray(drive.time_of(theta_rel[released]), dtype=float)
            released &= t_rel <= duration
            counted = released
        else:
            counted = folded

        # ---- events
        arrived = sheets.arrived
        tables += [
            make_events('sheet_handover', t_h, sheet=ids, cycle=cyc),
            make_events(
                'at_stops', sheets.t_a[arrived], sheet=ids[arrived], cycle=cyc[arrived], value=sheets.v_imp[arrived]
            ),
            make_events('knife_contact', t_c, cycle=k_c),
            make_events('knife_exit', t_x, cycle=k_x),
        ]
        if plan is not None:
            tables.append(make_events('released_on_pile', t_rel[released], sheet=ids[released], cycle=cyc[released]))
        events = merge_events(tables)

        constraints = evaluate_folder_constraints(events, timing, scene, drive, plan=plan)

        # ---- summary
        n_fed = int(ids.size)
        n_counted = int(np.count_nonzero(counted))
        # in the machine, from the event table: handed over, but no pile release (or not folded) by the end
        gone = events['sheet'][events['kind'] == event_kind('released_on_pile')] if plan is not None else ids[folded]
        handed = events['sheet'][events['kind'] == event_kind('sheet_handover')]
        in_machine = int(np.count_nonzero(~np.isin(handed, gone)))
        t_feed = L / V_tr
        summary: dict[str, Any] = {
            'cycles': int(k_c.size),
            'cycles_started': int(_indices(t_out, T, theta_end).size),
            'sheets_fed': n_fed,
            'sheets_at_stops': int(np.count_nonzero(arrived)),
            'sheets_folded': int(np.count_nonzero(folded)),
            'sheets_jammed': int(np.count_nonzero(jammed)),
            'sheets_counted': n_counted,
            'sheets_in_machine': in_machine,
            'sheets_balance_ok': bool(handed.size == n_fed and n_fed == n_counted + in_machine),
            'V_d': _json_float(V_d),
            'V_tr': _json_float(V_tr),
            'v_tr_over_v_d': _json_float(V_tr / V_d),
            'V_tr_min': _json_float(timing.V_tr_min),
            'timing': {
                'T': _json_float(T),
                't_in': _json_float(t_in),
                't_out': _json_float(t_out),
                't_knife': _json_float(timing.t_knife),
                't_dwell': _json_float(timing.t_dwell),
                't_fw': _json_float(timing.t_fw),
                't_allowed': _json_float(timing.t_allowed),
            },
            # nominal speed, no faults: what each part of the cycle leaves over (s)
            'slack': {'feed_margin_ideal': _json_float(timing.t_allowed - phase - t_feed)},
        }
        if slip is not None:
            from folder_line.core.effects import feed_slip

            cost = float(feed_slip.slip_cost(slip, V_d, V_tr, L))
            info: dict[str, Any] = {
                'accel': _json_float(slip.accel),
                'slip_cost': _json_float(cost),
                'feed_margin_with_slip': _json_float(timing.t_allowed - L / V_tr - cost),
            }
            try:
                info['V_tr_min_with_slip'] = _json_float(feed_slip.min_belt_speed(slip, V_d, L, timing.t_allowed))
            except ParameterError:
                info['V_tr_min_with_slip'] = None
            summary['feed_slip'] = info
            summary['slack']['slip_cost'] = _json_float(cost)
            t_feed += cost
        summary['slack']['feed_margin'] = _json_float(timing.t_allowed - phase - t_feed)
        rest = (T - timing.t_knife) - phase - t_feed
        summary['slack']['rest_at_stops'] = _json_float(rest)
        if bounce is not None:
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
        if faults_p is not None:
            summary['faults'] = {
                'missing': int(np.count_nonzero(missing)),
                'double': int(np.count_nonzero(double)),
                'late': int(np.count_nonzero(delay > 0.0)),
                'slowdowns': int(np.asarray(slowdowns.t_start).size) if slowdowns is not None else 0,
            }
        self.scene = scene
        self.drive = drive
        self.duration = duration
        self.timing = timing
        self.V_tr = V_tr
        self.belt = belt
        self.plan = plan
        self.events = events
        self.constraints = constraints
        self.summary = summary

        self.knife = knife_p
        self.with_torque = scene.has('chain_friction') and plan is not None
        self.torque_params = scene.effect('chain_friction') if self.with_torque else None
        self.nodes: dict[str, tuple[str, ...]] = {
            'crank_drive': ('knife_crank', 'knife'),
            'belt_conveyor': ('first_transporter',),
            'feed_transporter': ('feed_belt', 'chain', 'carriage') if plan is not None else ('feed_belt',),
        }

    # ------------------------------------------------------------------ joint states

    def sample_node(
        self, node: str, t: npt.ArrayLike, theta: np.ndarray | None = None, lam: np.ndarray | None = None
    ) -> JointSamples:
        """Joint states of one node (``crank_drive``, ``belt_conveyor``, ``feed_transporter``) at ``t``."""
        t = np.asarray(t, dtype=float).reshape(-1)
        theta, lam = self._drive_state(t, theta, lam)
        timing = self.timing
        wt = self.with_torque
        if node == 'crank_drive':
            kp = self.knife
            phi = np.mod(timing.omega_k * theta, TWO_PI)
            s = knf.position(kp, phi)
            v = knf.velocity(kp, phi) * lam
            zeros = np.zeros(t.size)
            return stack_samples(
                'crank_drive',
                ('knife_crank', 'knife'),
                t,
                [phi, s],
                [timing.omega_k * lam, v],
                [zeros, zeros] if wt else None,
            )
        if node == 'belt_conveyor':
            return stack_samples(
                'belt_conveyor',
                ('first_transporter',),
                t,
                [timing.V_d * theta],
                [timing.V_d * lam],
                [np.zeros(t.size)] if wt else None,
            )
        if node == 'feed_transporter':
            return self._feed_transporter(t, theta, lam)
        raise KeyError(f'node {node!r} has no folder joints; nodes: {", ".join(self.nodes)}')

    def _feed_transporter(self, t: np.ndarray, theta: np.ndarray, lam: np.ndarray) -> JointSamples:
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
                    from folder_line.core.effects import chain_friction

                    torque = np.asarray(chain_friction.sprocket_torque(self.scene, theta), dtype=float)
                if torque.shape != t.shape or not np.all(np.isfinite(torque)):
                    raise ValueError('chain_friction.sprocket_torque must return finite values shaped like Θ')
                eff += [torque, zeros]
        return stack_samples('feed_transporter', tuple(names), t, pos, vel, eff)

    def _sprocket_torque(
        self, a0: np.ndarray, slack: np.ndarray, on0: np.ndarray, u0: np.ndarray | None, st0: Any
    ) -> np.ndarray:
        """:func:`folder_line.core.effects.chain_friction.sprocket_torque` at the same Θ, bit for bit.

        The fast path of a node's tick: the same operations in the same order as
        ``chain_friction._stroke_torque`` (a test compares the two bit for bit), but the
        newest carriage's stroke evaluation is the carriage joint's own where it is the
        same (geometric return section), which halves the cost of the tick."""
        from folder_line.core.effects import chain_friction

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
        Events (see the module docstring), samples per node, constraints
        (:func:`folder_line.core.line.constraints.evaluate_folder_constraints`), summary.
    """
    return FolderLine(scene, drive, duration).result(t_samples)


def _feed(
    drive: Drive,
    duration: float,
    belt: BeltPhase,
    ids: np.ndarray,
    cyc: np.ndarray,
    theta_h: np.ndarray,
    t_h: np.ndarray,
    V_d: float,
    V_tr: float,
    L: float,
    slip: Any,
) -> _Sheets:
    """Arrival at the stops of every signature handed over (exact, vectorised)."""
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
        from folder_line.core.effects import feed_slip

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
