"""The parts the steppers share: breaks and terminal conditions, the recorded steps, the bookkeeping.

:class:`Stepper` holds the state of a step loop (time, state, derivative, piece of the
breaks, counters, recorded steps) and its public methods (``advance``, ``solution``,
``prune``); :class:`~folder_line.core.numerics.rk4_stepper.RK4Stepper` and
:class:`~folder_line.core.numerics.dopri5_stepper.Dopri5Stepper` add the method and its
step loop. How breaks, terminal conditions and failures behave is described in
:mod:`folder_line.core.numerics.integrators`.
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

__all__ = [
    'LANDING_FRACTION',
    'MAX_LANDING',
    'MAX_STEPS',
    'Breaks',
    'Fun',
    'Piece',
    'Recorder',
    'Stepper',
    'Terminal',
    'landing_tol',
    'quiet',
]

#: the bracketing break values ``(lo, hi)`` of the current piece
Piece = tuple[float, float]
#: the right-hand side ``fun(t, y)`` (``fun(t, y, piece)`` with breaks)
Fun = Callable[..., npt.ArrayLike]
_Params = ParamSpec('_Params')
_R = TypeVar('_R')

#: redo steps at most this many times to land on a break
MAX_LANDING = 8
#: dopri5 lands on a break to this fraction of its error allowance there (or to 8 eps)
LANDING_FRACTION = 1e-3
#: default bound on the steps (rk4) or step attempts (dopri5) of one call
MAX_STEPS = 10_000_000


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


def quiet(func: Callable[_Params, _R]) -> Callable[_Params, _R]:
    """Run ``func`` with numpy floating-point warnings off: overflow and invalid values
    are caught as non-finite states (with the step and the time), not as warnings."""

    @functools.wraps(func)
    def wrapper(*args: _Params.args, **kwargs: _Params.kwargs) -> _R:
        with np.errstate(all='ignore'):
            return func(*args, **kwargs)

    return wrapper


class Recorder:
    """Growable buffers of accepted steps: their end times, end states, lengths and dense-output
    polynomials, and the breaks landed on."""

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


def landing_tol(b: float, yj: float) -> float:
    """The landing tolerance on break ``b`` at 8 eps of the larger of ``|b|``, ``|y_j|`` (units of ``y_j``)."""
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


class Stepper:
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
        self._rec = Recorder(t_start, y)

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

    @quiet
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

    def _record(
        self, y: FloatArray, h: float, t_new: float, y_new: FloatArray, coef: FloatArray
    ) -> tuple[float, FloatArray] | None:
        """Record the accepted step from ``y`` to ``(t_new, y_new)`` (length ``h``, dense output ``coef``);
        where it meets the terminal condition it is cut there and its end ``(t, y)`` returned, else None."""
        rec = self._rec
        rec.add(h, t_new, y_new, coef)
        if rec.stop_at(self._terminal, coef, y, y_new):
            return rec.t[rec.n], rec.y[rec.n].copy()
        return None

    def _advance(self, until: float) -> None:
        raise NotImplementedError
