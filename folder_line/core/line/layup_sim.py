"""L — the leaf layup part of the line: ``simulate_layup(scene, drive, duration, t_samples)``.

Leaves stream into the two chutes (transporter 3 with exit C, transporter 4 with
exit E, alternating), leave the chute exits and, with ``leaf_flight``, fly to the
container floor (paper 000; MACHINES.md section L).

Stream
------
Leaf j (j = 0, 1, ...) enters at ``t_j = phase + j·interval + jitter·interval·U_j``,
``U_j ~ U(−0.5, 0.5)`` from the seeded stream ``rng.stream(seed, 'layup.leaves')``
(one draw per slot, always, so the draws do not depend on the other settings);
its chute is ``j mod 2`` (0: transporter 3, 1: transporter 4) and its id is j. As
jitter < 1 the times are strictly increasing. Slots with t_j < 0 (possible for
j = 0 when phase < jitter·interval/2) or t_j > duration do not enter.
With ``faults`` (:mod:`folder_line.core.effects.faults`, stream ``'layup.faults'``):
a missing leaf does not enter; a double leaf enters twice at the same time into
the same chute, both copies carrying id j (both exit and land); a late leaf
enters ``late_delay`` s after t_j. Fault events are at the nominal t_j. Belt
slow-downs (stream ``'layup.belt_slowdowns'``, one chance per crank cycle of 60/n_kr s)
are drawn only when the scene lists ``chute_belts``: without belts there is no belt
to slow down.

Crank and kinematics
--------------------
The crank turns through ``φ = ω Θ(t)``, ``ω = 2π n_kr/60``, Θ the master phase
(:mod:`folder_line.core.mechanisms.drive`); it is computed as ``2π · frac(n_kr/60 · Θ)`` in
[0, 2π), and the crank cycle of an event is ``floor(n_kr/60 · Θ(t))``. Chute angles
from :class:`folder_line.core.mechanisms.layup.LayupModel`; velocities and accelerations at the
drive's speed factor λ = dΘ/dt follow by linearity from the nominal ones:
``ω3 = λ ω3⁰``, ``ε3 = λ² ε3⁰ + λ' ω3⁰`` (the same as ``arrays(phi, omega=ω λ,
alpha=ω λ')``, without a per-leaf call); likewise for chute 4.

Exit
----
* ``chute_belts`` listed: the leaf enters at the pivot and rides the belt at
  ``v_tr λ f`` (f: belt slow-down factor of ``faults``) for the chute length;
  exact exit time (:mod:`folder_line.core.effects.chute_belts`); exit velocity
  ``v_C n̂ + v_belt t̂``.
* ``guide_friction`` listed (and no belts): the leaf slides under gravity, swing and
  Coulomb friction with stick–slip (:mod:`folder_line.core.effects.guide_friction`);
  exit velocity ``ṡ t̂ + v_C n̂``. With belts listed too, guide friction is inert
  (the leaf rides the belt; friction on the belt only holds it there): belts win
  and no guide-friction code runs.
* neither: the paper's picture — the leaf is dropped at the exit at its entry time,
  with the chute's swing velocity only, ``v_C n̂`` (no travel along the chute), so
  its exit speed is |v_C|, zero at the swing extremes.

Here t̂ is the unit vector along the chute from the pivot to the exit and
n̂ = ẑ × t̂; ``v_C = ω3 l3`` (``v_E = ω5 l5`` for transporter 4), signed.

Flight and damage
-----------------
With ``leaf_flight`` each exited leaf flies to ``container.y_floor``
(:mod:`folder_line.core.effects.leaf_flight`): ``leaf_landed`` (inside the walls) or
``leaf_spilled`` with the landing x, the histogram across the width and
``landing_cv``. Without it no leaf lands (there is no flight model): the landing
counts are 0 and there is no histogram. With ``leaf_damage``, leaves whose absolute
exit speed is >= v_damage emit ``leaf_damaged``.

Events are kept only up to ``duration``; a leaf still on a chute or in the air then
has not exited or landed.

Held line
---------
The leaf stream comes from upstream and is in line time, so it does not stop when
the supervisor holds the master drive (:mod:`folder_line.core.mechanisms.drive`): with belts a
leaf entering a standing chute waits on the standing belt and leaves when it runs
again; without belts (the paper's picture) it drops at the exit with the chute's
swing velocity, 0 while held. The crank and the belts stand still.

:class:`LayupLine` computes the events, constraints and summary once per scene,
drive and duration and samples the joint states at any times;
:func:`simulate_layup` is its thin wrapper.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
import numpy.typing as npt

from folder_line.core.effects import chute_belts, faults, guide_friction, leaf_damage, leaf_flight
from folder_line.core.line.constraints import chute_speed_series
from folder_line.core.line.events import (
    ConstraintSeries,
    JointSamples,
    LinePart,
    SubResult,
    make_events,
    merge_events,
    stack_samples,
)
from folder_line.core.line.machines import StreamParams
from folder_line.core.line.tuning import Tuning, belt_steps
from folder_line.core.mechanisms.belt import belt_intervals
from folder_line.core.mechanisms.drive import Drive
from folder_line.core.mechanisms.layup import TAU, LayupModel, LayupParams
from folder_line.core.mechanisms.layup_reach import sweep, swing_extremes
from folder_line.core.numerics import rng as rng_mod
from folder_line.errors import ParameterError

if TYPE_CHECKING:
    from folder_line.core.line.scene import Scene

__all__ = [
    'EXTREME_WINDOW',
    'PHASE_BINS',
    'LayupKinematics',
    'LayupLine',
    'LeafFlights',
    'leaf_stream',
    'simulate_layup',
]

#: half-width of the crank-angle window about a swing extreme for the summary, rad (5°)
EXTREME_WINDOW = math.radians(5.0)
#: crank-angle bins of the summary's exit speed by phase
PHASE_BINS = 36


def leaf_stream(stream: StreamParams, duration: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Nominal entry times of the leaf slots, with the slots' count of draws.

    Parameters
    ----------
    stream : StreamParams
        ``interval``, ``jitter``, ``phase``.
    duration : float
        Line time, s.
    seed : int
        Scene seed.

    Returns
    -------
    j : ndarray of int64
        Slot (leaf) ids of every drawn slot, 0..N-1.
    t : ndarray
        Their nominal entry times, s (some may lie outside [0, duration]).
    """
    span = duration - stream.phase + 0.5 * stream.jitter * stream.interval
    n = int(math.floor(span / stream.interval)) + 1 if span >= 0.0 else 0
    j = np.arange(n, dtype=np.int64)
    u = rng_mod.stream(seed, 'layup.leaves').random(n) - 0.5
    t = stream.phase + j * stream.interval + stream.jitter * stream.interval * u
    return j, t


class LayupKinematics:
    """Crank angle and chute kinematics at line times, geared to the master drive.

    Parameters
    ----------
    params : LayupParams
        The six-bar.
    drive : Drive
        The master drive.
    """

    def __init__(self, params: LayupParams, drive: Drive) -> None:
        self.params = params
        self.model = LayupModel(params)
        self.drive = drive
        self.turns_rate = params.n_kr / 60.0  # crank turns per nominal second
        self.omega = params.omega  # nominal crank speed, rad/s
        self._r = params.O2B / params.l3

    def turns(self, t: np.ndarray) -> np.ndarray:
        """Crank turns ``n_kr/60 · Θ(t)``."""
        return np.asarray(self.drive.theta(t), dtype=float) * self.turns_rate

    def cycle(self, t: np.ndarray) -> np.ndarray:
        """Crank cycle index ``floor(n_kr/60 · Θ(t))``."""
        cycles: np.ndarray = np.floor(self.turns(np.asarray(t, dtype=float))).astype(np.int64)
        return cycles

    @staticmethod
    def wrap(turns: np.ndarray) -> np.ndarray:
        """Crank angle in [0, 2π) of a number of turns."""
        phi = TAU * (turns - np.floor(turns))
        return np.where(phi >= TAU, 0.0, phi)

    def state(self, t: np.ndarray) -> tuple[np.ndarray, Any, np.ndarray, np.ndarray]:
        """(φ in [0, 2π), nominal LayupState with accelerations, λ, λ') at times t."""
        t = np.asarray(t, dtype=float)
        phi = self.wrap(self.turns(t))
        st = self.model.arrays(phi)
        return phi, st, np.asarray(self.drive.rate(t), dtype=float), np.asarray(self.drive.rate_dot(t), dtype=float)

    def chute(self, t: np.ndarray, chute: np.ndarray) -> dict[str, np.ndarray]:
        """Per-leaf chute quantities at times t (chute 0: transporter 3, exit C; 1: transporter 4, exit E).

        Returns
        -------
        dict
            ``phi`` (rad), ``x``, ``y`` (exit point, m), ``sin``, ``cos`` (of the chute
            angle θ' from the downward vertical; t̂ = (sin, −cos)), ``omega``, ``eps``
            (rad/s, rad/s², at the drive's speed), ``v_perp`` (exit speed across the
            chute, m/s, signed), ``lam`` (λ).
        """
        p = self.params
        phi, st, lam, lamd = self.state(t)
        c4 = np.asarray(chute) == 1
        x = np.where(c4, st.xE, st.xC)
        y = np.where(c4, st.yE, st.yC)
        sin = np.where(c4, (st.xE - p.O2O3) / p.l5, st.xC / p.l3)
        cos = np.where(c4, -st.yE / p.l5, -st.yC / p.l3)
        w0 = np.where(c4, st.omega5, st.omega3)
        e0 = np.where(c4, st.eps5, st.eps3)
        omega = w0 * lam
        eps = e0 * lam * lam + w0 * lamd
        length = np.where(c4, p.l5, p.l3)
        return {
            'phi': phi,
            'x': x,
            'y': y,
            'sin': sin,
            'cos': cos,
            'omega': omega,
            'eps': eps,
            'v_perp': omega * length,
            'lam': lam,
        }

    def chute_scalar(self, t: float, chute: int) -> tuple[float, float, float, float]:
        """(sin θ', cos θ', ω, ε) of one chute at one time (pure ``math``, a few µs)."""
        p = self.params
        d = self.drive
        ta = np.asarray(float(t))
        turns = float(d.theta(ta)) * self.turns_rate
        phi = TAU * (turns - math.floor(turns))
        lam = float(d.rate(ta))
        lamd = float(d.rate_dot(ta))
        pt = self.model.point(phi)
        w = self.omega
        c, s = math.cos(phi), math.sin(phi)
        R = p.R_kr
        rc, rs = R * c, R * s
        xA, yA = p.a + rc, p.b + rs
        xB, yB = pt.xC * self._r, pt.yC * self._r
        w3 = pt.omega3
        ux, uy = xB - xA, yB - yA
        rvx, rvy = -w3 * yB + w * rs, w3 * xB - w * rc
        num = w3 * w3 * (xB * ux + yB * uy) - w * w * (ux * rc + uy * rs) - (rvx * rvx + rvy * rvy)
        e3 = num / (xA * yB - yA * xB)
        if chute == 0:
            return (pt.xC / p.l3, -pt.yC / p.l3, w3 * lam, e3 * lam * lam + w3 * lamd)
        xC, yC = pt.xC, pt.yC
        wx, wy = pt.xE - p.O2O3, pt.yE
        w5 = pt.omega5
        ux, uy = pt.xE - xC, pt.yE - yC
        cdd = e3 * (uy * xC - ux * yC) - w3 * w3 * (ux * xC + uy * yC)
        rvx, rvy = -w5 * wy + w3 * yC, w5 * wx - w3 * xC
        num = w5 * w5 * (ux * wx + uy * wy) + cdd - (rvx * rvx + rvy * rvy)
        e5 = num / ((xC - p.O2O3) * wy - yC * wx)
        return (wx / p.l5, -wy / p.l5, w5 * lam, e5 * lam * lam + w5 * lamd)


class LeafFlights(NamedTuple):
    """The flights of the exited leaves (``leaf_flight``), in exit order; one element per leaf.

    Fields: ``t_exit`` (s), exit point ``x0, y0`` (m) and velocity ``vx, vy`` (m/s) in the
    project frame, ``t_land`` (s; past the duration for a leaf still in the air at the
    end) and ``x_land`` (m). :func:`folder_line.core.effects.leaf_flight.state` at
    ``t - t_exit`` gives a leaf's position in the air.
    """

    t_exit: np.ndarray
    x0: np.ndarray
    y0: np.ndarray
    vx: np.ndarray
    vy: np.ndarray
    t_land: np.ndarray
    x_land: np.ndarray


def _empty_slowdowns() -> faults.Slowdowns:
    z = np.zeros(0)
    return faults.Slowdowns(z, z, z)


def _stats(x: np.ndarray) -> dict[str, float] | None:
    if x.size == 0:
        return None
    return {'leaves': int(x.size), 'mean': float(np.mean(x)), 'min': float(np.min(x)), 'max': float(np.max(x))}


class LayupLine(LinePart):
    """The layup part of the line on a drive over ``[0, duration]``: built once, sampled anywhere.

    Construction computes the events, constraints and summary (:func:`simulate_layup`
    documents them); :meth:`sample` gives the joint states at any times.

    Parameters
    ----------
    scene : Scene
        Validated scene with a ``layup`` machine (and ``container`` for ``leaf_flight``).
    drive : Drive
        The master drive.
    duration : float
        Line time, s (> 0).
    tunings : iterable of Tuning
        The operator's changes (:mod:`folder_line.core.line.tuning`): here the chute belt
        speed ``layup.v_tr`` from each one's time on.

    Attributes
    ----------
    events : ndarray of EVENT_DTYPE
        Sorted by time.
    constraints : list of ConstraintSeries
    summary : dict
    nodes : dict of str to tuple of str
        Node -> joint names of this part.
    kinematics : LayupKinematics
    """

    def __init__(self, scene: Scene, drive: Drive, duration: float, tunings: Iterable[Tuning] = ()) -> None:
        lp: LayupParams = scene.machine('layup')
        kin = LayupKinematics(lp, drive)
        duration = float(duration)
        theta_end = float(np.asarray(drive.theta(np.asarray(duration)), dtype=float))
        belts_on = scene.has('chute_belts')
        friction_on = scene.has('guide_friction') and not belts_on
        flight_on = scene.has('leaf_flight')
        damage_on = scene.has('leaf_damage')
        faults_on = scene.has('faults')
        sw = sweep(lp)

        # ------------------------------------------------------------------ stream
        slot, t_nom = leaf_stream(scene.sheets, duration, scene.seed)
        in_run = (t_nom >= 0.0) & (t_nom <= duration)
        tables: list[np.ndarray] = []
        slow = None
        if faults_on:
            fp = scene.effect_params('faults')
            sf = faults.draw_sheet_faults(fp, int(slot.size), rng_mod.stream(scene.seed, 'layup.faults'))
            sub = faults.SheetFaults(sf.missing[in_run], sf.double[in_run], sf.delay[in_run])
            if belts_on:
                slow = faults.draw_slowdowns(
                    fp, duration, 60.0 / lp.n_kr, rng_mod.stream(scene.seed, 'layup.belt_slowdowns')
                )
            ids_run, t_run = slot[in_run], t_nom[in_run]
            tables.append(
                faults.fault_events(
                    sub,
                    t_run,
                    ids_run,
                    kin.cycle(t_run),
                    slow if slow is not None else _empty_slowdowns(),
                    duration,
                )
            )
            present = ~sub.missing
            dbl = present & sub.double
            ids = np.concatenate([ids_run[present], ids_run[dbl]])
            t_in = np.concatenate([(t_run + sub.delay)[present], (t_run + sub.delay)[dbl]])
            order = np.lexsort((ids, t_in))
            ids, t_in = ids[order], t_in[order]
        else:
            ids, t_in = slot[in_run], t_nom[in_run]
        entered = t_in <= duration
        ids, t_in = ids[entered], t_in[entered]
        chute = (ids % 2).astype(np.int64)
        length = np.where(chute == 1, lp.l5, lp.l3)
        n = int(ids.size)
        if n:
            tables.append(make_events('leaf_enter', t_in, sheet=ids, cycle=kin.cycle(t_in)))

        # ------------------------------------------------------------------ exit
        profile = None
        v_along = np.zeros(n)
        if belts_on:
            v_tr = chute_belts.check_belt_speed(lp.v_tr)
            steps = belt_steps(tunings, 'layup.v_tr', v_tr)
            profile = chute_belts.belt_profile(v_tr, drive, duration, *belt_intervals(slow, steps))
            t_out, exited = chute_belts.exit_times(profile, drive, length, t_in, theta_end)
            if exited.any():
                v_along[exited] = chute_belts.belt_speed(profile, drive, t_out[exited])
        elif friction_on:
            gp = scene.effect_params('guide_friction')
            guide_friction.check_geometry(gp, min(lp.l3, lp.l5), min(-sw.yC[1] / lp.l3, -sw.yE[1] / lp.l5))

            def kin_vec(t: np.ndarray, ch: np.ndarray) -> guide_friction.ChuteState[npt.NDArray[np.float64]]:
                q = kin.chute(t, ch)
                return guide_friction.ChuteState(q['sin'], q['cos'], q['omega'], q['eps'])

            def kin_one(t: float, ch: int) -> guide_friction.ChuteState[float]:
                return guide_friction.ChuteState(*kin.chute_scalar(t, ch))

            res = guide_friction.slide(gp, kin_vec, kin_one, t_in, chute, length, duration)
            t_out, exited = res.t_exit, res.exited
            v_along = np.where(exited, res.v_exit, 0.0)
            if res.stick_t.size:
                tables.append(
                    make_events('leaf_stick', res.stick_t, sheet=ids[res.stick_leaf], cycle=kin.cycle(res.stick_t))
                )
            if res.slip_t.size:
                tables.append(
                    make_events('leaf_slip', res.slip_t, sheet=ids[res.slip_leaf], cycle=kin.cycle(res.slip_t))
                )
        else:
            t_out, exited = t_in.copy(), np.ones(n, dtype=bool)

        xi = np.flatnonzero(exited)
        t_x, id_x, ch_x = t_out[xi], ids[xi], chute[xi]
        q = kin.chute(t_x, ch_x)
        u = v_along[xi]
        vp = q['v_perp']
        speed = chute_belts.absolute_speed(vp, u) if belts_on else np.sqrt(vp * vp + u * u)
        # t̂ = (sin, −cos), n̂ = (cos, sin)
        vx = u * q['sin'] + vp * q['cos']
        vy = -u * q['cos'] + vp * q['sin']
        cyc_x = kin.cycle(t_x)
        if xi.size:
            tables.append(make_events('leaf_exit', t_x, sheet=id_x, cycle=cyc_x, value=speed))

        constraints: list[ConstraintSeries] = []
        n_damaged = 0
        if damage_on:
            bad = leaf_damage.damaged(scene.effect_params('leaf_damage'), speed)
            n_damaged = int(bad.sum())
            if n_damaged:
                tables.append(
                    make_events('leaf_damaged', t_x[bad], sheet=id_x[bad], cycle=cyc_x[bad], value=speed[bad])
                )
        # the same code as the supervisor's (constraints.evaluate_layup_constraints on the leaf_exit rows)
        chute_series = chute_speed_series(scene, id_x, t_x, speed)
        if chute_series is not None:
            constraints.append(chute_series)

        # ------------------------------------------------------------------ flight
        summary_flight: dict[str, Any] = {}
        n_landed = n_spilled = 0
        flights = None
        if flight_on:
            fpar = scene.effect_params('leaf_flight')
            cont = scene.machine('container')
            lowest = min(sw.yC[0], sw.yE[0])
            if not cont.y_floor < lowest:
                raise ParameterError(
                    'container.y_floor', cont.y_floor, f'must be below the lowest chute exit (y = {lowest!r} m)'
                )
            t_f, x_land = leaf_flight.landing(fpar, q['x'], q['y'], vx, vy, cont.y_floor)
            t_land = t_x + t_f
            order = np.argsort(t_x, kind='stable')
            flights = LeafFlights(*(a[order] for a in (t_x, q['x'], q['y'], vx, vy, t_land, x_land)))
            down = t_land <= duration
            inside = (x_land >= cont.x_left) & (x_land <= cont.x_right)
            li, si = down & inside, down & ~inside
            n_landed, n_spilled = int(li.sum()), int(si.sum())
            if n_landed:
                tables.append(
                    make_events(
                        'leaf_landed', t_land[li], sheet=id_x[li], cycle=kin.cycle(t_land[li]), value=x_land[li]
                    )
                )
            if n_spilled:
                tables.append(
                    make_events(
                        'leaf_spilled', t_land[si], sheet=id_x[si], cycle=kin.cycle(t_land[si]), value=x_land[si]
                    )
                )
            hist = leaf_flight.histogram(x_land[li], cont.x_left, cont.x_right, cont.bins)
            summary_flight = {
                'landing_histogram': {'edges': [float(e) for e in hist.edges], 'counts': [int(c) for c in hist.counts]},
                'landing_cv': hist.cv,
                'landing_x': _stats(x_land[li]),
                'spilled_left': int((si & (x_land < cont.x_left)).sum()),
                'spilled_right': int((si & (x_land > cont.x_right)).sum()),
            }

        # ------------------------------------------------------------------ summary
        summary = _summary(kin, lp, theta_end, n, t_x, speed, u, q['phi'], n_landed, n_spilled, n_damaged)
        summary.update(summary_flight)
        if friction_on:
            summary['guide_friction'] = {
                'steps': int(res.steps),
                'sticks': int(res.stick_t.size),
                'slips': int(res.slip_t.size),
                'exit_speed_along': _stats(u),
            }
        self.scene = scene
        self.drive = drive
        self.duration = duration
        self.kinematics = kin
        self.profile = profile
        #: the leaves' flights with ``leaf_flight`` (what the scenery draws), else None
        self.flights = flights
        self.events = merge_events(tables)
        self.constraints = constraints
        self.summary = summary
        self.units: dict[str, tuple[str, ...]] = {'drive': ('layup_crank', 'transporter3', 'transporter4')}
        if belts_on:
            self.units['belts'] = ('chute_belts',)

    def sample_unit(
        self, unit: str, t: npt.ArrayLike, theta: np.ndarray | None = None, lam: np.ndarray | None = None
    ) -> JointSamples:
        """Joint states of one unit (``drive``; ``belts`` with belts) at ``t``."""
        t = np.asarray(t, dtype=float).reshape(-1)
        theta, lam = self._drive_state(t, theta, lam)
        kin = self.kinematics
        if unit == 'drive':
            phi = kin.wrap(theta * kin.turns_rate)
            st = kin.model.arrays(phi, accelerations=False)  # θ, ω do not depend on the accelerations
            return stack_samples(
                'drive',
                ['layup_crank', 'transporter3', 'transporter4'],
                t,
                [phi, st.theta3, st.theta5],
                [kin.omega * lam, st.omega3 * lam, st.omega5 * lam],
            )
        if unit == 'belts' and self.profile is not None:
            pr = self.profile
            return stack_samples(
                'belts',
                ['chute_belts'],
                t,
                [pr.v_tr * pr.phase.at(t, theta)],
                [pr.v_tr * lam * pr.phase.factor(t)],
            )
        raise KeyError(f'unit {unit!r} has no layup joints; units: {", ".join(self.units)}')


def simulate_layup(scene: Scene, drive: Drive, duration: float, t_samples: np.ndarray) -> SubResult:
    """Simulate the layup part of the line.

    Parameters
    ----------
    scene : Scene
        Validated scene with a ``layup`` machine (and ``container`` for ``leaf_flight``).
    drive : Drive
        The master drive.
    duration : float
        Line time, s (> 0).
    t_samples : ndarray
        Joint-state sample times, s (may be empty).

    Returns
    -------
    SubResult
        * events: ``leaf_enter``; ``leaf_exit`` (value: absolute exit speed, m/s);
          ``leaf_landed``/``leaf_spilled`` (value: landing x, m) with ``leaf_flight``;
          ``leaf_damaged`` (value: exit speed) with ``leaf_damage``;
          ``leaf_stick``/``leaf_slip`` with ``guide_friction``; the fault events with
          ``faults``. ``sheet`` is the leaf id, ``cycle`` the crank cycle at the event.
        * samples (if ``t_samples`` is not empty): unit ``drive``, joints
          ``layup_crank`` (φ in [0, 2π), ω λ), ``transporter3`` (θ3, ω3),
          ``transporter4`` (θ5, ω5), rad and rad/s; with belts, unit
          ``belts``, joint ``chute_belts``: belt travel since t = 0, m (v_tr Θ,
          less the travel lost in slow-downs), and belt speed v_tr λ f, m/s.
        * constraints: ``chute_speed`` per exited leaf (``cycle`` = leaf id), m/s, with
          belts (:mod:`folder_line.core.effects.chute_belts`).
        * summary (JSON-ready; None where there is nothing to report): ``crank_cycles``,
          ``leaves`` (entered), ``leaves_exited``, ``leaves_landed``,
          ``leaves_spilled``, ``leaves_damaged``, ``min_exit_speed``,
          ``max_exit_speed``, ``mean_exit_speed`` (m/s), ``exit_speed_at_extremes``
          (per dead centre ``extended``/``folded``: its crank angle ``phi`` and the
          exit-speed statistics of the leaves leaving within ±5° of it),
          ``exit_speed_by_phase`` (mean exit speed in 36 bins of exit crank angle),
          ``swing_speed`` (min/max of |v_C|, |v_E| over a turn at nominal speed, for
          reference); with ``leaf_flight``: ``landing_histogram`` {``edges``,
          ``counts``}, ``landing_cv``, ``landing_x`` statistics, ``spilled_left``,
          ``spilled_right``; with ``guide_friction``: ``guide_friction`` {``steps``,
          ``sticks``, ``slips``, ``exit_speed_along``}.

    Raises
    ------
    ParameterError
        ``layup.v_tr <= 0`` with belts; ``container.y_floor`` not below the exits
        with ``leaf_flight``; a guide-friction entry point beyond a chute, or a chute
        pointing upward, with ``guide_friction``.
    """
    return LayupLine(scene, drive, duration).result(t_samples)


def _summary(
    kin: LayupKinematics,
    lp: LayupParams,
    theta_end: float,
    n: int,
    t_x: np.ndarray,
    speed: np.ndarray,
    v_along: np.ndarray,
    phi_x: np.ndarray,
    n_landed: int,
    n_spilled: int,
    n_damaged: int,
) -> dict[str, Any]:
    ext = swing_extremes(lp)
    at_ext: dict[str, Any] = {}
    for e in ext:
        d = np.abs(np.remainder(phi_x - e.phi + math.pi, TAU) - math.pi)
        near = d <= EXTREME_WINDOW
        entry = _stats(speed[near])
        at_ext[e.kind] = {'phi': e.phi, 'window_deg': math.degrees(EXTREME_WINDOW), 'exit_speed': entry}
    edges = np.linspace(0.0, TAU, PHASE_BINS + 1)
    b = np.clip(np.searchsorted(edges, phi_x, side='right') - 1, 0, PHASE_BINS - 1)
    cnt = np.bincount(b, minlength=PHASE_BINS)
    tot = np.bincount(b, weights=speed, minlength=PHASE_BINS)
    by_phase = [float(tot[i] / cnt[i]) if cnt[i] else None for i in range(PHASE_BINS)]
    grid = kin.model.arrays(np.concatenate([np.arange(4096) * (TAU / 4096), [e.phi for e in ext]]), accelerations=False)
    swing = np.abs(np.concatenate([grid.vC, grid.vE]))
    return {
        'crank_cycles': int(math.floor(theta_end * kin.turns_rate)),
        'leaves': n,
        'leaves_exited': int(t_x.size),
        'leaves_landed': n_landed,
        'leaves_spilled': n_spilled,
        'leaves_damaged': n_damaged,
        'min_exit_speed': float(speed.min()) if speed.size else None,
        'max_exit_speed': float(speed.max()) if speed.size else None,
        'mean_exit_speed': float(speed.mean()) if speed.size else None,
        'exit_speed_at_extremes': at_ext,
        'exit_speed_by_phase': {'edges_deg': [float(math.degrees(x)) for x in edges], 'mean': by_phase},
        'swing_speed': {'min': float(swing.min()), 'max': float(swing.max())},
    }
