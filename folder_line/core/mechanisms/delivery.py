"""D: efficiency, forces and states of the chain-and-carriage delivery transporter (paper 002).

A chain driven by a sprocket at constant speed ``v_A`` runs in curved guides; a rod
AB of length ``l`` links the chain pin A to a gripper carriage B that runs in its own
straight guide. The carriage speed is ``v_k = K_v v_A``; where it is slowest the
sheet is released onto the pile. The guide profile is ``y = y_max psi(xi)`` with
``xi = x / x_max`` in [0, 1] over one section.

Model (paper 002, docs/machines.md section D; equation numbers as in the paper)
-------------------------------------------------------------------------------
::

    alpha = arcsin(psi sin alpha_m)          (sin alpha_m = y_max / l)
    beta  = arctan(psi' Lambda)              (Lambda = y_max / x_max)
    K_v   = cos(alpha - beta) / cos(alpha)   = cos beta + tan alpha sin beta
    v_BA  = v_A sin beta / cos alpha ,  omega_sh = v_BA / l

Velocity plan, from the geometry: put the carriage guide on ``y = 0``, pin A at
``(x_A, y_A = l sin alpha)`` and B *behind* A at ``x_B = x_A - l cos alpha`` (the chain
pulls the carriage through the rod). With ``dx_A = v_A cos beta dt`` and
``l cos alpha dalpha = dy_A = v_A sin beta dt`` one gets
``dx_B/dt = v_A (cos beta + tan alpha sin beta) = v_A cos(alpha - beta)/cos alpha``: the
paper's ``K_v`` and ``v_BA`` are exactly this, with ``beta`` the slope of the chain
guide *in the direction of travel*. (The test suite checks it by finite differences.)

Friction signs
--------------
The paper's friction terms carry ``tan(alpha - beta)``, ``sin(alpha - beta)`` and
``sin beta``, which change sign along the section. A Coulomb loss is
``f |N| |v_rel|``, never negative: the slider friction is proportional to the
*magnitude* of the normal force (``|sin(alpha - beta)|``, ``|tan alpha|``), and the
revolute-pair friction moment does work ``f r' P |omega_sh|`` with
``|omega_sh| = v_A |sin beta| / (l cos alpha)``. This module therefore uses::

    eta_B = 1 - f_Bp |tan a| - f_B r_B |sin b| / (K_v cos^2 a)                    (3)
    eta_A = 1 / (1 + f_Ap |tan(a - b)| + f_A r_A |sin b| / (cos a cos(a - b)))    (6)
    P_AB  = P_k / (cos a - f_Bp |sin a| - f_B r_B |sin b| / (K_v cos a))         (1)
    P_ch  = P_AB (cos(a - b) + f_Ap |sin(a - b)| + f_A r_A |sin b| / cos a)       (4)
    M_1   = P_ch r (1 + f_O r_O) ,  eta_O = 1 / (1 + f_O r_O) ,  eta = eta_O eta_A eta_B

so that no pair ever returns energy (``eta_A <= 1``, ``eta_B <= 1``). Where
``alpha >= beta`` and ``beta >= 0`` (in the paper's case: ``xi >~ 0.6``) this is the
paper's formula verbatim; where ``beta > alpha`` the signed formula gives
``eta_A > 1`` (e.g. 1.03 at ``xi = 0.3`` in the reference case), i.e. friction that
*helps* -- not a loss. With these forms the power balance is exact: wherever the
state is ``'ok'``, ``P_k v_k / (M_1 omega_sprocket) = eta`` and ``M_1_ideal / M_1 = eta``
to rounding. Only the chain-drives-carriage energy flow (eq. 10) is modelled;
the reverse flow (eq. 11) is not.

Sections and the slowest point
------------------------------
The paper plots a *deceleration* section (``xi`` 0 -> 1) then an *acceleration*
section, the latter mirrored. :func:`evaluate` is one section with the paper's
formulas as written (``beta = +arctan(psi' Lambda) >= 0``): this reproduces Fig. 2,
``eta`` falling from 0.985 at ``xi = 0`` to 0.694 at ``xi = 1``.

:func:`evaluate_stroke` covers the whole stroke, position ``u`` in [0, 2]:
``xi = u`` on the first section (``u <= 1``) and ``xi = 2 - u`` on the second. On
the second section the guide *descends* in the direction of travel, so the velocity
plan demands ``beta = -arctan(psi'(xi) Lambda)`` there
(``return_section='geometric'``, the default); only then does the integral of ``K_v``
over the chain path equal the carriage's travel, ``2 x_max`` (the rod is back at
``alpha = 0``; the tests check both). ``return_section='paper_mirror'`` keeps
``beta >= 0`` on both sections: the paper's Fig. 2 as plotted, kinematically
inconsistent for a closed profile (the carriage would gain ``2 l (1 - cos alpha_m)``).

What the formulas say, plainly: ``K_v = cos(alpha - beta)/cos(alpha)`` equals 1 at
``xi = 0`` *and* at ``xi = 1`` (``psi' = 0`` there for both laws, so ``beta = 0`` and
the rod does not turn): at the boundary of the sections the carriage moves at chain
speed. On the first section (``beta >= 0``) ``K_v = cos beta + tan alpha sin beta`` is
below 1 only where ``beta > 2 alpha`` -- in the reference case a shallow dip to 0.945
at ``xi = 0.318`` -- and then rises to 1.406 at ``xi = 0.734``: over the section the
paper calls deceleration the carriage gains ``l (1 - cos alpha_m)`` on the chain.
With the geometric return the carriage falls back on the second section; in the
reference case the stroke's minimum is ``K_v = 0.354`` at ``u = 1.354``
(``xi = 0.646`` of the return), not at the section boundary, and ``eta`` there is
0.61 (the stroke's lowest, 0.591, is at ``u = 1.298``), below the paper's 0.69.
The paper's "lowest, 0.69, at the boundary" holds for :func:`evaluate` and for
``'paper_mirror'``. :func:`stroke_minimum` locates such minima. The section labels
kept here are the paper's.

States (never NaN or inf)
-------------------------
Each sample carries an ``int8`` code, :data:`~.delivery_results.STATE_NAMES` gives the names::

    0 'ok'                 the model holds
    1 'self_locking'       cos(alpha) <= COS_ALPHA_TOL (rod across the carriage guide;
                           force amplification > 1e9 even without friction), or
                           eta <= ETA_TOL (friction losses eat the drive power; with
                           K_v > 0 this is exactly "denominator of P_AB <= 0")
    2 'kv_zero'            |K_v| < KV_TOL: the carriage stands, the 1/K_v term is void
    3 'carriage_reversed'  K_v <= -KV_TOL: the carriage is driven backwards (only on
                           the geometric return with alpha + |beta| > 90 deg)

Precedence: the ``cos(alpha)`` lock, then ``kv_zero``, ``carriage_reversed``, then the
friction lock. In every sample that is not ``'ok'``: ``eta``, ``eta_A``, ``eta_B`` and
every force ratio (actual and ideal) are 0.0 (the state tells why); ``eta_O`` is
always its constant; ``K_v`` and ``k_BA`` are reported as computed except under the
``cos(alpha)`` lock, where they are 0.0 (nothing moves).

Domain: ``xi`` must lie in [0, 1] and ``u`` in [0, 2]; values outside by at most
:data:`XI_TOL` (rounding) are clipped, anything further is a
:class:`~folder_line.errors.ParameterError`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
import numpy.typing as npt

from folder_line.core.mechanisms import delivery_laws
from folder_line.core.mechanisms.delivery_results import (
    SECTION_ACCELERATION,
    SECTION_DECELERATION,
    STATE_CARRIAGE_REVERSED,
    STATE_KV_ZERO,
    STATE_OK,
    STATE_SELF_LOCKING,
    DeliveryPoint,
    DeliverySamples,
)
from folder_line.core.numerics.arrays import FloatArray, Int8Array
from folder_line.core.numerics.roots import golden_section
from folder_line.core.numerics.validate import among, as_float, check_fields, non_negative, one_of, positive
from folder_line.errors import ParameterError

__all__ = [
    'COS_ALPHA_TOL',
    'ETA_TOL',
    'KV_TOL',
    'RETURN_SECTIONS',
    'XI_TOL',
    'DeliveryParams',
    'ReturnSection',
    'evaluate',
    'evaluate_point',
    'evaluate_stroke',
    'evaluate_stroke_point',
    'stroke_minimum',
]

ReturnSection = Literal['geometric', 'paper_mirror']

#: ``cos(alpha)`` at or below this is a self-locking state (rod force > 1e9 P_k, ideal).
COS_ALPHA_TOL = 1e-9
#: ``|K_v|`` below this: the carriage stands (< 1 nm/s at v_A = 1 m/s).
KV_TOL = 1e-9
#: ``eta`` at or below this is a self-locking state (forces would exceed 1e12 P_k / cos(alpha)).
ETA_TOL = 1e-12
#: ``xi`` (or ``u``) outside its interval by at most this is rounding, clipped.
XI_TOL = 1e-9
RETURN_SECTIONS: tuple[str, ...] = ('geometric', 'paper_mirror')


# --------------------------------------------------------------------------- parameters


def _pressure_angle(key: str, value: object) -> float:
    """The check of ``alpha_m_deg``: a number in (0, 90)."""
    a = as_float(key, value)
    if a >= 90.0:
        raise ParameterError(
            key,
            value,
            'must be < 90: at 90 the rod stands across the carriage guide at the end of '
            'the section and the transporter self-locks by construction',
        )
    if a <= 0.0:
        raise ParameterError(key, value, 'must be in (0, 90)')
    return a


@dataclass(frozen=True)
class DeliveryParams:
    """Validated parameters of the delivery transporter (``config/delivery.yaml``).

    Parameters
    ----------
    Lambda : float
        ``y_max / x_max`` of the chain guide profile, dimensionless, > 0.
    alpha_m_deg : float
        Maximum pressure angle, degrees, in (0, 90). Exactly 90 is rejected: the rod
        would stand across the carriage guide at ``psi = 1`` (``y_max = l``), the ideal
        rod force ``P_k / cos(alpha)`` is unbounded there -- a design that self-locks by
        construction, not a state passed through. Values just below 90 are accepted;
        the samples near ``psi = 1`` then report ``'self_locking'`` as the model says.
    law : str
        Guide profile law, a key of :data:`~folder_line.core.mechanisms.delivery_laws.LAWS`
        (``'sinusoidal'``, ``'harmonic'``, ...).
    f_Ap, f_Bp : float
        Sliding friction coefficients of pair A (pin in the chain guide) and of the
        translational pair B (carriage in its guide), >= 0.
    f_A, f_B, f_O : float
        Friction coefficients of the revolute pairs A, B and of the sprocket bearing O, >= 0.
    r_A, r_B : float
        Relative friction radii ``r_A'/l``, ``r_B'/l`` of the revolute pairs, >= 0.
    r_O : float
        Relative friction radius ``r_O'/r`` of the sprocket bearing (r sprocket radius), >= 0.

    Raises
    ------
    ParameterError
        Naming ``delivery.<field>`` and the value. Numbers must be finite; ints are
        accepted and stored as floats.
    """

    Lambda: float
    alpha_m_deg: float
    law: str
    f_Ap: float
    f_Bp: float
    f_A: float
    f_B: float
    f_O: float
    r_A: float
    r_B: float
    r_O: float

    def __post_init__(self) -> None:
        check_fields(
            self,
            'delivery',
            Lambda=positive,
            alpha_m_deg=_pressure_angle,
            law=among(delivery_laws.law_names()),
            **dict.fromkeys(('f_Ap', 'f_Bp', 'f_A', 'f_B', 'f_O', 'r_A', 'r_B', 'r_O'), non_negative),
        )

    @property
    def alpha_m(self) -> float:
        """Maximum pressure angle, rad."""
        return math.radians(self.alpha_m_deg)

    @property
    def eta_O(self) -> float:
        """Efficiency of the sprocket bearing, ``1 / (1 + f_O r_O)`` (eq. 8)."""
        return 1.0 / (1.0 + self.f_O * self.r_O)

    def rod_length(self, x_max: float) -> float:
        """Rod length ``l = y_max / sin(alpha_m) = Lambda x_max / sin(alpha_m)``, m.

        Parameters
        ----------
        x_max : float
            Length of one section along the carriage guide, m, > 0.

        Raises
        ------
        ParameterError
            The length is not finite (``alpha_m_deg`` so small that its sine is 0, or ``Lambda``
            so large): it names ``delivery.alpha_m_deg``.
        """
        sin_alpha = math.sin(self.alpha_m)
        length = self.Lambda * positive('x_max', x_max) / sin_alpha if sin_alpha > 0.0 else math.inf
        if not math.isfinite(length):
            reason = (
                f'with delivery.Lambda={self.Lambda:g} and x_max={x_max:g} m the rod, Lambda x_max / sin(alpha_m), '
                'would be infinitely long'
            )
            raise ParameterError('delivery.alpha_m_deg', self.alpha_m_deg, reason)
        return length


# --------------------------------------------------------------------------- results
# --------------------------------------------------------------------------- input checks


def _unit_positions(key: str, values: npt.ArrayLike, hi: float) -> FloatArray:
    try:
        arr = np.array(values, dtype=np.float64)
    except (TypeError, ValueError):
        raise ParameterError(key, values, 'must be a real number or an array of them') from None
    bad = ~np.isfinite(arr)
    if bad.any():
        raise ParameterError(key, arr[bad].flat[0], 'must be finite')
    bad = (arr < -XI_TOL) | (arr > hi + XI_TOL)
    if bad.any():
        raise ParameterError(key, float(arr[bad].flat[0]), f'must be in [0, {hi:g}]')
    return np.clip(arr, 0.0, hi)


def _unit_position(key: str, value: object, hi: float) -> float:
    x = as_float(key, value)
    if x < -XI_TOL or x > hi + XI_TOL:
        raise ParameterError(key, value, f'must be in [0, {hi:g}]')
    return min(max(x, 0.0), hi)


def _return_sign(return_section: str) -> float:
    one_of('return_section', return_section, RETURN_SECTIONS)
    return -1.0 if return_section == 'geometric' else 1.0


# --------------------------------------------------------------------------- vector kernel


def _scaled(c: float, g: FloatArray) -> FloatArray:
    """``c * g`` for ``c >= 0`` (possibly inf) and ``g >= 0`` finite, with ``0 * anything = 0``."""
    if c == 0.0:
        return np.zeros_like(g)
    if math.isinf(c):
        return np.where(g > 0.0, np.inf, 0.0)
    return c * g  # may overflow to inf: the caller holds np.errstate(over='ignore')


def _kernel(p: DeliveryParams, u: FloatArray, xi: FloatArray, section: Int8Array, sign: FloatArray) -> DeliverySamples:
    law = delivery_laws.LAWS[p.law]  # through the module: a replaced LAWS is seen too
    psi = np.clip(np.asarray(law.psi(xi), dtype=float), 0.0, 1.0)
    dpsi = np.maximum(np.asarray(law.dpsi(xi), dtype=float), 0.0)
    lam = p.Lambda
    # arctan(dpsi * Lambda) without overflow for huge Lambda
    beta = sign * (np.arctan(dpsi * lam) if lam <= 1.0 else np.arctan2(dpsi, 1.0 / lam))
    s_a = np.clip(psi * math.sin(p.alpha_m), 0.0, 1.0)  # sin(alpha)
    alpha = np.arcsin(s_a)
    c_a = np.sqrt((1.0 - s_a) * (1.0 + s_a))  # cos(alpha), accurate near 90 deg
    s_b, c_b = np.sin(beta), np.cos(beta)

    geom_lock = c_a <= COS_ALPHA_TOL
    c_a_s = np.where(geom_lock, 1.0, c_a)
    tan_a = s_a / c_a_s
    K_v = np.where(geom_lock, 0.0, c_b + tan_a * s_b)
    k_BA = np.where(geom_lock, 0.0, s_b / c_a_s)

    state = np.zeros(xi.shape, dtype=np.int8)
    state[geom_lock] = STATE_SELF_LOCKING
    state[~geom_lock & (np.abs(K_v) < KV_TOL)] = STATE_KV_ZERO
    state[~geom_lock & (K_v <= -KV_TOL)] = STATE_CARRIAGE_REVERSED
    kin_ok = state == STATE_OK

    K_v_s = np.where(kin_ok, K_v, 1.0)
    c_ab = c_a_s * K_v_s  # cos(alpha - beta) > 0 where kin_ok
    s_ab = np.abs(s_a * c_b - c_a * s_b)  # |sin(alpha - beta)|
    abs_s_b = np.where(kin_ok, np.abs(s_b), 0.0)
    fr_A, fr_B, fr_O = p.f_A * p.r_A, p.f_B * p.r_B, p.f_O * p.r_O  # python floats: may be inf, never raise
    eta_O = 1.0 / (1.0 + fr_O)
    with np.errstate(over='ignore'):
        loss_B = _scaled(p.f_Bp, tan_a) + _scaled(fr_B, abs_s_b / (K_v_s * c_a_s * c_a_s))
        eta_B_raw = 1.0 - loss_B
        loss_A = _scaled(p.f_Ap, s_ab / c_ab) + _scaled(fr_A, abs_s_b / (c_a_s * c_ab))
        eta_A_raw = 1.0 / (1.0 + loss_A)
        eta_raw = eta_O * eta_A_raw * np.where(eta_B_raw > 0.0, eta_B_raw, 0.0)
    state[kin_ok & (eta_raw <= ETA_TOL)] = STATE_SELF_LOCKING
    ok = state == STATE_OK

    zero = np.zeros(xi.shape)
    eta_B_s = np.where(ok, eta_B_raw, 1.0)
    p_AB = np.where(ok, 1.0 / (c_a_s * eta_B_s), 0.0)  # = P_k / (cos a - f_Bp sin a - f_B r_B |sin b|/(K_v cos a))
    s_ab_ok = np.where(ok, s_ab, 0.0)
    abs_s_b_ok = np.where(ok, abs_s_b, 0.0)
    p_ch = np.where(ok, p_AB * (c_ab + _scaled(p.f_Ap, s_ab_ok) + _scaled(fr_A, abs_s_b_ok / c_a_s)), 0.0)
    m_1 = _scaled(1.0 + fr_O, p_ch)
    p_AB_ideal = np.where(ok, 1.0 / c_a_s, 0.0)
    p_ch_ideal = np.where(ok, K_v, 0.0)
    return DeliverySamples(
        u=u,
        xi=xi,
        section=section,
        psi=psi,
        dpsi=dpsi,
        alpha=alpha,
        beta=beta,
        K_v=K_v,
        k_BA=k_BA,
        eta_O=np.full(xi.shape, eta_O),
        eta_A=np.where(ok, eta_A_raw, zero),
        eta_B=np.where(ok, eta_B_raw, zero),
        eta=np.where(ok, eta_raw, zero),
        p_AB=p_AB,
        p_ch=p_ch,
        m_1=m_1,
        p_AB_ideal=p_AB_ideal,
        p_ch_ideal=p_ch_ideal,
        m_1_ideal=p_ch_ideal.copy(),
        state=state,
    )


# --------------------------------------------------------------------------- scalar kernel


def _scaled1(c: float, g: float) -> float:
    if c == 0.0 or g == 0.0:
        return 0.0
    return c * g  # python floats overflow to inf without raising


#: a sample's efficiencies and force ratios in :class:`DeliveryPoint`'s order: eta_A, eta_B, eta,
#: p_AB, p_ch, m_1, p_AB_ideal, p_ch_ideal, m_1_ideal (all 0 unless the state is ok)
_Ratios = tuple[float, float, float, float, float, float, float, float, float]
_NO_RATIOS: _Ratios = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


def _point(p: DeliveryParams, u: float, xi: float, section: int, sign: float) -> DeliveryPoint:
    law = delivery_laws.LAWS[p.law]  # through the module: a replaced LAWS is seen too
    psi = min(max(float(law.psi(xi)), 0.0), 1.0)
    dpsi = max(float(law.dpsi(xi)), 0.0)
    lam = p.Lambda
    beta = sign * (math.atan(dpsi * lam) if lam <= 1.0 else math.atan2(dpsi, 1.0 / lam))
    s_a = min(max(psi * math.sin(p.alpha_m), 0.0), 1.0)
    alpha = math.asin(s_a)
    c_a = math.sqrt((1.0 - s_a) * (1.0 + s_a))
    s_b, c_b = math.sin(beta), math.cos(beta)
    eta_O = 1.0 / (1.0 + p.f_O * p.r_O)

    def sample(K_v: float, k_BA: float, state: int, ratios: _Ratios = _NO_RATIOS) -> DeliveryPoint:
        return DeliveryPoint(u, xi, section, psi, dpsi, alpha, beta, K_v, k_BA, eta_O, *ratios, state)

    if c_a <= COS_ALPHA_TOL:
        return sample(0.0, 0.0, STATE_SELF_LOCKING)
    tan_a = s_a / c_a
    K_v = c_b + tan_a * s_b
    k_BA = s_b / c_a
    if abs(K_v) < KV_TOL or K_v <= -KV_TOL:
        return sample(K_v, k_BA, STATE_KV_ZERO if abs(K_v) < KV_TOL else STATE_CARRIAGE_REVERSED)
    c_ab = c_a * K_v
    s_ab = abs(s_a * c_b - c_a * s_b)
    abs_s_b = abs(s_b)
    fr_A, fr_B, fr_O = p.f_A * p.r_A, p.f_B * p.r_B, p.f_O * p.r_O
    eta_B = 1.0 - (_scaled1(p.f_Bp, tan_a) + _scaled1(fr_B, abs_s_b / (K_v * c_a * c_a)))
    eta_A = 1.0 / (1.0 + _scaled1(p.f_Ap, s_ab / c_ab) + _scaled1(fr_A, abs_s_b / (c_a * c_ab)))
    eta = eta_O * eta_A * (eta_B if eta_B > 0.0 else 0.0)
    if eta <= ETA_TOL:
        return sample(K_v, k_BA, STATE_SELF_LOCKING)
    p_AB = 1.0 / (c_a * eta_B)
    p_ch = p_AB * (c_ab + _scaled1(p.f_Ap, s_ab) + _scaled1(fr_A, abs_s_b / c_a))
    return sample(K_v, k_BA, STATE_OK, (eta_A, eta_B, eta, p_AB, p_ch, p_ch * (1.0 + fr_O), 1.0 / c_a, K_v, K_v))


# --------------------------------------------------------------------------- public entry points


def _check_params(params: object) -> DeliveryParams:
    if not isinstance(params, DeliveryParams):
        raise ParameterError('params', type(params).__name__, 'must be a DeliveryParams')
    return params


def evaluate(params: DeliveryParams, xi: npt.ArrayLike) -> DeliverySamples:
    """One section with the paper's formulas as written (``beta >= 0``): Fig. 2, vectorised.

    Parameters
    ----------
    params : DeliveryParams
        Validated parameters.
    xi : array_like of float
        Relative positions ``x / x_max`` in [0, 1], any shape.

    Returns
    -------
    DeliverySamples
        Arrays shaped like ``xi``; ``section`` is 0 (the paper's deceleration section).

    Raises
    ------
    ParameterError
        ``xi`` not finite or outside [0, 1] (beyond :data:`XI_TOL`).
    """
    p = _check_params(params)
    x = _unit_positions('xi', xi, 1.0)
    return _kernel(p, x, x, np.zeros(x.shape, dtype=np.int8), np.ones(x.shape))


def evaluate_point(params: DeliveryParams, xi: float) -> DeliveryPoint:
    """Scalar :func:`evaluate` for node ticks (``math`` only, a few microseconds).

    Parameters
    ----------
    params : DeliveryParams
        Validated parameters.
    xi : float
        Relative position in [0, 1].
    """
    p = _check_params(params)
    x = _unit_position('xi', xi, 1.0)
    return _point(p, x, x, SECTION_DECELERATION, 1.0)


def evaluate_stroke(
    params: DeliveryParams, u: npt.ArrayLike, *, return_section: ReturnSection = 'geometric'
) -> DeliverySamples:
    """The whole delivery stroke: the paper's deceleration then acceleration section.

    Parameters
    ----------
    params : DeliveryParams
        Validated parameters.
    u : array_like of float
        Stroke position in [0, 2] (in units of ``x_max``): ``xi = u`` for ``u <= 1``,
        ``xi = 2 - u`` after.
    return_section : {'geometric', 'paper_mirror'}
        ``'geometric'``: on the second section the guide descends in the direction of
        travel, ``beta = -arctan(psi' Lambda)`` (what the velocity plan demands).
        ``'paper_mirror'``: ``beta >= 0`` on both, the paper's Fig. 2 as plotted.

    Returns
    -------
    DeliverySamples
        Arrays shaped like ``u``.
    """
    p = _check_params(params)
    sign_back = _return_sign(return_section)
    uu = _unit_positions('u', u, 2.0)
    back = uu > 1.0
    xi = np.where(back, 2.0 - uu, uu)
    return _kernel(p, uu, xi, back.astype(np.int8), np.where(back, sign_back, 1.0))


def evaluate_stroke_point(
    params: DeliveryParams, u: float, *, return_section: ReturnSection = 'geometric'
) -> DeliveryPoint:
    """Scalar :func:`evaluate_stroke` for node ticks."""
    p = _check_params(params)
    sign_back = _return_sign(return_section)
    uu = _unit_position('u', u, 2.0)
    if uu > 1.0:
        return _point(p, uu, 2.0 - uu, SECTION_ACCELERATION, sign_back)
    return _point(p, uu, uu, SECTION_DECELERATION, 1.0)


def stroke_minimum(
    params: DeliveryParams,
    quantity: Literal['K_v', 'eta'] = 'K_v',
    *,
    return_section: ReturnSection = 'geometric',
    n: int = 4001,
) -> tuple[float, float]:
    """Where ``K_v`` (or ``eta``) is smallest over the stroke, refined to ~1e-10 in ``u``.

    A grid of ``n`` points on [0, 2] brackets the minimum, a golden-section search
    on the scalar path refines it (it finds the grid's best local minimum; ties go to
    the smaller ``u``). For ``'K_v'`` samples under the ``cos(alpha)`` lock are skipped
    (their 0.0 is not a speed); for ``'eta'`` every sample counts (locked = 0).

    Parameters
    ----------
    params : DeliveryParams
        Validated parameters.
    quantity : {'K_v', 'eta'}
        What to minimise.
    return_section : {'geometric', 'paper_mirror'}
        As in :func:`evaluate_stroke`.
    n : int
        Grid size, >= 3.

    Returns
    -------
    (u, value) : tuple of float
        Stroke position in [0, 2] and the minimum value there.
    """
    one_of('quantity', quantity, ('K_v', 'eta'))
    if isinstance(n, bool) or not isinstance(n, int) or n < 3:
        raise ParameterError('n', n, 'must be an int >= 3')
    grid = np.linspace(0.0, 2.0, n)
    samples = evaluate_stroke(params, grid, return_section=return_section)
    vals = np.asarray(getattr(samples, quantity), dtype=float)
    usable = np.ones(n, dtype=bool)
    if quantity == 'K_v':
        usable = ~((samples.state == STATE_SELF_LOCKING) & (samples.K_v == 0.0))
    if not usable.any():
        raise ParameterError('params', params, 'the mechanism is locked over the whole stroke')
    i = int(np.argmin(np.where(usable, vals, np.inf)))

    def f(x: float) -> float:
        pt = evaluate_stroke_point(params, x, return_section=return_section)
        if quantity == 'K_v' and pt.state == STATE_SELF_LOCKING and pt.K_v == 0.0:
            return math.inf
        return float(getattr(pt, quantity))

    last = golden_section(f, grid[max(i - 1, 0)], grid[min(i + 1, n - 1)], xtol=1e-10)
    best_u, best = float(grid[i]), float(vals[i])
    for x in (last.lo, last.hi, 0.5 * (last.lo + last.hi)):
        fx = f(x)
        if fx < best:
            best_u, best = float(x), fx
    return best_u, best
