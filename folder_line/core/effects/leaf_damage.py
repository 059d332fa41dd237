"""``leaf_damage`` — leaves leaving a chute too fast are damaged (L).

Model (ours: docs/scenes.md, "Effects", leaf_damage; paper 000, last
section): a leaf is damaged when its absolute exit speed reaches the damage speed,

    damaged  ⇔  v_a >= v_damage ,        v_a = sqrt(v_C² + u²)            (paper eq. 25)

with v_C the chute's swing speed at the exit (across the chute) and u the leaf's
speed along the chute (the belt speed v_tr with ``chute_belts``). The paper tried
belt speeds of 2.8 and 5.6 m/s on the prototype: at 5.6 m/s the leaves were
noticeably damaged, at 2.8 m/s not; any ``v_damage`` in (≈3.6, 5.6] m/s reproduces
that with the default six-bar (peak swing speed ≈ 1.0 m/s: 2.8 m/s belts give at
most ≈ 2.98 m/s, 5.6 m/s belts at least 5.6 m/s). Suggested: ``v_damage = 4.5``.

The bound is inclusive for damage, so the *admissible* range of exit speeds is
open at the top: ``v_a < v_damage``. As a constraint margin (negative = violated)
that is encoded exactly in floating point as

    margin = nextafter(v_damage, 0) − v_a ,

which is 0 (admissible) at the largest float below ``v_damage`` and −ulp < 0
(violated) at ``v_a = v_damage`` itself.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from folder_line.core.numerics.validate import check_fields, within

__all__ = ['Params', 'damaged', 'upper_margin']


@dataclass(frozen=True)
class Params:
    """Parameters of ``leaf_damage``.

    Attributes
    ----------
    v_damage : float
        Absolute exit speed at and above which a leaf is damaged, m/s, in (0, 1000].
        Suggested 4.5 (paper: damage at 5.6 m/s, none at 2.8 m/s).
    """

    v_damage: float

    def __post_init__(self) -> None:
        check_fields(self, 'effects.leaf_damage', v_damage=within(0.0, 1e3, lo_open=True))


def damaged(params: Params, speed: npt.ArrayLike) -> np.ndarray:
    """Which leaves are damaged: ``speed >= v_damage``.

    Parameters
    ----------
    params : Params
        The effect's parameters.
    speed : array_like
        Absolute exit speeds, m/s.

    Returns
    -------
    ndarray of bool
    """
    return np.asarray(speed, dtype=float) >= params.v_damage


def upper_margin(params: Params, speed: npt.ArrayLike) -> np.ndarray:
    """Margin of the exclusive upper bound ``speed < v_damage``, m/s (negative: damaged).

    ``nextafter(v_damage, 0) − speed``: exactly 0 at the largest admissible float,
    negative from ``v_damage`` on (see the module docstring).

    Parameters
    ----------
    params : Params
        The effect's parameters.
    speed : array_like
        Absolute exit speeds, m/s.

    Returns
    -------
    ndarray of float
    """
    return math.nextafter(params.v_damage, 0.0) - np.asarray(speed, dtype=np.float64)
