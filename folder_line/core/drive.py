"""The master drive: the map between line time t and master phase Θ.

Every shaft and belt of the line is geared to the master drive. The drive turns at
a speed factor λ(t) = dΘ/dt of its nominal speed (λ = 1 in steady running), so a
machine whose nominal shaft speed is ω turns through ω·Θ(t) rad by time t, and a
belt of nominal speed V has advanced V·Θ(t) m. Kinematic events therefore sit at
fixed Θ whatever the drive does, and :meth:`Drive.time_of` turns them into exact
times. Θ is in "nominal seconds".

Profiles: :class:`ConstantDrive` (λ = 1, Θ = t: costs nothing),
:class:`RampDrive` (linear spin-up), and the ``motor_dynamics`` effect's ODE drive
(:mod:`folder_line.core.effects.motor_dynamics`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from folder_line.core.validate import non_negative, one_of

__all__ = ['DRIVE_PROFILES', 'ConstantDrive', 'Drive', 'DriveSpec', 'RampDrive', 'build_drive']

DRIVE_PROFILES = ('constant', 'ramp')


@runtime_checkable
class Drive(Protocol):
    """What the simulator needs from the master drive (all vectorised over arrays)."""

    def theta(self, t: npt.ArrayLike) -> np.ndarray:
        """Master phase Θ(t), nominal s, for t in [0, duration]."""
        ...

    def rate(self, t: npt.ArrayLike) -> np.ndarray:
        """Speed factor λ(t) = dΘ/dt, dimensionless (1 = nominal)."""
        ...

    def rate_dot(self, t: npt.ArrayLike) -> np.ndarray:
        """dλ/dt, 1/s."""
        ...

    def time_of(self, theta: npt.ArrayLike) -> np.ndarray:
        """Inverse of Θ(t): the earliest t with Θ(t) = theta, s. ``theta`` must lie in
        [Θ(0), Θ(duration)]; callers drop events beyond :meth:`theta` of the duration."""
        ...


@dataclass(frozen=True)
class DriveSpec:
    """The scene's ``drive`` section.

    Attributes
    ----------
    profile : {'constant', 'ramp'}
        ``constant``: nominal speed from t = 0. ``ramp``: λ rises linearly from 0 to 1
        over ``t_ramp`` s, then stays at 1. Ignored when the scene lists
        ``motor_dynamics`` (the motor's ODE sets λ).
    t_ramp : float
        Ramp time, s (> 0 for ``ramp``; ignored for ``constant``).
    """

    profile: str
    t_ramp: float = 0.0

    def __post_init__(self) -> None:
        one_of('drive.profile', self.profile, DRIVE_PROFILES)
        object.__setattr__(self, 't_ramp', non_negative('drive.t_ramp', self.t_ramp))
        if self.profile == 'ramp' and self.t_ramp <= 0.0:
            from folder_line.errors import ParameterError

            raise ParameterError('drive.t_ramp', self.t_ramp, 'must be > 0 for profile ramp')


class ConstantDrive:
    """λ = 1: Θ = t."""

    def theta(self, t: npt.ArrayLike) -> np.ndarray:
        return np.array(t, dtype=float)

    def rate(self, t: npt.ArrayLike) -> np.ndarray:
        return np.ones_like(np.asarray(t, dtype=float))

    def rate_dot(self, t: npt.ArrayLike) -> np.ndarray:
        return np.zeros_like(np.asarray(t, dtype=float))

    def time_of(self, theta: npt.ArrayLike) -> np.ndarray:
        return np.array(theta, dtype=float)


class RampDrive:
    """λ = t / t_ramp for t < t_ramp, then 1: Θ = t²/(2 t_ramp), then t − t_ramp/2.

    Parameters
    ----------
    t_ramp : float
        Ramp time, s (> 0).
    """

    def __init__(self, t_ramp: float) -> None:
        self.t_ramp = float(t_ramp)

    def theta(self, t: npt.ArrayLike) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        tr = self.t_ramp
        return np.where(t < tr, t * t / (2.0 * tr), t - 0.5 * tr)

    def rate(self, t: npt.ArrayLike) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        return np.minimum(t / self.t_ramp, 1.0)

    def rate_dot(self, t: npt.ArrayLike) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        return np.where(t < self.t_ramp, 1.0 / self.t_ramp, 0.0)

    def time_of(self, theta: npt.ArrayLike) -> np.ndarray:
        th = np.asarray(theta, dtype=float)
        tr = self.t_ramp
        return np.where(th < 0.5 * tr, np.sqrt(2.0 * tr * np.maximum(th, 0.0)), th + 0.5 * tr)


def build_drive(spec: DriveSpec) -> ConstantDrive | RampDrive:
    """The drive of a scene without ``motor_dynamics``."""
    if spec.profile == 'ramp':
        return RampDrive(spec.t_ramp)
    return ConstantDrive()
