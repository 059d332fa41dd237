"""``speed_ripple`` — a periodic ripple of the master drive's speed, locked to its phase (any machine).

Source: issue #13, item 5 ("drive speed ripple"). A gear's eccentricity or a motor's
cogging makes the drive speed ripple once per turn of some shaft, so the ripple is
locked to the machine's phase, not to the clock: it stands still when the drive does.

Model
-----
The drive without the ripple (the scene's profile with the supervisor's commands,
or the motor ODE) gives ``Θ_b(t)``, ``λ_b(t)``. The ripple maps that phase through::

    g(φ) = φ + (A / ω) (sin(ω φ + ψ) - sin ψ)      ω = 2π f,   g(0) = 0
    Θ(t) = g(Θ_b(t)),     λ(t) = g'(Θ_b) λ_b = (1 + A cos(ω Θ_b + ψ)) λ_b

so the speed factor has the relative amplitude ``A`` at ``f`` cycles per nominal second
of master phase (Hz at nominal speed), with phase ``ψ`` drawn once per run, uniform
in [0, 2π), from the scene seed's stream ``drive.speed_ripple``. On a constant drive
``Θ(t) = t + (A/ω)(sin(ω t + ψ) - sin ψ)`` in closed form, and ``Θ`` still advances
by exactly one nominal second per nominal second on average: the line's mean speed is
the nominal one. ``A < 1`` keeps ``g`` strictly increasing (``g' >= 1 - A > 0``).

Inverse: ``time_of(θ) = time_of_b(g⁻¹(θ))``; ``g⁻¹`` is found by Newton's method
safeguarded by bisection inside the bracket ``[θ - 2A/ω, θ + 2A/ω]`` to the last bit
(:func:`phase_inverse`). The supervisor's commands act on ``Θ_b`` (holds, restarts
and their causality, :mod:`folder_line.core.mechanisms.drive`) and the ripple is a
fixed map on top, so everything that held there still holds: a command changes
nothing before its time, and a held drive stands still.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from folder_line.core.mechanisms.drive import Drive, target_rate, theta_rate
from folder_line.core.numerics.rng import stream
from folder_line.core.numerics.validate import check_fields, within
from folder_line.errors import ParameterError

__all__ = ['Params', 'RippleDrive', 'draw_phase', 'phase_inverse', 'phase_map']

#: name of the seeded stream of the ripple's phase
STREAM = 'drive.speed_ripple'
#: most Newton/bisection steps of the inverse (it needs ~6)
_MAX_STEPS = 200


@dataclass(frozen=True)
class Params:
    """Ripple of the master drive's speed.

    Attributes
    ----------
    amplitude : float
        Relative amplitude A of the speed factor, dimensionless, in [0, 0.5].
    frequency : float
        Ripple cycles per nominal second of master phase (at nominal speed), Hz, in (0, 10000].
    """

    amplitude: float
    frequency: float

    def __post_init__(self) -> None:
        check_fields(self, 'effects.speed_ripple', amplitude=within(0.0, 0.5), frequency=within(0.0, 1e4, lo_open=True))


def draw_phase(seed: int) -> float:
    """The ripple's phase ψ of a scene seeded ``seed``, rad in [0, 2π)."""
    return float(stream(seed, STREAM).random()) * 2.0 * math.pi


def phase_map(params: Params, psi: float, phi: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``g(φ)``, ``g'(φ)`` and ``g''(φ)`` (nominal s, 1, 1/nominal s) at the base phase ``φ``."""
    p = np.asarray(phi, dtype=float)
    A, w = params.amplitude, 2.0 * math.pi * params.frequency
    arg = w * p + psi
    return p + (A / w) * (np.sin(arg) - math.sin(psi)), 1.0 + A * np.cos(arg), -A * w * np.sin(arg)


def phase_inverse(params: Params, psi: float, theta: npt.ArrayLike) -> np.ndarray:
    """``g⁻¹(θ)``: the base phase that the ripple maps to ``θ``, nominal s (to the last bit).

    Newton's method from ``θ``, each step kept inside the shrinking bracket
    ``[θ - 2A/ω, θ + 2A/ω]`` (a step that leaves it bisects instead). Each element stops on
    its own convergence, so its value does not depend on the other elements.
    """
    th = np.asarray(theta, dtype=float)
    if not np.all(np.isfinite(th)):
        raise ParameterError('theta', theta, 'must be finite')
    A, w = params.amplitude, 2.0 * math.pi * params.frequency
    if A == 0.0:
        return th.copy()
    reach = 2.0 * A / w
    flat = th.reshape(-1)
    out = flat.copy()
    active = np.arange(flat.size)
    target = flat
    lo, hi = flat - reach, flat + reach
    phi = flat.copy()
    for _ in range(_MAX_STEPS):
        g, dg, _ = phase_map(params, psi, phi)
        f = g - target
        lo = np.where(f < 0.0, phi, lo)
        hi = np.where(f > 0.0, phi, hi)
        new = phi - f / dg
        new = np.where((new > lo) & (new < hi), new, 0.5 * (lo + hi))
        new = np.where(f == 0.0, phi, new)
        done = np.abs(new - phi) <= 2.0 * np.spacing(np.abs(phi) + reach)
        out[active[done]] = new[done]
        keep = ~done
        if not keep.any():
            return out.reshape(th.shape)
        active, target, lo, hi, phi = active[keep], target[keep], lo[keep], hi[keep], new[keep]
    out[active] = phi  # pragma: no cover - Newton converges quadratically in a handful of steps
    return out.reshape(th.shape)


class RippleDrive:
    """A drive with its speed rippled by :func:`phase_map` (module docstring).

    Parameters
    ----------
    base : Drive
        The drive without the ripple (profile with commands, or the motor's).
    params : Params
        Amplitude and frequency.
    psi : float
        Phase of the ripple, rad (:func:`draw_phase`).
    """

    def __init__(self, base: Drive, params: Params, psi: float) -> None:
        self.base = base
        self.params = params
        self.psi = float(psi)

    def theta(self, t: npt.ArrayLike) -> np.ndarray:
        """Θ(t) = g(Θ_b(t)), nominal s."""
        g: np.ndarray = phase_map(self.params, self.psi, self.base.theta(t))[0]
        return g

    def rate(self, t: npt.ArrayLike) -> np.ndarray:
        """λ(t) = g'(Θ_b) λ_b."""
        th, lam = theta_rate(self.base, t)
        dg: np.ndarray = phase_map(self.params, self.psi, th)[1]
        return np.asarray(dg * lam, dtype=float)

    def theta_rate(self, t: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """``(Θ(t), λ(t))`` in one pass (the same values as :meth:`theta` and :meth:`rate`)."""
        th, lam = theta_rate(self.base, t)
        g, dg, _ = phase_map(self.params, self.psi, th)
        return g, dg * lam

    def rate_dot(self, t: npt.ArrayLike) -> np.ndarray:
        """dλ/dt = g''(Θ_b) λ_b² + g'(Θ_b) dλ_b/dt, 1/s."""
        th, lam = theta_rate(self.base, t)
        _, dg, ddg = phase_map(self.params, self.psi, th)
        return np.asarray(ddg * lam * lam + dg * np.asarray(self.base.rate_dot(t), dtype=float), dtype=float)

    def target_rate(self, t: npt.ArrayLike) -> np.ndarray:
        """The running speed the base drive heads for (the ripple rides on it)."""
        return target_rate(self.base, t)

    def time_of(self, theta: npt.ArrayLike) -> np.ndarray:
        """Earliest t with Θ(t) = theta: ``time_of_b(g⁻¹(theta))``, s."""
        return np.asarray(self.base.time_of(phase_inverse(self.params, self.psi, theta)), dtype=float)
