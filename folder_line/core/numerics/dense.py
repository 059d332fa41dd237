"""Dense output of the Runge-Kutta integrators: per-step polynomials, evaluation and inverse.

A :class:`DenseSolution` holds step endpoints ``t_i``, states ``y_i``, the
per-step polynomial of the dense output in ``x = (t - t_i)/h_i``, and the counters
``nfev``, ``steps`` and ``rejected`` (:func:`~folder_line.core.numerics.integrators.rk4`
and :func:`~folder_line.core.numerics.integrators.dopri5` return one). Evaluation
(:meth:`DenseSolution.__call__`, :meth:`~DenseSolution.component`,
:meth:`~DenseSolution.derivative`) is vectorised: ``searchsorted`` on the step grid, then
Horner's rule (:func:`horner`) on the gathered coefficients.
:meth:`DenseSolution.inverse` inverts a non-decreasing component (the drive phase
Θ(t)) at many targets at once: ``searchsorted`` on the endpoint values, then a
Newton iteration on the step's polynomial safeguarded by bisection (:func:`poly_solve`),
vectorised over the targets, to ~1e-15 of the step. :func:`constant_solution` and
:func:`concatenate` build and join solutions.
"""

from __future__ import annotations

import itertools

import numpy as np
import numpy.typing as npt

from folder_line.core.numerics.arrays import FloatArray

__all__ = [
    'DenseSolution',
    'concatenate',
    'constant_solution',
    'horner',
    'poly_solve',
]


# --------------------------------------------------------------------------- polynomials


def horner(c: FloatArray, x: FloatArray) -> FloatArray:
    """``sum_k c[k] x^k`` with ``c`` shaped (5, q) or (5, q, m) and ``x`` shaped (q,)."""
    xx = x if c.ndim == 2 else x[:, None]
    acc: FloatArray = c[4]
    for k in (3, 2, 1, 0):
        acc = acc * xx + c[k]
    return acc


def _horner_d(c: FloatArray, x: FloatArray) -> FloatArray:
    """``d/dx sum_k c[k] x^k``, same shapes as :func:`horner`."""
    xx = x if c.ndim == 2 else x[:, None]
    acc: FloatArray = 4.0 * c[4]
    for k in (3, 2, 1):
        acc = acc * xx + k * c[k]
    return acc


def poly_solve(
    c: FloatArray, target: FloatArray, x_hi: FloatArray, sign: FloatArray | float = 1.0, x0: FloatArray | None = None
) -> FloatArray:
    """Solve ``p(x) = target`` on ``[0, x_hi]`` for many quartics at once.

    ``c`` is (5, q); the bracket is assumed to be ``sign (p(0) - target) < 0 <=
    sign (p(x_hi) - target)``. Newton steps, replaced by bisection whenever they leave
    the current bracket or the slope has the wrong sign; stops when the step or the
    bracket is below ``2**-50 x_hi`` (or after 80 iterations: bisection alone gets
    there in ~50).
    """
    q = target.shape[0]
    s = np.broadcast_to(np.asarray(sign, dtype=float), (q,))
    lo = np.zeros(q)
    hi = x_hi.astype(float).copy()
    x = np.clip(0.5 * hi if x0 is None else x0, 0.0, hi)
    tol = 2.0**-50 * np.maximum(hi, 1e-300)
    active = np.arange(q)
    for _ in range(80):
        if active.size == 0:
            break
        ca = c[:, active]
        xa = x[active]
        g = s[active] * (horner(ca, xa) - target[active])
        d = s[active] * _horner_d(ca, xa)
        la, ha = lo[active], hi[active]
        la = np.where(g < 0.0, xa, la)
        ha = np.where(g > 0.0, xa, ha)
        with np.errstate(divide='ignore', invalid='ignore'):
            xn = xa - g / d
        bad = ~(d > 0.0) | ~(xn > la) | ~(xn < ha)
        xn = np.where(bad, 0.5 * (la + ha), xn)
        xn = np.where(g == 0.0, xa, xn)
        lo[active], hi[active] = la, ha
        x[active] = xn
        ta = tol[active]
        done = (g == 0.0) | (np.abs(xn - xa) <= ta) | (ha - la <= ta)
        active = active[~done]
    return np.clip(x, 0.0, x_hi)


# --------------------------------------------------------------------------- solution


class DenseSolution:
    """Step endpoints, states and a vectorised dense output.

    On step ``i`` (``t[i] <= t <= t[i+1]``) the solution is the polynomial
    ``y(t) = sum_k coef[k, i] x^k`` in ``x = (t - t[i]) / h[i]``; ``h[i]`` is the step
    the method took (``t[i+1] - t[i]`` except for a step truncated by a terminal
    condition, where ``t[i+1] - t[i] < h[i]``).

    Attributes
    ----------
    t : ndarray, shape (n + 1,)
        Step endpoints, increasing.
    y : ndarray, shape (n + 1, m)
        States at the endpoints.
    h : ndarray, shape (n,)
        Step sizes of the polynomials' scaling.
    coef : ndarray, shape (5, n, m)
        Polynomial coefficients per step (degree <= 4; ``coef[0] = y[:-1]``).
    method : str
        ``'rk4'``, ``'dopri5'``, ``'constant'`` or ``'+'``-joined for :func:`concatenate`.
    nfev : int
        Right-hand-side evaluations.
    steps : int
        Accepted steps (``n``).
    rejected : int
        Rejected trial steps (dopri5), 0 for rk4.
    status : str
        ``'finished'`` (reached the end), ``'terminal'`` (terminal condition) or
        ``'stopped'`` (an ``on_break`` callback asked to stop).
    break_t, break_value : ndarray
        Times at which breaks were crossed and the break values.
    max_landing_error : float
        Largest ``|y_j - b|`` left at a break landing (0 without breaks).
    """

    def __init__(
        self,
        t: FloatArray,
        y: FloatArray,
        h: FloatArray,
        coef: FloatArray,
        *,
        method: str,
        nfev: int = 0,
        rejected: int = 0,
        status: str = 'finished',
        break_t: FloatArray | None = None,
        break_value: FloatArray | None = None,
        max_landing_error: float = 0.0,
    ) -> None:
        self.t = np.ascontiguousarray(t, dtype=np.float64)
        self.y = np.ascontiguousarray(y, dtype=np.float64)
        self.h = np.ascontiguousarray(h, dtype=np.float64)
        self.coef = np.ascontiguousarray(coef, dtype=np.float64)
        n = self.h.shape[0]
        if n < 1 or self.t.shape != (n + 1,) or self.y.shape[0] != n + 1 or self.coef.shape[:2] != (5, n):
            msg = (
                f'inconsistent dense solution: t {self.t.shape}, y {self.y.shape}, h {self.h.shape}, '
                f'coef {self.coef.shape}'
            )
            raise ValueError(msg)
        self.method = method
        self.nfev = int(nfev)
        self.steps = n
        self.rejected = int(rejected)
        self.status = status
        self.break_t = np.zeros(0) if break_t is None else np.asarray(break_t, dtype=float)
        self.break_value = np.zeros(0) if break_value is None else np.asarray(break_value, dtype=float)
        self.max_landing_error = float(max_landing_error)

    @property
    def n_components(self) -> int:
        """Number of state components ``m``."""
        return int(self.y.shape[1])

    @property
    def t0(self) -> float:
        """First time."""
        return float(self.t[0])

    @property
    def t_end(self) -> float:
        """Last time."""
        return float(self.t[-1])

    def _locate(self, t: npt.ArrayLike) -> tuple[FloatArray, npt.NDArray[np.intp], FloatArray]:
        tq = np.asarray(t, dtype=float)
        flat = tq.ravel()
        if not np.all(np.isfinite(flat)):
            raise ValueError('t must be finite')
        idx = np.searchsorted(self.t, flat, side='right') - 1
        np.clip(idx, 0, self.steps - 1, out=idx)
        x = (flat - self.t[idx]) / self.h[idx]
        return tq, idx, x

    def __call__(self, t: npt.ArrayLike) -> FloatArray:
        """The dense output at ``t`` (any shape): shape ``(m,) + t.shape`` (scipy's layout).

        Times outside ``[t0, t_end]`` are extrapolated with the first or last step's
        polynomial (as scipy's ``OdeSolution`` does); callers that must not
        extrapolate clip first.
        """
        tq, idx, x = self._locate(t)
        c = self.coef[:, idx, :]
        return np.ascontiguousarray(horner(c, x).T).reshape((self.n_components, *tq.shape))

    def component(self, t: npt.ArrayLike, j: int) -> FloatArray:
        """Component ``j`` of the dense output at ``t``, shaped like ``t``."""
        tq, idx, x = self._locate(t)
        return horner(self.coef[:, idx, j], x).reshape(tq.shape)

    def derivative(self, t: npt.ArrayLike, j: int | None = None) -> FloatArray:
        """Time derivative of the dense output (all components, ``(m,) + t.shape``, or one)."""
        tq, idx, x = self._locate(t)
        if j is not None:
            return (_horner_d(self.coef[:, idx, j], x) / self.h[idx]).reshape(tq.shape)
        d = _horner_d(self.coef[:, idx, :], x) / self.h[idx][:, None]
        return np.ascontiguousarray(d.T).reshape((self.n_components, *tq.shape))

    def inverse(self, targets: npt.ArrayLike, j: int) -> FloatArray:
        """Earliest times at which the non-decreasing component ``j`` equals each target.

        Parameters
        ----------
        targets : array_like of float
            Values of ``y_j``, any shape. Values below ``y_j(t0)`` give ``t0``, values
            above ``y_j(t_end)`` give ``t_end`` (clipped, never NaN).
        j : int
            Component; its endpoint values must be non-decreasing.

        Returns
        -------
        ndarray
            Times shaped like ``targets``. The step is found by ``searchsorted`` on the
            endpoint values (``side='left'``: on a plateau the earliest time), the time in
            the step by :func:`poly_solve` to ~1e-15 of the step.

        Raises
        ------
        ValueError
            Component ``j`` decreases somewhere, or a target is not finite.
        """
        Y = self.y[:, j]
        if np.any(np.diff(Y) < 0.0):
            k = int(np.argmax(np.diff(Y) < 0.0))
            msg = (
                f'component {j} is not non-decreasing: it falls from {Y[k]!r} to {Y[k + 1]!r} '
                f'at t={self.t[k + 1]!r}; inverse() needs a monotone component'
            )
            raise ValueError(msg)
        v = np.asarray(targets, dtype=float)
        flat = v.ravel()
        if not np.all(np.isfinite(flat)):
            raise ValueError('targets must be finite')
        out = np.empty(flat.shape)
        low = flat <= Y[0]
        high = flat > Y[-1]
        out[low] = self.t[0]
        out[high] = self.t[-1]
        mid = np.flatnonzero(~low & ~high)
        if mid.size:
            tv = flat[mid]
            ks = np.searchsorted(Y, tv, side='left') - 1
            x_end = (self.t[ks + 1] - self.t[ks]) / self.h[ks]
            y_lo, y_hi = Y[ks], Y[ks + 1]
            x0 = x_end * (tv - y_lo) / (y_hi - y_lo)
            x = poly_solve(self.coef[:, ks, j], tv, x_end, 1.0, x0)
            out[mid] = np.minimum(self.t[ks] + x * self.h[ks], self.t[ks + 1])
        return out.reshape(v.shape)


def constant_solution(t0: float, t1: float, y: npt.ArrayLike) -> DenseSolution:
    """A one-step solution holding ``y`` constant on ``[t0, t1]`` (``t1 > t0``)."""
    yy = np.asarray(y, dtype=float).ravel()
    if not t1 > t0:
        raise ValueError(f'constant_solution needs t1 > t0, got [{t0!r}, {t1!r}]')
    coef = np.zeros((5, 1, yy.size))
    coef[0, 0] = yy
    return DenseSolution(np.array([t0, t1]), np.vstack([yy, yy]), np.array([t1 - t0]), coef, method='constant')


def concatenate(parts: list[DenseSolution]) -> DenseSolution:
    """Join solutions end to start (each must start where the previous one ends).

    Counters add up; the status is the last part's.
    """
    if not parts:
        raise ValueError('nothing to concatenate')
    for a, b in itertools.pairwise(parts):
        if a.t[-1] != b.t[0]:
            raise ValueError(f'parts do not join: one ends at t={a.t[-1]!r}, the next starts at t={b.t[0]!r}')
        if a.n_components != b.n_components:
            raise ValueError('parts have different numbers of components')
    t = np.concatenate([p.t[:-1] for p in parts] + [parts[-1].t[-1:]])
    y = np.concatenate([p.y[:-1] for p in parts] + [parts[-1].y[-1:]])
    return DenseSolution(
        t,
        y,
        np.concatenate([p.h for p in parts]),
        np.concatenate([p.coef for p in parts], axis=1),
        method='+'.join(p.method for p in parts),
        nfev=sum(p.nfev for p in parts),
        rejected=sum(p.rejected for p in parts),
        status=parts[-1].status,
        break_t=np.concatenate([p.break_t for p in parts]),
        break_value=np.concatenate([p.break_value for p in parts]),
        max_landing_error=max(p.max_landing_error for p in parts),
    )
