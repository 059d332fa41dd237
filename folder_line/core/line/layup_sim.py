"""L over a span in one window: :class:`LayupLine` and ``simulate_layup(scene, drive, duration, t_samples)``.

:class:`LayupLine` runs the streamed layup (:class:`folder_line.core.line.layup_stream.LayupStream`)
over ``[0, duration]`` in one window and keeps what it handed out.

Leaves stream into the two chutes (transporter 3 with exit C, transporter 4 with
exit E, alternating), leave the chute exits and, with ``leaf_flight``, fly to the
container floor (paper 000; docs/machines.md, section L).

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
  its exit speed is ``|v_C|``, zero at the swing extremes.

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

The crank kinematics are :class:`folder_line.core.line.layup_kinematics.LayupKinematics`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
import numpy.typing as npt

from folder_line.core.line.folder_sim import join_rows
from folder_line.core.line.layup_figures import LayupFigures
from folder_line.core.line.layup_stream import LayupStream
from folder_line.core.line.tuning import Tuning
from folder_line.core.mechanisms.drive import Drive
from folder_line.core.numerics import rng as rng_mod
from folder_line.core.types.events import JointSamples, LinePart, SubResult
from folder_line.core.types.machines import StreamParams

if TYPE_CHECKING:
    from folder_line.core.line.scene import Scene

__all__ = [
    'LayupLine',
    'LeafFlights',
    'leaf_stream',
    'simulate_layup',
]


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
    n = math.floor(span / stream.interval) + 1 if span >= 0.0 else 0
    j = np.arange(n, dtype=np.int64)
    u = rng_mod.stream(seed, 'layup.leaves').random(n) - 0.5
    t = stream.phase + j * stream.interval + stream.jitter * stream.interval * u
    return j, t


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


class LayupLine(LinePart[LayupFigures]):
    """The layup part of the line on a drive over ``[0, duration]``, in one window, kept.

    Parameters
    ----------
    scene : Scene
        Validated scene with a ``layup`` machine (and ``container`` for ``leaf_flight``).
    drive : Drive
        The master drive.
    duration : float
        Line time, s (> 0).
    tunings : iterable of Tuning
        The operator's changes: here the chute belt speed ``layup.v_tr``.

    Attributes
    ----------
    events : ndarray of EVENT_DTYPE
        Sorted by time, kind, sheet.
    constraints : list of ConstraintSeries
    summary : LayupFigures
    kinematics : LayupKinematics
    flights : LeafFlights or None
        Every exited leaf's flight with ``leaf_flight``, in exit order.
    stream : LayupStream
    """

    def __init__(self, scene: Scene, drive: Drive, duration: float, tunings: Iterable[Tuning] = ()) -> None:
        ls = LayupStream(scene, drive, tunings)
        duration = float(duration)
        ls.compute(duration + ls.lookahead)
        events, rows = ls.emit(duration)
        self.scene = scene
        self.drive = drive
        self.duration = duration
        self.stream = ls
        self.kinematics = ls.kinematics
        self.profile = ls.profile
        self.events = events
        names = ['chute_speed'] if scene.has('chute_belts') else []
        self.constraints = join_rows(rows, names, {}) if rows else []
        theta_end = float(np.asarray(drive.theta(np.array([duration])), dtype=float)[0])
        self.summary = ls.summary(theta_end)
        self.units = ls.units
        self.flights: LeafFlights | None = None
        if ls.flight_on:
            fv = ls.flights_view()
            fv = fv[fv['t_exit'] <= duration]
            self.flights = LeafFlights(*(fv[k] for k in ('t_exit', 'x0', 'y0', 'vx', 'vy', 't_land', 'x_land')))

    def sample_unit(
        self, unit: str, t: npt.ArrayLike, theta: np.ndarray | None = None, lam: np.ndarray | None = None
    ) -> JointSamples:
        """Joint states of one unit (``drive``; ``belts`` with belts) at ``t`` (s, in ``[0, duration]``)."""
        tt = np.asarray(t, dtype=float).reshape(-1)
        theta, lam = self._drive_state(tt, theta, lam)
        return self.stream.sample_unit(unit, tt, theta, lam)


def simulate_layup(scene: Scene, drive: Drive, duration: float, t_samples: np.ndarray) -> SubResult[LayupFigures]:
    """Simulate the layup part of the line: ``LayupLine(scene, drive, duration).result(t_samples)``.

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
        * constraints: ``chute_speed`` per exited leaf (``cycle`` = leaf id), m/s, with belts.
        * summary (:class:`~folder_line.core.line.layup_figures.LayupFigures`; its ``as_json()``, None
          where there is nothing to report): ``crank_cycles``,
          ``leaves`` (entered), ``leaves_exited``, ``leaves_landed``, ``leaves_spilled``,
          ``leaves_damaged``, ``min_exit_speed``, ``max_exit_speed``, ``mean_exit_speed``
          (m/s), ``exit_speed_at_extremes``, ``exit_speed_by_phase`` (mean exit speed in 36
          bins of exit crank angle), ``swing_speed``; with ``leaf_flight``:
          ``landing_histogram`` {``edges``, ``counts``}, ``landing_cv``, ``landing_x``,
          ``spilled_left``, ``spilled_right``; with ``guide_friction``: ``guide_friction``
          {``steps`` (RK4 steps summed over the leaves), ``sticks``, ``slips``, ``exit_speed_along``}.

    Raises
    ------
    ParameterError
        ``layup.v_tr <= 0`` with belts; ``container.y_floor`` not below the exits
        with ``leaf_flight``; a guide-friction entry point beyond a chute, or a chute
        pointing upward, with ``guide_friction``.
    """
    return LayupLine(scene, drive, duration).result(t_samples)
