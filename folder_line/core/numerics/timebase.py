"""Drift-free crank phase from integer time.

Line time is kept as an integer count of nanoseconds (as ROS 2 stamps are), and a
constant shaft speed as an exact rational number of revolutions per second, so the
phase after any number of turns is computed with integer arithmetic: no angle is
accumulated, nothing drifts, and ``phase_at(k * period)`` is exactly 0 for every
whole number of turns k that the period represents exactly.

A float time t (s) near 1e7 s is itself only known to about 2e-9 s; integers are
exact up to 2**63 ns (292 years).
"""

from __future__ import annotations

import math
from fractions import Fraction

from folder_line.core.numerics.validate import positive

__all__ = ['NS_PER_S', 'ShaftClock', 'seconds_to_ns']

#: nanoseconds per second (the one definition; :mod:`folder_line.interfaces` re-exports it)
NS_PER_S = 1_000_000_000


def seconds_to_ns(seconds: float) -> int:
    """Round a time in seconds to integer nanoseconds, exactly.

    The float's exact binary value is rounded (half to even), so
    ``seconds_to_ns(0.1) == 100_000_000`` with no ``0.1 * 1e9`` error.

    Parameters
    ----------
    seconds : float
        Finite time, s.

    Returns
    -------
    int
        Time, ns.

    Raises
    ------
    ValueError
        ``seconds`` is NaN or infinite.
    """
    if not math.isfinite(seconds):
        msg = f'seconds={seconds!r}: must be finite'
        raise ValueError(msg)
    return round(Fraction(seconds) * NS_PER_S)


class ShaftClock:
    """Exact phase of a shaft turning at a constant speed.

    Parameters
    ----------
    rev_per_s : float or Fraction
        Shaft speed, rev/s (> 0). A float is taken at its exact binary value; pass
        ``Fraction(50000, 3600)`` for an exactly rational speed such as 50000 rev/h.
    phase0 : float
        Phase at t = 0, in turns (fraction of a revolution), default 0.
    """

    __slots__ = ('_den', '_num', '_phase0', 'rev_per_s')

    def __init__(self, rev_per_s: float | Fraction, phase0: float = 0.0) -> None:
        speed = Fraction(rev_per_s) if isinstance(rev_per_s, Fraction) else Fraction(positive('rev_per_s', rev_per_s))
        if speed <= 0:
            msg = f'rev_per_s={rev_per_s!r}: must be > 0'
            raise ValueError(msg)
        self.rev_per_s = speed
        # turns(t_ns) = t_ns * num / den, exactly
        self._num = speed.numerator
        self._den = speed.denominator * NS_PER_S
        self._phase0 = Fraction(phase0) % 1

    def turns(self, t_ns: int) -> tuple[int, float]:
        """Whole turns completed and the fraction of the current turn at ``t_ns``.

        Returns
        -------
        whole : int
            Completed revolutions (floor; negative before t = 0).
        frac : float
            Fraction of a revolution in [0, 1), to float rounding only.
        """
        n = int(t_ns) * self._num * self._phase0.denominator + self._phase0.numerator * self._den
        d = self._den * self._phase0.denominator
        whole, rem = divmod(n, d)
        return whole, rem / d

    def angle(self, t_ns: int) -> float:
        """Shaft angle in [0, 2π) at ``t_ns``, rad."""
        return 2.0 * math.pi * self.turns(t_ns)[1]

    def period_ns(self) -> Fraction:
        """Exact period in nanoseconds (a Fraction)."""
        return Fraction(NS_PER_S) / self.rev_per_s

    def time_of_turn(self, whole: int, frac: float = 0.0) -> int:
        """Nearest integer nanosecond at which the shaft reaches ``whole + frac`` turns."""
        target = Fraction(whole) + Fraction(frac) - self._phase0
        return round(target / self.rev_per_s * NS_PER_S)
