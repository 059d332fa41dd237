"""Explicit Runge-Kutta steppers (RK4, DOPRI5) with breaks and terminal conditions: resumable, with dense output.

Methods
-------
:class:`~folder_line.core.numerics.rk4_stepper.RK4Stepper`, :func:`rk4`
    The classic four-stage Runge-Kutta method with a fixed step ``h``. Dense output:
    the cubic Hermite interpolant of each step's end states and derivatives
    (C1 across steps; exact for solutions that are cubics; local error O(h^4)).
:class:`~folder_line.core.numerics.dopri5_stepper.Dopri5Stepper`, :func:`dopri5`
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
The steppers are defined in :mod:`~folder_line.core.numerics.rk4_stepper` and
:mod:`~folder_line.core.numerics.dopri5_stepper`, on the common parts of
:mod:`~folder_line.core.numerics.stepper`; this module has the one-call functions. A stepper
(:class:`~folder_line.core.numerics.rk4_stepper.RK4Stepper`,
:class:`~folder_line.core.numerics.dopri5_stepper.Dopri5Stepper`) holds the whole state of the
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
:class:`folder_line.errors.IntegrationError` naming the step, the
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

import math

import numpy.typing as npt

from folder_line.core.numerics.dense import DenseSolution
from folder_line.core.numerics.dopri5_stepper import Dopri5Stepper
from folder_line.core.numerics.rk4_stepper import RK4Stepper
from folder_line.core.numerics.stepper import MAX_STEPS, Breaks, Fun, Terminal

__all__ = [
    'dopri5',
    'rk4',
]


def _span(method: str, t_span: tuple[float, float]) -> tuple[float, float]:
    """``(t0, t_end)`` of a one-call integration: two finite numbers, ``t_end > t0``."""
    try:
        t0, t1 = (float(v) for v in t_span)
    except (TypeError, ValueError):
        raise ValueError(f'{method}: t_span must be two numbers, got {t_span!r}') from None
    if not (math.isfinite(t0) and math.isfinite(t1)) or not t1 > t0:
        raise ValueError(f'{method}: t_span must be finite with t_end > t0, got {t_span!r}')
    return t0, t1


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
        Raise :class:`~folder_line.errors.IntegrationError` when a run needs more steps than this.

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
        Raise :class:`~folder_line.errors.IntegrationError` after this many attempted steps.

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
