"""Adaptive Dormand-Prince 5(4) with scipy RK45's step control and 4th-order dense output, as a resumable stepper.

The tableau, error norm and step-size control are scipy's ``RK45``; the behaviour (breaks,
terminal condition, failures) is described in :mod:`folder_line.core.numerics.integrators`,
which also has the one-call :func:`~folder_line.core.numerics.integrators.dopri5`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import ClassVar

import numpy as np
import numpy.typing as npt

from folder_line.core.numerics.arrays import FloatArray
from folder_line.core.numerics.constants import EPS
from folder_line.core.numerics.dense import poly_solve
from folder_line.core.numerics.stepper import (
    LANDING_FRACTION,
    MAX_LANDING,
    MAX_STEPS,
    Breaks,
    Fun,
    Piece,
    Stepper,
    Terminal,
    landing_tol,
    quiet,
)
from folder_line.errors import IntegrationError

__all__ = ['MAX_FACTOR', 'MIN_FACTOR', 'SAFETY', 'Dopri5Stepper']

#: scipy RK45 step control
SAFETY = 0.9
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0

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


def _rms(x: FloatArray) -> float:
    """Root mean square of ``x``."""
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
    """Coefficients (5, m) in the step fraction of the dense output of a step of length ``h`` from ``y``."""
    Q = np.dot(K.T, _P)  # (m, 4)
    return np.vstack([y[None, :], h * Q.T])


def _shrink(err: float) -> float:
    """Step factor after a failed error test (error norm ``err``; ``inf`` for a non-finite trial)."""
    return max(MIN_FACTOR, SAFETY * err**_ERROR_EXPONENT) if math.isfinite(err) else MIN_FACTOR


def _growth(err: float, step_rejected: bool) -> float:
    """Step factor after an accepted step of error norm ``err`` (not above 1 right after a rejection)."""
    factor = MAX_FACTOR if err == 0.0 else min(MAX_FACTOR, SAFETY * err**_ERROR_EXPONENT)
    if step_rejected:
        factor = min(1.0, factor)
    return factor


class Dopri5Stepper(Stepper):
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

    @quiet
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

    def _check_span(self, span: tuple[float, float]) -> None:
        """Refuse before the first step a ``span`` that needs more than ``max_steps`` steps of ``max_step``
        when nothing can end the call early."""
        max_step, max_steps = self._max_step, self._max_steps
        if self._cannot_end_early() and (span[1] - span[0]) / max_step > max_steps:
            # every step is at most max_step and this call cannot end early: bound to exceed max_steps
            raise IntegrationError(
                'dopri5',
                self._steps,
                self._t,
                max_step,
                f'more than max_steps={max_steps} step attempts '
                f'(the span {span!r} needs at least {(span[1] - span[0]) / max_step:.3g} steps '
                f'of max_step)',
            )

    def _first_attempt_size(self, t: float, h_abs: float, step_rejected: bool) -> tuple[float, float]:
        """``(h_abs, min_step)``: the proposed step size from ``t``, on a step's first attempt clipped to
        ``[min_step, max_step]``, and the smallest step ``10 ulp(t)``."""
        max_step = self._max_step
        min_step = 10.0 * abs(np.nextafter(t, math.inf) - t)
        if not step_rejected:  # the first attempt of a step
            if h_abs > max_step:
                h_abs = max_step
            elif h_abs < min_step:
                h_abs = min_step
        return h_abs, min_step

    def _check_attempt(self, t: float, h_abs: float, min_step: float, steps: int, rejected: int, attempts: int) -> None:
        """Raise once the step size ``h_abs`` is below ``min_step`` or the attempts of this call exceed
        ``max_steps``."""
        max_steps = self._max_steps
        if h_abs < min_step:
            raise IntegrationError(
                'dopri5',
                steps,
                t,
                h_abs,
                f'step size fell below the resolvable {min_step!r} after {rejected} '
                'rejections (non-finite right-hand side or extreme stiffness)',
            )
        if attempts > max_steps:
            raise IntegrationError('dopri5', steps, t, h_abs, f'more than max_steps={max_steps} step attempts')

    def _attempt_end(self, t: float, h_abs: float) -> tuple[float, float]:
        """``(h, t_new)``: the trial step of size ``h_abs`` from ``t``, cut at ``t_bound``."""
        t_new = t + h_abs
        if t_new > self._t_bound:
            t_new = self._t_bound
        return t_new - t, t_new

    def _land(
        self, t: float, t_new: float, y: FloatArray, f: FloatArray, y_new: FloatArray, h: float, piece: Piece
    ) -> tuple[float, float, FloatArray, float | None, float | None, int]:
        """Cut the accepted step from ``(t, y)`` (derivative ``f``) to ``(t_new, y_new)`` of length ``h``
        where the break component reaches the piece's upper break: the step redone to land there,
        refined by Newton iterations on its length (the stages are left in ``self._K``); without breaks
        the step as it is.

        Returns
        -------
        tuple
            ``(h, t_new, y_new, miss, retry, nfev)``: the step (cut, or as it was), ``miss``
            ``|y_j - b|`` at the landing (None if the step stays below the break), ``retry`` the
            step size to try again from ``t`` if a redone step failed its error test (else
            None) and the right-hand-side evaluations used.
        """
        rtol, atol, atol_j, K, F = self._rtol, self._atol, self._atol_j, self._K, self._rhs
        breaks = self._breaks
        if breaks is None:
            return h, t_new, y_new, None, None, 0
        j = breaks.component
        b = piece[1]
        tol = max(landing_tol(b, float(y[j])), LANDING_FRACTION * (atol_j + rtol * abs(b)))
        if y_new[j] > b + tol:
            nfev = 0
            c = _dopri_coef(y, K, h)[:, j].reshape(5, 1)
            x0 = np.array([(b - y[j]) / (y_new[j] - y[j])])
            x = poly_solve(c, np.array([b]), np.array([1.0]), 1.0, x0)[0]
            h1 = x * h
            for _ in range(MAX_LANDING):
                y1, err1 = _dopri_step(F, t, y, f, h1, piece, K, rtol, atol)
                nfev += 6
                if not err1 < 1.0:
                    # the shorter step failed its error test: shrink and try again from t (as a new step)
                    return h, t_new, y_new, None, h1 * _shrink(err1), nfev
                e = float(y1[j] - b)
                if abs(e) <= tol or not K[-1][j] > 0.0:
                    break
                h1 = min(max(h1 - e / float(K[-1][j]), 0.0), h)
            return h1, t + h1, y1, abs(float(y1[j] - b)), None, nfev
        if y_new[j] >= b - tol:
            return h, t_new, y_new, abs(float(y_new[j] - b)), None, 0
        return h, t_new, y_new, None, None, 0

    def _advance(self, until: float) -> None:
        rtol, atol, K, F = self._rtol, self._atol, self._K, self._rhs
        t, y, f, piece, h_abs, step_rejected = self._t, self._y, self._f, self._piece, self._h_abs, self._step_rejected
        nfev, rejected, steps, landing_err, status = (
            self._nfev,
            self._rejected,
            self._steps,
            self._landing,
            self._status,
        )
        self._check_span((float(t), float(min(until, self._t_bound))))
        attempts = 0
        try:
            while t < until:
                h_abs, min_step = self._first_attempt_size(t, h_abs, step_rejected)
                attempts += 1
                self._check_attempt(t, h_abs, min_step, steps, rejected, attempts)
                h, t_new = self._attempt_end(t, h_abs)
                h_abs = abs(h)
                y_new, err = _dopri_step(F, t, y, f, h, piece, K, rtol, atol)
                nfev += 6
                if not err < 1.0:  # rejected: shrink and try again
                    h_abs, step_rejected, rejected = h_abs * _shrink(err), True, rejected + 1
                    continue
                h_next = h_abs * _growth(err, step_rejected)
                h, t_new, y_new, miss, retry, ne = self._land(t, t_new, y, f, y_new, h, piece)
                nfev += ne
                if retry is not None:  # the step cut at the break failed: try again from t as a new step
                    h_abs, step_rejected, rejected = retry, False, rejected + 1
                    continue
                if miss is not None:
                    landing_err = max(landing_err, miss)
                steps += 1
                step_rejected = False
                cut = self._record(y, h, t_new, y_new, _dopri_coef(y, K, h))
                if cut is not None:
                    status = 'terminal'
                    t, y = cut
                    break
                t, y = t_new, y_new
                h_abs = h_next
                if miss is None:
                    f = K[-1].copy()
                else:
                    piece, f, stop = self._switch_piece(t, y, piece[1])
                    nfev += 1
                    if stop:
                        status = 'stopped'
                        break
                if t >= self._t_bound:
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
