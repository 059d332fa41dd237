"""Effect ``motor_dynamics``: the master drive from a motor torque-speed curve and inertia.

Source: MACHINES.md, "Effects: suggested models", ``motor_dynamics``
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
import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from folder_line.core.effects import chain_friction
from folder_line.core.limits import HORIZON, MOTOR_SPEED
from folder_line.core.mechanisms.drive import Command, check_commands
from folder_line.core.numerics import dense
from folder_line.core.numerics import integrators as ig
from folder_line.core.numerics.arrays import FloatArray
from folder_line.core.numerics.constants import EPS
from folder_line.core.numerics.validate import among, check_fields, in_range, non_negative, positive, within
from folder_line.errors import ParameterError

if TYPE_CHECKING:
    from folder_line.core.line.scene import Scene

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
#: RK4 is stable for h·|λ| up to 2.785 on the negative real axis
RK4_STABILITY = 2.785
#: largest h·|λ| accepted for RK4: its dense output stays monotone on a linear start-up (z* = 2.2134)
RK4_STEP_LIMIT = 2.21
#: relative agreement of ω (and of the period) at three marks that counts as periodic
PERIODIC_TOL = 1e-12
#: longest run accepted, s (as core.line.MAX_DURATION: :data:`folder_line.core.limits.HORIZON`)
MAX_DURATION = HORIZON.hi
#: step attempts allowed per integration
MAX_STEPS = 20_000_000


@dataclass(frozen=True)
class Params:
    """Parameters of ``motor_dynamics`` (no defaults: the scene gives them all).

    Attributes
    ----------
    J : float
        Inertia of the master shaft with everything geared to it, kg m² (> 0).
    T_0 : float
        Stall torque of the linear motor curve ``T_m = T_0 (1 - ω/ω_0)``, N m (> 0).
    omega_0 : float
        No-load speed, rad/s (> omega_nom).
    omega_nom : float
        Nominal master-shaft speed (λ = ω/omega_nom), rad/s, in :data:`~folder_line.core.limits.MOTOR_SPEED`.
    b : float
        Viscous load of the line, N m s (>= 0).
    method : {'rk4', 'dopri5'}
        Fixed-step RK4 (step ``h``) or adaptive DOPRI5 (``rtol``, ``atol``, max step ``h``).
    h : float
        RK4 step / DOPRI5 largest step, s (> 0).
    rtol : float
        DOPRI5 relative tolerance, in [100 eps, 1).
    atol : float
        DOPRI5 absolute tolerance (Θ in nominal s, ω in rad/s), > 0.
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
            **dict.fromkeys(('J', 'T_0', 'omega_0', 'h', 'atol'), positive),
            omega_nom=MOTOR_SPEED.check,
            **dict.fromkeys(('b', 't_stop', 'T_brake'), non_negative),
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


@dataclass(frozen=True, eq=False)
class MotorSegment:
    """A stretch of constant motor state: motor on, or off with the brake applied.

    Attributes
    ----------
    t0, t1 : float
        The segment holds for ``t0 <= t < t1`` (``t1``: the next switch, or the end
        of the run), s.
    on : bool
        Motor on (else off, braking, then at rest).
    theta0 : float
        Θ(t0), nominal s.
    solution : DenseSolution
        Motor on: the integration from ``t0`` (up to the base period if ``tail``);
        off: the brake integration from ``t0`` and the rest after it, up to the end of
        the run.
    tail : PeriodicTail or None
        Motor on: the repeated period, if the shortcut was taken.
    t_rest : float
        Off: standstill reached, s (``inf`` if not within the run); on: ``inf``.
    """

    t0: float
    t1: float
    on: bool
    theta0: float
    solution: dense.DenseSolution
    tail: PeriodicTail | None
    t_rest: float

    def component(self, tt: FloatArray, j: int) -> FloatArray:
        """Θ (j = 0) or ω (j = 1) at times ``tt`` of this segment."""
        tl = self.tail
        if tl is None:
            return self.solution.component(tt, j)
        out = np.empty(tt.shape)
        head = tt <= tl.t_b
        in_tail = ~head
        if head.any():
            out[head] = self.solution.component(tt[head], j)
        if in_tail.any():
            x = tt[in_tail] - tl.t_a
            n = np.floor(x / tl.period)
            tb = tl.t_a + np.clip(x - n * tl.period, 0.0, tl.period)
            out[in_tail] = self.solution.component(tb, j) + (n * tl.dtheta if j == 0 else 0.0)
        return out

    def state1(self, t: float) -> tuple[float, float]:
        """``(Θ, ω)`` at one time of the segment in plain Python: the same operations as
        :meth:`component` (dense-output lookup, Horner's rule, the tail's shift), so the
        same values bit for bit, at a few µs (a node's tick)."""
        lists = self.__dict__.get('_lists')
        sol = self.solution
        if lists is None:  # built on first use
            lists = (sol.t.tolist(), sol.h.tolist(), [sol.coef[:, i, :].T.tolist() for i in range(sol.steps)])
            object.__setattr__(self, '_lists', lists)
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
        """``(Θ, ω)`` at time ``t`` of the segment (its end included): where the
        integration ended exactly there, its end state."""
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

    def inverse(self, th: FloatArray) -> FloatArray:
        """Earliest times of this segment with Θ = ``th`` (``th`` within the segment's Θ range)."""
        tl = self.tail
        if tl is None:
            return np.minimum(self.solution.inverse(th, 0), self.t1)
        out = np.empty(th.shape)
        head = th <= tl.theta_b
        in_tail = ~head
        if head.any():
            out[head] = self.solution.inverse(th[head], 0)
        if in_tail.any():
            n = np.floor((th[in_tail] - tl.theta_a) / tl.dtheta)
            r = np.clip(th[in_tail] - n * tl.dtheta, tl.theta_a, tl.theta_b)
            out[in_tail] = np.minimum(self.solution.inverse(r, 0) + n * tl.period, tl.t_end)
        return np.minimum(out, self.t1)


class MotorDrive:
    """The master drive from the motor ODE (Drive protocol of :mod:`folder_line.core.mechanisms.drive`).

    Built by :func:`build_drive`: a list of :class:`MotorSegment` (motor on / off),
    switched at the scene's ``t_stop`` and at the supervisor's commands.

    Attributes
    ----------
    params : Params
    duration : float
        Run length, s.
    segments : list of MotorSegment
        In time order; segment i holds on ``[t0_i, t0_{i+1})``.
    switches : list of (float, bool)
        Effective switches ``(t, motor on after t)`` within the run.
    solution : DenseSolution
        The first motor-on integration (with the periodic shortcut: up to the end of its
        base period); without the shortcut and without commands, the whole run
        including brake and rest (as before commands existed).
    brake_solution : DenseSolution or None
        The second segment's solution when the first one has a periodic tail, else None.
    tail : PeriodicTail or None
        The first segment's repeated period, if the shortcut was taken.
    load : MasterLoad or None
        The chain load.
    t_stop : float
        First motor-off switch, s (``inf`` if none within the run).
    t_rest : float
        First standstill after a motor-off, s (``inf`` if none within the run).
    nfev, steps, rejected : int
        Cost of all integrations.
    """

    def __init__(
        self,
        params: Params,
        duration: float,
        segments: list[MotorSegment],
        load: chain_friction.MasterLoad | None,
        switches: list[tuple[float, bool]],
        solution: dense.DenseSolution | None = None,
        commanded: bool = False,
    ) -> None:
        self.params = params
        self.duration = duration
        self.segments = segments
        self.switches = switches
        self.commanded = commanded
        self.load = load
        first = segments[0]
        self.tail = first.tail
        self.solution = solution if solution is not None else first.solution
        self.brake_solution = segments[1].solution if first.tail is not None and len(segments) > 1 else None
        off = [s for s in segments if not s.on]
        self.t_stop = off[0].t0 if off else math.inf
        self.t_rest = next((s.t_rest for s in off if math.isfinite(s.t_rest)), math.inf)
        self.nfev = sum(s.solution.nfev for s in segments)
        self.steps = sum(s.solution.steps for s in segments)
        self.rejected = sum(s.solution.rejected for s in segments)
        self._t0 = np.array([s.t0 for s in segments])
        self._t0_list = self._t0.tolist()
        self._theta0 = np.array([s.theta0 for s in segments])
        self._on = np.array([s.on for s in segments])
        self._rest = np.array([s.t_rest for s in segments])
        self.theta_end = float(self._component(duration, 0))

    # evaluation -------------------------------------------------------------------------
    def _segment_index(self, tt: FloatArray) -> npt.NDArray[np.intp]:
        return np.maximum(np.searchsorted(self._t0, tt, side='right') - 1, 0)

    def _component(self, t: npt.ArrayLike, j: int) -> FloatArray:
        """Θ (j = 0, nominal s) or ω (j = 1, rad/s) at times clipped to [0, duration]."""
        tt = np.clip(np.asarray(t, dtype=float), 0.0, self.duration)
        if len(self.segments) == 1:
            return self.segments[0].component(tt, j)
        idx = self._segment_index(tt)
        if tt.size == 1:
            return self.segments[int(idx.reshape(-1)[0])].component(tt, j)
        out = np.empty(tt.shape)
        for k in np.unique(idx):
            m = idx == k
            out[m] = self.segments[k].component(tt[m], j)
        return out

    def theta(self, t: npt.ArrayLike) -> FloatArray:
        """Master phase Θ(t), nominal s (t clipped to [0, duration])."""
        return self._component(t, 0)

    def rate(self, t: npt.ArrayLike) -> FloatArray:
        """Speed factor λ = ω/ω_nom (t clipped to [0, duration])."""
        return self._component(t, 1) / self.params.omega_nom

    def theta_rate(self, t: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
        """``(Θ(t), λ(t))`` at once: the same values as :meth:`theta` and :meth:`rate`, bit for bit;
        one element (a node's tick) goes through :meth:`MotorSegment.state1` (a few µs)."""
        tt = np.clip(np.asarray(t, dtype=float), 0.0, self.duration)
        if tt.size != 1:
            return self._component(tt, 0), self._component(tt, 1) / self.params.omega_nom
        tv = float(tt.reshape(-1)[0])
        k = 0 if len(self.segments) == 1 else max(bisect.bisect_right(self._t0_list, tv) - 1, 0)
        th, w = self.segments[k].state1(tv)
        return np.full(tt.shape, th), np.full(tt.shape, w) / self.params.omega_nom

    def omega(self, t: npt.ArrayLike) -> FloatArray:
        """Master-shaft speed ω(t), rad/s (t clipped to [0, duration])."""
        return self._component(t, 1)

    def rate_dot(self, t: npt.ArrayLike) -> FloatArray:
        """dλ/dt, 1/s: the right-hand side at the dense state, divided by ω_nom."""
        tt = np.clip(np.asarray(t, dtype=float), 0.0, self.duration)
        theta, omega = self._component(tt, 0), self._component(tt, 1)
        p = self.params
        load = self.load.torque(theta) if self.load is not None else np.zeros(tt.shape)
        idx = self._segment_index(tt)
        on = self._on[idx]
        rest = tt >= self._rest[idx]
        drive = np.where(on, p.T_0 * (1.0 - omega / p.omega_0), -p.T_brake)
        acc = (drive - p.b * omega - load) / p.J
        return np.where(rest & ~on, 0.0, acc) / p.omega_nom

    def time_of(self, theta: npt.ArrayLike) -> FloatArray:
        """Earliest t with Θ(t) = theta, s; theta clipped to [0, Θ(duration)] (never NaN)."""
        th = np.asarray(theta, dtype=float)
        if not np.all(np.isfinite(th)):
            raise ParameterError('theta', theta, 'must be finite')
        th = np.clip(th, 0.0, self.theta_end)
        # the last segment starting below th (on a plateau: the earliest time)
        idx = np.maximum(np.searchsorted(self._theta0, th, side='left') - 1, 0)
        if len(self.segments) == 1 or th.size == 1:
            out = self.segments[int(idx.reshape(-1)[0]) if th.size else 0].inverse(th)
        else:
            out = np.empty(th.shape)
            for k in np.unique(idx):
                m = idx == k
                out[m] = self.segments[k].inverse(th[m])
        return np.minimum(out, self.duration)

    # summaries --------------------------------------------------------------------------
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


def _integrate(
    p: Params,
    fun: Any,
    span: tuple[float, float],
    y0: FloatArray,
    breaks: ig.Breaks | None,
    terminal: ig.Terminal | None = None,
) -> dense.DenseSolution:
    if p.method == 'rk4':
        return ig.rk4(fun, span, y0, p.h, breaks=breaks, terminal=terminal, max_steps=MAX_STEPS)
    return ig.dopri5(
        fun, span, y0, rtol=p.rtol, atol=p.atol, max_step=p.h, breaks=breaks, terminal=terminal, max_steps=MAX_STEPS
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


def _switches(t_stop: float, duration: float, commands: Iterable[Command]) -> list[tuple[float, bool]]:
    """Effective motor switches ``(t, on after t)`` before ``duration``: the scene's ``t_stop`` (motor off)
    and the commands (``hold``/``stop`` off, ``unhold``/``start`` on), in time order, the scene's
    switch first among equal times; switches that change nothing dropped."""
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


def build_drive(
    scene: Scene, duration: float, *, periodic: bool = True, commands: Iterable[Command] = ()
) -> MotorDrive:
    """Integrate the motor over ``[0, duration]``, segment by segment, and return the drive.

    Parameters
    ----------
    scene : Scene
        Lists ``motor_dynamics`` (and possibly ``chain_friction``).
    duration : float
        Run length, s (> 0).
    periodic : bool
        Take the periodic-steady-state shortcut (module docstring).
    commands : iterable of Command
        Supervisor commands (:class:`folder_line.core.mechanisms.drive.Command`, sorted by time):
        ``hold``/``stop`` switch the motor off and apply the brake from their time,
        ``unhold``/``start`` switch it on again from the state there. The scene's
        ``t_stop`` is one more motor-off switch.

    Returns
    -------
    MotorDrive

    Raises
    ------
    ParameterError
        The scene does not list ``motor_dynamics``; RK4 step beyond its stability limit;
        stall torque not above the peak chain load; a self-locking delivery; commands
        not sorted by time.
    IntegrationError
        The integration failed (too many steps, non-finite state).

    Notes
    -----
    Segments (module docstring, "Supervisor commands"): a motor-on segment starting at
    ``t_0`` is integrated up to the scene's ``t_stop`` if that is later, else to
    ``duration`` -- never to a command's time -- and only *evaluated* up to the next
    switch; a brake segment is integrated from its start until standstill (or
    ``duration``). So the drive before a command's time does not depend on that
    command: adding a command leaves Θ(t) for earlier t unchanged bit for bit.
    """
    p: Params | None = scene.effect('motor_dynamics')
    if p is None:
        raise ParameterError('effects', 'motor_dynamics', f'scene {scene.name!r} does not list motor_dynamics')
    duration = in_range('duration', duration, 0.0, MAX_DURATION, lo_open=True)
    commands = check_commands(commands)
    if p.method == 'rk4' and p.h * p.damping / p.J > RK4_STEP_LIMIT:
        z = p.h * p.damping / p.J
        what = 'unstable' if z > RK4_STABILITY else 'stalls and overshoots between steps (not yet unstable)'
        raise ParameterError(
            'effects.motor_dynamics.h',
            p.h,
            f'RK4 {what} here: h (T_0/omega_0 + b)/J = {z:.4g} > {RK4_STEP_LIMIT}; '
            f'use h < {RK4_STEP_LIMIT * p.J / p.damping:.4g} s or method dopri5',
        )
    load = chain_friction.master_load(scene, p.omega_nom) if scene.has('chain_friction') else None
    if load is not None:
        _check_load(p, load)
    J, T0, w0, b, Tb, wn = p.J, p.T_0, p.omega_0, p.b, p.T_brake, p.omega_nom
    if load is not None:
        load_torque = load.torque_piece
        next_break = load.next_break
        is_mark = load.is_entry
    else:
        # period marks: the Θ advance over one time constant (or one largest step, if longer) at the free speed
        mark = max(p.tau, p.h) * p.omega_free / wn

        def load_torque(theta: float, piece: tuple[float, float]) -> float:
            return 0.0

        def next_break(v: float) -> float:
            k = math.floor(v / mark) + 1
            bk = k * mark
            return bk if bk > v else (k + 1) * mark

        def is_mark(b: float) -> bool:
            return True

    # with breaks the integrator passes the current piece; without (no load, no periodic marks) it does not
    def rhs_on(t: float, y: FloatArray, piece: tuple[float, float] = (0.0, math.inf)) -> FloatArray:
        w = y[1]
        return np.array([w / wn, (T0 * (1.0 - w / w0) - b * w - load_torque(y[0], piece)) / J])

    def rhs_brake(t: float, y: FloatArray, piece: tuple[float, float] = (0.0, math.inf)) -> FloatArray:
        w = y[1]
        return np.array([w / wn, (-b * w - load_torque(y[0], piece) - Tb) / J])

    def motor_on(t0: float, t1: float, y0: FloatArray) -> MotorSegment:
        """Motor on from state y0 at t0, evaluated up to t1 (integrated further: see Notes)."""
        t_int = p.t_stop if t0 < p.t_stop < duration else duration
        marks: list[tuple[float, float]] = []

        def on_break(t: float, y: FloatArray, brk: float) -> bool:
            if not is_mark(brk):
                return False
            marks.append((t, float(y[1])))
            del marks[:-3]
            if len(marks) < 3:
                return False
            (ta, wa), (tb, wb), (tc, wc) = marks
            tol = PERIODIC_TOL * wn
            return (
                abs(wc - wb) <= tol and abs(wb - wa) <= tol and abs((tc - tb) - (tb - ta)) <= PERIODIC_TOL * (tc - tb)
            )

        use_breaks = load is not None or periodic
        breaks = ig.Breaks(0, next_break, on_break if periodic else None) if use_breaks else None
        sol = _integrate(p, rhs_on, (t0, t_int), y0, breaks)
        tail: PeriodicTail | None = None
        if sol.status == 'stopped' and sol.t_end < t_int:
            (ta, _), (tb, _) = marks[-2], marks[-1]
            th = sol.component(np.array([ta, tb]), 0)
            tail = PeriodicTail(t_a=ta, t_b=tb, theta_a=float(th[0]), theta_b=float(th[1]), t_end=t_int)
        return MotorSegment(t0, t1, True, float(y0[0]), sol, tail, math.inf)

    def motor_off(t0: float, t1: float, y0: FloatArray) -> MotorSegment:
        """Brake from state y0 at t0 until standstill (or the end of the run), then rest."""
        t_rest = math.inf
        if y0[1] > 0.0:
            brk = ig.Breaks(0, next_break) if load is not None else None
            sol_b = _integrate(p, rhs_brake, (t0, duration), y0, brk, ig.Terminal(1, 0.0))
            parts = [sol_b]
            if sol_b.status == 'terminal':
                t_rest = sol_b.t_end
                if t_rest < duration:
                    parts.append(dense.constant_solution(t_rest, duration, [sol_b.y[-1, 0], 0.0]))
            sol = dense.concatenate(parts) if len(parts) > 1 else sol_b
        else:
            t_rest = t0
            sol = dense.constant_solution(t0, duration, [y0[0], 0.0])
        return MotorSegment(t0, t1, False, float(y0[0]), sol, None, t_rest)

    switches = _switches(p.t_stop, duration, commands)
    bounds = [t for t, _ in switches] + [duration]
    segments: list[MotorSegment] = []
    y = np.zeros(2)
    t0, on = 0.0, True
    for i, t1 in enumerate(bounds):
        if t1 > t0:
            seg = motor_on(t0, t1, y) if on else motor_off(t0, t1, y)
            segments.append(seg)
            if i < len(switches):
                y = seg.state(t1)
                y[1] = max(y[1], 0.0)  # a dense output a hair below 0 at the brake's end is standstill
        if i < len(switches):
            t0, on = t1, switches[i][1]
    solution = None
    if not commands and segments[0].tail is None:
        # as before commands existed: the whole run as one solution (on, brake, rest)
        solution = dense.concatenate([s.solution for s in segments]) if len(segments) > 1 else segments[0].solution
    return MotorDrive(p, duration, segments, load, switches, solution, commanded=bool(commands))
