"""Belts geared to the master drive, with slow-downs: exact travel and its inverse.

Every belt of the line is geared to the master drive (:mod:`folder_line.core.mechanisms.drive`):
a belt of nominal speed ``V`` has moved ``V Θ(t)``. A slow-down of factor ``f`` over
``[t_s, t_e)`` (the ``faults`` effect's ``Slowdowns``; ``0 < f <= 1``) makes it move
``f V dΘ`` there. :class:`BeltPhase` is the belt's phase ``B(t)`` in nominal seconds,
its travel being ``V B(t)``::

    B(t) = Θ(t) - Σ_j (1 - f_j) (Θ(clip(t, t_s_j, t_e_j)) - Θ(t_s_j))

piecewise linear in Θ, so it is evaluated and inverted exactly (``theta_of``, then
``drive.time_of``): no quadrature, no sampling. Used for the feed belt of the folder
(:mod:`folder_line.core.line.folder_sim`) and the chute belts of the layup device
(:mod:`folder_line.core.effects.chute_belts`).

An operator's change of a belt's speed (:mod:`folder_line.core.line.tuning`) is a factor
from its time on, ``f > 1`` when it speeds the belt up; :func:`combine_factors` merges
those steps with the slow-downs into one list of intervals for :class:`BeltPhase`.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
import numpy.typing as npt

from folder_line.core.mechanisms.drive import Drive
from folder_line.core.numerics.arrays import FloatArray

__all__ = ['BeltPhase', 'Intervals', 'belt_intervals', 'combine_factors']


class BeltPhase:
    """Phase ``B(t)`` of a belt geared to the master drive, with slow-downs (nominal s).

    Parameters
    ----------
    drive : Drive
        Master drive.
    duration : float
        Simulated line time, s: ``B`` is never needed beyond it, and slow-downs are
        clipped to ``[0, duration]``.
    t_start, t_end, factor : array_like, optional
        Slow-downs ``[t_start, t_end)`` (s, sorted, non-overlapping; ``t_end`` may be
        ``inf``) and their speed factors (> 0; above 1 a speed-up); none if omitted or empty.
    """

    def __init__(
        self,
        drive: Drive,
        duration: float,
        t_start: npt.ArrayLike | None = None,
        t_end: npt.ArrayLike | None = None,
        factor: npt.ArrayLike | None = None,
    ) -> None:
        self.drive = drive
        self.duration = float(duration)
        if t_start is None or np.size(t_start) == 0:
            self.ts = np.zeros(0)
            return
        self.ts = np.asarray(t_start, dtype=float)
        self.te_raw = np.asarray(t_end, dtype=float)
        self.f = np.asarray(factor, dtype=float)
        ts = np.clip(self.ts, 0.0, self.duration)
        self.te = np.clip(self.te_raw, ts, self.duration)
        self.th_s = np.asarray(drive.theta(ts), dtype=float)
        self.th_e = np.asarray(drive.theta(self.te), dtype=float)
        self.loss = (1.0 - self.f) * (self.th_e - self.th_s)
        self.C = np.cumsum(self.loss) - self.loss  # loss before slow-down j
        self.B_s = self.th_s - self.C
        self.B_e = self.th_e - self.C - self.loss

    @property
    def plain(self) -> bool:
        """No slow-downs: ``B = Θ``."""
        return self.ts.size == 0

    def factor(self, t: npt.ArrayLike) -> FloatArray:
        """Belt speed factor at line times ``t`` (1 outside slow-downs)."""
        t = np.asarray(t, dtype=float)
        if self.plain:
            return np.ones_like(t)
        j = np.searchsorted(self.ts, t, side='right') - 1
        jc = np.clip(j, 0, None)
        return np.where((j >= 0) & (t < self.te_raw[jc]), self.f[jc], 1.0)

    def at(self, t: npt.ArrayLike, theta: npt.ArrayLike | None = None) -> FloatArray:
        """``B(t)`` for line times ``t`` in [0, duration] (``theta``: Θ(t) if known), nominal s."""
        t = np.asarray(t, dtype=float)
        th = np.asarray(self.drive.theta(t) if theta is None else theta, dtype=float)
        if self.plain:
            return th
        j = np.searchsorted(self.ts, t, side='right') - 1
        jc = np.clip(j, 0, None)
        inner = np.asarray(self.drive.theta(np.minimum(t, self.te[jc])), dtype=float)
        return np.where(j >= 0, th - self.C[jc] - (1.0 - self.f[jc]) * (inner - self.th_s[jc]), th)

    def theta_of(self, b: npt.ArrayLike) -> FloatArray:
        """Master phase Θ at which the belt phase is ``b``, nominal s."""
        b = np.asarray(b, dtype=float)
        if self.plain:
            return b
        j = np.searchsorted(self.B_s, b, side='right') - 1
        jc = np.clip(j, 0, None)
        inside = b < self.B_e[jc]
        return np.where(
            j < 0, b, np.where(inside, self.th_s[jc] + (b - self.B_s[jc]) / self.f[jc], b + self.C[jc] + self.loss[jc])
        )


def combine_factors(
    t_start: npt.ArrayLike | None,
    t_end: npt.ArrayLike | None,
    factor: npt.ArrayLike | None,
    steps: list[tuple[float, float]],
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Slow-downs and speed steps as one list of intervals for :class:`BeltPhase`.

    Parameters
    ----------
    t_start, t_end, factor : array_like or None
        Slow-downs ``[t_start, t_end)`` with their factors (None: none).
    steps : list of (float, float)
        ``(t, g)``, sorted by ``t``: from ``t`` on (until the next step) the belt runs at
        ``g`` times its nominal speed (an operator's tuning).

    Returns
    -------
    (t_start, t_end, factor) : ndarrays
        Sorted, non-overlapping intervals, each with the product of the factors that
        hold in it; intervals at factor 1 are left out, and the last may end at ``inf``.
    """
    ts = np.zeros(0) if t_start is None else np.asarray(t_start, dtype=float).reshape(-1)
    te = np.zeros(0) if t_end is None else np.asarray(t_end, dtype=float).reshape(-1)
    fs = np.zeros(0) if factor is None else np.asarray(factor, dtype=float).reshape(-1)
    edges = sorted({*ts.tolist(), *te[np.isfinite(te)].tolist(), *(float(t) for t, _ in steps)})
    out_s: list[float] = []
    out_e: list[float] = []
    out_f: list[float] = []
    step_t = [float(t) for t, _ in steps]
    for i, a in enumerate(edges):
        b = edges[i + 1] if i + 1 < len(edges) else np.inf
        k = int(np.searchsorted(step_t, a, side='right')) - 1
        g = float(steps[k][1]) if k >= 0 else 1.0
        inside = (ts <= a) & (a < te)
        f = g * float(np.prod(fs[inside]))
        if f == 1.0:
            continue
        if out_e and out_e[-1] == a and out_f[-1] == f:
            out_e[-1] = b
        else:
            out_s.append(a)
            out_e.append(b)
            out_f.append(f)
    return np.array(out_s), np.array(out_e), np.array(out_f)


class Intervals(Protocol):
    """Slow-downs as the ``faults`` effect gives them (``Slowdowns``)."""

    @property
    def t_start(self) -> np.ndarray: ...

    @property
    def t_end(self) -> np.ndarray: ...

    @property
    def factor(self) -> np.ndarray: ...


def belt_intervals(
    slow: Intervals | None, steps: list[tuple[float, float]]
) -> tuple[FloatArray | None, FloatArray | None, FloatArray | None]:
    """``(t_start, t_end, factor)`` for :class:`BeltPhase`: the slow-downs ``slow`` as they are when no
    operator's ``steps`` change the belt (so the phase is bit for bit the untuned one), else combined with
    them (:func:`combine_factors`); ``(None, None, None)`` for neither."""
    if not steps:
        return (None, None, None) if slow is None else (slow.t_start, slow.t_end, slow.factor)
    if slow is None:
        return combine_factors(None, None, None, steps)
    return combine_factors(slow.t_start, slow.t_end, slow.factor, steps)
