"""Effect ``motor_dynamics``: the master drive from a motor torque-speed curve and inertia.

Source: ours (docs/scenes.md, "Effects", ``motor_dynamics``)
(``J dω/dt = T_m(ω) - T_load(φ, ω)``, linear ``T_m = T_0 (1 - ω/ω_0)`` near the
operating point, load from ``chain_friction`` plus viscous ``b ω``, start from
standstill, stop by a brake torque).

Equations
---------
State ``y = (Θ, ω)``: Θ the master phase in nominal seconds (the drive's phase,
:mod:`folder_line.core.mechanisms.drive`), ω the master-shaft speed (rad/s)::

    dΘ/dt = ω / ω_nom                                      (λ = ω / ω_nom)
    J dω/dt = T_0 (1 - ω/ω_0) - b ω - T_load(Θ)            motor on,  0 <= t < t_stop
    J dω/dt =                - b ω - T_load(Θ) - T_brake   braking,   t_stop <= t < t_rest
    ω = 0, Θ = Θ(t_rest)                                   at rest,   t >= t_rest

``T_load`` is the delivery's sprocket torque reflected to the master shaft
(:func:`folder_line.core.effects.chain_friction.master_load_torque`) when the scene
lists ``chain_friction``, else 0. Start at standstill: Θ(0) = 0, ω(0) = 0.

Without position-dependent load the motor-on equation is linear:
``ω(t) = ω_ss (1 - exp(-t/τ))`` with ``c = T_0/ω_0 + b``, ``τ = J/c``,
``ω_ss = T_0 / c``, and ``Θ(t) = (ω_ss/ω_nom) (t - τ (1 - exp(-t/τ)))``. In general the
steady speed solves ``T_0 (1 - ω/ω_0) = b ω + mean load``:
``ω_ss = (T_0 - L̄)/c`` (:func:`steady_speed`; ``L̄`` the mean of ``T_load`` over Θ, a
good estimate while the speed ripple is small), ``λ_ss = ω_ss/ω_nom``. Pick ``T_0``
for ``λ_ss = 1`` with :func:`stall_torque_for`.

Discontinuities, handled exactly
--------------------------------
* **Brake.** The run is integrated in segments: motor on over ``[0, min(t_stop,
  duration)]``; from ``t_stop`` the brake segment, whose right-hand side is the ω > 0
  branch (the brake and the load oppose the motion), ends at the root ω = 0 located on
  the dense output (:class:`~folder_line.core.numerics.integrators.Terminal`); from then on the
  shaft stands (the brake holds it; nothing drives it) and Θ is constant.
  ``t_stop >= duration``: the motor never stops. ``T_brake = 0``: the shaft coasts
  down on ``b`` and the load (it may never reach rest).
* **Chain load.** The load jumps where a carriage enters or leaves the stroke; those
  Θ are breaks of the integrator (:class:`~folder_line.core.numerics.integrators.Breaks`):
  no step straddles one, so both methods keep their order.

Periodic steady state (``periodic=True``, the default)
------------------------------------------------------
The load is periodic in Θ (period ``T``, one carriage per knife cycle) and the motor
equation does not depend on t, so once the transient has died out the solution
repeats: ``Θ(t + P) = Θ(t) + T``, ``ω(t + P) = ω(t)``. The integrator lands on the
period marks Θ_k (a carriage entering the stroke; without load every
``max(τ, h) λ_free`` nominal s). When ω at three consecutive marks agrees to
``PERIODIC_TOL ω_nom`` and the two periods ``P`` to ``PERIODIC_TOL P``, integration
stops and the last period is repeated up to ``t_stop`` (the brake segment is
integrated again from there). The transient left out is below about
``PERIODIC_TOL ω_nom / (1 - exp(-T/τ))``. An hour of line time then costs the
transient's steps only (~8 s of it on the suggested scene values: 0.2-0.6 s of CPU);
``periodic=False`` integrates the whole span (for benchmarks of the methods).

Supervisor commands (switching times)
-------------------------------------
:func:`build_drive` takes the supervisor's commands
(:class:`folder_line.core.mechanisms.drive.Command`): ``hold``/``stop`` at ``t`` switch the motor
off and apply the brake from ``t`` (the brake segment above, from the state at ``t``);
``unhold``/``start`` switch it on again from the state at ``t`` (standstill or still
coasting down). The scene's ``t_stop`` is one more motor-off switch. Switches that do
not change the motor's state are ignored. The run is a list of
:class:`MotorSegment`; a motor-on segment from ``t_0`` is *integrated* up to the
scene's ``t_stop`` (if later) or the end of the run, never to a command's time, and
*evaluated* only up to the next switch; a brake segment is integrated until
standstill. Hence Θ(t) before a command's time is the same, bit for bit, with or
without that command. Limits: each on-segment finds its own periodic tail (a restart
re-integrates its transient, ~8 s of line time); the brake holds the shaft at rest
whatever the load (the load never drives the shaft backwards).

Phase and tolerances: the error norm of ``dopri5`` is relative to ``|y|``, and Θ grows
with time, so ``rtol`` bounds the *relative* phase error per step. ``rk4`` uses the
fixed step ``h``; it is rejected up front when ``z = h c / J`` exceeds
:data:`RK4_STEP_LIMIT` = 2.21 on the linear part. RK4 is stable up to ``z = 2.785``, but
its error factor per step ``R(z) = 1 - z + z²/2 - z³/6 + z⁴/24`` creeps back to 1 there
(0.42 at z = 2.2, 0.9996 at 2.785: the start-up stalls), and from ``z = 2.2134`` the cubic
Hermite dense output between the steps overshoots (from standstill the speed dips below
zero in the first step from z ≈ 2.65). Up to 2.21 the dense output of a start-up is
monotone.

Drive protocol (:class:`MotorDrive`): ``theta``, ``rate`` (λ = ω/ω_nom), ``rate_dot``
(the right-hand side at the dense state, /ω_nom), ``time_of`` (the integrator's
vectorised inverse of Θ). Times are clipped to ``[0, duration]`` (the drive knows
nothing outside the run); ``time_of`` clips Θ to ``[0, Θ(duration)]`` -- a phase
beyond the end of the run returns ``duration`` (callers drop such events), a phase on
the rest plateau the time the shaft came to rest. Never NaN.

The step loop is sequential Python (an ODE); the right-hand side is scalar
(:meth:`~folder_line.core.effects.chain_friction.MasterLoad.torque_piece`, ~10 µs).
"""

from __future__ import annotations

import bisect
import copy
import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from folder_line.core.effects import chain_friction
from folder_line.core.limits import DURATION, LINE_DAMPING, MOTOR_INERTIA, MOTOR_SPEED, MOTOR_TORQUE
from folder_line.core.mechanisms.drive import Command, check_commands
from folder_line.core.mechanisms.scene_view import SceneView
from folder_line.core.numerics import dense
from folder_line.core.numerics import integrators as ig
from folder_line.core.numerics.arrays import FloatArray
from folder_line.core.numerics.constants import EPS
from folder_line.core.numerics.validate import among, check_fields, in_range, non_negative, positive, within
from folder_line.errors import ParameterError

__all__ = [
    'METHODS',
    'PERIODIC_TOL',
    'RK4_STABILITY',
    'RK4_STEP_LIMIT',
    'MotorDrive',
    'MotorSegment',
    'Params',
    'PeriodicTail',
    'build_drive',
    'stall_torque_for',
    'steady_speed',
]


METHODS = ('rk4', 'dopri5')
#: RK4 is stable for ``h·|λ|`` up to 2.785 on the negative real axis
RK4_STABILITY = 2.785
#: largest ``h·|λ|`` accepted for RK4: its dense output stays monotone on a linear start-up (z* = 2.2134)
RK4_STEP_LIMIT = 2.21
#: relative agreement of ω (and of the period) at three marks that counts as periodic
PERIODIC_TOL = 1e-12
#: longest span :func:`build_drive` integrates, s (:data:`folder_line.core.limits.DURATION`, and an hour)
MAX_DURATION = DURATION.hi + 3600.0
#: step attempts allowed per integration
MAX_STEPS = 20_000_000


@dataclass(frozen=True)
class Params:
    """Parameters of ``motor_dynamics`` (no defaults: the scene gives them all).

    Attributes
    ----------
    J : float
        Inertia of the master shaft with everything geared to it, kg m², in
        :data:`~folder_line.core.limits.MOTOR_INERTIA`.
    T_0 : float
        Stall torque of the linear motor curve ``T_m = T_0 (1 - ω/ω_0)``, N m, in
        :data:`~folder_line.core.limits.MOTOR_TORQUE`.
    omega_0 : float
        No-load speed, rad/s (> omega_nom).
    omega_nom : float
        Nominal master-shaft speed (λ = ω/omega_nom), rad/s, in :data:`~folder_line.core.limits.MOTOR_SPEED`.
    b : float
        Viscous load of the line, N m s, in :data:`~folder_line.core.limits.LINE_DAMPING`.
    method : {'rk4', 'dopri5'}
        Fixed-step RK4 (step ``h``) or adaptive DOPRI5 (``rtol``, ``atol``, max step ``h``).
    h : float
        RK4 step / DOPRI5 largest step, s (> 0).
    rtol : float
        DOPRI5 relative tolerance, in [100 eps, 1).
    atol : float
        DOPRI5 absolute tolerance (Θ in nominal s, ω in rad/s), in [1e-20, 1000].
    t_stop : float
        Motor switched off and brake applied at this time, s (>= 0; ``>= duration``: never).
    T_brake : float
        Brake torque, N m (>= 0).
    """

    J: float
    T_0: float
    omega_0: float
    omega_nom: float
    b: float
    method: str
    h: float
    rtol: float
    atol: float
    t_stop: float
    T_brake: float

    def __post_init__(self) -> None:
        check_fields(
            self,
            'effects.motor_dynamics',
            J=MOTOR_INERTIA.check,
            T_0=MOTOR_TORQUE.check,
            **dict.fromkeys(('omega_0', 'h'), positive),
            atol=within(1e-20, 1e3),  # a tolerance, not a physical magnitude: reference solutions go to 1e-16
            omega_nom=MOTOR_SPEED.check,
            b=LINE_DAMPING.check,
            **dict.fromkeys(('t_stop', 'T_brake'), non_negative),
            rtol=within(100 * EPS, 1.0, hi_open=True),
            method=among(METHODS),
        )
        if not self.omega_nom < self.omega_0:
            raise ParameterError(
                'effects.motor_dynamics.omega_nom',
                self.omega_nom,
                f'must be < omega_0 = {self.omega_0!r} rad/s: the motor cannot reach its nominal '
                'speed at or above its no-load speed',
            )

    @property
    def damping(self) -> float:
        """``c = T_0/ω_0 + b``: slope of the net torque against ω, N m s."""
        return self.T_0 / self.omega_0 + self.b

    @property
    def tau(self) -> float:
        """Mechanical time constant ``J / c``, s."""
        return self.J / self.damping

    @property
    def omega_free(self) -> float:
        """Steady speed without chain load, ``T_0 / c``, rad/s."""
        return self.T_0 / self.damping


def steady_speed(params: Params, mean_load: float = 0.0) -> float:
    """Steady speed ``(T_0 - mean_load) / (T_0/ω_0 + b)``, rad/s (mean_load in N m)."""
    return (params.T_0 - float(mean_load)) / params.damping


def stall_torque_for(omega_0: float, omega_nom: float, b: float, mean_load: float = 0.0, lam: float = 1.0) -> float:
    """The ``T_0`` (N m) whose steady speed is ``lam omega_nom`` with viscous ``b`` and ``mean_load``.

    Solves ``T_0 (1 - ω/ω_0) = b ω + mean_load`` at ``ω = lam omega_nom`` (rad/s; needs ω < ω_0).
    """
    w = lam * omega_nom
    if not 0.0 < w < omega_0:
        raise ParameterError('lam', lam, f'needs 0 < lam omega_nom < omega_0 = {omega_0!r}')
    return (b * w + mean_load) / (1.0 - w / omega_0)


@dataclass(frozen=True)
class PeriodicTail:
    """The repeated last period: on ``[t_b, t_end]``, ``y(t) = y(t_a + s) + n (dTheta, 0)``.

    Attributes
    ----------
    t_a, t_b : float
        The base period ``[t_a, t_b]`` of the integrated solution, s.
    theta_a, theta_b : float
        Θ at ``t_a`` and ``t_b`` (``dTheta = theta_b - theta_a``), nominal s.
    t_end : float
        End of the tail (motor switched off, or the end of the run), s.
    """

    t_a: float
    t_b: float
    theta_a: float
    theta_b: float
    t_end: float

    @property
    def period(self) -> float:
        """Period in time ``P = t_b - t_a``, s."""
        return self.t_b - self.t_a

    @property
    def dtheta(self) -> float:
        """Θ advance per period, nominal s."""
        return self.theta_b - self.theta_a


class MotorSegment:
    """A stretch of constant motor state: motor on, or off with the brake applied, integrated as far as asked.

    Parameters
    ----------
    t0 : float
        Start, s.
    t1 : float
        The next switch, s (``inf`` if none is known): the segment holds for ``t0 <= t < t1``.
    on : bool
        Motor on (else off, braking, then at rest).
    y0 : ndarray, shape (2,)
        ``(Θ, ω)`` at ``t0``.
    stepper : RK4Stepper or Dopri5Stepper or None
        The integration from ``t0`` (None: off and already at rest).
    period : PeriodMarks or None
        Motor on with the periodic shortcut: the ``on_break`` of the stepper's breaks.
    t_bound : float
        Where the integration ends (motor on: the scene's ``t_stop`` if later, else ``inf``), s.

    Attributes
    ----------
    tail : PeriodicTail or None
        Motor on: the repeated period, once found.
    t_rest : float
        Off: standstill reached, s (``inf`` until then); on: ``inf``.
    """

    def __init__(
        self,
        t0: float,
        t1: float,
        on: bool,
        y0: FloatArray,
        stepper: ig.RK4Stepper | ig.Dopri5Stepper | None,
        period: PeriodMarks | None = None,
        t_bound: float = math.inf,
    ) -> None:
        self.t0, self.t1, self.on = float(t0), float(t1), on
        self.t_bound = float(t_bound)
        self.theta0 = float(y0[0])
        self.stepper = stepper
        self.period = period
        self.tail: PeriodicTail | None = None
        self.t_rest = math.inf if stepper is not None or on else self.t0
        self.theta_rest = self.theta0
        self._sol: dense.DenseSolution | None = None
        self._lists: tuple[list[float], list[float], list[list[list[float]]]] | None = None

    # integration -------------------------------------------------------------------------
    @property
    def done(self) -> bool:
        """Nothing more to integrate: the period repeats, the shaft rests, or the integration ended."""
        st = self.stepper
        return self.tail is not None or not math.isinf(self.t_rest) or st is None or st.status != 'running'

    @property
    def covered(self) -> float:
        """The time up to which the state is known, s."""
        if self.tail is not None or not math.isinf(self.t_rest) or self.stepper is None:
            return math.inf
        return self.stepper.t

    def advance(self, t: float) -> None:
        """Integrate until the state at ``t`` is known (or nothing is left to integrate)."""
        st = self.stepper
        if st is None or self.done or (st.t >= t and st.t > self.t0):
            return
        st.advance(max(t, math.nextafter(st.t, math.inf)))  # at least one step: the segment evaluates at t0
        self._sol = None
        self._lists = None
        if st.status == 'terminal':  # the brake's standstill
            sol = self.solution
            self.t_rest = float(sol.t[-1])
            self.theta_rest = float(sol.y[-1, 0])
        elif st.status == 'stopped' and self.period is not None:  # three period marks agree
            (ta, _), (tb, _) = self.period.marks[-2], self.period.marks[-1]
            th = self.solution.component(np.array([ta, tb]), 0)
            self.tail = PeriodicTail(t_a=ta, t_b=tb, theta_a=float(th[0]), theta_b=float(th[1]), t_end=self.t_bound)

    def prune(self, t_keep: float) -> None:
        """Forget the steps that end before ``t_keep`` (s): never those of the repeated period, nor those
        from the second-last period mark on while the period is being looked for."""
        st = self.stepper
        if st is None or self.tail is not None:
            return
        marks = [] if self.period is None else self.period.marks
        st.prune(t_keep if len(marks) < 2 else min(t_keep, marks[-2][0]))
        self._sol = None
        self._lists = None

    @property
    def solution(self) -> dense.DenseSolution:
        """The steps kept (the dense output)."""
        if self._sol is None:
            assert self.stepper is not None
            self._sol = self.stepper.solution()
        return self._sol

    # evaluation --------------------------------------------------------------------------
    def component(self, tt: FloatArray, j: int) -> FloatArray:
        """Θ (j = 0) or ω (j = 1) at times ``tt`` of this segment (integrated there)."""
        if self.stepper is None:
            return np.full(tt.shape, self.theta_rest if j == 0 else 0.0)
        out = np.empty(tt.shape)
        rest = tt >= self.t_rest
        if rest.any():
            out[rest] = self.theta_rest if j == 0 else 0.0
        live = ~rest
        if not live.any():
            return out
        tl, sol = self.tail, self.solution
        if tl is None:
            out[live] = sol.component(tt[live], j)
            return out
        head = live & (tt <= tl.t_b)
        in_tail = live & ~head
        if head.any():
            out[head] = sol.component(tt[head], j)
        if in_tail.any():
            x = tt[in_tail] - tl.t_a
            n = np.floor(x / tl.period)
            tb = tl.t_a + np.clip(x - n * tl.period, 0.0, tl.period)
            out[in_tail] = sol.component(tb, j) + (n * tl.dtheta if j == 0 else 0.0)
        return out

    def state1(self, t: float) -> tuple[float, float]:
        """``(Θ, ω)`` at one time in plain Python: the same operations as :meth:`component` (dense-output
        lookup, Horner's rule, the tail's shift), so the same values bit for bit, at a few µs (a node's tick)."""
        if self.stepper is None or t >= self.t_rest:
            return self.theta_rest, 0.0
        lists = self._lists
        sol = self.solution
        if lists is None:  # built on first use
            lists = (sol.t.tolist(), sol.h.tolist(), [sol.coef[:, i, :].T.tolist() for i in range(sol.steps)])
            self._lists = lists
        tl = self.tail
        advance = None  # Θ gained over the whole periods skipped on the tail
        if tl is not None and t > tl.t_b:
            x = t - tl.t_a
            shift = math.floor(x / tl.period)
            t = tl.t_a + min(max(x - shift * tl.period, 0.0), tl.period)
            advance = shift * tl.dtheta
        ts, hs, cs = lists
        i = min(max(bisect.bisect_right(ts, t) - 1, 0), len(hs) - 1)
        x = (t - ts[i]) / hs[i]
        y = []
        for c in cs[i]:  # per component, c[k] the coefficient of x^k
            acc = c[4]
            for k in (3, 2, 1, 0):
                acc = acc * x + c[k]
            y.append(acc)
        if advance is None:
            return y[0], y[1]
        return y[0] + advance, y[1] + 0.0

    def state(self, t: float) -> FloatArray:
        """``(Θ, ω)`` at time ``t`` of the segment (its end included): where the integration ended exactly
        there, its end state."""
        if self.stepper is None or t >= self.t_rest:
            return np.array([self.theta_rest, 0.0])
        tl = self.tail
        sol = self.solution
        if tl is not None and t > tl.t_b:
            x = t - tl.t_a
            n = math.floor(x / tl.period)
            ts = tl.t_a + min(max(x - n * tl.period, 0.0), tl.period)
            return np.array([float(sol.component(ts, 0)) + n * tl.dtheta, float(sol.component(ts, 1))])
        if t == sol.t_end:
            return sol.y[-1, :].copy()
        return np.array([float(sol.component(t, 0)), float(sol.component(t, 1))])

    def theta_known(self) -> float:
        """Θ at the end of what is integrated (``inf`` on a repeated period)."""
        if self.tail is not None:
            return math.inf
        if self.stepper is None or not math.isinf(self.t_rest):
            return self.theta_rest
        return float(self.stepper.y[0])

    def inverse(self, th: FloatArray) -> FloatArray:
        """Earliest times of this segment with Θ = ``th`` (``th`` within what is integrated)."""
        if self.stepper is None:
            return np.full(th.shape, self.t0)
        tl = self.tail
        sol = self.solution
        if tl is None:
            return np.minimum(sol.inverse(th, 0), self.t1)
        out = np.empty(th.shape)
        head = th <= tl.theta_b
        in_tail = ~head
        if head.any():
            out[head] = sol.inverse(th[head], 0)
        if in_tail.any():
            n = np.floor((th[in_tail] - tl.theta_a) / tl.dtheta)
            r = np.clip(th[in_tail] - n * tl.dtheta, tl.theta_a, tl.theta_b)
            out[in_tail] = sol.inverse(r, 0) + n * tl.period
        return np.minimum(out, self.t1)


class PeriodMarks:
    """The ``on_break`` of a motor-on integration: the last three period marks ``(t, ω)``; True (stop) once
    ω at three consecutive marks agrees to ``PERIODIC_TOL ω_nom`` and the two periods to ``PERIODIC_TOL``.

    Parameters
    ----------
    is_mark : callable
        Whether a break value is a period mark.
    omega_nom : float
        Nominal shaft speed, rad/s.
    """

    def __init__(self, is_mark: Callable[[float], bool], omega_nom: float) -> None:
        self.is_mark = is_mark
        self.omega_nom = omega_nom
        self.marks: list[tuple[float, float]] = []

    def __call__(self, t: float, y: FloatArray, b: float) -> bool:
        if not self.is_mark(b):
            return False
        self.marks.append((t, float(y[1])))
        del self.marks[:-3]
        if len(self.marks) < 3:
            return False
        (ta, wa), (tb, wb), (tc, wc) = self.marks
        tol = PERIODIC_TOL * self.omega_nom
        return abs(wc - wb) <= tol and abs(wb - wa) <= tol and abs((tc - tb) - (tb - ta)) <= PERIODIC_TOL * (tc - tb)


#: line time past what is integrated that :meth:`MotorDrive.time_of` integrates to find a phase, s: beyond
#: it a phase counts as never reached (a shaft coasting to rest without a brake never gets there)
REACH = 3600.0


class MotorDrive:
    """The master drive from the motor ODE (Drive protocol of :mod:`folder_line.core.mechanisms.drive`).

    A list of :class:`MotorSegment` (motor on / off), switched at the scene's ``t_stop`` and at
    the supervisor's commands, integrated as far as the line is asked for: a time beyond
    what is integrated integrates on (:meth:`extend`), so the steps never depend on where
    the line was asked (a step straddles every window end). :meth:`prune` forgets the steps
    before a time; a motor-on segment stops integrating once its period repeats.

    Attributes
    ----------
    params : Params
    duration : float
        Times are clipped to ``[0, duration]`` (``inf`` for a stream: no clip).
    segments : list of MotorSegment
        In time order (those before the last :meth:`prune` gone).
    switches : list of (float, bool)
        Effective switches ``(t, motor on after t)``.
    load : MasterLoad or None
        The chain load.
    """

    def __init__(
        self,
        params: Params,
        load: chain_friction.MasterLoad | None,
        switches: list[tuple[float, bool]],
        *,
        periodic: bool = True,
        commanded: bool = False,
        duration: float = math.inf,
    ) -> None:
        self.params = params
        self.load = load
        self.switches = switches
        self.periodic = periodic
        self.commanded = commanded
        self.duration = float(duration)
        p = params
        J, T0, w0, b, Tb, wn = p.J, p.T_0, p.omega_0, p.b, p.T_brake, p.omega_nom
        if load is not None:
            self._load_torque = load.torque_piece
            self._next_break = load.next_break
            self._is_mark = load.is_entry
        else:
            # period marks: the Θ advance over one time constant (or one largest step, if longer) at the free speed
            self._mark = max(p.tau, p.h) * p.omega_free / wn
            self._load_torque = _no_load
            self._next_break = self._mark_after
            self._is_mark = _every
        load_torque = self._load_torque

        def rhs_on(t: float, y: FloatArray, piece: tuple[float, float] = (0.0, math.inf)) -> FloatArray:
            w = y[1]
            return np.array([w / wn, (T0 * (1.0 - w / w0) - b * w - load_torque(y[0], piece)) / J])

        def rhs_brake(t: float, y: FloatArray, piece: tuple[float, float] = (0.0, math.inf)) -> FloatArray:
            w = y[1]
            return np.array([w / wn, (-b * w - load_torque(y[0], piece) - Tb) / J])

        self._rhs_on, self._rhs_brake = rhs_on, rhs_brake
        on0 = True  # the line starts running, unless switched off at t = 0
        for ts, on in switches:
            if ts <= 0.0:
                on0 = on
        self.segments: list[MotorSegment] = [self._segment(0.0, on0, np.zeros(2))]
        self.nfev_dropped = self.steps_dropped = self.rejected_dropped = 0

    def __deepcopy__(self, memo: dict[int, Any]) -> MotorDrive:
        """A copy that integrates on independently (the parameters and the chain load shared)."""
        memo[id(self.params)] = self.params
        if self.load is not None:
            memo[id(self.load)] = self.load
        new = MotorDrive.__new__(MotorDrive)
        memo[id(self)] = new
        for key, value in self.__dict__.items():
            setattr(new, key, copy.deepcopy(value, memo))
        return new

    # building ----------------------------------------------------------------------------
    def _mark_after(self, v: float) -> float:
        k = math.floor(v / self._mark) + 1
        bk = k * self._mark
        return bk if bk > v else (k + 1) * self._mark

    def _next_switch(self, t0: float) -> float:
        return next((t for t, _ in self.switches if t > t0), math.inf)

    def _segment(self, t0: float, on: bool, y0: FloatArray) -> MotorSegment:
        """The segment from ``t0`` with state ``y0``: motor on, integrated up to the scene's ``t_stop`` (if
        later; never to a command's time), or the brake until standstill."""
        p = self.params
        t1 = self._next_switch(t0)
        if on:
            t_bound = p.t_stop if t0 < p.t_stop else math.inf
            period = PeriodMarks(self._is_mark, p.omega_nom) if self.periodic else None
            use_breaks = self.load is not None or self.periodic
            breaks = ig.Breaks(0, self._next_break, period) if use_breaks else None
            stepper = _stepper(p, self._rhs_on, t0, y0, t_bound, breaks, None)
            return MotorSegment(t0, t1, True, y0, stepper, period, t_bound)
        if y0[1] > 0.0:
            brk = ig.Breaks(0, self._next_break) if self.load is not None else None
            stepper = _stepper(p, self._rhs_brake, t0, y0, math.inf, brk, ig.Terminal(1, 0.0))
            return MotorSegment(t0, t1, False, y0, stepper)
        return MotorSegment(t0, t1, False, y0, None)

    def set_switches(self, switches: list[tuple[float, bool]], commanded: bool) -> None:
        """New effective switches: the segments before the first one that changed are kept (cut there)."""
        old = self.switches
        n = 0
        while n < min(len(old), len(switches)) and old[n] == switches[n]:
            n += 1
        firsts = [x[0] for x in (old[n : n + 1] + switches[n : n + 1])]
        te = min(firsts) if firsts else None
        self.switches = switches
        self.commanded = commanded
        if te is None:
            return
        keep = [s for s in self.segments if s.t0 < te]
        if not keep:
            raise ValueError(
                f'MotorDrive: a switch at {te!r} s is before what is kept (from {self.segments[0].t0!r} s)'
            )
        self.segments = keep
        keep[-1].t1 = self._next_switch(keep[-1].t0)

    def extend(self, t: float) -> None:
        """Integrate until the drive at ``t`` (s) is known, opening the segments of the switches on the way."""
        t = min(float(t), self.duration)
        while True:
            seg = self.segments[-1]
            if seg.t1 <= t:
                seg.advance(seg.t1)
                y = seg.state(seg.t1)
                y[1] = max(y[1], 0.0)  # a dense output a hair below 0 at the brake's end is standstill
                on = next(on for ts, on in self.switches if ts == seg.t1)
                self.segments.append(self._segment(seg.t1, on, y))
                continue
            seg.advance(t)
            return

    def prune(self, t_keep: float) -> None:
        """Forget the segments and steps that end before ``t_keep`` (s)."""
        while len(self.segments) > 1 and self.segments[1].t0 <= t_keep:
            gone = self.segments.pop(0)
            if gone.stepper is not None:
                sol = gone.solution
                self.nfev_dropped += sol.nfev
                self.steps_dropped += sol.steps
                self.rejected_dropped += sol.rejected
        self.segments[0].prune(t_keep)

    # evaluation -------------------------------------------------------------------------
    @property
    def _t0(self) -> list[float]:
        return [s.t0 for s in self.segments]

    def _clip(self, t: npt.ArrayLike) -> FloatArray:
        tt: FloatArray = np.clip(np.asarray(t, dtype=float), 0.0, self.duration)
        if tt.size:
            self.extend(float(tt.max()))
        return tt

    def _component(self, t: npt.ArrayLike, j: int) -> FloatArray:
        """Θ (j = 0, nominal s) or ω (j = 1, rad/s) at times clipped to [0, duration]."""
        tt = self._clip(t)
        if len(self.segments) == 1:
            return self.segments[0].component(tt, j)
        idx = np.maximum(np.searchsorted(self._t0, tt, side='right') - 1, 0)
        if tt.size == 1:
            return self.segments[int(idx.reshape(-1)[0])].component(tt, j)
        out = np.empty(tt.shape)
        for k in np.unique(idx):
            m = idx == k
            out[m] = self.segments[k].component(tt[m], j)
        return out

    def theta(self, t: npt.ArrayLike) -> FloatArray:
        """Master phase Θ(t), nominal s."""
        return self._component(t, 0)

    def rate(self, t: npt.ArrayLike) -> FloatArray:
        """Speed factor λ = ω/ω_nom."""
        return self._component(t, 1) / self.params.omega_nom

    def theta_rate(self, t: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
        """``(Θ(t), λ(t))`` at once: the same values as :meth:`theta` and :meth:`rate`, bit for bit;
        one element (a node's tick) goes through :meth:`MotorSegment.state1` (a few µs)."""
        tt = self._clip(t)
        if tt.size != 1:
            return self._component(tt, 0), self._component(tt, 1) / self.params.omega_nom
        tv = float(tt.reshape(-1)[0])
        k = 0 if len(self.segments) == 1 else max(bisect.bisect_right(self._t0, tv) - 1, 0)
        th, w = self.segments[k].state1(tv)
        return np.full(tt.shape, th), np.full(tt.shape, w) / self.params.omega_nom

    def omega(self, t: npt.ArrayLike) -> FloatArray:
        """Master-shaft speed ω(t), rad/s."""
        return self._component(t, 1)

    def rate_dot(self, t: npt.ArrayLike) -> FloatArray:
        """dλ/dt, 1/s: the right-hand side at the dense state, divided by ω_nom."""
        tt = self._clip(t)
        theta, omega = self._component(tt, 0), self._component(tt, 1)
        p = self.params
        load = self.load.torque(theta) if self.load is not None else np.zeros(tt.shape)
        idx = np.maximum(np.searchsorted(self._t0, tt, side='right') - 1, 0)
        on = np.array([s.on for s in self.segments])[idx]
        rest = tt >= np.array([s.t_rest for s in self.segments])[idx]
        drive = np.where(on, p.T_0 * (1.0 - omega / p.omega_0), -p.T_brake)
        acc = (drive - p.b * omega - load) / p.J
        return np.where(rest & ~on, 0.0, acc) / p.omega_nom

    def _reach(self, theta: float) -> None:
        """Integrate until Θ passes ``theta`` (or the shaft rests for good, or :data:`REACH` s on)."""
        limit = self.segments[-1].covered + REACH
        while True:
            seg = self.segments[-1]
            cov = seg.covered
            if math.isinf(cov):
                if seg.t1 == math.inf or seg.t1 > self.duration:
                    return
                self.extend(seg.t1)
                continue
            if seg.theta_known() >= theta or cov >= min(limit, self.duration):
                return
            self.extend(min(cov + max(1.0, 0.01 * (cov - seg.t0)), limit, self.duration))

    def time_of(self, theta: npt.ArrayLike) -> FloatArray:
        """Earliest t with Θ(t) = theta, s (``inf`` for a phase the drive does not reach)."""
        th = np.asarray(theta, dtype=float)
        if not np.all(np.isfinite(th)):
            raise ParameterError('theta', theta, 'must be finite')
        if math.isfinite(self.duration):  # a drive over [0, duration]: phases clipped to its range
            th = np.clip(th, 0.0, self.theta_end)
        if th.size:
            self._reach(float(th.max()))
        top = self.segments[-1].theta_known()
        th0 = np.array([s.theta0 for s in self.segments])
        # the last segment starting below th (on a plateau: the earliest time)
        idx = np.maximum(np.searchsorted(th0, th, side='left') - 1, 0)
        out = np.empty(th.shape)
        flat_th, flat_idx, flat_out = th.reshape(-1), idx.reshape(-1), out.reshape(-1)
        for k in np.unique(flat_idx):
            m = flat_idx == k
            flat_out[m] = self.segments[int(k)].inverse(np.minimum(flat_th[m], top))
        out = np.where(th > top, math.inf, out)
        if math.isfinite(self.duration):
            out = np.minimum(out, self.duration)
        return out

    # figures ----------------------------------------------------------------------------
    @property
    def theta_end(self) -> float:
        """Θ at :attr:`duration` (a stream: at what is integrated), nominal s."""
        t = self.duration if math.isfinite(self.duration) else self.segments[-1].covered
        return float(self.theta(np.array([t]))[0]) if math.isfinite(t) else self.segments[-1].theta_known()

    @property
    def tail(self) -> PeriodicTail | None:
        """The first motor-on segment's repeated period, if found."""
        return self.segments[0].tail

    @property
    def solution(self) -> dense.DenseSolution:
        """The first segment's integration (its kept steps)."""
        return self.segments[0].solution

    @property
    def t_stop(self) -> float:
        """First motor-off switch, s (``inf`` if none)."""
        return next((t for t, on in self.switches if not on), math.inf)

    @property
    def t_rest(self) -> float:
        """First standstill after a motor-off, s (``inf`` if none so far)."""
        return next((s.t_rest for s in self.segments if not s.on and math.isfinite(s.t_rest)), math.inf)

    def _count(self, what: str) -> int:
        total = {'nfev': self.nfev_dropped, 'steps': self.steps_dropped, 'rejected': self.rejected_dropped}[what]
        for s in self.segments:
            if s.stepper is not None:
                total += getattr(s.solution, what)
        return total

    @property
    def nfev(self) -> int:
        """Right-hand-side evaluations so far (those of forgotten segments included)."""
        return self._count('nfev')

    @property
    def steps(self) -> int:
        """Accepted steps kept, and of forgotten segments."""
        return self._count('steps')

    @property
    def rejected(self) -> int:
        """Rejected trial steps so far."""
        return self._count('rejected')

    def mean_rate(self, t0: float, t1: float) -> float:
        """Mean λ over [t0, t1]: ``(Θ(t1) - Θ(t0)) / (t1 - t0)``."""
        th = self.theta(np.array([t0, t1]))
        return float((th[1] - th[0]) / (t1 - t0))

    def summary(self) -> dict[str, Any]:
        """Figures for reports: cost, steady λ, stop and rest times."""
        out: dict[str, Any] = {
            'method': self.params.method,
            'nfev': self.nfev,
            'steps': self.steps,
            'rejected': self.rejected,
            'theta_end': self.theta_end,
            't_stop': self.t_stop,
            't_rest': self.t_rest,
            'lambda_free': self.params.omega_free / self.params.omega_nom,
        }
        if self.tail is not None:
            out['t_periodic'] = float(self.tail.t_b)
            out['lambda_steady'] = float(self.tail.dtheta / self.tail.period)
        if self.load is not None:
            out['load_mean'] = float(self.load.mean)
            out['load_peak'] = float(self.load.peak)
            out['lambda_estimate'] = steady_speed(self.params, self.load.mean) / self.params.omega_nom
        if self.commanded:
            out['switches'] = [[float(t), bool(on)] for t, on in self.switches]
        return out


def _no_load(theta: float, piece: tuple[float, float]) -> float:
    return 0.0


def _every(b: float) -> bool:
    return True


def _stepper(
    p: Params,
    fun: Callable[..., FloatArray],
    t0: float,
    y0: FloatArray,
    t_bound: float,
    breaks: ig.Breaks | None,
    terminal: ig.Terminal | None,
) -> ig.RK4Stepper | ig.Dopri5Stepper:
    if p.method == 'rk4':
        return ig.RK4Stepper(fun, t0, y0, t_bound=t_bound, h=p.h, breaks=breaks, terminal=terminal, max_steps=MAX_STEPS)
    return ig.Dopri5Stepper(
        fun,
        t0,
        y0,
        t_bound=t_bound,
        rtol=p.rtol,
        atol=p.atol,
        max_step=p.h,
        breaks=breaks,
        terminal=terminal,
        max_steps=MAX_STEPS,
    )


def _check_load(p: Params, load: chain_friction.MasterLoad) -> None:
    if load.params.P_k > 0.0 and load.locked_u.size:
        u = load.locked_u
        raise ParameterError(
            'delivery.alpha_m_deg',
            load.delivery.alpha_m_deg,
            f'the delivery self-locks (or stalls) on the stroke at u in '
            f'[{u.min():.4g}, {u.max():.4g}]: the motor cannot drive it against '
            f'P_k = {load.params.P_k!r} N',
        )
    if not load.peak < p.T_0:
        raise ParameterError(
            'effects.motor_dynamics.T_0',
            p.T_0,
            f'must exceed the peak chain load on the master shaft, {load.peak:.6g} N m: '
            'otherwise the line stalls at standstill',
        )


def _switches(t_stop: float, commands: Iterable[Command], duration: float = math.inf) -> list[tuple[float, bool]]:
    """Effective motor switches ``(t, on after t)``: the scene's ``t_stop`` (motor off) and the commands
    (``hold``/``stop`` off, ``unhold``/``start`` on), in time order, the scene's switch first among equal
    times; switches that change nothing dropped."""
    raw: list[tuple[float, int, bool]] = [(float(t_stop), 0, False)]
    raw += [(c.t, 1, c.running) for c in check_commands(commands)]
    raw.sort(key=lambda r: (r[0], r[1]))  # stable: commands keep their order
    out: list[tuple[float, bool]] = []
    on = True
    for t, _, state in raw:
        if t < duration and state != on:
            on = state
            out.append((t, on))
    return out


def _params(scene: SceneView) -> Params:
    p: Params | None = scene.effect('motor_dynamics')
    if p is None:
        raise ParameterError('effects', 'motor_dynamics', f'scene {scene.name!r} does not list motor_dynamics')
    if p.method == 'rk4' and p.h * p.damping / p.J > RK4_STEP_LIMIT:
        z = p.h * p.damping / p.J
        what = 'unstable' if z > RK4_STABILITY else 'stalls and overshoots between steps (not yet unstable)'
        raise ParameterError(
            'effects.motor_dynamics.h',
            p.h,
            f'RK4 {what} here: h (T_0/omega_0 + b)/J = {z:.4g} > {RK4_STEP_LIMIT}; '
            f'use h < {RK4_STEP_LIMIT * p.J / p.damping:.4g} s or method dopri5',
        )
    return p


#: the drive is integrated at least this many mechanical time constants (or to the end) before it can settle
SETTLE_TAUS = 5.0


def _check_work(p: Params, duration: float) -> None:
    """Refuse, naming ``h``, a step that cannot settle the drive within :data:`MAX_STEPS` steps: the
    integration covers at least ``min(duration, SETTLE_TAUS tau)`` of line time with steps of at most ``h``."""
    span = min(duration, SETTLE_TAUS * p.tau)
    if span / p.h > MAX_STEPS:
        raise ParameterError(
            'effects.motor_dynamics.h',
            p.h,
            f'asks for ~{span / p.h:.3g} steps before the drive can settle ({span:.3g} s of line time: '
            f'{SETTLE_TAUS:g} x its time constant {p.tau:.3g} s, or the run if shorter); at most '
            f'max_steps={MAX_STEPS}: use h >= {span / MAX_STEPS:.3g} s',
        )


def stream_drive(
    scene: SceneView,
    commands: Iterable[Command] = (),
    previous: MotorDrive | None = None,
    *,
    periodic: bool = True,
    duration: float = math.inf,
) -> MotorDrive:
    """The motor drive of ``scene`` under the supervisor's ``commands``, integrated as far as it is asked.

    Parameters
    ----------
    scene : SceneView
        Lists ``motor_dynamics`` (and possibly ``chain_friction``).
    commands : iterable of Command
        Sorted by time: ``hold``/``stop`` switch the motor off and apply the brake from their
        time, ``unhold``/``start`` switch it on again from the state there. The scene's
        ``t_stop`` is one more motor-off switch.
    previous : MotorDrive, optional
        The drive under the commands before: its integration is kept up to the first switch
        that changed (it is taken over, not copied).
    periodic : bool
        Take the periodic-steady-state shortcut (module docstring).
    duration : float
        Times are clipped to ``[0, duration]`` (default: none; :func:`build_drive`).

    Raises
    ------
    ParameterError
        The scene does not list ``motor_dynamics``; RK4 step beyond its stability limit; stall
        torque not above the peak chain load; a self-locking delivery; commands not sorted.
    """
    commands = check_commands(commands)
    switches = _switches(_params(scene).t_stop, commands, duration)
    if previous is not None and previous.periodic == periodic and math.isinf(previous.duration):
        previous.set_switches(switches, bool(commands))
        return previous
    p = _params(scene)
    _check_work(p, duration)
    load = chain_friction.master_load(scene, p.omega_nom) if scene.has('chain_friction') else None
    if load is not None:
        _check_load(p, load)
    return MotorDrive(p, load, switches, periodic=periodic, commanded=bool(commands), duration=duration)


def build_drive(
    scene: SceneView, duration: float, *, periodic: bool = True, commands: Iterable[Command] = ()
) -> MotorDrive:
    """The motor drive over ``[0, duration]``: :func:`stream_drive` integrated to ``duration``, its times
    clipped there (``theta_end`` is Θ at ``duration``; a phase beyond it maps to ``duration``).

    Raises
    ------
    ParameterError
        As :func:`stream_drive`; ``duration`` not in ``(0, MAX_DURATION]``.
    IntegrationError
        The integration failed (too many steps, non-finite state).
    """
    duration = in_range('duration', duration, 0.0, MAX_DURATION, lo_open=True)
    drive = stream_drive(scene, commands, periodic=periodic, duration=duration)
    drive.extend(duration)
    return drive
