"""What the delivery transporter's model returns (:mod:`folder_line.core.mechanisms.delivery`).

:class:`DeliverySamples` (arrays) and :class:`DeliveryPoint` (one sample) hold the
kinematics, efficiencies, force ratios and a state code per sample (:data:`STATE_NAMES`);
:class:`DeliveryForces` the forces for one useful carriage force and sprocket radius. What a
sample that is not ``'ok'`` holds is told in the delivery module's docstring, section States.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from folder_line.core.numerics.arrays import BoolArray, FloatArray, Int8Array
from folder_line.core.numerics.validate import as_float, non_negative, positive
from folder_line.errors import ParameterError

__all__ = [
    'SAMPLE_FIELDS',
    'SECTION_ACCELERATION',
    'SECTION_DECELERATION',
    'SECTION_NAMES',
    'STATE_CARRIAGE_REVERSED',
    'STATE_KV_ZERO',
    'STATE_NAMES',
    'STATE_OK',
    'STATE_SELF_LOCKING',
    'DeliveryForces',
    'DeliveryPoint',
    'DeliverySamples',
    'StateCoded',
    'state_names',
]

STATE_OK = 0
STATE_SELF_LOCKING = 1
STATE_KV_ZERO = 2
STATE_CARRIAGE_REVERSED = 3
#: state code -> name (for CSV and diagnostics)
STATE_NAMES: tuple[str, ...] = ('ok', 'self_locking', 'kv_zero', 'carriage_reversed')

SECTION_DECELERATION = 0
SECTION_ACCELERATION = 1
#: section code -> the paper's name of the section
SECTION_NAMES: tuple[str, ...] = ('deceleration', 'acceleration')


@dataclass(frozen=True, eq=False)
class DeliveryForces:
    """Forces at the samples for one useful carriage force ``P_k`` and sprocket radius ``r``.

    All arrays share the samples' shape; 0.0 wherever the state is not ``'ok'``.

    Attributes
    ----------
    P_AB, P_ch : ndarray
        Rod force (eq. 1) and chain pull (eq. 4), N.
    M_1 : ndarray
        Sprocket torque (eq. 7), N m.
    P_AB_ideal, P_ch_ideal, M_1_ideal : ndarray
        The same with all friction coefficients zero: ``P_k / cos(alpha)``,
        ``P_AB_ideal cos(alpha - beta) = K_v P_k``, ``P_ch_ideal r``.
    """

    P_AB: FloatArray
    P_ch: FloatArray
    M_1: FloatArray
    P_AB_ideal: FloatArray
    P_ch_ideal: FloatArray
    M_1_ideal: FloatArray


def _scaled_forces(ratios: tuple[FloatArray, ...], P_k: float, r: float) -> DeliveryForces:
    P_k, r = non_negative('P_k', P_k), positive('r', r)
    p_ab, p_ch, m_1, p_ab0, p_ch0, m_0 = ratios
    with np.errstate(over='ignore'):
        out = (p_ab * P_k, p_ch * P_k, m_1 * (P_k * r), p_ab0 * P_k, p_ch0 * P_k, m_0 * (P_k * r))
    if not all(np.all(np.isfinite(a)) for a in out):
        raise ParameterError('P_k', P_k, f'with r={r!r} the forces overflow float64')
    return DeliveryForces(*(np.asarray(a, dtype=float) for a in out))


class StateCoded:
    """Base of the sample arrays that hold a state code per sample (:data:`STATE_NAMES` index) in ``state``."""

    state: Int8Array

    @property
    def ok(self) -> BoolArray:
        """Boolean mask of the ``'ok'`` samples."""
        ok: BoolArray = self.state == STATE_OK  # ndarray.__eq__ is typed Any
        return ok


@dataclass(frozen=True, eq=False)
class DeliverySamples(StateCoded):
    """Kinematics, efficiencies, force ratios and states at an array of positions.

    Every array has the shape of the positions given. Angles in rad; everything else
    dimensionless. The module docstring of :mod:`folder_line.core.mechanisms.delivery` tells
    what non-``'ok'`` samples hold.

    Attributes
    ----------
    u : ndarray
        Stroke position in [0, 2] (equals ``xi`` for :func:`evaluate`).
    xi : ndarray
        Relative position in the section, [0, 1].
    section : ndarray of int8
        :data:`SECTION_NAMES` index.
    psi, dpsi : ndarray
        Profile law and its derivative, ``a_g`` and ``b_g`` of the paper.
    alpha, beta : ndarray
        Pressure angle and chain-guide slope (in the direction of travel), rad.
    K_v : ndarray
        Carriage speed invariant, ``v_k / v_A``.
    k_BA : ndarray
        ``v_BA / v_A = sin(beta)/cos(alpha)``, signed (positive: the rod turns up).
    eta_O, eta_A, eta_B, eta : ndarray
        Efficiencies of bearing O, pair A, pair B and of the transporter (eqs. 8, 6, 3, 9).
    p_AB, p_ch, m_1 : ndarray
        ``P_AB / P_k``, ``P_ch / P_k``, ``M_1 / (P_k r)``.
    p_AB_ideal, p_ch_ideal, m_1_ideal : ndarray
        Same, all friction zero.
    state : ndarray of int8
        :data:`STATE_NAMES` index.
    """

    u: FloatArray
    xi: FloatArray
    section: Int8Array
    psi: FloatArray
    dpsi: FloatArray
    alpha: FloatArray
    beta: FloatArray
    K_v: FloatArray
    k_BA: FloatArray
    eta_O: FloatArray
    eta_A: FloatArray
    eta_B: FloatArray
    eta: FloatArray
    p_AB: FloatArray
    p_ch: FloatArray
    m_1: FloatArray
    p_AB_ideal: FloatArray
    p_ch_ideal: FloatArray
    m_1_ideal: FloatArray
    state: Int8Array

    def state_names(self) -> npt.NDArray[np.str_]:
        """State names (``'ok'``, ``'self_locking'``, ...) as a string array."""
        return state_names(self.state)

    def forces(self, P_k: float, r: float) -> DeliveryForces:
        """Forces for a useful carriage force ``P_k`` (N, >= 0) and sprocket radius ``r`` (m, > 0).

        Raises
        ------
        ParameterError
            ``P_k`` negative or not finite, ``r`` not positive, or the product overflows.
        """
        return _scaled_forces(
            (self.p_AB, self.p_ch, self.m_1, self.p_AB_ideal, self.p_ch_ideal, self.m_1_ideal), P_k, r
        )

    def carriage_speed(self, v_A: float) -> FloatArray:
        """Carriage speed ``v_k = K_v v_A``, m/s, for chain speed ``v_A`` (m/s)."""
        return self.K_v * as_float('v_A', v_A)

    def rod_relative_speed(self, v_A: float) -> FloatArray:
        """``v_BA = v_A sin(beta)/cos(alpha)``, m/s, signed."""
        return self.k_BA * as_float('v_A', v_A)

    def rod_angular_speed(self, v_A: float, l: float) -> FloatArray:  # noqa: E741  (public keyword `l=`, the paper's rod length; callers pass it by name)
        """Rod angular speed ``omega_sh = v_BA / l``, rad/s, for rod length ``l`` (m, > 0)."""
        return self.k_BA * (as_float('v_A', v_A) / positive('l', l))

    def columns(self) -> dict[str, np.ndarray]:
        """Flat 1-D columns for a CSV writer, including ``state_name`` and ``section_name``."""
        cols: dict[str, np.ndarray] = {name: np.ravel(getattr(self, name)) for name in SAMPLE_FIELDS}
        cols['state_name'] = np.ravel(self.state_names())
        cols['section_name'] = np.ravel(np.asarray(SECTION_NAMES)[self.section])
        return cols


SAMPLE_FIELDS: tuple[str, ...] = tuple(DeliverySamples.__dataclass_fields__)


@dataclass(frozen=True)
class DeliveryPoint:
    """One sample, plain floats; the fields mean what they mean in :class:`DeliverySamples`."""

    u: float
    xi: float
    section: int
    psi: float
    dpsi: float
    alpha: float
    beta: float
    K_v: float
    k_BA: float
    eta_O: float
    eta_A: float
    eta_B: float
    eta: float
    p_AB: float
    p_ch: float
    m_1: float
    p_AB_ideal: float
    p_ch_ideal: float
    m_1_ideal: float
    state: int

    @property
    def state_name(self) -> str:
        """``'ok'``, ``'self_locking'``, ``'kv_zero'`` or ``'carriage_reversed'``."""
        return STATE_NAMES[self.state]

    @property
    def section_name(self) -> str:
        """``'deceleration'`` or ``'acceleration'`` (the paper's labels)."""
        return SECTION_NAMES[self.section]

    def forces(self, P_k: float, r: float) -> DeliveryForces:
        """As :meth:`DeliverySamples.forces` (0-d arrays)."""
        ratios = tuple(
            np.asarray(v, dtype=float)
            for v in (self.p_AB, self.p_ch, self.m_1, self.p_AB_ideal, self.p_ch_ideal, self.m_1_ideal)
        )
        return _scaled_forces(ratios, P_k, r)


def state_names(codes: npt.ArrayLike) -> npt.NDArray[np.str_]:
    """Map state codes to their names (:data:`STATE_NAMES`), element-wise."""
    return np.asarray(STATE_NAMES)[np.asarray(codes, dtype=np.intp)]
