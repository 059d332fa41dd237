"""Bracketing searches in pure Python: Brent's method, sign-change scanning, golden section.

The core may not import scipy, so :func:`brentq` is a line-by-line port of
scipy's ``brentq`` (``scipy/optimize/Zeros/brentq.c``, Brent 1973 with the
inverse-quadratic extrapolation of the C version): same tolerances, same
defaults, same iterates, so it returns the same root as
``scipy.optimize.brentq`` to the last bit for the same ``f, a, b, xtol, rtol``.

Termination: the bracket half-width ``|x_blk - x_cur| / 2`` drops below
``delta = (xtol + rtol * |x_cur|) / 2``, or ``f(x_cur) == 0``. The returned
root is therefore within ``xtol + rtol * |x|`` of a sign change of ``f``.

:func:`find_sign_changes` samples ``f`` on a grid and refines each sign change
with Brent's method. It is the event detector of the core; its rules for zeros
that fall exactly on samples and for grazing touches are documented there.

:func:`golden_section` narrows a bracket around a minimum (no derivatives).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from folder_line.errors import (
    NoConvergenceError,
    NonFiniteValueError,
    NotBracketedError,
    ParameterError,
)

__all__ = [
    'MAXITER',
    'RTOL',
    'XTOL',
    'GoldenSection',
    'RootResult',
    'SignChanges',
    'brent',
    'brentq',
    'find_sign_changes',
    'golden_section',
]

#: default absolute tolerance on the root (same as scipy.optimize.brentq)
XTOL: float = 2e-12
#: default and smallest relative tolerance on the root, 4 machine epsilons (as scipy)
RTOL: float = 4.0 * float(np.finfo(float).eps)
#: default iteration limit (as scipy)
MAXITER: int = 100


@dataclass(frozen=True)
class RootResult:
    """A converged root of Brent's method.

    Attributes
    ----------
    root : float
        The root, in the units of ``x``.
    f_root : float
        ``f(root)``, in the units of ``f`` (0 where the root is exact).
    iterations : int
        Brent iterations (0 when a bracket end was already a root).
    function_calls : int
        Evaluations of ``f``, the two bracket ends included.
    bracket : tuple of float
        Final bracket ``(lo, hi)`` with ``lo <= root <= hi`` and a sign change of
        ``f`` inside, in the units of ``x``.
    """

    root: float
    f_root: float
    iterations: int
    function_calls: int
    bracket: tuple[float, float]


@dataclass(frozen=True)
class SignChanges:
    """Sign changes of a sampled function, refined (see :func:`find_sign_changes`).

    Attributes
    ----------
    x : ndarray of float, shape (k,)
        The crossings, ascending, in the units of the grid. Read-only.
    direction : ndarray of int, shape (k,)
        ``+1`` where ``f`` goes from negative to positive (rising), ``-1`` where it
        falls. Read-only.
    on_sample : ndarray of bool, shape (k,)
        True where the crossing is a sample at which ``f`` was exactly zero
        (no refinement needed). Read-only.
    function_calls : int
        Evaluations of ``f`` (the grid samples included, unless given as ``values``).
    """

    x: NDArray[np.float64]
    direction: NDArray[np.int8]
    on_sample: NDArray[np.bool_]
    function_calls: int

    def __len__(self) -> int:
        return int(self.x.size)


def _check_tolerances(xtol: float, rtol: float, maxiter: int) -> tuple[float, float, int]:
    xt = float(xtol)
    rt = float(rtol)
    if not (math.isfinite(xt) and xt > 0.0):
        raise ParameterError('xtol', xtol, 'must be finite and > 0')
    if not (math.isfinite(rt) and rt >= RTOL):
        raise ParameterError('rtol', rtol, f'must be finite and >= 4 machine epsilons ({RTOL!r})')
    if isinstance(maxiter, bool) or not isinstance(maxiter, (int, np.integer)) or maxiter < 1:
        raise ParameterError('maxiter', maxiter, 'must be an integer >= 1')
    return xt, rt, int(maxiter)


def _value(f: Callable[[float], float], x: float) -> float:
    fx = float(f(x))
    if not math.isfinite(fx):
        raise NonFiniteValueError(x, fx)
    return fx


def _brent_step(
    xpre: float,
    xcur: float,
    xblk: float,
    fpre: float,
    fcur: float,
    fblk: float,
    spre: float,
    scur: float,
    sbis: float,
    delta: float,
) -> tuple[float, float]:
    """The new ``(spre, scur)`` of brentq.c: an interpolation step (secant, or inverse quadratic
    extrapolation) if it is short enough, else bisection (``sbis``)."""
    if abs(spre) > delta and abs(fcur) < abs(fpre):
        if xpre == xblk:  # secant (linear interpolation)
            stry = -fcur * (xcur - xpre) / (fcur - fpre)
        else:  # inverse quadratic extrapolation
            dpre = (fpre - fcur) / (xpre - xcur)
            dblk = (fblk - fcur) / (xblk - xcur)
            stry = -fcur * (fblk * dblk - fpre * dpre) / (dblk * dpre * (fblk - fpre))
        if 2.0 * abs(stry) < min(abs(spre), 3.0 * abs(sbis) - delta):
            return scur, stry  # good short step
    return sbis, sbis  # bisect


def _brent_core(
    f: Callable[[float], float],
    xa: float,
    xb: float,
    fa: float,
    fb: float,
    xtol: float,
    rtol: float,
    maxiter: int,
    calls: int,
) -> RootResult:
    """scipy's brentq.c iteration, from ends whose values are already known."""
    xpre, xcur = xa, xb
    fpre, fcur = fa, fb
    xblk = fblk = spre = scur = 0.0
    if fpre == 0.0:
        return RootResult(xpre, fpre, 0, calls, (xpre, xpre))
    if fcur == 0.0:
        return RootResult(xcur, fcur, 0, calls, (xcur, xcur))
    if math.copysign(1.0, fpre) == math.copysign(1.0, fcur):
        raise NotBracketedError(xa, xb, fa, fb)
    for i in range(1, maxiter + 1):
        if fpre != 0.0 and fcur != 0.0 and math.copysign(1.0, fpre) != math.copysign(1.0, fcur):
            xblk, fblk = xpre, fpre
            spre = scur = xcur - xpre
        if abs(fblk) < abs(fcur):
            xpre, xcur, xblk = xcur, xblk, xcur
            fpre, fcur, fblk = fcur, fblk, fcur
        delta = (xtol + rtol * abs(xcur)) / 2.0
        sbis = (xblk - xcur) / 2.0
        if fcur == 0.0 or abs(sbis) < delta:
            lo, hi = (xcur, xblk) if xcur <= xblk else (xblk, xcur)
            if fcur == 0.0:
                lo = hi = xcur
            return RootResult(xcur, fcur, i, calls, (lo, hi))
        spre, scur = _brent_step(xpre, xcur, xblk, fpre, fcur, fblk, spre, scur, sbis, delta)
        xpre, fpre = xcur, fcur
        if abs(scur) > delta:
            xcur += scur
        else:
            xcur += delta if sbis > 0.0 else -delta
        fcur = _value(f, xcur)
        calls += 1
    raise NoConvergenceError(xcur, maxiter, abs(xblk - xcur))


def brent(
    f: Callable[[float], float], a: float, b: float, *, xtol: float = XTOL, rtol: float = RTOL, maxiter: int = MAXITER
) -> RootResult:
    """Root of ``f`` in the bracket ``[a, b]`` by Brent's method, with statistics.

    Parameters
    ----------
    f : callable ``f(x) -> float``
        Continuous on ``[a, b]``; any units.
    a, b : float
        Bracket ends (either order), units of ``x``. ``f(a)`` and ``f(b)`` must
        have opposite signs, or one of them be exactly zero.
    xtol : float, optional
        Absolute tolerance on the root, units of ``x``; > 0. Default 2e-12.
    rtol : float, optional
        Relative tolerance on the root, dimensionless; >= 4 eps (the default).
    maxiter : int, optional
        Iteration limit, >= 1. Default 100.

    Returns
    -------
    RootResult
        ``root`` is within ``xtol + rtol * |root|`` of a sign change of ``f``.
        If ``f(a) == 0`` (resp. ``f(b) == 0``) the root is exactly ``a`` (``b``),
        ``a`` checked first, with no iteration.

    Raises
    ------
    NotBracketedError
        ``f(a)`` and ``f(b)`` are both non-zero with the same sign (a ValueError).
    NonFiniteValueError
        A bracket end is not finite, or ``f`` returned NaN/inf (a ValueError).
    NoConvergenceError
        ``maxiter`` iterations were not enough (a RuntimeError).
    ParameterError
        Bad ``xtol``, ``rtol`` or ``maxiter``.
    """
    xt, rt, mi = _check_tolerances(xtol, rtol, maxiter)
    xa, xb = float(a), float(b)
    for x in (xa, xb):
        if not math.isfinite(x):
            raise NonFiniteValueError(x, math.nan)
    fa = _value(f, xa)
    fb = _value(f, xb)
    return _brent_core(f, xa, xb, fa, fb, xt, rt, mi, 2)


def brentq(
    f: Callable[[float], float], a: float, b: float, *, xtol: float = XTOL, rtol: float = RTOL, maxiter: int = MAXITER
) -> float:
    """Root of ``f`` in ``[a, b]``: :func:`brent` returning only the root (like scipy's ``brentq``).

    Parameters
    ----------
    f : callable ``f(x) -> float``
        Continuous on ``[a, b]``; any units.
    a, b : float
        Bracket ends, units of ``x``.
    xtol : float, optional
        Absolute tolerance, units of ``x``. Default 2e-12.
    rtol : float, optional
        Relative tolerance, dimensionless; >= 4 eps (default).
    maxiter : int, optional
        Iteration limit. Default 100.

    Returns
    -------
    float
        The root, units of ``x``.

    Raises
    ------
    NotBracketedError, NonFiniteValueError, NoConvergenceError, ParameterError
        As :func:`brent`.
    """
    return brent(f, a, b, xtol=xtol, rtol=rtol, maxiter=maxiter).root


def _sign(v: float) -> int:
    return 0 if v == 0.0 else (1 if v > 0.0 else -1)


def find_sign_changes(
    f: Callable[[float], float],
    grid: ArrayLike,
    *,
    values: ArrayLike | None = None,
    left_sign: int | None = None,
    ftol: float = 0.0,
    xtol: float = XTOL,
    rtol: float = RTOL,
    maxiter: int = MAXITER,
) -> SignChanges:
    """All sign changes of ``f`` resolved by the samples on ``grid``, each refined by Brent's method.

    Rules (they make every crossing reported exactly once and a touch never):

    1. A sample with ``|f| <= ftol`` counts as zero (``ftol = 0`` by default:
       only exact zeros).
    2. Between two consecutive non-zero samples of opposite sign there is one
       crossing, refined by :func:`brent` inside that interval. An even number
       of roots between two samples is invisible: the grid must be finer than
       the spacing of the roots the caller cares about.
    3. A run of one or more consecutive zero samples is one *crossing* if the
       nearest non-zero samples on its two sides have opposite signs; it is
       reported once, at its first sample, exactly (no refinement). If they
       have the same sign it is a *touch* (``f`` reaches 0 without crossing,
       e.g. a grazing contact) and is **not reported**.
    4. A zero run touching the start of the grid takes its left-hand sign from
       ``left_sign`` (the sign of ``f`` just before ``grid[0]``, e.g. the last
       non-zero sign of the previous step when an interval is scanned step by
       step); without it, and for a zero run touching the end of the grid, the
       direction is undecidable and the run is not reported. Scanning
       consecutive steps that share their boundary sample, passing
       ``left_sign``, therefore reports a crossing on the boundary once, in the
       later step.
    5. After refinement, a rising and a falling crossing (in either order)
       closer than ``2 (xtol + rtol |x|)`` are the two halves of a touch that
       rounding split into a sign change pair; both are dropped (a touch is
       reported not at all, never twice). A touch whose *values* are noisy
       (cancellation, e.g. ``x*x - 2*a*x + a*a``) is split wider, about
       ``2 sqrt(noise / |f''/2|)``; if a sample lands inside that band it is a
       genuine sign change pair of the float function and is reported as two
       crossings. Give ``ftol`` at the noise level of ``f`` (rule 1) and such a
       touch is not reported.

    Parameters
    ----------
    f : callable ``f(x) -> float``
        Continuous between the samples; any units.
    grid : array_like of float, shape (n,)
        Strictly increasing sample points, units of ``x``; n >= 2.
    values : array_like of float, shape (n,), optional
        ``f(grid)`` if already computed (e.g. vectorised); otherwise ``f`` is
        called at each grid point.
    left_sign : {-1, 0, 1}, optional
        Sign of ``f`` just before ``grid[0]`` (rule 4); 0 or None means unknown.
    ftol : float, optional
        Samples with ``|f| <= ftol`` count as zero, units of ``f``; >= 0. Default 0.
    xtol : float, optional
        Absolute root tolerance of the refinement, units of ``x``. Default 2e-12.
    rtol : float, optional
        Relative root tolerance, dimensionless; >= 4 eps (default).
    maxiter : int, optional
        Iteration limit of each refinement. Default 100.

    Returns
    -------
    SignChanges
        Crossings ascending, with their direction.

    Raises
    ------
    ParameterError
        Grid not 1-D, shorter than 2, not finite or not strictly increasing;
        ``values`` of the wrong shape or not finite; bad tolerances.
    NonFiniteValueError, NoConvergenceError
        From the refinement.
    """
    xt, rt, mi = _check_tolerances(xtol, rtol, maxiter)
    x, ft = _check_scan(grid, ftol, left_sign)
    g, calls = _sample(f, x, values)
    sg = np.where(np.abs(g) <= ft, 0, np.sign(g)).astype(int).tolist()
    found, refine_calls = _crossings(f, x.tolist(), g.tolist(), sg, left_sign or 0, xt, rt, mi)
    kept = _drop_split_touches(found, xt, rt)
    xr = np.array([k[0] for k in kept], dtype=float)
    dr = np.array([k[1] for k in kept], dtype=np.int8)
    sr = np.array([k[2] for k in kept], dtype=bool)
    for arr in (xr, dr, sr):
        arr.flags.writeable = False
    return SignChanges(xr, dr, sr, calls + refine_calls)


def _check_scan(grid: ArrayLike, ftol: float, left_sign: int | None) -> tuple[NDArray[np.float64], float]:
    """The grid as a float array and ``ftol`` as a float, checked (:func:`find_sign_changes`)."""
    x = np.asarray(grid, dtype=float)
    if x.ndim != 1 or x.size < 2:
        raise ParameterError('grid', grid, 'must be a 1-D array of at least 2 points')
    if not np.all(np.isfinite(x)):
        raise ParameterError('grid', grid, 'must be finite')
    if not np.all(np.diff(x) > 0.0):
        raise ParameterError('grid', grid, 'must be strictly increasing')
    ft = float(ftol)
    if not (math.isfinite(ft) and ft >= 0.0):
        raise ParameterError('ftol', ftol, 'must be finite and >= 0')
    if left_sign not in (None, -1, 0, 1):
        raise ParameterError('left_sign', left_sign, 'must be -1, 0, 1 or None')
    return x, ft


def _sample(
    f: Callable[[float], float], x: NDArray[np.float64], values: ArrayLike | None
) -> tuple[NDArray[np.float64], int]:
    """``f`` on the grid ``x`` (``values`` if given, checked) and the evaluations it took."""
    if values is None:
        g = np.empty_like(x)
        for i, xi in enumerate(x.tolist()):
            g[i] = _value(f, xi)
        return g, x.size
    g = np.array(values, dtype=float)
    if g.shape != x.shape:
        raise ParameterError('values', values, f'must have the shape of grid {x.shape}, got {g.shape}')
    if not np.all(np.isfinite(g)):
        bad = int(np.flatnonzero(~np.isfinite(g))[0])
        raise NonFiniteValueError(float(x[bad]), float(g[bad]))
    return g, 0


def _crossings(
    f: Callable[[float], float],
    xs: list[float],
    gs: list[float],
    sg: list[int],
    left_sign: int,
    xt: float,
    rt: float,
    mi: int,
) -> tuple[list[tuple[float, int, bool]], int]:
    """The crossings ``(x, direction, on_sample)`` of rules 2-4 of :func:`find_sign_changes` (samples
    ``xs``, values ``gs``, signs ``sg`` with zeros within ``ftol``) and the evaluations of the refinement."""
    calls = 0
    found: list[tuple[float, int, bool]] = []
    n = len(xs)
    prev_sign = left_sign  # last non-zero sign seen to the left
    i = 0
    while i < n:
        if sg[i] != 0:
            if i + 1 < n and sg[i + 1] != 0 and sg[i + 1] != sg[i]:
                res = _brent_core(f, xs[i], xs[i + 1], gs[i], gs[i + 1], xt, rt, mi, 0)
                calls += res.function_calls
                found.append((res.root, sg[i + 1], False))
            prev_sign = sg[i]
            i += 1
            continue
        j = i  # zero run i..j
        while j + 1 < n and sg[j + 1] == 0:
            j += 1
        right_sign = sg[j + 1] if j + 1 < n else 0
        if prev_sign != 0 and right_sign != 0 and prev_sign != right_sign:
            found.append((xs[i], right_sign, True))
        i = j + 1
    return found, calls


def _drop_split_touches(found: list[tuple[float, int, bool]], xt: float, rt: float) -> list[tuple[float, int, bool]]:
    """Rule 5 of :func:`find_sign_changes`: drop opposite pairs closer than the refinement tolerance."""
    kept: list[tuple[float, int, bool]] = []
    for item in found:
        if kept:
            xp, dp, _ = kept[-1]
            if dp != item[1] and abs(item[0] - xp) <= 2.0 * (xt + rt * max(abs(xp), abs(item[0]))):
                kept.pop()
                continue
        kept.append(item)
    return kept


class GoldenSection(NamedTuple):
    """The last bracket of :func:`golden_section`: ``lo < x1 < x2 < hi`` (up to rounding), with
    ``f1 = f(x1)`` and ``f2 = f(x2)``; units of ``x`` and of ``f``."""

    lo: float
    hi: float
    x1: float
    f1: float
    x2: float
    f2: float

    @property
    def best(self) -> tuple[float, float]:
        """``(x, f(x))`` of the better inner point (``x1`` on a tie)."""
        return (self.x1, self.f1) if self.f1 <= self.f2 else (self.x2, self.f2)


def golden_section(
    f: Callable[[float], float], lo: float, hi: float, *, xtol: float | None = None, maxiter: int | None = None
) -> GoldenSection:
    """Golden-section search for a minimum of ``f`` in ``[lo, hi]``.

    Each iteration drops the outer part beyond the worse of the two inner points and
    evaluates ``f`` once; the bracket shrinks by ``(sqrt(5) - 1) / 2`` per iteration.
    ``f`` is assumed unimodal in the bracket (else a local minimum is found).

    Parameters
    ----------
    f : callable ``f(x) -> float``
        The function; any units. Called with the bracket's arithmetic type.
    lo, hi : float
        Bracket, ``lo < hi``, units of ``x``.
    xtol : float, optional
        Stop once ``hi - lo <= xtol`` (units of ``x``).
    maxiter : int, optional
        Stop after this many iterations. At least one of ``xtol`` and ``maxiter`` must be
        given (``maxiter`` alone runs exactly that many).

    Returns
    -------
    GoldenSection
        The last bracket and its two inner points.
    """
    if xtol is None and maxiter is None:
        raise ParameterError('xtol', xtol, 'xtol or maxiter must be given')
    g = (math.sqrt(5.0) - 1.0) / 2.0
    x1 = hi - g * (hi - lo)
    x2 = lo + g * (hi - lo)
    f1, f2 = f(x1), f(x2)
    k = 0
    while (maxiter is None or k < maxiter) and (xtol is None or hi - lo > xtol):
        k += 1
        if f1 <= f2:
            hi, x2, f2 = x2, x1, f1
            x1 = hi - g * (hi - lo)
            f1 = f(x1)
        else:
            lo, x1, f1 = x1, x2, f2
            x2 = lo + g * (hi - lo)
            f2 = f(x2)
    return GoldenSection(lo, hi, x1, f1, x2, f2)
