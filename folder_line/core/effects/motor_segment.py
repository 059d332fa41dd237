"""The segments of the ``motor_dynamics`` drive: a stretch of constant motor state and its periodic tail.

A :class:`MotorSegment` is motor on (integrated until its period repeats, :class:`PeriodMarks`,
then the last period repeated, :class:`PeriodicTail`) or motor off (the brake until standstill,
then at rest); :class:`~folder_line.core.effects.motor_dynamics.MotorDrive` strings them together
at the switches. The model is described in :mod:`folder_line.core.effects.motor_dynamics` and
docs/machines.md ("The motor drive").
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from folder_line.core.numerics import dense
from folder_line.core.numerics.arrays import FloatArray
from folder_line.core.numerics.dopri5_stepper import Dopri5Stepper
from folder_line.core.numerics.rk4_stepper import RK4Stepper

__all__ = ['PERIODIC_TOL', 'MotorSegment', 'PeriodMarks', 'PeriodicTail']

#: relative agreement of ω (and of the period) at three marks that counts as periodic
PERIODIC_TOL = 1e-12


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
        stepper: RK4Stepper | Dopri5Stepper | None,
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
