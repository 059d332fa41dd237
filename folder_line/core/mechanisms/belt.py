"""Belts geared to the master drive, with slow-downs and speed steps: exact travel and its inverse.

Every belt of the line is geared to the master drive (:mod:`folder_line.core.mechanisms.drive`):
a belt of nominal speed ``V`` has moved ``V Θ(t)``. A slow-down of factor ``f`` over
``[t_s, t_e)`` (the ``faults`` effect; ``0 < f <= 1``), or an operator's speed step
(``f > 1`` speeds it up, :mod:`folder_line.core.line.tuning`), makes it move ``f V dΘ``
there. :class:`BeltPhase` is the belt's phase ``B(t)`` in nominal seconds, its travel
being ``V B(t)``::

    B(t) = Θ(t) - C_j - (1 - f_j) (Θ(t) - Θ(t_s_j))      inside interval j
    B(t) = Θ(t) - C_{j+1}                                after it, before the next one

with ``C_j`` the phase lost in the intervals before j, added up one interval at a time.
It is piecewise linear in Θ, so it is evaluated and inverted exactly (``theta_of``, then
``drive.time_of``): no quadrature, no sampling. Without any interval ``B = Θ`` exactly.

Streaming
---------
The intervals are learnt as the line runs: :meth:`BeltPhase.open` starts one at its
start time, :meth:`BeltPhase.close` ends the open one (the drive's phase is read at
those times only, so a phase never depends on the drive after the last time given).
An open interval counts as lasting for ever, which gives the same values as its
closed form at every time before its end. :meth:`BeltPhase.prune` forgets closed
intervals before a time (their loss stays in ``C``): the memory of a belt that runs for
ever stays bounded. :class:`BeltStream` feeds a phase from the two sources of intervals
(the slow-downs as the ``faults`` effect draws them, and the operator's speed steps)
up to a time, combining them as :func:`combine_factors` does.

Used for the feed belt of the folder (:mod:`folder_line.core.line.folder_stream`) and the
chute belts of the layup device (:mod:`folder_line.core.effects.chute_belts`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Protocol

import numpy as np
import numpy.typing as npt

from folder_line.core.mechanisms.drive import Drive
from folder_line.core.numerics.arrays import FloatArray

__all__ = ['BeltPhase', 'BeltStream', 'Intervals', 'SlowdownSource', 'belt_intervals', 'combine_factors']


def _theta1(drive: Drive, t: float) -> float:
    return float(np.asarray(drive.theta(np.array([t])), dtype=float)[0])


class BeltPhase:
    """Phase ``B(t)`` of a belt geared to the master drive, with slow-downs and speed steps (nominal s).

    Parameters
    ----------
    drive : Drive
        Master drive.
    duration : float, optional
        With intervals given here: they are not needed beyond this line time, s (an
        interval still running then stays open). Default: no limit.
    t_start, t_end, factor : array_like, optional
        Intervals ``[t_start, t_end)`` (s, sorted, non-overlapping; ``t_end`` may be
        ``inf``) and their speed factors (> 0; above 1 a speed-up); none if omitted or empty.
        More can be added as the line runs (:meth:`open`, :meth:`close`).
    """

    def __init__(
        self,
        drive: Drive,
        duration: float = math.inf,
        t_start: npt.ArrayLike | None = None,
        t_end: npt.ArrayLike | None = None,
        factor: npt.ArrayLike | None = None,
    ) -> None:
        self.drive = drive
        # the intervals kept, in time order: start, end (inf while open), factor, phase at the start,
        # phase lost before (C) and up to the end of (C_next; None while open) each
        self._ts: list[float] = []
        self._te: list[float] = []
        self._f: list[float] = []
        self._th_s: list[float] = []
        self._th_e: list[float] = []
        self._C: list[float] = []
        self._Cn: list[float] = []
        self._C_end = 0.0  # phase lost in every closed interval (the C after the last one)
        self._ever = False
        self._arrays: tuple[FloatArray, ...] | None = None
        if t_start is not None and np.size(t_start):
            ts = np.asarray(t_start, dtype=float).reshape(-1)
            te = np.asarray(t_end, dtype=float).reshape(-1)
            ff = np.asarray(factor, dtype=float).reshape(-1)
            for a, b, f in zip(ts.tolist(), te.tolist(), ff.tolist(), strict=True):
                self.open(max(a, 0.0), f)
                if b <= duration:
                    self.close(b)

    # ------------------------------------------------------------------ building

    @property
    def plain(self) -> bool:
        """No interval, ever: ``B = Θ``."""
        return not self._ever

    @property
    def is_open(self) -> bool:
        """An interval is running (its end not known yet)."""
        return bool(self._te) and self._te[-1] == math.inf

    @property
    def intervals(self) -> int:
        """Intervals kept (open, closed and not pruned)."""
        return len(self._ts)

    def open(self, t_start: float, factor: float) -> None:
        """Start an interval of speed ``factor`` at ``t_start`` (s, not before the last one's end)."""
        if self.is_open:
            raise ValueError('BeltPhase.open: close the running interval first')
        if self._te and t_start < self._te[-1]:
            raise ValueError(f'BeltPhase.open: {t_start!r} s is before the last interval ends ({self._te[-1]!r} s)')
        if not (math.isfinite(factor) and factor > 0.0):
            raise ValueError(f'BeltPhase.open: factor must be finite and > 0, got {factor!r}')
        self._ever = True
        self._ts.append(float(t_start))
        self._te.append(math.inf)
        self._f.append(float(factor))
        self._th_s.append(_theta1(self.drive, t_start))
        self._th_e.append(math.inf)
        self._C.append(self._C_end)
        self._Cn.append(math.nan)
        self._arrays = None

    def close(self, t_end: float) -> None:
        """End the running interval at ``t_end`` (s, not before its start)."""
        if not self.is_open:
            raise ValueError('BeltPhase.close: no interval is running')
        if t_end < self._ts[-1]:
            raise ValueError(f'BeltPhase.close: {t_end!r} s is before the interval starts ({self._ts[-1]!r} s)')
        th_e = _theta1(self.drive, t_end)
        loss = (1.0 - self._f[-1]) * (th_e - self._th_s[-1])
        self._te[-1] = float(t_end)
        self._th_e[-1] = th_e
        self._Cn[-1] = self._C[-1] + loss
        self._C_end = self._Cn[-1]
        self._arrays = None

    def prune(self, t_keep: float) -> None:
        """Forget the closed intervals that end at or before ``t_keep`` (s): the phase at later times,
        and of later phases, is unchanged, bit for bit."""
        n = 0
        while n < len(self._te) and self._te[n] <= t_keep:
            n += 1
        if n:
            for lst in (self._ts, self._te, self._f, self._th_s, self._th_e, self._C, self._Cn):
                del lst[:n]
            self._arrays = None

    def _get(self) -> tuple[FloatArray, ...]:
        if self._arrays is None:
            ts, te, f, th_s = (np.array(x, dtype=float) for x in (self._ts, self._te, self._f, self._th_s))
            C = np.array(self._C, dtype=float)
            Cn = np.array([c if math.isfinite(c) else 0.0 for c in self._Cn], dtype=float)
            th_e = np.array(self._th_e, dtype=float)
            B_s = th_s - C
            B_e = np.where(np.isfinite(te), th_e - Cn, math.inf)
            c0 = np.array([self._C[0] if self._C else self._C_end])
            self._arrays = (ts, te, f, th_s, C, Cn, B_s, B_e, c0)
        return self._arrays

    # ------------------------------------------------------------------ evaluation

    def factor(self, t: npt.ArrayLike) -> FloatArray:
        """Belt speed factor at line times ``t`` (1 outside every interval)."""
        t = np.asarray(t, dtype=float)
        if not self._ts:
            return np.ones_like(t)
        ts, te, f = self._get()[:3]
        j = np.searchsorted(ts, t, side='right') - 1
        jc = np.clip(j, 0, None)
        return np.where((j >= 0) & (t < te[jc]), f[jc], 1.0)

    def at(self, t: npt.ArrayLike, theta: npt.ArrayLike | None = None) -> FloatArray:
        """``B(t)`` at line times ``t`` (``theta``: Θ(t) if known), nominal s."""
        t = np.asarray(t, dtype=float)
        th = np.asarray(self.drive.theta(t) if theta is None else theta, dtype=float)
        if not self._ever:
            return th
        if not self._ts:
            return th - self._C_end
        ts, te, f, th_s, C, Cn, _, _, c0 = self._get()
        j = np.searchsorted(ts, t, side='right') - 1
        jc = np.clip(j, 0, None)
        inside = th - C[jc] - (1.0 - f[jc]) * (th - th_s[jc])
        return np.where(j < 0, th - c0[0], np.where(t < te[jc], inside, th - Cn[jc]))

    def theta_of(self, b: npt.ArrayLike) -> FloatArray:
        """Master phase Θ at which the belt phase is ``b``, nominal s (exact for ``b`` up to the phase at
        the last time the belt knows)."""
        b = np.asarray(b, dtype=float)
        if not self._ever:
            return b
        if not self._ts:
            return b + self._C_end
        _, _, f, th_s, _, Cn, B_s, B_e, c0 = self._get()
        j = np.searchsorted(B_s, b, side='right') - 1
        jc = np.clip(j, 0, None)
        inside = b < B_e[jc]
        return np.where(j < 0, b + c0[0], np.where(inside, th_s[jc] + (b - B_s[jc]) / f[jc], b + Cn[jc]))


class Intervals(Protocol):
    """Slow-downs as the ``faults`` effect gives them (``Slowdowns``)."""

    @property
    def t_start(self) -> np.ndarray: ...

    @property
    def t_end(self) -> np.ndarray: ...

    @property
    def factor(self) -> np.ndarray: ...


class SlowdownSource(Protocol):
    """The slow-downs of a belt as they are drawn (:class:`folder_line.core.effects.faults.SlowdownStream`)."""

    def breaks(self, t0: float, t1: float) -> list[tuple[float, float]]:
        """``(t, factor from t on)`` where the slow-down factor changes in ``(t0, t1]``, in time order (known
        for every time up to the last the source was advanced to)."""
        ...


class BeltStream:
    """A :class:`BeltPhase` fed up to a time from the slow-downs drawn and the operator's speed steps.

    Parameters
    ----------
    drive : Drive
        Master drive.
    slowdowns : SlowdownSource or None
        The belt's slow-downs (``faults``), or None.
    steps : sequence of (float, float)
        ``(t, g)``: from ``t`` on the belt runs at ``g`` times its nominal speed (an
        operator's tuning); sorted by ``t``.

    Attributes
    ----------
    phase : BeltPhase
        The phase, known up to :attr:`t`.
    t : float
        The line time up to which the phase knows every interval, s.
    """

    def __init__(self, drive: Drive, slowdowns: SlowdownSource | None, steps: Sequence[tuple[float, float]]) -> None:
        self.phase = BeltPhase(drive)
        self.slowdowns = slowdowns
        self.steps = _changes(steps)
        self.t = -math.inf
        self._slow = 1.0  # the slow-down factor in force at self.t
        self._factor = 1.0  # the combined factor in force at self.t

    def set_steps(self, steps: Sequence[tuple[float, float]]) -> None:
        """The operator's speed steps; those at or before :attr:`t` must be the ones already applied."""
        new = _changes(steps)
        if [s for s in new if s[0] <= self.t] != [s for s in self.steps if s[0] <= self.t]:
            raise ValueError(f'BeltStream: speed steps before {self.t!r} s changed')
        self.steps = new

    def _step_factor(self, t: float) -> float:
        g = 1.0
        for ts, value in self.steps:
            if ts <= t:
                g = value
            else:
                break
        return g

    def advance(self, t: float) -> None:
        """Learn every change of the belt's speed up to line time ``t`` (s)."""
        if t <= self.t:
            return
        changes: dict[float, None] = {}
        slow: list[tuple[float, float]] = [] if self.slowdowns is None else self.slowdowns.breaks(self.t, t)
        for ts, _ in slow:
            changes[ts] = None
        for ts, _ in self.steps:
            if self.t < ts <= t:
                changes[ts] = None
        slow_at = dict(slow)
        for tc in sorted(changes):
            if tc in slow_at:
                self._slow = slow_at[tc]
            f = self._step_factor(tc) * self._slow
            if f != self._factor:
                if self._factor != 1.0:
                    self.phase.close(tc)
                if f != 1.0:
                    self.phase.open(tc, f)
                self._factor = f
        self.t = t


def _changes(steps: Sequence[tuple[float, float]]) -> list[tuple[float, float]]:
    """The steps that change the factor (from 1 before the first)."""
    out: list[tuple[float, float]] = []
    g = 1.0
    for t, value in steps:
        if float(value) != g:
            out.append((float(t), float(value)))
            g = float(value)
    return out


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


def belt_intervals(
    slow: Intervals | None, steps: list[tuple[float, float]]
) -> tuple[FloatArray | None, FloatArray | None, FloatArray | None]:
    """``(t_start, t_end, factor)`` for :class:`BeltPhase`: the slow-downs ``slow`` as they are when no
    operator's ``steps`` change the belt, else combined with them (:func:`combine_factors`);
    ``(None, None, None)`` for neither."""
    if not steps:
        return (None, None, None) if slow is None else (slow.t_start, slow.t_end, slow.factor)
    if slow is None:
        return combine_factors(None, None, None, steps)
    return combine_factors(slow.t_start, slow.t_end, slow.factor, steps)
