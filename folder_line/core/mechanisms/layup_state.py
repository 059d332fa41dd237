"""What the layup kinematics return: one crank position, many, and the toggle margins of a turn.

:class:`LayupPoint` comes from the scalar path, :class:`LayupState` from the vectorised one
(:class:`folder_line.core.mechanisms.layup.LayupModel`), :class:`AssemblyMargins` from
:func:`folder_line.core.mechanisms.layup.check_assembly`.

The outputs: θ3, θ5 (angles of O2C and O3E from +x, rad, in (-π, π]); ω3, ω5 (rad/s) and
ε3, ε5 (rad/s²) from the differentiated loop equations; the exit speeds across the
chutes ``v_C = ω3 l3``, ``v_E = ω5 l5`` (signed, m/s) and, with the belt speed
``v_tr`` along the chutes, the absolute exit speeds ``v_aC = sqrt(v_C² + v_tr²)``,
``v_aE = sqrt(v_E² + v_tr²)`` (paper eq. 25).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

__all__ = ['AssemblyMargins', 'LayupPoint', 'LayupState']


class LayupPoint(NamedTuple):
    """One crank position from the scalar path (:meth:`folder_line.core.mechanisms.layup.LayupModel.point`).

    Fields: exits ``xC, yC, xE, yE`` (m); chute angles ``theta3, theta5`` (rad, from +x);
    ``omega3, omega5`` (rad/s, signed); exit speeds across the chutes ``vC, vE`` (m/s,
    signed); absolute exit speeds with the belts ``vaC, vaE`` (m/s).
    """

    xC: float
    yC: float
    xE: float
    yE: float
    theta3: float
    theta5: float
    omega3: float
    omega5: float
    vC: float
    vE: float
    vaC: float
    vaE: float


@dataclass(frozen=True)
class LayupState:
    """Vectorised kinematics; every array has the shape of ``phi``.

    From :meth:`folder_line.core.mechanisms.layup.LayupModel.arrays`.

    Attributes
    ----------
    phi : ndarray
        Crank angles as given, rad.
    xA, yA, xB, yB, xC, yC, xE, yE : ndarray
        Joints A (crank pin), B (rod on chute 3), C and E (chute exits), m.
    theta3, theta5 : ndarray
        Angles of O2C and O3E from +x, rad, in (-π, π].
    omega3, omega5 : ndarray
        Their angular velocities, rad/s.
    eps3, eps5 : ndarray or None
        Their angular accelerations, rad/s² (None when not requested).
    vC, vE : ndarray
        Exit speeds across the chutes ``ω3 l3``, ``ω5 l5``, m/s (signed).
    vaC, vaE : ndarray
        Absolute exit speeds with the belts, ``sqrt(v² + v_tr²)``, m/s.
    margin1, margin2 : ndarray
        Toggle margins of the loops: sine of the transmission angle (at B between
        BA and BO2; at E between EC and EO3), in (0, 1]; 0 would be a toggle.
    """

    phi: np.ndarray
    xA: np.ndarray
    yA: np.ndarray
    xB: np.ndarray
    yB: np.ndarray
    xC: np.ndarray
    yC: np.ndarray
    xE: np.ndarray
    yE: np.ndarray
    theta3: np.ndarray
    theta5: np.ndarray
    omega3: np.ndarray
    omega5: np.ndarray
    eps3: np.ndarray | None
    eps5: np.ndarray | None
    vC: np.ndarray
    vE: np.ndarray
    vaC: np.ndarray
    vaE: np.ndarray
    margin1: np.ndarray
    margin2: np.ndarray


_ROWS = (
    'xA',
    'yA',
    'xB',
    'yB',
    'xC',
    'yC',
    'xE',
    'yE',
    'theta3',
    'theta5',
    'omega3',
    'omega5',
    'vC',
    'vE',
    'vaC',
    'vaE',
    'margin1',
    'margin2',
    'eps3',
    'eps5',
)


class AssemblyMargins(NamedTuple):
    """Toggle margins over a crank turn (:func:`folder_line.core.mechanisms.layup.check_assembly`).

    Fields: ``margin1``, ``margin2`` — smallest sine of the transmission angle of
    loops O1-A-B-O2 and O2-C-E-O3 (dimensionless); ``phi1``, ``phi2`` — crank angles
    where they occur, rad in [0, 2π).
    """

    margin1: float
    phi1: float
    margin2: float
    phi2: float
