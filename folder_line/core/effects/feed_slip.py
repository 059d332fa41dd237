"""``feed_slip`` — the signature is brought from V_d to V_tr by kinetic friction (F).

Source: ours (docs/scenes.md, "Effects", *feed_slip (F)*); docs/machines.md section F (paper
001): the first transporter delivers the signature at the printing speed ``V_d``, the
second (feed) transporter runs at ``V_tr`` (≈ 1.6 V_d) and carries it ``L_feed`` to
the front stops. The paper treats the hand-over as instantaneous (eq. 1,
``t_tr = L / V_tr``); this effect drops that idealisation.

Model
-----
The signature (mass ``m``, kg) lies on the feed belt under a hold-down force ``p``
(N, tapes/brushes pressing it on the belt) and slides until it has the belt's
speed. Kinetic (Coulomb) friction with coefficient ``mu`` gives a constant
acceleration of magnitude::

    a = mu (g + p / m)          g = 9.80665 m/s²

directed towards the belt speed (``V_tr < V_d``: friction decelerates it; both
signs are handled). Starting at ``V0`` (the first transporter's speed) on a belt at
``V1``:

* slip time and slip distance until the speeds match::

      t1 = |V1 - V0| / a ,   d1 = |V1² - V0²| / (2 a)

* if ``d1 < L`` the signature reaches belt speed before the stops and rides the belt
  for the rest (piecewise exact)::

      t = t1 + (L - d1) / V1 ,    impact speed V1

* otherwise it slides all the way: ``V0 t + s a t² / 2 = L`` (``s = ±1``), whose
  root is taken in the cancellation-free form::

      t = 2 L / (V0 + sqrt(V0² + 2 s a L)) ,   impact speed sqrt(V0² + 2 s a L)

  (for ``s = -1`` the radicand is ``>= V1² >= 0`` because ``d1 >= L``).

The time the slip costs over the ideal ride, ``t - L / V1``, is
``sign(V1 - V0) (V1 - V0)² / (2 a V1)`` when it reaches belt speed: a faster belt
eats more of it, a stronger hold-down less.

Variable drive: the simulator (:mod:`folder_line.core.line.folder_sim`) freezes the
speeds at the hand-over, ``V0 = λ_h V_d``, ``V1 = λ_h f_h V_tr`` (λ_h the drive's
speed factor, f_h a belt slow-down factor at the hand-over), for the slip phase
only; after the slip the signature rides the belt, whose travel is integrated
exactly (drive phase and slow-downs). At constant speed this is exact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from folder_line.core.limits import FRICTION_COEFFICIENT
from folder_line.core.numerics.constants import G
from folder_line.core.numerics.validate import check_fields, non_negative, positive
from folder_line.errors import ParameterError

__all__ = ['Params', 'SlipArrival', 'accel', 'arrival', 'min_belt_speed', 'slip_cost']


@dataclass(frozen=True)
class Params:
    """Friction of the signature on the feed belt.

    Attributes
    ----------
    mu : float
        Kinetic friction coefficient signature/belt, dimensionless, in [0.001, 10]
        (:data:`folder_line.core.limits.FRICTION_COEFFICIENT`).
    p : float
        Hold-down force pressing the signature on the belt, N (>= 0).
    m : float
        Signature mass, kg (> 0).
    """

    mu: float
    p: float
    m: float

    def __post_init__(self) -> None:
        check_fields(self, 'effects.feed_slip', mu=FRICTION_COEFFICIENT.check, p=non_negative, m=positive)
        if not math.isfinite(self.accel) or self.accel > 1e9:
            raise ParameterError(
                'effects.feed_slip.p',
                self.p,
                f'p/m = {self.p / self.m!r} N/kg is not a physical hold-down (friction acceleration above 1e9 m/s²)',
            )

    @property
    def accel(self) -> float:
        """Friction acceleration ``mu (g + p / m)``, m/s²."""
        return self.mu * (G + self.p / self.m)


def accel(params: Params) -> float:
    """Friction acceleration ``mu (g + p / m)``, m/s²."""
    return params.accel


@dataclass(frozen=True, eq=False)
class SlipArrival:
    """Arrival at the stops with slip, element-wise over the inputs' broadcast shape.

    Attributes
    ----------
    t : ndarray
        Time from the hand-over to the stops, s.
    v_impact : ndarray
        Speed at the stops, m/s.
    t_slip, d_slip : ndarray
        Time and distance until the speeds match, s and m (``t_slip`` as if the stops
        were not there: ``|V1 - V0| / a``).
    reached : ndarray of bool
        The signature reached belt speed before the stops (``d_slip < L``).
    """

    t: np.ndarray
    v_impact: np.ndarray
    t_slip: np.ndarray
    d_slip: np.ndarray
    reached: np.ndarray


def arrival(
    params: Params, V0: npt.ArrayLike, V1: npt.ArrayLike, L: npt.ArrayLike, mu: npt.ArrayLike | None = None
) -> SlipArrival:
    """Piecewise-exact time and speed at the stops.

    Parameters
    ----------
    params : Params
        Friction.
    V0 : array_like
        Speed at the hand-over (the first transporter's), m/s, >= 0.
    V1 : array_like
        Feed-belt speed, m/s, > 0.
    L : array_like
        Travel to the stops, m, > 0.
    mu : array_like, optional
        A friction coefficient per signature, > 0 (``property_scatter``), broadcast with the
        speeds; None: ``params.mu`` for all.

    Returns
    -------
    SlipArrival
        Arrays of the broadcast shape.

    Raises
    ------
    ParameterError
        A speed negative or not finite, ``V1`` or ``L`` not > 0.
    """
    V0, V1, L = np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in (V0, V1, L)))
    if not (np.all(np.isfinite(V0)) and np.all(V0 >= 0.0)):
        raise ParameterError('V0', V0, 'hand-over speed must be finite and >= 0 (m/s)')
    if not (np.all(np.isfinite(V1)) and np.all(V1 > 0.0)):
        raise ParameterError('V1', V1, 'belt speed must be finite and > 0 (m/s)')
    if not (np.all(np.isfinite(L)) and np.all(L > 0.0)):
        raise ParameterError('L', L, 'travel must be finite and > 0 (m)')
    a = params.accel if mu is None else np.asarray(mu, dtype=float) * (G + params.p / params.m)
    dv = V1 - V0
    s = np.sign(dv)
    t1 = np.abs(dv) / a
    d1 = np.abs(dv) * (V1 + V0) / (2.0 * a)
    reached = d1 < L
    # slides all the way: V0 t + s a t²/2 = L; radicand >= V1² where s < 0 (d1 >= L)
    rad = np.sqrt(np.maximum(V0 * V0 + 2.0 * s * a * L, 0.0))
    with np.errstate(divide='ignore', invalid='ignore'):
        t_slide = np.where(V0 + rad > 0.0, 2.0 * L / np.where(V0 + rad > 0.0, V0 + rad, 1.0), 0.0)
    t = np.where(reached, t1 + (L - np.minimum(d1, L)) / V1, t_slide)
    v = np.where(reached, V1, rad)
    return SlipArrival(t, v, t1, d1, reached)


def slip_cost(params: Params, V0: npt.ArrayLike, V1: npt.ArrayLike, L: npt.ArrayLike) -> np.ndarray:
    """Time the slip adds to the ideal ride ``L / V1``, s (negative if it saves time).

    Parameters
    ----------
    params : Params
        Friction.
    V0, V1, L : array_like
        As in :func:`arrival`.
    """
    return arrival(params, V0, V1, L).t - np.asarray(L, dtype=np.float64) / np.asarray(V1, dtype=np.float64)


def min_belt_speed(params: Params, V_d: float, L: float, t_allowed: float) -> float:
    """Slowest feed belt ``V_tr >= V_d`` that brings the signature to the stops within ``t_allowed``.

    With slip the feed time is ``L / V + (V - V_d)² / (2 a V)`` while the signature
    reaches belt speed (``V <= V* = sqrt(V_d² + 2 a L)``), and beyond ``V*`` it no
    longer depends on V. Setting it equal to ``t_allowed`` gives the quadratic
    ``V² - 2 (V_d + a t_allowed) V + V_d² + 2 a L = 0``, whose smaller root is taken in
    the stable form ``c / (b + sqrt(b² - c))``.

    Parameters
    ----------
    params : Params
        Friction.
    V_d : float
        Hand-over speed, m/s (> 0).
    L : float
        Feed travel, m (> 0).
    t_allowed : float
        Time the feed may use, s (> 0).

    Returns
    -------
    float
        m/s; ``V_d`` itself if the signature is in time without speed-up.

    Raises
    ------
    ParameterError
        No belt speed is fast enough (the slide at full friction from ``V_d`` over
        ``L`` already takes longer than ``t_allowed``).
    """
    V_d, L, t_al = positive('V_d', V_d), positive('L', L), positive('t_allowed', t_allowed)
    if V_d * t_al >= L:
        return V_d
    a = params.accel
    b = V_d + a * t_al
    c = V_d * V_d + 2.0 * a * L
    disc = b * b - c
    v_star = math.sqrt(c)
    t_star = 2.0 * L / (V_d + v_star)  # fastest possible feed: friction all the way
    if disc < 0.0 or t_star > t_al:
        raise ParameterError(
            'effects.feed_slip',
            params,
            f'no belt speed feeds {L!r} m within {t_al!r} s: at full friction '
            f'a = {a!r} m/s² the signature needs {t_star!r} s',
        )
    v = c / (b + math.sqrt(disc))
    return min(v, v_star)
