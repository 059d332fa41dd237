"""``chute_belts`` — belts along the chutes carry the leaves at v_tr (L).

The paper's remedy (paper 000, after eq. 24; docs/machines.md, section L): belts
on the guides O2C and O3E, driven synchronously at ``v_tr`` along the chutes, so that
the absolute exit speed of a leaf

    v_aC = sqrt(v_C² + v_tr²) ,   v_aE = sqrt(v_E² + v_tr²)                    (25)

no longer drops to zero at the swing extremes (where v_C = v_E = 0).

Model
-----
* Entry. A leaf enters its chute at the pivot end, at distance ``s_in = 0`` from the
  pivot (O2 for transporter 3, O3 for transporter 4), and rides the belt without
  slipping to the exit, a belt travel of ``l = l3`` (resp. ``l5``). The chute swings
  meanwhile; the belt runs along the chute, so the leaf's distance from the pivot is
  the belt travel whatever the swing does.
* Belt speed. The belt (motor 9) is geared to the master drive like every speed of
  the line (:mod:`folder_line.core.mechanisms.drive`): it runs at ``v_tr · λ(t) · f(t)`` with λ
  the drive's speed factor and ``f`` the belt slow-down factor of the ``faults``
  effect (1 without faults). Its travel since t = 0 is

      P(t) = v_tr ∫₀ᵗ λ f dt = P(b_i) + v_tr f_i (Θ(t) − Θ(b_i))   for b_i <= t < b_{i+1}

  with ``b_i`` the slow-down boundaries (f piecewise constant) and Θ the master
  phase: exact, no quadrature (:class:`folder_line.core.mechanisms.belt.BeltPhase`, shared with
  the folder's feed belt).
* Exit time. The leaf leaves when the belt has moved ``l`` since its entry,
  ``P(t_exit) = P(t_enter) + l``; inverting the piecewise form,

      Θ* = Θ(b_i) + (P(t_enter) + l − P(b_i)) / (v_tr f_i) ,   t_exit = drive.time_of(Θ*)

  which without slow-downs is ``t_exit = drive.time_of(Θ(t_enter) + l / v_tr)`` and
  with the constant drive ``t_exit = t_enter + l / v_tr``: exact (closed form).
* Exit velocity. ``v_C n̂ + v_belt t̂`` with t̂ the unit vector along the chute from
  the pivot to the exit and n̂ = ẑ × t̂ (the direction the exit moves when the chute
  turns counter-clockwise); absolute speed eq. (25) with ``v_tr`` replaced by the
  belt's actual speed at the exit instant.

Constraint ``chute_speed`` (per leaf, m/s): the absolute exit speed must be at least
``v_min`` (margin ``v_a − v_min``), and, if ``leaf_damage`` is listed, below its
``v_damage`` (exclusive; margin from :func:`folder_line.core.effects.leaf_damage.upper_margin`);
the margin is the smaller of the two.

What the model shows (default geometry, drag-free flight, every crank phase sampled,
1 h): the landing coefficient of variation across the width drops from 0.716 without
belts to 0.518 with 2.8 m/s belts. A fast leaf keeps the chute's direction, so it
lands near where the chute's axis meets the floor (x_exit + H tan θ'), which spreads
the layup by H tan θ' beyond the exits' sweep and fills the wall bins; without
belts the leaf leaves across the chute at v_C only. Above ~2 m/s the pattern hardly
depends on the belt speed (landing_cv 0.518–0.526 for 2–5.6 m/s, 0.547 at 1 m/s).

Suggested parameters: ``v_min = 2.0`` m/s (a floor under the paper's 2.8 m/s belts;
with the default geometry 2.8 m/s belts land drag-free leaves 0.03 m inside the
walls).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from folder_line.core.mechanisms.belt import BeltPhase
from folder_line.core.mechanisms.drive import Drive
from folder_line.core.numerics.validate import check_fields, within
from folder_line.errors import ParameterError

__all__ = [
    'BeltProfile',
    'Params',
    'absolute_speed',
    'belt_position',
    'belt_profile',
    'belt_speed',
    'check_belt_speed',
    'exit_times',
    'speed_margin',
]


@dataclass(frozen=True)
class Params:
    """Parameters of ``chute_belts`` (the belt speed itself is ``layup.v_tr``).

    Attributes
    ----------
    v_min : float
        Smallest admissible absolute exit speed of a leaf, m/s, in [0, 1000]; the
        ``chute_speed`` constraint. Suggested 2.0.
    """

    v_min: float

    def __post_init__(self) -> None:
        check_fields(self, 'effects.chute_belts', v_min=within(0.0, 1e3))


@dataclass(frozen=True, eq=False)
class BeltProfile:
    """The chute belt: nominal speed and its phase under slow-downs.

    Attributes
    ----------
    v_tr : float
        Nominal belt speed, m/s (> 0).
    phase : BeltPhase
        Belt phase ``B(t)`` (nominal s; travel ``v_tr B``) with the slow-downs,
        :class:`folder_line.core.mechanisms.belt.BeltPhase`.
    """

    v_tr: float
    phase: BeltPhase


def check_belt_speed(v_tr: float) -> float:
    """The belt speed, which must be > 0 when the belts are on.

    Raises
    ------
    ParameterError
        ``layup.v_tr <= 0``: a leaf would never reach the exit.
    """
    if not v_tr > 0.0:
        raise ParameterError(
            'layup.v_tr', v_tr, 'must be > 0 when the scene lists chute_belts (the leaves ride the belts to the exits)'
        )
    return float(v_tr)


def belt_profile(
    v_tr: float,
    drive: Drive,
    duration: float,
    t_start: npt.ArrayLike | None = None,
    t_end: npt.ArrayLike | None = None,
    factor: npt.ArrayLike | None = None,
) -> BeltProfile:
    """The belt's speed profile over [0, duration].

    Parameters
    ----------
    v_tr : float
        Nominal belt speed, m/s (> 0).
    drive : Drive
        The master drive.
    duration : float
        Simulated line time, s.
    t_start, t_end, factor : array_like, optional
        Belt slow-downs ``[t_start, t_end)`` (s, sorted, non-overlapping) with their
        speed factors (the ``faults`` effect's ``Slowdowns``); none if omitted.

    Returns
    -------
    BeltProfile
    """
    return BeltProfile(float(v_tr), BeltPhase(drive, duration, t_start, t_end, factor))


def belt_position(profile: BeltProfile, drive: Drive, t: npt.ArrayLike) -> np.ndarray:
    """Belt travel since t = 0, m: ``v_tr B(t)`` (exact, piecewise linear in Θ).

    Parameters
    ----------
    profile : BeltProfile
        From :func:`belt_profile`.
    drive : Drive
        The master drive (the one the profile was built with).
    t : array_like
        Times in [0, duration], s.
    """
    return profile.v_tr * profile.phase.at(t)


def belt_speed(profile: BeltProfile, drive: Drive, t: npt.ArrayLike) -> np.ndarray:
    """Belt speed ``v_tr λ(t) f(t)``, m/s."""
    t = np.asarray(t, dtype=np.float64)
    return profile.v_tr * np.asarray(drive.rate(t), dtype=np.float64) * profile.phase.factor(t)


def exit_times(
    profile: BeltProfile, drive: Drive, length: npt.ArrayLike, t_enter: npt.ArrayLike, theta_end: float
) -> tuple[np.ndarray, np.ndarray]:
    """When leaves that enter at ``t_enter`` (at the pivot) leave the exit ``length`` m down the belt.

    Parameters
    ----------
    profile : BeltProfile
        From :func:`belt_profile`.
    drive : Drive
        The master drive.
    length : array_like
        Chute length per leaf (l3 or l5), m.
    t_enter : array_like
        Entry times, s, in [0, duration].
    theta_end : float
        Θ(duration): exits beyond it are not reached in the run.

    Returns
    -------
    t_exit : ndarray
        Exit times, s (where ``reached``; ``t_enter`` elsewhere, never inf/NaN).
    reached : ndarray of bool
        The leaf exits within the run.
    """
    t_enter = np.asarray(t_enter, dtype=float)
    length = np.broadcast_to(np.asarray(length, dtype=float), t_enter.shape)
    ph = profile.phase
    with np.errstate(over='ignore'):  # a subnormal v_tr: the travel time overflows to inf, the leaf never exits
        theta_x = ph.theta_of(ph.at(t_enter) + length / profile.v_tr)
    reached = theta_x <= theta_end
    t_exit = t_enter.copy()
    if reached.any():
        t_exit[reached] = np.asarray(drive.time_of(theta_x[reached]), dtype=float)
    return t_exit, reached


def absolute_speed(v_across: npt.ArrayLike, v_along: npt.ArrayLike) -> np.ndarray:
    """Paper eq. (25): ``sqrt(v_across² + v_along²)``, m/s."""
    a = np.asarray(v_across, dtype=np.float64)
    b = np.asarray(v_along, dtype=np.float64)
    return np.sqrt(a * a + b * b)


def speed_margin(params: Params, speed: npt.ArrayLike, upper: np.ndarray | None = None) -> np.ndarray:
    """Margin of the ``chute_speed`` constraint, m/s (negative: violated).

    Parameters
    ----------
    params : Params
        The effect's parameters.
    speed : array_like
        Absolute exit speeds, m/s.
    upper : ndarray, optional
        Margin of the upper bound (``leaf_damage.upper_margin``), m/s; the result is
        the smaller of the two margins.

    Returns
    -------
    ndarray of float
    """
    m = np.asarray(speed, dtype=float) - params.v_min
    return m if upper is None else np.minimum(m, upper)
