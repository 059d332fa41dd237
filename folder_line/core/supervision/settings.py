"""The supervisor's parameters, checked once: :class:`Settings`.

Every number the supervisor's logic (:class:`folder_line.core.supervision.supervisor.Supervisor`)
takes from its caller is checked here, at the entry, with an error that names the
parameter (:class:`folder_line.errors.ParameterError`); the parts of the logic then take
the frozen result as it is.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from folder_line.core.numerics.validate import as_float, one_of, positive
from folder_line.errors import ParameterError

__all__ = ['CHECK_PERIOD', 'SPEED_REACHED', 'STALE_PERIODS', 'Settings']

#: speed factor at which a run command's acting state ends
SPEED_REACHED = 0.99
#: default spacing of the check grid, s
CHECK_PERIOD = 0.005
#: default k: periods (and clock ticks) a node may stay silent
STALE_PERIODS = 10.0


@dataclass(frozen=True)
class Settings:
    """The supervisor's checked parameters (see :class:`~folder_line.core.supervision.supervisor.Supervisor`).

    Attributes
    ----------
    stale_periods : float
        ``k``: a node is stale when not heard within ``k`` periods (> 0).
    lead : float
        Earliest effective time of a drive command after its decision, s (finite, >= 0).
    check_period : float
        Spacing ``h`` of the check grid, s (> 0).
    enforce : bool
        Command holds, suspends and aborts (else only record violations).
    double : {'hold', 'abort'}
        What a double sheet leads to.
    speed_reached : float
        Speed factor in (0, 1] at which a run command's acting state ends.

    Raises
    ------
    ParameterError
        On construction, naming the first bad parameter (in the order above).
    """

    stale_periods: float = STALE_PERIODS
    lead: float = 0.0
    check_period: float = CHECK_PERIOD
    enforce: bool = True
    double: str = 'hold'
    speed_reached: float = SPEED_REACHED

    def __post_init__(self) -> None:
        object.__setattr__(self, 'stale_periods', positive('stale_periods', self.stale_periods))
        lead = as_float('lead', self.lead)
        if not (math.isfinite(lead) and lead >= 0.0):
            raise ParameterError('lead', self.lead, 'must be finite and >= 0')
        object.__setattr__(self, 'lead', lead)
        object.__setattr__(self, 'check_period', positive('check_period', self.check_period))
        object.__setattr__(self, 'enforce', bool(self.enforce))
        object.__setattr__(self, 'double', one_of('double', self.double, ('hold', 'abort')))
        speed = as_float('speed_reached', self.speed_reached)
        if not 0.0 < speed <= 1.0:
            raise ParameterError('speed_reached', self.speed_reached, 'must be in (0, 1]')
        object.__setattr__(self, 'speed_reached', speed)
