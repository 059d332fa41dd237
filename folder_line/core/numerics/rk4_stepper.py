"""Classic RK4 with a fixed step and cubic Hermite dense output, as a resumable stepper.

The behaviour (grid, breaks, terminal condition, failures) is described in
:mod:`folder_line.core.numerics.integrators`, which also has the one-call
:func:`~folder_line.core.numerics.integrators.rk4`.
"""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np
import numpy.typing as npt

from folder_line.core.numerics.arrays import FloatArray
from folder_line.core.numerics.dense import poly_solve
from folder_line.core.numerics.stepper import (
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

__all__ = ['RK4_SNAP', 'RK4Stepper']

#: the last fixed step of rk4 is stretched to t_bound instead of leaving a sliver below this fraction of h
RK4_SNAP = 1e-6


def _hermite_coef(y0: FloatArray, y1: FloatArray, f0: FloatArray, f1: FloatArray, h: float) -> FloatArray:
    """Coefficients (5, m) in the step fraction of the cubic Hermite interpolant of one step of length ``h``."""
    d = y1 - y0
    hf0, hf1 = h * f0, h * f1
    return np.stack([y0, hf0, 3.0 * d - 2.0 * hf0 - hf1, hf0 + hf1 - 2.0 * d, np.zeros_like(y0)])


class RK4Stepper(Stepper):
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
        Switches of the right-hand side (:mod:`folder_line.core.numerics.integrators`).
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

    @quiet
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

    def _too_many(self, steps: int, t: float, span: tuple[float, float]) -> IntegrationError:
        """The error for more than ``max_steps`` steps in one call (``steps`` taken so far, at ``t``)."""
        h, max_steps = self._h, self._max_steps
        return IntegrationError(
            'rk4',
            steps,
            t,
            h,
            f'more than max_steps={max_steps} steps (the span {span!r} needs ~{(span[1] - span[0]) / h:.3g} '
            'steps of h)',
        )

    def _land(
        self,
        t: float,
        t_next: float,
        y: FloatArray,
        f: FloatArray,
        y_new: FloatArray,
        f_new: FloatArray,
        hh: float,
        piece: Piece,
        steps: int,
    ) -> tuple[float, float, FloatArray, FloatArray, float | None, int]:
        """Cut the step from ``(t, y)`` (derivative ``f``) to ``(t_next, y_new)`` (``f_new``) of length ``hh``
        where the break component reaches the piece's upper break, by Newton iterations on the step length
        (without breaks: the step as it is).

        Returns
        -------
        tuple
            ``(hh, t_next, y_new, f_new, miss, nfev)``: the step (cut, or as it was), ``miss``
            ``|y_j - b|`` at the landing (None if the step stays below the break) and the
            right-hand-side evaluations used.
        """
        breaks = self._breaks
        if breaks is None:
            return hh, t_next, y_new, f_new, None, 0
        j = breaks.component
        b = piece[1]
        tol = landing_tol(b, float(y[j]))
        if y_new[j] > b + tol:
            nfev = 0
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
            return h1, t + h1, y1, f1, abs(float(y1[j] - b)), nfev
        if y_new[j] >= b - tol:
            return hh, t_next, y_new, f_new, abs(float(y_new[j] - b)), 0
        return hh, t_next, y_new, f_new, None, 0

    def _step_end(self, t_piece: float, k_piece: int) -> float:
        """End of the next step on the grid ``t_piece + k h`` of the piece, clipped (or stretched) to ``t_bound``."""
        h, t1 = self._h, self._t_bound
        t_next = t_piece + (k_piece + 1) * h
        if t_next > t1 or t1 - t_next <= RK4_SNAP * h:
            t_next = t1
        return t_next

    def _advance(self, until: float) -> None:
        h, t1, max_steps = self._h, self._t_bound, self._max_steps
        t, y, f, piece = self._t, self._y, self._f, self._piece
        t_piece, k_piece = self._t_piece, self._k_piece
        nfev, steps, landing_err, status = self._nfev, self._steps, self._landing, self._status
        span = (float(t), float(min(until, t1)))
        if self._cannot_end_early() and (span[1] - span[0]) / (h * (1.0 + RK4_SNAP)) > max_steps + 1:
            # this call cannot end early, so it is bound to exceed max_steps: say so before the first step
            raise self._too_many(steps, t, span)
        n = 0
        try:
            while t < until:
                if n >= max_steps:
                    raise self._too_many(steps, t, span)
                t_next = self._step_end(t_piece, k_piece)
                hh = t_next - t
                y_new, ne = self._step(t, y, f, hh, piece, steps)
                nfev += ne
                f_new = self._rhs(t_next, y_new, piece)
                nfev += 1
                hh, t_next, y_new, f_new, miss, ne = self._land(t, t_next, y, f, y_new, f_new, hh, piece, steps)
                nfev += ne
                if miss is not None:
                    landing_err = max(landing_err, miss)
                coef = _hermite_coef(y, y_new, f, f_new, hh)
                steps += 1
                n += 1
                cut = self._record(y, hh, t_next, y_new, coef)
                if cut is not None:
                    status = 'terminal'
                    t, y = cut
                    break
                t, y = t_next, y_new
                if miss is None:
                    k_piece += 1
                    f = f_new
                else:  # landed on a break: the grid restarts there
                    piece, f, stop = self._switch_piece(t, y, piece[1])
                    nfev += 1
                    t_piece, k_piece = t, 0
                    if stop:
                        status = 'stopped'
                        break
                if t >= t1:
                    status = 'finished'
                    break
        finally:
            self._t, self._y, self._f, self._piece = t, y, f, piece
            self._t_piece, self._k_piece = t_piece, k_piece
            self._nfev, self._steps, self._landing, self._status = nfev, steps, landing_err, status
