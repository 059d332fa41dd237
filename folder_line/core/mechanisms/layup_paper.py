"""The paper's projection-theorem velocities of the layup six-bar — a cross-check ONLY.

Formulas (1)–(19) and (23)–(24) of paper 000 (docs/machines.md, section L), kept as
written (``acos`` of cosine-theorem ratios, divisions by ``cos γ2`` and ``cos γ4``,
a chosen root of a quadratic) so that the tests can compare them with the
loop-closure kinematics of :mod:`folder_line.core.mechanisms.layup`. The simulator never uses
this module.

Angle mapping (worked out once, here)
-------------------------------------
The paper writes ``A - O2 = (a + R cos φ_p, b - R sin φ_p)`` and measures
``α1`` as the polar angle of O2A, ``β = 90° - α1 - α2`` as the rocker angle and
``β + 90°`` as the angle O3-O2-C. All of that is consistent with the project frame
only if the paper's axes are the project axes turned by 180° (``X = -x``,
``Y = -y``: its Y points down, where the chutes hang, and O3 lies on its -X side):

    a_p = -a,   b_p = -b,   φ_p = π - φ.

Then ``α1 = ψ + 180°`` (ψ the polar angle of O2A in the project frame),
``β = -θ3 - 90°`` (the chute's angle from the downward vertical, positive away from
O3), and the paper's crank angle runs the other way (``dφ_p/dt = -ω``), so its
speeds are the project's signed speeds times -1; :func:`paper_speeds` returns them
in the project sign convention (``v_C = ω3 l3``). The simpler reading
``φ_paper = -φ`` (y up, a_p = a, b_p = b) gives the same point A but makes
``β + 90°`` the wrong angle at O2, so eq. (13) would fail; the 180° turn is the
mapping under which (6)–(13) hold.

Interpretation of the garbled scan
----------------------------------
* (13) ``δ1`` is the angle at E in triangle C-E-O3 (sides l4, l5 about it).
* (15)–(16) ``δ4 = δ5 - δ3`` with ``δ5 = 270° - β - δ1`` (angle sum of the convex
  quadrilateral O2-O3-E-C); ``a1 = 2 O2O3 l5 sin δ5``,
  ``a2 = 2 O2O3 l5 cos δ5 - 2 l3 l4``, ``a3 = l3² + l4² - O2O3² - l5²``, and (17)
  ``a2 cos δ3 + a3 = -a1 sin δ3``.
* (24) ``γ4`` is the angle between v_E (perpendicular to O3E) and CE, i.e.
  ``90° - δ1`` with δ1 the angle at E. The paper's eq. (24) writes ``90° - δ4`` (δ4 is the
  angle at O3); that does not follow from the projection theorem and does not
  match, so the geometric reading is used.
* Root of (19). Squaring (17) into (18) adds a spurious root; the true one is
  ``cos δ3 = (-a2 a3 - σ a1 sqrt(a1² + a2² - a3²)) / (a1² + a2²)`` with one fixed
  σ along the assembly branch, so in the paper's ``±`` notation the sign flips where
  ``a1 = 0``, i.e. where the quadrilateral O2-O3-E-C is cyclic (δ3 + δ4 = 180°).
  The paper switches instead at δ3 = 90° (rocker angle β5, eqs. 20–22). The two
  coincide only when ``l3² + l4² = O2O3² + l5²``; otherwise the paper's rule picks
  the spurious root between the two positions. ``root='paper'`` reproduces the
  paper (``+`` for β > β5); ``root='eq17'`` takes the root that satisfies the
  unsquared equation (17) with ``sin δ3 > 0``, which is right everywhere.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple, overload

import numpy as np
import numpy.typing as npt

from folder_line.core.mechanisms.layup import LayupParams
from folder_line.errors import ParameterError

__all__ = ['PaperSpeeds', 'beta5', 'paper_frame', 'paper_speeds']


class PaperSpeeds(NamedTuple):
    """Result of :func:`paper_speeds`; arrays of the shape of ``phi``.

    Speeds are in the project sign convention (paper's value × -1), m/s:
    ``vA`` (crank pin, ``ω R_kr``, positive), ``vB = ω3 O2B``, ``vC = ω3 l3``,
    ``vE = ω5 l5``; ``omega3``, ``omega5`` rad/s. Angles (rad): ``beta`` (rocker
    angle, eq. 10), ``delta1`` (at E), ``delta3`` (at C), ``gamma1``..``gamma4``
    (between the velocities and the rods, eqs. 11, 12, 23, 24); ``a1`` (eq. 16, m²)
    and ``root`` (+1 or -1, the sign taken before the root of eq. 19).
    """

    vA: np.ndarray
    vB: np.ndarray
    vC: np.ndarray
    vE: np.ndarray
    omega3: np.ndarray
    omega5: np.ndarray
    beta: np.ndarray
    delta1: np.ndarray
    delta3: np.ndarray
    gamma1: np.ndarray
    gamma2: np.ndarray
    gamma3: np.ndarray
    gamma4: np.ndarray
    a1: np.ndarray
    root: np.ndarray


def paper_frame(params: LayupParams, phi: npt.ArrayLike) -> tuple[float, float, np.ndarray]:
    """The paper's ``a``, ``b`` and crank angle for project-frame inputs.

    Parameters
    ----------
    params : LayupParams
        Project-frame parameters.
    phi : array_like
        Project crank angle, rad.

    Returns
    -------
    a_p, b_p : float
        ``-a``, ``-b``, m.
    phi_p : ndarray
        ``π - φ``, rad.
    """
    return -params.a, -params.b, math.pi - np.asarray(phi, dtype=np.float64)


@overload
def _acos(x: float) -> float: ...
@overload
def _acos(x: npt.NDArray[Any]) -> npt.NDArray[np.float64]: ...
def _acos(x: npt.NDArray[Any] | float) -> npt.NDArray[np.float64] | float:
    angle: npt.NDArray[np.float64] | float = np.arccos(np.clip(x, -1.0, 1.0))  # np.clip of a union is typed Any
    return angle


def beta5(params: LayupParams) -> float:
    """Rocker angle β5 at which δ3 = 90°, eqs. (20)–(22), rad.

    Parameters
    ----------
    params : LayupParams
        The parameters.

    Returns
    -------
    float
        ``β5 = δ6 + δ7 - 90°`` with ``tan δ6 = l4/l3`` and δ7 the angle at O2 of
        triangle O2-O3-E when ``O2E = sqrt(l3² + l4²)``.
    """
    l3, l4, l5, d = params.l3, params.l4, params.l5, params.O2O3
    o2e = math.hypot(l3, l4)
    d6 = math.atan(l4 / l3)
    d7 = float(_acos((o2e * o2e + d * d - l5 * l5) / (2.0 * o2e * d)))
    return d6 + d7 - 0.5 * math.pi


def paper_speeds(params: LayupParams, phi: npt.ArrayLike, *, root: str = 'paper') -> PaperSpeeds:
    """Exit speeds by the paper's projection theorem, eqs. (1)–(19), (23)–(24).

    Parameters
    ----------
    params : LayupParams
        The parameters (project frame; mapped to the paper's here).
    phi : array_like
        Project crank angle, rad.
    root : {'paper', 'eq17'}, optional
        Sign before the root of (19): as the paper (``+`` for β > β5, else ``-``), or
        the root that satisfies (17) (see the module docstring).

    Returns
    -------
    PaperSpeeds
        Near a toggle ``cos γ2`` or ``cos γ4`` goes to 0 and the speeds blow up: the
        paper's formulas are not protected (compare only where both exceed ~1e-3).

    Raises
    ------
    ParameterError
        ``root`` is not one of the two choices.
    """
    if root not in ('paper', 'eq17'):
        raise ParameterError('root', root, "must be 'paper' or 'eq17'")
    R, n = params.R_kr, params.n_kr
    l2, O2B, l3, l4, l5, d = params.l2, params.O2B, params.l3, params.l4, params.l5, params.O2O3
    a_p, b_p, phi_p = paper_frame(params, phi)
    half = 0.5 * np.pi
    # (1)
    vA = math.pi * n / 30.0 * R
    # (6): triangle O1 O2 A
    X = a_p + R * np.cos(phi_p)
    Y = b_p - R * np.sin(phi_p)
    O2A = np.sqrt(X * X + Y * Y)
    alpha1 = _acos(X / O2A)
    alpha1 = np.where(Y > 0.0, alpha1, -alpha1)
    # (7)-(9): triangle O2 A B, cosine theorem
    alpha2 = _acos((O2A * O2A + O2B * O2B - l2 * l2) / (2.0 * O2A * O2B))
    alpha3 = _acos((l2 * l2 + O2A * O2A - O2B * O2B) / (2.0 * l2 * O2A))
    alpha4 = _acos((l2 * l2 + O2B * O2B - O2A * O2A) / (2.0 * l2 * O2B))
    # (10)-(12)
    beta = half - alpha1 - alpha2
    gamma1 = alpha3 - alpha1 + (half - phi_p)
    gamma2 = half - alpha4
    # (2), (4)
    vB = vA * np.cos(gamma1) / np.cos(gamma2)
    vC = vB * l3 / O2B
    # (13)-(14): triangle C E O3
    O3C2 = l3 * l3 + d * d - 2.0 * l3 * d * np.cos(beta + half)
    delta1 = _acos((l4 * l4 + l5 * l5 - O3C2) / (2.0 * l4 * l5))
    # (15)-(17): quadrilateral O2 O3 E C
    delta5 = 3.0 * half - beta - delta1
    a1 = 2.0 * d * l5 * np.sin(delta5)
    a2 = 2.0 * d * l5 * np.cos(delta5) - 2.0 * l3 * l4
    a3 = l3 * l3 + l4 * l4 - d * d - l5 * l5
    # (18)-(19)
    A = a1 * a1 + a2 * a2
    rad = np.sqrt(np.maximum(4.0 * a2 * a2 * a3 * a3 - 4.0 * A * (a3 * a3 - a1 * a1), 0.0))
    c_plus = (-2.0 * a2 * a3 + rad) / (2.0 * A)
    c_minus = (-2.0 * a2 * a3 - rad) / (2.0 * A)
    if root == 'paper':
        sign = np.where(beta > beta5(params), 1.0, -1.0)
    else:
        # (17) with sin δ3 > 0: a2 cos δ3 + a3 has the sign of -a1
        sign = np.where((a2 * c_plus + a3) * a1 <= 0.0, 1.0, -1.0)
    delta3 = _acos(np.where(sign > 0.0, c_plus, c_minus))
    # (23), (24), (3), (5)
    gamma3 = half - delta3
    gamma4 = half - delta1
    vE = vC * np.cos(gamma3) / np.cos(gamma4)
    # the paper's crank angle runs the other way: project sign = -paper sign
    vB, vC, vE = -vB, -vC, -vE
    return PaperSpeeds(
        vA=np.broadcast_to(vA, X.shape).copy(),
        vB=vB,
        vC=vC,
        vE=vE,
        omega3=vC / l3,
        omega5=vE / l5,
        beta=beta,
        delta1=delta1,
        delta3=delta3,
        gamma1=gamma1,
        gamma2=gamma2,
        gamma3=gamma3,
        gamma4=gamma4,
        a1=a1,
        root=sign,
    )
