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
from collections.abc import Iterable
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from folder_line.core.effects import chain_friction
from folder_line.core.line import folder_steps
from folder_line.core.line.constraints import evaluate_folder_constraints
from folder_line.core.line.events import JointSamples, LinePart, SubResult, merge_events, stack_samples
from folder_line.core.line.tuning import Tuning, belt_steps
from folder_line.core.mechanisms import delivery as dlv
from folder_line.core.mechanisms import knife as knf
from folder_line.core.mechanisms.drive import Drive

if TYPE_CHECKING:
    from folder_line.core.line.scene import Scene

__all__ = ['FolderLine', 'simulate_folder']

TWO_PI = 2.0 * math.pi


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
    tunings : iterable of Tuning
        The operator's changes (:mod:`folder_line.core.line.tuning`): here the feed
        transporter's speed ``feed_transporter.V_tr`` from each one's time on.

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

    def __init__(self, scene: Scene, drive: Drive, duration: float, tunings: Iterable[Tuning] = ()) -> None:
        s = folder_steps.setup(scene, drive, duration)
        st = folder_steps.hand_overs(s)
        belt = folder_steps.belt_phase(s, st, belt_steps(tunings, 'feed_transporter.V_tr', s.V_tr))
        n = st.ids.size
        L = folder_steps.travel(s, n)
        mu = folder_steps.friction(s, n)
        sheets = folder_steps.feed(drive, s.duration, belt, st, s.timing.V_d, s.V_tr, L, s.slip, mu)
        knife = folder_steps.knife_cycles(s)
        fates = folder_steps.fates(s, sheets, knife)
        bounce_tables, bounce_info = folder_steps.bounces(s, sheets)
        events = merge_events(
            [*folder_steps.fault_events(s, st), *bounce_tables, *folder_steps.sheet_events(s, sheets, knife, fates)]
        )

        self.scene = scene
        self.drive = drive
        self.duration = s.duration
        self.timing = s.timing
        self.V_tr = s.V_tr
        self.belt = belt
        self.plan = s.plan
        self.events = events
        self.constraints = evaluate_folder_constraints(events, s.timing, scene, drive, plan=s.plan)
        self.summary = folder_steps.summary(s, st, sheets, knife, fates, events, bounce_info)
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
