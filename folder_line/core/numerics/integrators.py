"""Explicit Runge-Kutta steppers (RK4, DOPRI5) with breaks and terminal conditions; they return a dense output.

Methods
-------
:func:`rk4`
    The classic four-stage Runge-Kutta method with a fixed step ``h``. Dense output:
    the cubic Hermite interpolant of each step's end states and derivatives
    (C1 across steps; exact for solutions that are cubics; local error O(h^4)).
:func:`dopri5`
    The Dormand-Prince 5(4) pair with the tableau, error norm and step-size control of
    scipy's ``RK45`` (``scipy/integrate/_ivp/rk.py``, ``common.py``): local
    extrapolation (steps taken with the 5th-order solution), error estimated for the
    4th-order one, RMS norm of ``err / (atol + max(|y|, |y_new|) rtol)``, the first
    step from Hairer-Norsett-Wanner II.4 (``select_initial_step``), safety 0.9, step
    factor limited to [0.2, 10] (not above 1 right after a rejection), ``max_step``,
    smallest step ``10 ulp(t)``. Dense output: the 4th-order continuous extension
    of Shampine (1986), the same as scipy's. Without breaks or a terminal condition the
    step sequence is scipy's to rounding (a test checks it).

Both return a :class:`~folder_line.core.numerics.dense.DenseSolution` (step endpoints,
states, the per-step polynomial of the dense output, the counters ``nfev``, ``steps`` and
``rejected``; its evaluation and vectorised inverse are described in
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
The step size proposed before the switch is kept (scipy's controller is not reset).

Terminal condition (``terminal``)
---------------------------------
``Terminal(j, value)`` ends the integration where ``y_j`` first crosses ``value``
(either direction, not counting a start on it): the root is found on the dense output
of the step (safeguarded Newton), the last step is truncated there and its end state
gets ``y_j = value`` exactly.

Failure is loud
---------------
A non-finite state or derivative never passes silently. :func:`rk4` raises
:class:`folder_line.errors.IntegrationError` (re-exported here) naming the step, the
time and the step size at the first non-finite stage (an unstable step on a stiff
problem overflows after a few steps). :func:`dopri5` treats a non-finite trial as a
rejection (the step shrinks, like scipy, which sees a NaN error norm); if the step
falls below ``10 ulp(t)`` it raises. Both raise if ``max_steps`` would be exceeded (a
stalled or absurdly stiff run) -- before the first step when the span alone needs more
steps of ``h`` (``max_step``) and nothing can end the run early (no ``terminal``, no
``on_break``). numpy's floating-point warnings are switched off while
a method runs (the right-hand side included): overflow and invalid operations show up
as non-finite values, which are checked after every step and reported with the step
and the time.

The step loop is a Python loop over steps (an ODE is sequential); each step does a
fixed handful of numpy operations on the state vector.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from folder_line.core.numerics.arrays import FloatArray
from folder_line.core.numerics.constants import EPS
from folder_line.core.numerics.dense import DenseSolution, horner, poly_solve
from folder_line.errors import IntegrationError  # re-exported: defined with the other errors

__all__ = [
    'Breaks',
    'IntegrationError',
    'Terminal',
    'dopri5',
    'rk4',
]

Piece = tuple[float, float]
Fun = Callable[..., npt.ArrayLike]

#: scipy RK45 step control
SAFETY = 0.9
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0
#: redo steps at most this many times to land on a break
MAX_LANDING = 8
#: dopri5 lands on a break to this fraction of its error allowance there (or to 8 eps)
LANDING_FRACTION = 1e-3
#: the last fixed step of :func:`rk4` is stretched instead of leaving a sliver below this fraction of h
RK4_SNAP = 1e-6

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


# --------------------------------------------------------------------------- common setup


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


def _setup(
    method: str, fun: Fun, t_span: tuple[float, float], y0: npt.ArrayLike, breaks: Breaks | None
) -> tuple[float, float, FloatArray, Callable[[float, FloatArray, Piece], FloatArray], Piece]:
    try:
        t0, t1 = (float(v) for v in t_span)
    except (TypeError, ValueError):
        raise ValueError(f'{method}: t_span must be two numbers, got {t_span!r}') from None
    if not (math.isfinite(t0) and math.isfinite(t1)) or not t1 > t0:
        raise ValueError(f'{method}: t_span must be finite with t_end > t0, got {t_span!r}')
    y = np.array(y0, dtype=float).ravel()
    if y.size == 0 or not np.all(np.isfinite(y)):
        raise ValueError(f'{method}: y0 must be a non-empty finite vector, got {y0!r}')
    if breaks is None:

        def F(t: float, yy: FloatArray, piece: Piece) -> FloatArray:
            return np.asarray(fun(t, yy), dtype=float)

        return t0, t1, y, F, (-math.inf, math.inf)
    j = breaks.component
    if not 0 <= j < y.size:
        raise ValueError(f'{method}: breaks.component={j!r} is not a component of y (size {y.size})')
    lo = float(y[j])
    hi = float(breaks.next_after(lo))
    if not hi > lo:
        raise ValueError(f'{method}: breaks.next_after({lo!r}) = {hi!r} is not above its argument')

    def G(t: float, yy: FloatArray, piece: Piece) -> FloatArray:
        return np.asarray(fun(t, yy, piece), dtype=float)

    return t0, t1, y, G, (lo, hi)


def _switch_piece(
    method: str,
    rec: _Recorder,
    breaks: Breaks,
    F: Callable[[float, FloatArray, Piece], FloatArray],
    t: float,
    y: FloatArray,
    b: float,
) -> tuple[Piece, FloatArray, bool]:
    """Record the landing on break ``b`` at ``(t, y)`` and move on to the next piece: returns the
    piece, the derivative there (one evaluation of ``F``) and whether ``on_break`` ends the run."""
    rec.break_t.append(t)
    rec.break_value.append(b)
    nb = float(breaks.next_after(b))
    if not nb > b:
        raise ValueError(f'{method}: breaks.next_after({b!r}) = {nb!r} is not above its argument')
    piece = (b, nb)
    f = F(t, y, piece)
    return piece, f, breaks.on_break is not None and bool(breaks.on_break(t, y.copy(), b))


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


# --------------------------------------------------------------------------- RK4


def _hermite_coef(y0: FloatArray, y1: FloatArray, f0: FloatArray, f1: FloatArray, h: float) -> FloatArray:
    d = y1 - y0
    hf0, hf1 = h * f0, h * f1
    return np.stack([y0, hf0, 3.0 * d - 2.0 * hf0 - hf1, hf0 + hf1 - 2.0 * d, np.zeros_like(y0)])


def _quiet(func: Callable[..., DenseSolution]) -> Callable[..., DenseSolution]:
    """Run ``func`` with numpy floating-point warnings off: overflow and invalid values
    are caught as non-finite states (with the step and the time), not as warnings."""

    @functools.wraps(func)
    def wrapper(*args: object, **kwargs: object) -> DenseSolution:
        with np.errstate(all='ignore'):
            return func(*args, **kwargs)

    return wrapper


@_quiet
def rk4(
    fun: Fun,
    t_span: tuple[float, float],
    y0: npt.ArrayLike,
    h: float,
    *,
    breaks: Breaks | None = None,
    terminal: Terminal | None = None,
    max_steps: int = 10_000_000,
) -> DenseSolution:
    """Classic RK4 with a fixed step and cubic Hermite dense output.

    Parameters
    ----------
    fun : callable
        ``fun(t, y) -> dy/dt`` (``fun(t, y, piece)`` with ``breaks``), ``y`` of shape (m,).
    t_span : (float, float)
        ``(t0, t_end)``, ``t_end > t0``.
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

    Raises
    ------
    IntegrationError
        A stage or the new state is not finite (names the step, its start time and h).
    ValueError
        Bad arguments.
    """
    t0, t1, y, F, piece = _setup('rk4', fun, t_span, y0, breaks)
    h = float(h)
    if not (math.isfinite(h) and h > 0.0):
        raise ValueError(f'rk4: h must be finite and > 0, got {h!r}')
    rec = _Recorder(t0, y)
    nfev = 0
    f = F(t0, y, piece)
    nfev += 1
    if not np.all(np.isfinite(f)):
        raise IntegrationError('rk4', 0, t0, h, f'the right-hand side is not finite at the initial state: {f!r}')
    if (
        terminal is None
        and (breaks is None or breaks.on_break is None)
        and (t1 - t0) / (h * (1.0 + RK4_SNAP)) > max_steps + 1
    ):
        # the run cannot end early, so it is bound to exceed max_steps: say so before the first step
        raise IntegrationError(
            'rk4',
            0,
            t0,
            h,
            f'more than max_steps={max_steps} steps (the span {t_span!r} needs ~{(t1 - t0) / h:.3g} steps of h)',
        )
    status = 'finished'
    landing_err = 0.0
    t_piece, k_piece = t0, 0
    t = t0
    n = 0

    def step(t: float, y: FloatArray, f: FloatArray, hh: float, piece: Piece) -> tuple[FloatArray, int]:
        half = 0.5 * hh
        k2 = F(t + half, y + half * f, piece)
        k3 = F(t + half, y + half * k2, piece)
        k4 = F(t + hh, y + hh * k3, piece)
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

    while t < t1:
        if n >= max_steps:
            raise IntegrationError(
                'rk4',
                n,
                t,
                h,
                f'more than max_steps={max_steps} steps (the span {t_span!r} needs ~{(t1 - t0) / h:.3g} steps of h)',
            )
        t_next = t_piece + (k_piece + 1) * h
        if t_next > t1 or t1 - t_next <= RK4_SNAP * h:
            t_next = t1
        hh = t_next - t
        y_new, ne = step(t, y, f, hh, piece)
        nfev += ne
        f_new = F(t_next, y_new, piece)
        nfev += 1
        crossed = False
        if breaks is not None:
            j = breaks.component
            b = piece[1]
            tol = _landing_tol(b, float(y[j]))
            if y_new[j] > b + tol:
                c = _hermite_coef(y, y_new, f, f_new, hh)[:, j].reshape(5, 1)
                x = poly_solve(c, np.array([b]), np.array([1.0]), 1.0, np.array([(b - y[j]) / (y_new[j] - y[j])]))[0]
                h1 = x * hh
                for _ in range(MAX_LANDING):
                    y1, ne = step(t, y, f, h1, piece)
                    f1 = F(t + h1, y1, piece)
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
        n += 1
        if rec.stop_at(terminal, coef, y, y_new):
            status = 'terminal'
            break
        t, y = t_next, y_new
        if crossed:
            assert breaks is not None
            piece, f, stop = _switch_piece('rk4', rec, breaks, F, t, y, piece[1])
            nfev += 1
            t_piece, k_piece = t, 0
            if stop:
                status = 'stopped'
                break
        else:
            k_piece += 1
            f = f_new
    return rec.build('rk4', nfev, 0, status, landing_err)


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


@_quiet
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
    max_steps: int = 10_000_000,
) -> DenseSolution:
    """Adaptive Dormand-Prince 5(4) with scipy RK45's step control and 4th-order dense output.

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

    Raises
    ------
    IntegrationError
        The step fell below ``10 ulp(t)`` (non-finite right-hand side or extreme
        stiffness) or ``max_steps`` attempts were used.
    ValueError
        Bad arguments.
    """
    t0, t_bound, y, F, piece = _setup('dopri5', fun, t_span, y0, breaks)
    rtol = float(rtol)
    if not (math.isfinite(rtol) and rtol >= 100 * EPS):
        raise ValueError(f'dopri5: rtol must be >= 100 eps = {100 * EPS!r}, got {rtol!r}')
    atol_a = np.asarray(atol, dtype=float)
    if atol_a.ndim > 0 and atol_a.shape != y.shape:
        raise ValueError(f'dopri5: atol must be a number or have shape {y.shape}, got shape {atol_a.shape}')
    if not (np.all(np.isfinite(atol_a)) and np.all(atol_a > 0.0)):
        raise ValueError(f'dopri5: atol must be finite and > 0, got {atol!r}')
    atol_v: FloatArray | float = float(atol_a) if atol_a.ndim == 0 else atol_a
    max_step = float(max_step)
    if not max_step > 0.0:
        raise ValueError(f'dopri5: max_step must be > 0, got {max_step!r}')
    rec = _Recorder(t0, y)
    f = F(t0, y, piece)
    nfev = 1
    if not np.all(np.isfinite(f)):
        raise IntegrationError('dopri5', 0, t0, 0.0, f'the right-hand side is not finite at the initial state: {f!r}')
    if first_step is None:
        h_abs = _select_initial_step(F, t0, y, t_bound, max_step, f, rtol, atol_v, piece)
        nfev += 1
    else:
        h_abs = float(first_step)
        if not (math.isfinite(h_abs) and h_abs > 0.0):
            raise ValueError(f'dopri5: first_step must be finite and > 0, got {first_step!r}')
        h_abs = min(h_abs, t_bound - t0)
    if terminal is None and (breaks is None or breaks.on_break is None) and (t_bound - t0) / max_step > max_steps:
        # every step is at most max_step and the run cannot end early: bound to exceed max_steps
        raise IntegrationError(
            'dopri5',
            0,
            t0,
            max_step,
            f'more than max_steps={max_steps} step attempts '
            f'(the span {t_span!r} needs at least {(t_bound - t0) / max_step:.3g} steps '
            f'of max_step)',
        )
    K = np.empty((7, y.size))
    t = t0
    rejected = 0
    attempts = 0
    status = 'finished'
    landing_err = 0.0
    j = breaks.component if breaks is not None else -1
    atol_j = float(atol_a) if atol_a.ndim == 0 else float(atol_a[j])
    while t < t_bound:
        min_step = 10.0 * abs(np.nextafter(t, math.inf) - t)
        if h_abs > max_step:
            h_abs = max_step
        elif h_abs < min_step:
            h_abs = min_step
        step_rejected = False
        while True:
            if h_abs < min_step:
                raise IntegrationError(
                    'dopri5',
                    rec.n,
                    t,
                    h_abs,
                    f'step size fell below the resolvable {min_step!r} after {rejected} '
                    'rejections (non-finite right-hand side or extreme stiffness)',
                )
            attempts += 1
            if attempts > max_steps:
                raise IntegrationError('dopri5', rec.n, t, h_abs, f'more than max_steps={max_steps} step attempts')
            t_new = t + h_abs
            if t_new > t_bound:
                t_new = t_bound
            h = t_new - t
            h_abs = abs(h)
            y_new, err = _dopri_step(F, t, y, f, h, piece, K, rtol, atol_v)
            nfev += 6
            if err < 1.0:
                factor = MAX_FACTOR if err == 0.0 else min(MAX_FACTOR, SAFETY * err**_ERROR_EXPONENT)
                if step_rejected:
                    factor = min(1.0, factor)
                h_next = h_abs * factor
                break
            h_abs *= max(MIN_FACTOR, SAFETY * err**_ERROR_EXPONENT) if math.isfinite(err) else MIN_FACTOR
            step_rejected = True
            rejected += 1
        crossed = False
        if breaks is not None:
            b = piece[1]
            tol = max(_landing_tol(b, float(y[j])), LANDING_FRACTION * (atol_j + rtol * abs(b)))
            if y_new[j] > b + tol:
                c = _dopri_coef(y, K, h)[:, j].reshape(5, 1)
                x = poly_solve(c, np.array([b]), np.array([1.0]), 1.0, np.array([(b - y[j]) / (y_new[j] - y[j])]))[0]
                h1 = x * h
                redo_ok = True
                for _ in range(MAX_LANDING):
                    y1, err1 = _dopri_step(F, t, y, f, h1, piece, K, rtol, atol_v)
                    nfev += 6
                    if not err1 < 1.0:
                        redo_ok = False
                        break
                    e = float(y1[j] - b)
                    if abs(e) <= tol or not K[-1][j] > 0.0:
                        break
                    h1 = min(max(h1 - e / float(K[-1][j]), 0.0), h)
                if not redo_ok:
                    # the shorter step failed its error test: shrink and try again from t
                    h_abs = h1 * (
                        max(MIN_FACTOR, SAFETY * err1**_ERROR_EXPONENT) if math.isfinite(err1) else MIN_FACTOR
                    )
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
        if rec.stop_at(terminal, coef, y, y_new):
            status = 'terminal'
            break
        t, y = t_new, y_new
        h_abs = h_next
        if crossed:
            assert breaks is not None
            piece, f, stop = _switch_piece('dopri5', rec, breaks, F, t, y, piece[1])
            nfev += 1
            if stop:
                status = 'stopped'
                break
        else:
            f = K[-1].copy()
    return rec.build('dopri5', nfev, rejected, status, landing_err)
