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

The run is a list of :class:`~folder_line.core.effects.motor_segment.MotorSegment` (motor on, or
off with the brake applied), switched at the scene's ``t_stop`` and at the supervisor's
commands (:func:`build_drive`, :func:`stream_drive`). Each is integrated by the resumable
steppers of :mod:`folder_line.core.numerics.integrators`, the chain load's jumps as breaks and
the brake's standstill as a terminal condition; a motor-on segment stops integrating once its
period repeats (``periodic=True``). The closed form without load and the steady speed
(:func:`steady_speed`, :func:`stall_torque_for`), the exact handling of the brake and of the
load's jumps, the periodic steady state, the commands, the tolerances and RK4's step limit
(:data:`RK4_STEP_LIMIT`) and the drive protocol of :class:`MotorDrive` are described in
docs/machines.md, "The motor drive".
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
from folder_line.core.effects.motor_figures import MotorFigures
from folder_line.core.effects.motor_segment import MotorSegment, PeriodicTail, PeriodMarks
from folder_line.core.limits import DURATION, LINE_DAMPING, MOTOR_INERTIA, MOTOR_SPEED, MOTOR_TORQUE
from folder_line.core.mechanisms.drive import Command, check_commands
from folder_line.core.mechanisms.scene_view import SceneView
from folder_line.core.numerics import dense
from folder_line.core.numerics.arrays import FloatArray
from folder_line.core.numerics.constants import EPS
from folder_line.core.numerics.dopri5_stepper import Dopri5Stepper
from folder_line.core.numerics.rk4_stepper import RK4Stepper
from folder_line.core.numerics.stepper import Breaks, Terminal
from folder_line.core.numerics.validate import among, check_fields, in_range, non_negative, positive, within
from folder_line.errors import ParameterError

__all__ = [
    'METHODS',
    'RK4_STABILITY',
    'RK4_STEP_LIMIT',
    'MotorDrive',
    'Params',
    'build_drive',
    'motor_params',
    'stall_torque_for',
    'steady_speed',
]


METHODS = ('rk4', 'dopri5')
#: RK4 is stable for ``h·|λ|`` up to 2.785 on the negative real axis
RK4_STABILITY = 2.785
#: largest ``h·|λ|`` accepted for RK4: its dense output stays monotone on a linear start-up (z* = 2.2134)
RK4_STEP_LIMIT = 2.21
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


#: line time past what is integrated that :meth:`MotorDrive.time_of` integrates to find a phase, s: beyond
#: it a phase counts as never reached (a shaft coasting to rest without a brake never gets there)
REACH = 3600.0


class MotorDrive:
    """The master drive from the motor ODE (Drive protocol of :mod:`folder_line.core.mechanisms.drive`).

    A list of :class:`~folder_line.core.effects.motor_segment.MotorSegment` (motor on / off), switched at
    the scene's ``t_stop`` and at the supervisor's commands, integrated as far as the line is asked for: a time beyond
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
            breaks = Breaks(0, self._next_break, period) if use_breaks else None
            stepper = _stepper(p, self._rhs_on, t0, y0, t_bound, breaks, None)
            return MotorSegment(t0, t1, True, y0, stepper, period, t_bound)
        if y0[1] > 0.0:
            brk = Breaks(0, self._next_break) if self.load is not None else None
            stepper = _stepper(p, self._rhs_brake, t0, y0, math.inf, brk, Terminal(1, 0.0))
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

    def summary(self) -> MotorFigures:
        """Figures for reports: cost, steady λ, stop and rest times."""
        tail, load, p = self.tail, self.load, self.params
        return MotorFigures(
            method=p.method,
            nfev=self.nfev,
            steps=self.steps,
            rejected=self.rejected,
            theta_end=self.theta_end,
            t_stop=self.t_stop,
            t_rest=self.t_rest,
            lambda_free=p.omega_free / p.omega_nom,
            t_periodic=None if tail is None else float(tail.t_b),
            lambda_steady=None if tail is None else float(tail.dtheta / tail.period),
            load_mean=None if load is None else float(load.mean),
            load_peak=None if load is None else float(load.peak),
            lambda_estimate=None if load is None else steady_speed(p, load.mean) / p.omega_nom,
            switches=[(float(t), bool(on)) for t, on in self.switches] if self.commanded else None,
        )


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
    breaks: Breaks | None,
    terminal: Terminal | None,
) -> RK4Stepper | Dopri5Stepper:
    if p.method == 'rk4':
        return RK4Stepper(fun, t0, y0, t_bound=t_bound, h=p.h, breaks=breaks, terminal=terminal, max_steps=MAX_STEPS)
    return Dopri5Stepper(
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


def motor_params(scene: SceneView) -> Params:
    """The scene's ``motor_dynamics`` parameters, checked for the method's step (``ParameterError`` naming
    the key when the scene does not list the effect or the step cannot settle)."""
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
        Take the periodic-steady-state shortcut (docs/machines.md, "The motor drive").
    duration : float
        Times are clipped to ``[0, duration]`` (default: none; :func:`build_drive`).

    Raises
    ------
    ParameterError
        The scene does not list ``motor_dynamics``; RK4 step beyond its stability limit; stall
        torque not above the peak chain load; a self-locking delivery; commands not sorted.
    """
    commands = check_commands(commands)
    switches = _switches(motor_params(scene).t_stop, commands, duration)
    if previous is not None and previous.periodic == periodic and math.isinf(previous.duration):
        previous.set_switches(switches, bool(commands))
        return previous
    p = motor_params(scene)
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
