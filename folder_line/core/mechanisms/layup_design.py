"""Design constraints of the layup six-bar, as margins (>= 0 where met) for an optimiser.

:class:`folder_line.core.mechanisms.layup.LayupParams` refuses a geometry outright; a design
study needs to know *how far* a candidate is from each constraint, and to know it without
building (validating) the candidate. Every function here takes plain dimensions and returns
a finite margin that is positive where the constraint holds and grows with the distance
from its boundary:

* :func:`crank_rocker_margin` — loop O1-A-B-O2 is a Grashof crank-rocker with the crank
  the shortest link (m);
* :func:`transmission_check` — the transmission angles of both loops over a crank turn, by
  the law of cosines (the smallest deviation from a toggle, and whether loop 2 closes at all);
* :func:`exit_clearance` — both chute exits inside the container walls and above its floor
  over the whole swing (m).

The frame and the names are those of :mod:`folder_line.core.mechanisms.layup`.

Transmission angle. In a four-bar with ground ``g``, crank ``r`` at angle ``θ`` from the
ground line, coupler ``c`` and rocker ``s``, the diagonal from the crank pin to the rocker
pivot is ``d² = g² + r² − 2 g r cos θ`` and the transmission angle μ (between the coupler
and the rocker, at their joint) follows from the law of cosines:
``cos μ = (c² + s² − d²) / (2 c s)``. Force transmission degrades as μ nears 0 or π; the
linkage locks (toggles) there and does not close where ``|cos μ| > 1``. The design figure
is ``min(μ, π − μ)`` over the turn, the *transmission angle* of the usual requirement
``≥ 40°``. In the six-bar: loop 1 is the four-bar O2-O1-A-B (diagonal ``|A − O2|``, coupler
``l2``, rocker ``O2B``, μ1 at B); loop 2 is O3-O2-C-E driven by chute 3 (diagonal
``|C − O3|``, coupler ``l4``, rocker ``l5``, μ2 at E). Their sines are the toggle margins
``margin1``, ``margin2`` of :class:`folder_line.core.mechanisms.layup_state.LayupState`.
"""

from __future__ import annotations

import math
from typing import NamedTuple, Protocol

import numpy as np

from folder_line.core.mechanisms.layup import ASSEMBLY_SAMPLES, LayupParams
from folder_line.core.mechanisms.layup_angles import TAU
from folder_line.core.mechanisms.layup_reach import sweep
from folder_line.core.numerics.roots import golden_section

__all__ = [
    'ExitClearance',
    'LayupDimensions',
    'TransmissionCheck',
    'crank_rocker_margin',
    'exit_clearance',
    'fourbar_transmission_cos',
    'transmission_check',
    'transmission_cosines',
]


class LayupDimensions(Protocol):
    """The dimensions of the six-bar (m), as held by :class:`LayupParams` or any unvalidated record."""

    @property
    def R_kr(self) -> float: ...
    @property
    def a(self) -> float: ...
    @property
    def b(self) -> float: ...
    @property
    def l2(self) -> float: ...
    @property
    def O2B(self) -> float: ...
    @property
    def l3(self) -> float: ...
    @property
    def l4(self) -> float: ...
    @property
    def l5(self) -> float: ...
    @property
    def O2O3(self) -> float: ...


def crank_rocker_margin(ground: float, crank: float, coupler: float, rocker: float) -> float:
    """How far a four-bar is inside the Grashof crank-rocker class, m.

    Parameters
    ----------
    ground, crank, coupler, rocker : float
        Link lengths, m (> 0); ``crank`` is the input.

    Returns
    -------
    float
        ``min((p + q) − (s + l), min(ground, coupler, rocker) − crank)`` with ``s``, ``l`` the
        shortest and longest of the four links and ``p``, ``q`` the other two: positive exactly
        when the Grashof inequality ``s + l < p + q`` holds and the crank is the unique shortest
        link (:func:`folder_line.core.mechanisms.layup_angles.classify_fourbar` says ``'crank-rocker'``),
        zero on the boundary, negative outside, continuous everywhere.
    """
    s, p, q, big = sorted((ground, crank, coupler, rocker))
    return min((p + q) - (s + big), min(ground, coupler, rocker) - crank)


def fourbar_transmission_cos(
    ground: float, crank: float, coupler: float, rocker: float, theta: np.ndarray | float
) -> np.ndarray:
    """``cos μ`` of a four-bar at crank angles ``theta``, by the law of cosines.

    Parameters
    ----------
    ground, crank, coupler, rocker : float
        Link lengths, m.
    theta : float or ndarray
        Crank angle from the ground line, measured at the crank pivot from the direction of the
        rocker pivot, rad.

    Returns
    -------
    ndarray
        ``(c² + s² − d²) / (2 c s)`` with ``d² = g² + r² − 2 g r cos θ`` (dimensionless); a value
        outside [−1, 1] means the loop does not close at that angle.
    """
    th = np.asarray(theta, dtype=float)
    d2 = ground * ground + crank * crank - 2.0 * ground * crank * np.cos(th)
    out: np.ndarray = (coupler * coupler + rocker * rocker - d2) / (2.0 * coupler * rocker)
    return out


def transmission_cosines(dims: LayupDimensions, phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``cos μ1`` and ``cos μ2`` of the six-bar at crank angles ``phi`` (law of cosines).

    Parameters
    ----------
    dims : LayupDimensions
        The dimensions (need not be valid).
    phi : ndarray
        Crank angles, rad (project frame, as :class:`folder_line.core.mechanisms.layup.LayupModel`).

    Returns
    -------
    cos1, cos2 : ndarray
        Dimensionless. ``cos2`` is NaN where loop 1 does not close (there is no C to drive loop 2).

    Notes
    -----
    With ``A = O1 + R_kr (cos φ, sin φ)`` and ``d1 = |A − O2|``:
    ``cos μ1 = (l2² + O2B² − d1²) / (2 l2 O2B)``. Chute 3 is at ``θ3 = atan2(A) + β``,
    ``cos β = (d1² + O2B² − l2²) / (2 d1 O2B)`` (B on the assembly branch, counter-clockwise of
    A about O2), ``C = l3 (cos θ3, sin θ3)``, ``d2² = l3² + O2O3² − 2 l3 O2O3 cos θ3`` and
    ``cos μ2 = (l4² + l5² − d2²) / (2 l4 l5)``.
    """
    ax = dims.a + dims.R_kr * np.cos(phi)
    ay = dims.b + dims.R_kr * np.sin(phi)
    d1sq = ax * ax + ay * ay
    cos1 = (dims.l2**2 + dims.O2B**2 - d1sq) / (2.0 * dims.l2 * dims.O2B)
    cos_beta = (d1sq + dims.O2B**2 - dims.l2**2) / (2.0 * np.sqrt(d1sq) * dims.O2B)
    closes = np.abs(cos1) <= 1.0
    beta = np.arccos(np.where(closes, np.clip(cos_beta, -1.0, 1.0), np.nan))
    theta3 = np.arctan2(ay, ax) + beta
    d2sq = dims.l3**2 + dims.O2O3**2 - 2.0 * dims.l3 * dims.O2O3 * np.cos(theta3)
    cos2 = (dims.l4**2 + dims.l5**2 - d2sq) / (2.0 * dims.l4 * dims.l5)
    return cos1, cos2


class TransmissionCheck(NamedTuple):
    """Transmission angles of the six-bar over a crank turn (:func:`transmission_check`).

    Fields: ``worst_cos1``, ``worst_cos2`` — largest ``|cos μ|`` of loops 1 and 2 over the turn
    (dimensionless; above 1 the loop does not close somewhere; loop 2 is ``inf`` when loop 1
    does not close); ``phi1``, ``phi2`` — crank angles where they occur, rad in [0, 2π).
    """

    worst_cos1: float
    phi1: float
    worst_cos2: float
    phi2: float

    @property
    def mu1(self) -> float | None:
        """Smallest ``min(μ1, π − μ1)`` over the turn, rad (None: loop 1 does not close everywhere)."""
        return math.acos(self.worst_cos1) if self.worst_cos1 <= 1.0 else None

    @property
    def mu2(self) -> float | None:
        """Smallest ``min(μ2, π − μ2)`` over the turn, rad (None: loop 2 does not close everywhere)."""
        return math.acos(self.worst_cos2) if self.worst_cos2 <= 1.0 else None

    def margin(self, mu_min: float) -> float:
        """``cos(mu_min) − max(worst_cos1, worst_cos2)``: >= 0 exactly when both loops close and
        keep ``min(μ, π − μ) >= mu_min`` (rad) all turn; continuous, finite (−1e3 for an open loop 1)."""
        worst = max(self.worst_cos1, self.worst_cos2)
        return math.cos(mu_min) - worst if math.isfinite(worst) else -1e3


def transmission_check(dims: LayupDimensions, n: int = ASSEMBLY_SAMPLES) -> TransmissionCheck:
    """The worst transmission angle of each loop over a whole crank turn.

    Loop 1's extremes are exact: ``|A − O2|`` is extremal where the crank lies on the line
    O1O2, and those two angles are evaluated with the ``n`` samples. Loop 2's worst sample is
    refined by a golden-section search over its neighbouring samples (to about 1e-10 rad).

    Parameters
    ----------
    dims : LayupDimensions
        The dimensions (need not be valid).
    n : int, optional
        Crank angles sampled per turn.

    Returns
    -------
    TransmissionCheck
    """
    toward = math.atan2(-dims.b, -dims.a)  # crank pointing from O1 toward O2: |A − O2| smallest
    phis = np.concatenate([np.arange(n) * (TAU / n), [toward % TAU, (toward + math.pi) % TAU]])
    cos1, cos2 = transmission_cosines(dims, phis)
    a1 = np.abs(cos1)
    i1 = int(np.argmax(a1))
    if not (a1 <= 1.0).all():
        return TransmissionCheck(float(a1[i1]), float(phis[i1]), math.inf, float(phis[i1]))
    a2 = np.abs(cos2[:n])
    i2 = int(np.argmax(a2))

    def neg_abs_cos2(x: float) -> float:
        return -abs(float(transmission_cosines(dims, np.array([x]))[1][0]))

    h = TAU / n
    x, fx = golden_section(neg_abs_cos2, float(phis[i2]) - h, float(phis[i2]) + h, maxiter=50).best
    worst2, phi2 = (-fx, x % TAU) if -fx > a2[i2] else (float(a2[i2]), float(phis[i2]))
    return TransmissionCheck(float(a1[i1]), float(phis[i1]), worst2, phi2)


class ExitClearance(NamedTuple):
    """Clearances of the chute exits C and E over the whole swing, m (>= 0: inside).

    Fields: ``left`` — leftmost exit x minus the left wall; ``right`` — right wall minus the
    rightmost exit x; ``floor`` — lowest exit y minus the floor.
    """

    left: float
    right: float
    floor: float


def exit_clearance(params: LayupParams, x_left: float, x_right: float, y_floor: float) -> ExitClearance:
    """How far both chute exits stay inside the container over a crank turn.

    Parameters
    ----------
    params : LayupParams
        Validated parameters (the exits' reach is :func:`folder_line.core.mechanisms.layup_reach.sweep`).
    x_left, x_right : float
        The container's inner walls, m.
    y_floor : float
        Its floor, m.

    Returns
    -------
    ExitClearance
    """
    sw = sweep(params)
    return ExitClearance(sw.x[0] - x_left, x_right - sw.x[1], min(sw.yC[0], sw.yE[0]) - y_floor)
