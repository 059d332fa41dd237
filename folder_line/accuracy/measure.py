"""Rows of the accuracy benchmark and the CPU-time measurement they share."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

__all__ = ['COLUMNS', 'Row', 'cpu_budget', 'cpu_per_call']

#: CSV columns, in order (the first five are the documented interface)
COLUMNS = ('method', 'knob', 'value', 'error', 'cpu_s_per_sim_s', 'study', 'quantity', 'unit', 'reference')


@dataclass(frozen=True)
class Row:
    """One point of a Pareto curve: one method at one knob setting.

    Attributes
    ----------
    study : str
        The study that measured it (``linkage``, ``fourbar``, ``motor``, ``events``, ``publishing``).
    method : str
        Method name; one curve per (study, method).
    knob : str
        Name of the knob varied along the curve (``tol``, ``h``, ``rtol``, ``rate``, ``xtol``, ``batch``).
    value : float
        Knob setting, in the knob's unit (``h`` s, ``rate`` Hz, tolerances dimensionless or s).
    error : float
        Largest absolute error against the reference over the simulated span, in ``unit``
        (>= 0, finite; an exact result is reported as 0).
    cpu_s_per_sim_s : float
        CPU seconds per simulated second (``time.process_time``), > 0.
    quantity : str
        What the error is of (``rocker angle``, ``event time`` ...).
    unit : str
        Unit of ``error``.
    reference : str
        The reference and how it was checked, in a few words.
    """

    study: str
    method: str
    knob: str
    value: float
    error: float
    cpu_s_per_sim_s: float
    quantity: str
    unit: str
    reference: str

    def __post_init__(self) -> None:
        for name in ('value', 'error', 'cpu_s_per_sim_s'):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v)):
                raise ValueError(f'Row.{name} must be a finite number, got {v!r} ({self.study}/{self.method})')
        if self.error < 0.0 or self.cpu_s_per_sim_s <= 0.0:
            raise ValueError(
                f'Row needs error >= 0 and cpu_s_per_sim_s > 0, got {self.error!r}, '
                f'{self.cpu_s_per_sim_s!r} ({self.study}/{self.method})'
            )

    def as_dict(self) -> dict[str, object]:
        """The row as a mapping of :data:`COLUMNS` to values."""
        return {c: getattr(self, c) for c in COLUMNS}


def cpu_budget(quick: bool) -> tuple[float, int]:
    """``(min_s, repeats)`` of :func:`cpu_per_call` for a study: 0.05 s three times, or 0.02 s twice
    with ``--quick``."""
    return (0.02, 2) if quick else (0.05, 3)


def cpu_per_call(fn: Callable[[], object], *, min_s: float = 0.05, repeats: int = 3) -> float:
    """CPU seconds of one call of ``fn``: the best of ``repeats`` batches of at least ``min_s`` each.

    Parameters
    ----------
    fn : callable
        Called with no arguments; its result is discarded.
    min_s : float
        Least CPU time of one batch, s (calls are repeated until reached).
    repeats : int
        Batches; the fastest per-call time is returned (the least disturbed by the machine).

    Returns
    -------
    float
        CPU seconds per call (``time.process_time``), > 0.
    """
    best = math.inf
    n = 1
    for _ in range(repeats):
        while True:
            t0 = time.process_time()
            for _ in range(n):
                fn()
            dt = time.process_time() - t0
            if dt >= min_s:
                break
            n = max(n * 2, int(n * 1.2 * min_s / dt) + 1) if dt > 0 else n * 10
        best = min(best, dt / n)
    return max(best, 1e-12)
