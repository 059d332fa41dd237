"""The figures of a motor drive for reports: :class:`MotorFigures`
(:meth:`folder_line.core.effects.motor_dynamics.MotorDrive.summary`)."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ['MotorFigures']


@dataclass(frozen=True)
class MotorFigures:
    """A motor drive's cost, steady speed factor, stop and rest times.

    Attributes
    ----------
    method : str
        The integrator.
    nfev, steps, rejected : int
        Right-hand-side evaluations, accepted and rejected steps of the integration.
    theta_end : float
        Θ at the end of what is integrated, nominal s.
    t_stop, t_rest : float
        First motor-off switch and first standstill after it, s (``inf`` if none).
    lambda_free : float
        The no-load speed factor ω_free / ω_nom.
    t_periodic, lambda_steady : float or None
        Where the motor-on period repeats, s, and the speed factor over it (None: no period found).
    load_mean, load_peak : float or None
        The chain load's mean and peak torque, N m (None: no load).
    lambda_estimate : float or None
        The steady speed factor estimated from the mean load (None: no load).
    switches : list of (float, bool) or None
        The effective switches ``(t, motor on after t)`` under the supervisor's commands (None: not commanded).
    """

    method: str
    nfev: int
    steps: int
    rejected: int
    theta_end: float
    t_stop: float
    t_rest: float
    lambda_free: float
    t_periodic: float | None = None
    lambda_steady: float | None = None
    load_mean: float | None = None
    load_peak: float | None = None
    lambda_estimate: float | None = None
    switches: list[tuple[float, bool]] | None = None

    def as_json(self) -> dict[str, object]:
        """The JSON document: the fields in order, the optional ones only where known."""
        out: dict[str, object] = {
            'method': self.method,
            'nfev': self.nfev,
            'steps': self.steps,
            'rejected': self.rejected,
            'theta_end': self.theta_end,
            't_stop': self.t_stop,
            't_rest': self.t_rest,
            'lambda_free': self.lambda_free,
        }
        if self.t_periodic is not None:
            out['t_periodic'] = self.t_periodic
            out['lambda_steady'] = self.lambda_steady
        if self.load_mean is not None:
            out['load_mean'] = self.load_mean
            out['load_peak'] = self.load_peak
            out['lambda_estimate'] = self.lambda_estimate
        if self.switches is not None:
            out['switches'] = [[t, on] for t, on in self.switches]
        return out
