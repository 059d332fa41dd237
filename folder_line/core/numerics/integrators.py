"""Explicit Runge-Kutta steppers (RK4, DOPRI5) with breaks and terminal conditions: resumable, with dense output.

Methods
-------
:class:`RK4Stepper`, :func:`rk4`
    The classic four-stage Runge-Kutta method with a fixed step ``h``. Dense output:
    the cubic Hermite interpolant of each step's end states and derivatives
    (C1 across steps; exact for solutions that are cubics; local error O(h^4)).
:class:`Dopri5Stepper`, :func:`dopri5`
    The Dormand-Prince 5(4) pair with the tableau, error norm and step-size control of
    scipy's ``RK45`` (``scipy/integrate/_ivp/rk.py``, ``common.py``): local
    extrapolation (steps taken with the 5th-order solution), error estimated for the
    4th-order one, RMS norm of ``err / (atol + max(|y|, |y_new|) rtol)``, the first
    step from Hairer-Norsett-Wanner II.4 (``select_initial_step``), safety 0.9, step
    factor limited to [0.2, 10] (not above 1 right after a rejection), ``max_step``,
    smallest step ``10 ulp(t)``. Dense output: the 4th-order continuous extension
    of Shampine (1986), the same as scipy's. Without breaks or a terminal condition the
    step sequence is scipy's to rounding (a test checks it).

Steppers and streams
--------------------
A stepper (:class:`RK4Stepper`, :class:`Dopri5Stepper`) holds the whole state of the
step loop as attributes: the current time, state and derivative, the piece of the
breaks, rk4's grid origin and index on the piece, dopri5's proposed step size and whether
its last attempt was rejected, the counters and the recorded steps.
``advance(until)`` takes accepted steps until the last one ends at or after ``until``; it
never cuts a step there (the last step straddles ``until``). Steps are cut only at
``t_bound``, at a break landing and at a terminal root, so **the steps of a stream do not
depend on where it is advanced to**: ``advance(u1); advance(u2); ...`` takes bit for bit
the steps of a single ``advance`` to the end. With ``t_bound=inf`` a stepper integrates
for ever, window by window; ``prune(t_keep)`` drops the recorded steps that end before
``t_keep`` (the dense output on the kept range is unchanged) so that memory stays
bounded, and ``solution()`` returns the kept steps as a
:class:`~folder_line.core.numerics.dense.DenseSolution`. ``copy.deepcopy`` gives an
independent stepper that takes the same steps (the right-hand side and the callbacks are
shared, not copied: whatever state they keep is shared too).

:func:`rk4` and :func:`dopri5` integrate a finite span in one call: they build a stepper
with ``t_bound = t_end``, advance it to ``t_end`` and return its solution (step
endpoints, states, the per-step polynomial of the dense output, the counters ``nfev``,
``steps`` and ``rejected``; its evaluation and vectorised inverse are described in
:mod:`folder_line.core.numerics.dense`).

Discontinuous right-hand sides (``breaks``)
-------------------------------------------
A right-hand side that switches at known values ``b_1 < b_2 < ...`` of a
non-decreasing state component ``y_j`` (the chain load of the delivery switches on
and off at fixed master phases) is integrated piece by piece: ``fun(t, y, piece)``
gets ``piece = (lo, hi)``, the break values bracketing the current piece (``lo`` is
``y_j(t0)`` on the first piece), and must be smooth there, extended smoothly a little
beyond. A step that would carry ``y_j`` past ``hi`` is cut: the crossing is located on
the trial step's dense output, the step is redone to land there and refined by
Newton iterations on the step length (``d y_j / d h = f_j`` at the end of the step)
until ``|y_j - hi| <= 8 eps max(|hi|, |y_j|)`` (rk4) or until the miss is below
``LANDING_FRACTION`` (1e-3) of dopri5's error allowance ``atol_j + rtol |hi|`` (at most
8 redos; the largest miss is kept in ``max_landing_error``). Then the piece advances
and ``fun`` is evaluated anew on the new piece. The method keeps its order across the
switch instead of dropping to first order, as it would if a step straddled the jump.
The step size proposed before the switch is kept (scipy's controller is not reset);
rk4's grid restarts at the landing (``t_piece + k h``).

Terminal condition (``terminal``)
---------------------------------
``Terminal(j, value)`` ends the integration where ``y_j`` first crosses ``value``
(either direction, not counting a start on it): the root is found on the dense output
of the step (safeguarded Newton), the last step is truncated there and its end state
gets ``y_j = value`` exactly.

Failure is loud
---------------
A non-finite state or derivative never passes silently. RK4 raises
:class:`folder_line.errors.IntegrationError` (re-exported here) naming the step, the
time and the step size at the first non-finite stage (an unstable step on a stiff
problem overflows after a few steps). DOPRI5 treats a non-finite trial as a
rejection (the step shrinks, like scipy, which sees a NaN error norm); if the step
falls below ``10 ulp(t)`` it raises. Both raise if one ``advance`` would take more than
``max_steps`` steps (rk4) or step attempts (dopri5) (a stalled or absurdly stiff run) --
before the first step when the span to advance alone needs more steps of ``h``
(``max_step``) and nothing can end the run early (no ``terminal``, no ``on_break``).
numpy's floating-point warnings are switched off while a stepper starts or advances
(the right-hand side included): overflow and invalid operations show up as non-finite
values, which are checked after every step and reported with the step and the time.

The step loop is a Python loop over steps (an ODE is sequential); each step does a
fixed handful of numpy operations on the state vector.
"""

from __future__ import annotations

import bisect
import functools
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import ClassVar, ParamSpec, TypeVar

import numpy as np
import numpy.typing as npt

from folder_line.core.numerics.arrays import FloatArray
from folder_line.core.numerics.constants import EPS
from folder_line.core.numerics.dense import DenseSolution, horner, poly_solve
from folder_line.errors import IntegrationError  # re-exported: defined with the other errors

__all__ = [
    'Breaks',
    'Dopri5Stepper',
    'IntegrationError',
    'RK4Stepper',
    'Terminal',
    'dopri5',
    'rk4',
]

Piece = tuple[float, float]
Fun = Callable[..., npt.ArrayLike]
_Params = ParamSpec('_Params')
_R = TypeVar('_R')

#: scipy RK45 step control
SAFETY = 0.9
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0
#: redo steps at most this many times to land on a break
MAX_LANDING = 8
#: dopri5 lands on a break to this fraction of its error allowance there (or to 8 eps)
LANDING_FRACTION = 1e-3
#: the last fixed step of rk4 is stretched to t_bound instead of leaving a sliver below this fraction of h
RK4_SNAP = 1e-6
#: default bound on the steps (rk4) or step attempts (dopri5) of one call
MAX_STEPS = 10_000_000

# Dormand-Prince 5(4), exactly as scipy.integrate._ivp.rk.RK45
_C = np.array([0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1])
_A = np.array(
    [
        [0, 0, 0, 0, 0],
        [1 / 5, 0, 0, 0, 0],
        [3 / 40, 9 / 40, 0, 0, 0],
        [44 / 45, -56 / 15, 32 / 9, 0, 0],
        [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729, 0],
        [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656],
    ]
)
_B = np.array([35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84])
_E = np.array([-71 / 57600, 0, 71 / 16695, -71 / 1920, 17253 / 339200, -22 / 525, 1 / 40])
_P = np.array(
    [
        [1, -8048581381 / 2820520608, 8663915743 / 2820520608, -12715105075 / 11282082432],
        [0, 0, 0, 0],
        [0, 131558114200 / 32700410799, -68118460800 / 10900136933, 87487479700 / 32700410799],
        [0, -1754552775 / 470086768, 14199869525 / 1410260304, -10690763975 / 1880347072],
        [0, 127303824393 / 49829197408, -318862633887 / 49829197408, 701980252875 / 199316789632],
        [0, -282668133 / 205662961, 2019193451 / 616988883, -1453857185 / 822651844],
        [0, 40617522 / 29380423, -110615467 / 29380423, 69997945 / 29380423],
    ]
)
_ERROR_EXPONENT = -1.0 / 5.0  # error estimator of order 4


@dataclass(frozen=True)
class Breaks:
    """Values of a non-decreasing state component where the right-hand side switches.

    Attributes
    ----------
    component : int
        Index ``j`` of the component (it must not decrease along the solution).
    next_after : callable
        ``next_after(v) -> b``: the smallest break value strictly greater than ``v``
        (``inf`` if there is none).
    on_break : callable, optional
        ``on_break(t, y, b) -> bool`` called after landing on break ``b`` at time
        ``t`` with state ``y`` (a copy); returning True ends the integration there
        (status ``'stopped'``).
    """

    component: int
    next_after: Callable[[float], float]
    on_break: Callable[[float, FloatArray, float], bool] | None = None


@dataclass(frozen=True)
class Terminal:
    """End the integration where ``y[component]`` first crosses ``value``."""

    component: int
    value: float


# --------------------------------------------------------------------------- common parts


def _quiet(func: Callable[_Params, _R]) -> Callable[_Params, _R]:
    """Run ``func`` with numpy floating-point warnings off: overflow and invalid values
    are caught as non-finite states (with the step and the time), not as warnings."""

    @functools.wraps(func)
    def wrapper(*args: _Params.args, **kwargs: _Params.kwargs) -> _R:
        with np.errstate(all='ignore'):
            return func(*args, **kwargs)

    return wrapper


class _Recorder:
    """Growable buffers of accepted steps."""

    def __init__(self, t0: float, y0: FloatArray) -> None:
        m = y0.size
        self.cap = 256
        self.n = 0
        self.t = np.empty(self.cap + 1)
        self.y = np.empty((self.cap + 1, m))
        self.h = np.empty(self.cap)
        self.coef = np.empty((5, self.cap, m))
        self.t[0] = t0
        self.y[0] = y0
        self.break_t: list[float] = []
        self.break_value: list[float] = []

    def add(self, h: float, t_end: float, y_end: FloatArray, coef: FloatArray) -> None:
        if self.n == self.cap:
            cap = 2 * self.cap
            t = np.empty(cap + 1)
            t[: self.n + 1] = self.t[: self.n + 1]
            y = np.empty((cap + 1, self.y.shape[1]))
            y[: self.n + 1] = self.y[: self.n + 1]
            hh = np.empty(cap)
            hh[: self.n] = self.h[: self.n]
            c = np.empty((5, cap, self.y.shape[1]))
            c[:, : self.n] = self.coef[:, : self.n]
            self.t, self.y, self.h, self.coef, self.cap = t, y, hh, c, cap
        self.h[self.n] = h
        self.coef[:, self.n] = coef
        self.n += 1
        self.t[self.n] = t_end
        self.y[self.n] = y_end

    def stop_at(self, terminal: Terminal | None, coef: FloatArray, y_start: FloatArray, y_end: FloatArray) -> bool:
        """Cut the last step (from ``y_start`` to ``y_end``, dense output ``coef``) where it meets
        ``terminal``, its end state then exactly on the value; True if it does."""
        if terminal is None:
            return False
        j = terminal.component
        x = _terminal_root(coef, j, terminal.value, float(y_start[j]), float(y_end[j]))
        if x is None:
            return False
        y_cut = horner(coef.reshape(5, 1, -1), np.array([x]))[0]
        y_cut[j] = terminal.value
        i = self.n - 1
        self.t[self.n] = min(self.t[i] + x * self.h[i], self.t[self.n])
        self.y[self.n] = y_cut
        return True

    def prune(self, t_keep: float) -> None:
        """Drop the steps that end before ``t_keep`` (keeping the last step) and the breaks
        landed on before the first kept step."""
        d = min(int(np.searchsorted(self.t[1 : self.n + 1], t_keep, side='left')), self.n - 1)
        if d <= 0:
            return
        n = self.n - d
        # numpy copies through a temporary when source and destination overlap
        self.t[: n + 1] = self.t[d : self.n + 1]
        self.y[: n + 1] = self.y[d : self.n + 1]
        self.h[:n] = self.h[d : self.n]
        self.coef[:, :n] = self.coef[:, d : self.n]
        self.n = n
        k = bisect.bisect_left(self.break_t, float(self.t[0]))
        del self.break_t[:k], self.break_value[:k]

    def build(self, method: str, nfev: int, rejected: int, status: str, landing: float) -> DenseSolution:
        if self.n == 0:
            raise ValueError('no step was taken')
        return DenseSolution(
            self.t[: self.n + 1].copy(),
            self.y[: self.n + 1].copy(),
            self.h[: self.n].copy(),
            self.coef[:, : self.n].copy(),
            method=method,
            nfev=nfev,
            rejected=rejected,
            status=status,
            break_t=np.array(self.break_t),
            break_value=np.array(self.break_value),
            max_landing_error=landing,
        )


def _span(method: str, t_span: tuple[float, float]) -> tuple[float, float]:
    """``(t0, t_end)`` of a one-call integration: two finite numbers, ``t_end > t0``."""
    try:
        t0, t1 = (float(v) for v in t_span)
    except (TypeError, ValueError):
        raise ValueError(f'{method}: t_span must be two numbers, got {t_span!r}') from None
    if not (math.isfinite(t0) and math.isfinite(t1)) or not t1 > t0:
        raise ValueError(f'{method}: t_span must be finite with t_end > t0, got {t_span!r}')
    return t0, t1


def _landing_tol(b: float, yj: float) -> float:
    return 8.0 * EPS * max(abs(b), abs(yj), 1e-300)


def _terminal_root(coef: FloatArray, j: int, value: float, y_start: float, y_end: float) -> float | None:
    """Fraction x in (0, 1] of the step where component j crosses ``value``, or None."""
    g0, g1 = y_start - value, y_end - value
    if g0 == 0.0 or not (g1 == 0.0 or (g0 < 0.0) != (g1 < 0.0)):
        return None
    sign = 1.0 if g1 > g0 else -1.0
    c = coef[:, j].reshape(5, 1)
    x = poly_solve(c, np.array([value]), np.array([1.0]), sign, np.array([g0 / (g0 - g1)]))
    return float(x[0])


class _Stepper:
    """State and bookkeeping common to the steppers (validation, right-hand side, breaks,
    recorded steps); the subclasses add the method and its step loop (``_advance``)."""

    method: ClassVar[str] = ''

    def __init__(
        self,
        fun: Fun,
        t0: float,
        y0: npt.ArrayLike,
        *,
        t_bound: float,
        breaks: Breaks | None,
        terminal: Terminal | None,
        max_steps: int,
    ) -> None:
        method = self.method
        try:
            t_start, t_end = float(t0), float(t_bound)
        except (TypeError, ValueError):
            raise ValueError(f'{method}: t0 and t_bound must be numbers, got {t0!r} and {t_bound!r}') from None
        if not (math.isfinite(t_start) and t_end > t_start):
            raise ValueError(
                f'{method}: t0 must be finite and t_bound > t0 (t_bound may be inf), got t0={t0!r}, t_bound={t_bound!r}'
            )
        y = np.array(y0, dtype=float).ravel()
        if y.size == 0 or not np.all(np.isfinite(y)):
            raise ValueError(f'{method}: y0 must be a non-empty finite vector, got {y0!r}')
        piece: Piece = (-math.inf, math.inf)
        if breaks is not None:
            j = breaks.component
            if not 0 <= j < y.size:
                raise ValueError(f'{method}: breaks.component={j!r} is not a component of y (size {y.size})')
            lo = float(y[j])
            hi = float(breaks.next_after(lo))
            if not hi > lo:
                raise ValueError(f'{method}: breaks.next_after({lo!r}) = {hi!r} is not above its argument')
            piece = (lo, hi)
        self._fun = fun
        self._breaks = breaks
        self._terminal = terminal
        self._max_steps = max_steps
        self._t_bound = t_end
        self._t: float = t_start
        self._y: FloatArray = y
        self._f: FloatArray = np.zeros_like(y)  # the derivative at (t, y): set by the subclass
        self._piece = piece
        self._status = 'running'
        self._nfev = 0
        self._rejected = 0
        self._steps = 0
        self._landing = 0.0
        self._rec = _Recorder(t_start, y)

    # ------------------------------------------------------------------ public

    @property
    def t(self) -> float:
        """End of the last accepted step (``t0`` before the first), in the unit of ``t``."""
        return float(self._t)

    @property
    def y(self) -> FloatArray:
        """State at :attr:`t` (a copy), shape (m,)."""
        return self._y.copy()

    @property
    def status(self) -> str:
        """``'running'``, ``'finished'`` (reached ``t_bound``), ``'terminal'`` (terminal
        condition) or ``'stopped'`` (an ``on_break`` callback asked to stop)."""
        return self._status

    @_quiet
    def advance(self, until: float) -> None:
        """Take accepted steps until the last one ends at or after ``until``.

        Stops earlier when the status leaves ``'running'`` (``t_bound`` reached, terminal
        condition, ``on_break``). No step is cut at ``until``: the last one straddles it, so
        the steps do not depend on how a run is split into calls. An ``until`` already
        covered (``until <= t``) or a stepper that is no longer running does nothing.

        Parameters
        ----------
        until : float
            Time to reach, in the unit of ``t`` (may be ``inf``: run to ``t_bound`` or to
            the terminal condition, ``on_break`` or ``max_steps``).

        Raises
        ------
        IntegrationError
            A non-finite step (rk4), a step below ``10 ulp(t)`` (dopri5), or more than
            ``max_steps`` steps (rk4) / step attempts (dopri5) in this call. The stepper
            keeps its last accepted step; after ``max_steps`` it can be advanced again
            and goes on with the steps of an unbroken run.
        ValueError
            ``until`` is NaN.
        """
        until = float(until)
        if math.isnan(until):
            raise ValueError(f'{self.method}: advance(until) needs a number, got {until!r}')
        if self._status != 'running' or not self._t < until:
            return
        self._advance(until)

    def solution(self) -> DenseSolution:
        """The recorded (and not pruned) steps as a dense solution.

        Its counters ``nfev`` and ``rejected``, its breaks kept and ``max_landing_error``
        cover the run since ``t0``; ``steps`` counts the kept steps; ``status`` is the
        stepper's (``'running'`` while it is).

        Raises
        ------
        ValueError
            No step was taken yet (or kept).
        """
        return self._rec.build(self.method, self._nfev, self._rejected, self._status, self._landing)

    def prune(self, t_keep: float) -> None:
        """Drop the recorded steps that end before ``t_keep`` (the last step is always kept).

        The kept steps and their polynomials are untouched, so the solution evaluates to
        the same values, bit for bit, on ``[t_keep, t]``; its first time is the end of the
        last dropped step (at most ``t_keep``). Breaks landed on before that are dropped
        too. Memory stays bounded by the steps taken between prunes.

        Parameters
        ----------
        t_keep : float
            Earliest time still needed, in the unit of ``t``.
        """
        t_keep = float(t_keep)
        if math.isnan(t_keep):
            raise ValueError(f'{self.method}: prune(t_keep) needs a number, got {t_keep!r}')
        self._rec.prune(t_keep)

    # ------------------------------------------------------------------ for the methods

    def _rhs(self, t: float, y: FloatArray, piece: Piece) -> FloatArray:
        if self._breaks is None:
            return np.asarray(self._fun(t, y), dtype=float)
        return np.asarray(self._fun(t, y, piece), dtype=float)

    def _cannot_end_early(self) -> bool:
        return self._terminal is None and (self._breaks is None or self._breaks.on_break is None)

    def _switch_piece(self, t: float, y: FloatArray, b: float) -> tuple[Piece, FloatArray, bool]:
        """Record the landing on break ``b`` at ``(t, y)`` and move on to the next piece: returns the
        piece, the derivative there (one evaluation of the right-hand side) and whether
        ``on_break`` ends the run."""
        breaks = self._breaks
        assert breaks is not None
        self._rec.break_t.append(t)
        self._rec.break_value.append(b)
        nb = float(breaks.next_after(b))
        if not nb > b:
            raise ValueError(f'{self.method}: breaks.next_after({b!r}) = {nb!r} is not above its argument')
        piece = (b, nb)
        f = self._rhs(t, y, piece)
        return piece, f, breaks.on_break is not None and bool(breaks.on_break(t, y.copy(), b))

    def _advance(self, until: float) -> None:
        raise NotImplementedError


# --------------------------------------------------------------------------- RK4


def _hermite_coef(y0: FloatArray, y1: FloatArray, f0: FloatArray, f1: FloatArray, h: float) -> FloatArray:
    d = y1 - y0
    hf0, hf1 = h * f0, h * f1
    return np.stack([y0, hf0, 3.0 * d - 2.0 * hf0 - hf1, hf0 + hf1 - 2.0 * d, np.zeros_like(y0)])


class RK4Stepper(_Stepper):
    """Classic RK4 with a fixed step and cubic Hermite dense output, advanced on demand.

    Parameters
    ----------
    fun : callable
        ``fun(t, y) -> dy/dt`` (``fun(t, y, piece)`` with ``breaks``), ``y`` of shape (m,).
    t0 : float
        Initial time (finite), in the unit of the ODE's time (s for the motor).
    y0 : array_like, shape (m,)
        Initial state.
    t_bound : float
        End of the integration (> ``t0``), same unit; ``inf`` (default) for a stream that
        runs for ever.
    h : float
        Step size (> 0), same unit. Within a piece the grid is ``t_piece + k h`` (no
        accumulated rounding; ``t_piece`` is ``t0`` or the last break landing); the last
        step is clipped to ``t_bound`` (or stretched by at most ``RK4_SNAP h`` rather than
        leave a sliver).
    breaks : Breaks, optional
        Switches of the right-hand side (module docstring).
    terminal : Terminal, optional
        Stop where a component crosses a value.
    max_steps : int
        Raise :class:`IntegrationError` when one :meth:`advance` needs more steps than this.

    Raises
    ------
    IntegrationError
        The right-hand side is not finite at the initial state.
    ValueError
        Bad arguments.
    """

    method: ClassVar[str] = 'rk4'

    @_quiet
    def __init__(
        self,
        fun: Fun,
        t0: float,
        y0: npt.ArrayLike,
        *,
        t_bound: float = math.inf,
        h: float,
        breaks: Breaks | None = None,
        terminal: Terminal | None = None,
        max_steps: int = MAX_STEPS,
    ) -> None:
        super().__init__(fun, t0, y0, t_bound=t_bound, breaks=breaks, terminal=terminal, max_steps=max_steps)
        h = float(h)
        if not (math.isfinite(h) and h > 0.0):
            raise ValueError(f'rk4: h must be finite and > 0, got {h!r}')
        self._h = h
        #: the grid of the current piece: steps end at t_piece + (k_piece + 1) h
        self._t_piece: float = self._t
        self._k_piece = 0
        f = self._rhs(self._t, self._y, self._piece)
        self._nfev += 1
        if not np.all(np.isfinite(f)):
            raise IntegrationError(
                'rk4', 0, self._t, h, f'the right-hand side is not finite at the initial state: {f!r}'
            )
        self._f = f

    def _step(self, t: float, y: FloatArray, f: FloatArray, hh: float, piece: Piece, n: int) -> tuple[FloatArray, int]:
        """One RK4 step of size ``hh`` from ``(t, y)`` with ``f = F(t, y)`` (step number ``n``):
        the new state and the evaluations used."""
        half = 0.5 * hh
        k2 = self._rhs(t + half, y + half * f, piece)
        k3 = self._rhs(t + half, y + half * k2, piece)
        k4 = self._rhs(t + hh, y + hh * k3, piece)
        y_new = y + (hh / 6.0) * (f + 2.0 * k2 + 2.0 * k3 + k4)
        if not np.isfinite(y_new).all():  # a non-finite stage always reaches y_new (no zero weights)
            raise IntegrationError(
                'rk4',
                n,
                t,
                hh,
                f'non-finite state {y_new!r} after the step (from y={y!r}): the step is '
                'too large for this problem (RK4 is unstable beyond h |lambda| ~ 2.8 on a '
                'decaying mode); reduce h or use dopri5',
            )
        return y_new, 3

    def _advance(self, until: float) -> None:
        h, t1, breaks, terminal, max_steps = self._h, self._t_bound, self._breaks, self._terminal, self._max_steps
        rec = self._rec
        t, y, f, piece = self._t, self._y, self._f, self._piece
        t_piece, k_piece = self._t_piece, self._k_piece
        nfev, steps, landing_err, status = self._nfev, self._steps, self._landing, self._status
        span = (float(t), float(min(until, t1)))

        def too_many() -> IntegrationError:
            return IntegrationError(
                'rk4',
                steps,
                t,
                h,
                f'more than max_steps={max_steps} steps (the span {span!r} needs ~{(span[1] - span[0]) / h:.3g} '
                'steps of h)',
            )

        if self._cannot_end_early() and (span[1] - span[0]) / (h * (1.0 + RK4_SNAP)) > max_steps + 1:
            # this call cannot end early, so it is bound to exceed max_steps: say so before the first step
            raise too_many()
        n = 0
        try:
            while t < until:
                if n >= max_steps:
                    raise too_many()
                t_next = t_piece + (k_piece + 1) * h
                if t_next > t1 or t1 - t_next <= RK4_SNAP * h:
                    t_next = t1
                hh = t_next - t
                y_new, ne = self._step(t, y, f, hh, piece, steps)
                nfev += ne
                f_new = self._rhs(t_next, y_new, piece)
                nfev += 1
                crossed = False
                if breaks is not None:
                    j = breaks.component
                    b = piece[1]
                    tol = _landing_tol(b, float(y[j]))
                    if y_new[j] > b + tol:
                        c = _hermite_coef(y, y_new, f, f_new, hh)[:, j].reshape(5, 1)
                        x0 = np.array([(b - y[j]) / (y_new[j] - y[j])])
                        x = poly_solve(c, np.array([b]), np.array([1.0]), 1.0, x0)[0]
                        h1 = x * hh
                        for _ in range(MAX_LANDING):
                            y1, ne = self._step(t, y, f, h1, piece, steps)
                            f1 = self._rhs(t + h1, y1, piece)
                            nfev += ne + 1
                            e = float(y1[j] - b)
                            if abs(e) <= tol or not f1[j] > 0.0:
                                break
                            h1 = min(max(h1 - e / float(f1[j]), 0.0), hh)
                        landing_err = max(landing_err, abs(float(y1[j] - b)))
                        hh, t_next, y_new, f_new = h1, t + h1, y1, f1
                        crossed = True
                    elif y_new[j] >= b - tol:
                        landing_err = max(landing_err, abs(float(y_new[j] - b)))
                        crossed = True
                coef = _hermite_coef(y, y_new, f, f_new, hh)
                rec.add(hh, t_next, y_new, coef)
                steps += 1
                n += 1
                if rec.stop_at(terminal, coef, y, y_new):
                    status = 'terminal'
                    t, y = rec.t[rec.n], rec.y[rec.n].copy()
                    break
                t, y = t_next, y_new
                if crossed:
                    piece, f, stop = self._switch_piece(t, y, piece[1])
                    nfev += 1
                    t_piece, k_piece = t, 0
                    if stop:
                        status = 'stopped'
                        break
                else:
                    k_piece += 1
                    f = f_new
                if t >= t1:
                    status = 'finished'
                    break
        finally:
            self._t, self._y, self._f, self._piece = t, y, f, piece
            self._t_piece, self._k_piece = t_piece, k_piece
            self._nfev, self._steps, self._landing, self._status = nfev, steps, landing_err, status


def rk4(
    fun: Fun,
    t_span: tuple[float, float],
    y0: npt.ArrayLike,
    h: float,
    *,
    breaks: Breaks | None = None,
    terminal: Terminal | None = None,
    max_steps: int = MAX_STEPS,
) -> DenseSolution:
    """Classic RK4 with a fixed step and cubic Hermite dense output, over a finite span.

    Parameters
    ----------
    fun : callable
        ``fun(t, y) -> dy/dt`` (``fun(t, y, piece)`` with ``breaks``), ``y`` of shape (m,).
    t_span : (float, float)
        ``(t0, t_end)``, finite, ``t_end > t0``.
    y0 : array_like, shape (m,)
        Initial state.
    h : float
        Step size (> 0). Within a piece the grid is ``t_piece + k h`` (no accumulated
        rounding); the last step is clipped to ``t_end`` (or stretched by at most
        ``RK4_SNAP h`` rather than leave a sliver).
    breaks : Breaks, optional
        Switches of the right-hand side (module docstring).
    terminal : Terminal, optional
        Stop where a component crosses a value.
    max_steps : int
        Raise :class:`IntegrationError` when a run needs more steps than this.

    Returns
    -------
    DenseSolution
        The steps of :class:`RK4Stepper` with ``t_bound = t_end`` advanced to ``t_end``.

    Raises
    ------
    IntegrationError
        A stage or the new state is not finite (names the step, its start time and h).
    ValueError
        Bad arguments.
    """
    t0, t1 = _span('rk4', t_span)
    stepper = RK4Stepper(fun, t0, y0, t_bound=t1, h=h, breaks=breaks, terminal=terminal, max_steps=max_steps)
    stepper.advance(t1)
    return stepper.solution()


# --------------------------------------------------------------------------- DOPRI5


def _rms(x: FloatArray) -> float:
    return float(np.linalg.norm(x) / x.size**0.5)


def _select_initial_step(
    F: Callable[[float, FloatArray, Piece], FloatArray],
    t0: float,
    y0: FloatArray,
    t_bound: float,
    max_step: float,
    f0: FloatArray,
    rtol: float,
    atol: FloatArray | float,
    piece: Piece,
) -> float:
    """scipy's ``select_initial_step`` (Hairer-Norsett-Wanner II.4), order 4, forward."""
    interval_length = abs(t_bound - t0)
    scale = atol + np.abs(y0) * rtol
    d0 = _rms(y0 / scale)
    d1 = _rms(f0 / scale)
    h0 = 1e-6 if (d0 < 1e-5 or d1 < 1e-5) else 0.01 * d0 / d1
    h0 = min(h0, interval_length)
    y1 = y0 + h0 * f0
    f1 = F(t0 + h0, y1, piece)
    d2 = _rms((f1 - f0) / scale) / h0
    if not math.isfinite(d2):
        return min(h0 * 1e-3, max_step)
    h1 = max(1e-6, h0 * 1e-3) if d1 <= 1e-15 and d2 <= 1e-15 else (0.01 / max(d1, d2)) ** (1 / 5)
    return min(100 * h0, h1, interval_length, max_step)


def _dopri_step(
    F: Callable[[float, FloatArray, Piece], FloatArray],
    t: float,
    y: FloatArray,
    f: FloatArray,
    h: float,
    piece: Piece,
    K: FloatArray,
    rtol: float,
    atol: FloatArray | float,
) -> tuple[FloatArray, float]:
    """One DOPRI5 step (scipy's ``rk_step``); returns the new state and the error norm (inf if non-finite)."""
    K[0] = f
    for s in range(1, 6):
        dy = np.dot(K[:s].T, _A[s, :s]) * h
        K[s] = F(t + _C[s] * h, y + dy, piece)
    y_new = y + h * np.dot(K[:-1].T, _B)
    K[-1] = F(t + h, y_new, piece)
    # a non-finite stage reaches y_new or K[-1] (every stage feeds a later one with a non-zero weight)
    if not (np.isfinite(y_new).all() and np.isfinite(K[-1]).all()):
        return y_new, math.inf
    scale = atol + np.maximum(np.abs(y), np.abs(y_new)) * rtol
    err = _rms(np.dot(K.T, _E) * h / scale)
    return y_new, err if math.isfinite(err) else math.inf


def _dopri_coef(y: FloatArray, K: FloatArray, h: float) -> FloatArray:
    Q = np.dot(K.T, _P)  # (m, 4)
    return np.vstack([y[None, :], h * Q.T])


class Dopri5Stepper(_Stepper):
    """Adaptive Dormand-Prince 5(4) with scipy RK45's step control and 4th-order dense output,
    advanced on demand.

    Parameters
    ----------
    fun, t0, y0, t_bound
        As for :class:`RK4Stepper`.
    rtol : float
        Relative tolerance (>= 100 eps).
    atol : float or array_like of shape (m,)
        Absolute tolerance (> 0), in the units of the components.
    max_step : float
        Largest step (> 0; default unbounded), in the unit of ``t``.
    first_step : float, optional
        First step, same unit; default chosen as scipy does.
    breaks, terminal : optional
        As for :class:`RK4Stepper`.
    max_steps : int
        Raise :class:`IntegrationError` when one :meth:`advance` needs more step attempts
        than this.

    Raises
    ------
    IntegrationError
        The right-hand side is not finite at the initial state.
    ValueError
        Bad arguments.
    """

    method: ClassVar[str] = 'dopri5'

    @_quiet
    def __init__(
        self,
        fun: Fun,
        t0: float,
        y0: npt.ArrayLike,
        *,
        t_bound: float = math.inf,
        rtol: float = 1e-3,
        atol: float | npt.ArrayLike = 1e-6,
        max_step: float = math.inf,
        first_step: float | None = None,
        breaks: Breaks | None = None,
        terminal: Terminal | None = None,
        max_steps: int = MAX_STEPS,
    ) -> None:
        super().__init__(fun, t0, y0, t_bound=t_bound, breaks=breaks, terminal=terminal, max_steps=max_steps)
        y = self._y
        rtol = float(rtol)
        if not (math.isfinite(rtol) and rtol >= 100 * EPS):
            raise ValueError(f'dopri5: rtol must be >= 100 eps = {100 * EPS!r}, got {rtol!r}')
        atol_a = np.asarray(atol, dtype=float)
        if atol_a.ndim > 0 and atol_a.shape != y.shape:
            raise ValueError(f'dopri5: atol must be a number or have shape {y.shape}, got shape {atol_a.shape}')
        if not (np.all(np.isfinite(atol_a)) and np.all(atol_a > 0.0)):
            raise ValueError(f'dopri5: atol must be finite and > 0, got {atol!r}')
        max_step = float(max_step)
        if not max_step > 0.0:
            raise ValueError(f'dopri5: max_step must be > 0, got {max_step!r}')
        self._rtol = rtol
        self._atol: FloatArray | float = float(atol_a) if atol_a.ndim == 0 else atol_a
        j = breaks.component if breaks is not None else -1
        #: the absolute tolerance of the break component (for the landing)
        self._atol_j = float(atol_a) if atol_a.ndim == 0 else float(atol_a[j])
        self._max_step = max_step
        t0, t_bound = self._t, self._t_bound
        f = self._rhs(t0, y, self._piece)
        self._nfev = 1
        if not np.all(np.isfinite(f)):
            raise IntegrationError(
                'dopri5', 0, t0, 0.0, f'the right-hand side is not finite at the initial state: {f!r}'
            )
        self._f = f
        if first_step is None:
            h_abs = _select_initial_step(self._rhs, t0, y, t_bound, max_step, f, rtol, self._atol, self._piece)
            self._nfev += 1
        else:
            h_abs = float(first_step)
            if not (math.isfinite(h_abs) and h_abs > 0.0):
                raise ValueError(f'dopri5: first_step must be finite and > 0, got {first_step!r}')
            h_abs = min(h_abs, t_bound - t0)
        #: the step size proposed for the next attempt
        self._h_abs = h_abs
        #: whether the last attempt was rejected (the next step may then not grow)
        self._step_rejected = False
        self._K = np.empty((7, y.size))  # the stages of the current attempt

    def _advance(self, until: float) -> None:
        rtol, atol, atol_j, max_step = self._rtol, self._atol, self._atol_j, self._max_step
        t_bound, breaks, terminal, max_steps = self._t_bound, self._breaks, self._terminal, self._max_steps
        rec, K, F = self._rec, self._K, self._rhs
        t, y, f, piece = self._t, self._y, self._f, self._piece
        h_abs, step_rejected = self._h_abs, self._step_rejected
        nfev, rejected, steps, landing_err, status = (
            self._nfev,
            self._rejected,
            self._steps,
            self._landing,
            self._status,
        )
        span = (float(t), float(min(until, t_bound)))
        if self._cannot_end_early() and (span[1] - span[0]) / max_step > max_steps:
            # every step is at most max_step and this call cannot end early: bound to exceed max_steps
            raise IntegrationError(
                'dopri5',
                steps,
                t,
                max_step,
                f'more than max_steps={max_steps} step attempts '
                f'(the span {span!r} needs at least {(span[1] - span[0]) / max_step:.3g} steps '
                f'of max_step)',
            )
        j = breaks.component if breaks is not None else -1
        attempts = 0
        try:
            while t < until:
                min_step = 10.0 * abs(np.nextafter(t, math.inf) - t)
                if not step_rejected:  # the first attempt of a step
                    if h_abs > max_step:
                        h_abs = max_step
                    elif h_abs < min_step:
                        h_abs = min_step
                if h_abs < min_step:
                    raise IntegrationError(
                        'dopri5',
                        steps,
                        t,
                        h_abs,
                        f'step size fell below the resolvable {min_step!r} after {rejected} '
                        'rejections (non-finite right-hand side or extreme stiffness)',
                    )
                attempts += 1
                if attempts > max_steps:
                    raise IntegrationError('dopri5', steps, t, h_abs, f'more than max_steps={max_steps} step attempts')
                t_new = t + h_abs
                if t_new > t_bound:
                    t_new = t_bound
                h = t_new - t
                h_abs = abs(h)
                y_new, err = _dopri_step(F, t, y, f, h, piece, K, rtol, atol)
                nfev += 6
                if not err < 1.0:
                    h_abs *= max(MIN_FACTOR, SAFETY * err**_ERROR_EXPONENT) if math.isfinite(err) else MIN_FACTOR
                    step_rejected = True
                    rejected += 1
                    continue
                factor = MAX_FACTOR if err == 0.0 else min(MAX_FACTOR, SAFETY * err**_ERROR_EXPONENT)
                if step_rejected:
                    factor = min(1.0, factor)
                h_next = h_abs * factor
                crossed = False
                if breaks is not None:
                    b = piece[1]
                    tol = max(_landing_tol(b, float(y[j])), LANDING_FRACTION * (atol_j + rtol * abs(b)))
                    if y_new[j] > b + tol:
                        c = _dopri_coef(y, K, h)[:, j].reshape(5, 1)
                        x0 = np.array([(b - y[j]) / (y_new[j] - y[j])])
                        x = poly_solve(c, np.array([b]), np.array([1.0]), 1.0, x0)[0]
                        h1 = x * h
                        redo_ok = True
                        for _ in range(MAX_LANDING):
                            y1, err1 = _dopri_step(F, t, y, f, h1, piece, K, rtol, atol)
                            nfev += 6
                            if not err1 < 1.0:
                                redo_ok = False
                                break
                            e = float(y1[j] - b)
                            if abs(e) <= tol or not K[-1][j] > 0.0:
                                break
                            h1 = min(max(h1 - e / float(K[-1][j]), 0.0), h)
                        if not redo_ok:
                            # the shorter step failed its error test: shrink and try again from t (as a new step)
                            h_abs = h1 * (
                                max(MIN_FACTOR, SAFETY * err1**_ERROR_EXPONENT) if math.isfinite(err1) else MIN_FACTOR
                            )
                            step_rejected = False
                            rejected += 1
                            continue
                        landing_err = max(landing_err, abs(float(y1[j] - b)))
                        h, t_new, y_new = h1, t + h1, y1
                        crossed = True
                    elif y_new[j] >= b - tol:
                        landing_err = max(landing_err, abs(float(y_new[j] - b)))
                        crossed = True
                coef = _dopri_coef(y, K, h)
                rec.add(h, t_new, y_new, coef)
                steps += 1
                step_rejected = False
                if rec.stop_at(terminal, coef, y, y_new):
                    status = 'terminal'
                    t, y = rec.t[rec.n], rec.y[rec.n].copy()
                    break
                t, y = t_new, y_new
                h_abs = h_next
                if crossed:
                    piece, f, stop = self._switch_piece(t, y, piece[1])
                    nfev += 1
                    if stop:
                        status = 'stopped'
                        break
                else:
                    f = K[-1].copy()
                if t >= t_bound:
                    status = 'finished'
                    break
        finally:
            self._t, self._y, self._f, self._piece = t, y, f, piece
            self._h_abs, self._step_rejected = h_abs, step_rejected
            self._nfev, self._rejected, self._steps, self._landing, self._status = (
                nfev,
                rejected,
                steps,
                landing_err,
                status,
            )


def dopri5(
    fun: Fun,
    t_span: tuple[float, float],
    y0: npt.ArrayLike,
    *,
    rtol: float = 1e-3,
    atol: float | npt.ArrayLike = 1e-6,
    max_step: float = math.inf,
    first_step: float | None = None,
    breaks: Breaks | None = None,
    terminal: Terminal | None = None,
    max_steps: int = MAX_STEPS,
) -> DenseSolution:
    """Adaptive Dormand-Prince 5(4) with scipy RK45's step control and 4th-order dense output,
    over a finite span.

    Parameters
    ----------
    fun, t_span, y0
        As for :func:`rk4`.
    rtol : float
        Relative tolerance (>= 100 eps).
    atol : float or array_like of shape (m,)
        Absolute tolerance (> 0).
    max_step : float
        Largest step (> 0; default unbounded).
    first_step : float, optional
        First step; default chosen as scipy does.
    breaks, terminal : optional
        As for :func:`rk4`.
    max_steps : int
        Raise :class:`IntegrationError` after this many attempted steps.

    Returns
    -------
    DenseSolution
        The steps of :class:`Dopri5Stepper` with ``t_bound = t_end`` advanced to ``t_end``.

    Raises
    ------
    IntegrationError
        The step fell below ``10 ulp(t)`` (non-finite right-hand side or extreme
        stiffness) or ``max_steps`` attempts were used.
    ValueError
        Bad arguments.
    """
    t0, t1 = _span('dopri5', t_span)
    stepper = Dopri5Stepper(
        fun,
        t0,
        y0,
        t_bound=t1,
        rtol=rtol,
        atol=atol,
        max_step=max_step,
        first_step=first_step,
        breaks=breaks,
        terminal=terminal,
        max_steps=max_steps,
    )
    stepper.advance(t1)
    return stepper.solution()
