"""The line's machine cycles in time: which cycle runs at a time, and when the next one starts.

The folder's cycle k starts at the knife exit that ends cycle k - 1 (cycle 0 at the first
knife exit phase ``t_out``, where the feed window opens); without the folder, the layup
crank's turn k starts at ``Θ = k 60/n_kr``. Both sit at fixed master phases, so their
times are the drive's inverse there (:meth:`folder_line.core.mechanisms.drive.Drive.time_of`).
The supervisor times its commands at these boundaries
(:mod:`folder_line.core.supervision.commands`).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from folder_line.core.mechanisms.cyclogram import cycle_timing
from folder_line.core.mechanisms.drive import Drive
from folder_line.core.numerics.validate import as_float

if TYPE_CHECKING:
    from folder_line.core.line.scene import Scene

__all__ = ['MachineCycles']


class MachineCycles:
    """The machine cycles of a scene (see the module docstring).

    Parameters
    ----------
    scene : Scene

    Attributes
    ----------
    what : {'knife_exit', 'crank_turn'}
    theta0 : float
        Θ at which cycle 0 starts, nominal s.
    period : float
        Cycle length in Θ, nominal s.
    """

    def __init__(self, scene: Scene) -> None:
        if scene.has_folder:
            timing = cycle_timing(scene.machine('cyclogram'), scene.machine('knife'))
            self.what, self.theta0, self.period = 'knife_exit', float(timing.knife.t_out), float(timing.T)
        else:
            self.what, self.theta0, self.period = 'crank_turn', 0.0, 60.0 / float(scene.machine('layup').n_kr)

    def start_phase(self, k: int) -> float:
        """Θ at which cycle k (>= 0) starts: for the folder the knife exit that ends cycle k - 1 (the
        expression of the ``knife_exit`` events, so that the times agree bit for bit)."""
        if self.what == 'knife_exit':
            return self.theta0 if k == 0 else float((k - 1) * self.period + (self.period + self.theta0))
        return float(k * self.period)

    def start_time(self, drive: Drive, k: int, theta_end: float = math.inf) -> float:
        """Line time at which cycle k starts (``inf`` if the drive never gets there, or not by ``theta_end``)."""
        th = self.start_phase(k)
        if th > theta_end:
            return math.inf
        return float(np.asarray(drive.time_of(np.array([th])), dtype=float)[0])

    def index(self, drive: Drive, t: float, theta_end: float = math.inf) -> int:
        """The cycle running at line time ``t``: the last one started at or before ``t`` (-1 before the first)."""
        t = as_float('t', t)
        theta = float(np.asarray(drive.theta(np.array([max(t, 0.0)])), dtype=float)[0])
        k = max(math.floor((theta - self.theta0) / self.period), -1)
        while self.start_time(drive, k + 1, theta_end) <= t:
            k += 1
        while k >= 0 and self.start_time(drive, k, theta_end) > t:
            k -= 1
        return k

    def next_boundary(self, drive: Drive, t: float, theta_end: float = math.inf) -> float:
        """The start of the next cycle strictly after ``t``, s (``inf`` if none: the line stands, or
        ``theta_end`` comes first)."""
        return self.start_time(drive, self.index(drive, t, theta_end) + 1, theta_end)
