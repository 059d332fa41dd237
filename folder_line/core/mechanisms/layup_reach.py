"""Where the layup linkage goes over a crank turn: the rocker dead centres and the swept ranges.

:func:`swing_extremes` gives the two crank angles where the chutes stop (ω3 = 0) in
closed form; :func:`sweep` the x and y ranges the chute exits C and E cover (container
coverage). The parameters and kinematics are in :mod:`folder_line.core.mechanisms.layup`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from folder_line.core.mechanisms.layup import ASSEMBLY_SAMPLES, LayupParams, cached_model
from folder_line.core.mechanisms.layup_angles import TAU
from folder_line.core.mechanisms.layup_state import LayupPoint

__all__ = [
    'Sweep',
    'SwingExtreme',
    'sweep',
    'swing_extremes',
]

_PI = math.pi


class SwingExtreme(NamedTuple):
    """A rocker dead centre (ω3 = 0): ``kind`` is 'extended' (crank and rod in line,
    ``|O1B| = l2 + R_kr``) or 'folded' (``|O1B| = l2 - R_kr``); ``phi`` the crank angle, rad in
    [0, 2π); ``point`` the kinematics there."""

    kind: str
    phi: float
    point: LayupPoint


def swing_extremes(params: LayupParams) -> tuple[SwingExtreme, SwingExtreme]:
    """The two crank angles where chute 3 (and with it chute 4) stops: ω3 = 0.

    Closed form: at a rocker dead centre O1, A and B are collinear, so B lies on
    circle(O1, l2 ± R_kr) and on circle(O2, O2B) (on the branch with
    ``(O1 - O2) × (B - O2) > 0``, the one that matches the assembly branch there),
    and ``A = O1 ± R_kr (B - O1)/|B - O1|``.

    Parameters
    ----------
    params : LayupParams
        Validated parameters.

    Returns
    -------
    (SwingExtreme, SwingExtreme)
        The extended and the folded dead centre.
    """
    model = cached_model(params)
    a, b, R, p, l2 = params.a, params.b, params.R_kr, params.O2B, params.l2
    out = []
    for kind, rho, sgn in (('extended', l2 + R, 1.0), ('folded', l2 - R, -1.0)):
        dx, dy = a, b
        d2 = dx * dx + dy * dy
        disc = ((p + rho) ** 2 - d2) * (d2 - (p - rho) ** 2)  # > 0 for a crank-rocker
        along = 0.5 + (p * p - rho * rho) / (2.0 * d2)
        across = 0.5 * math.sqrt(disc) / d2
        bx = along * dx - across * dy
        by = along * dy + across * dx
        phi = math.atan2(sgn * (by - b), sgn * (bx - a))
        out.append(SwingExtreme(kind, phi % TAU, model.point(phi)))
    return out[0], out[1]


class Sweep(NamedTuple):
    """Ranges swept by the chute exits over a crank turn, m.

    Fields ``xC``, ``xE``, ``yC``, ``yE``: (min, max) tuples; ``x`` the (min, max) of
    both exits together.
    """

    xC: tuple[float, float]
    yC: tuple[float, float]
    xE: tuple[float, float]
    yE: tuple[float, float]
    x: tuple[float, float]


def _arc_box(theta: np.ndarray, extra: list[float], r: float, cx: float) -> tuple[tuple[float, float], ...]:
    """x and y ranges of the points ``(cx + r cos t, r sin t)`` for t over the arc spanned by the angles."""
    ref = extra[0]
    rel = np.concatenate([np.asarray(theta, dtype=float).ravel(), extra]) - ref
    rel = np.remainder(rel + _PI, TAU) - _PI  # unwrapped about the first extreme
    t0, t1 = ref + float(rel.min()), ref + float(rel.max())
    cand_x = [t0, t1] + [k * _PI for k in range(math.ceil(t0 / _PI), math.floor(t1 / _PI) + 1)]
    cand_y = [t0, t1] + [(k + 0.5) * _PI for k in range(math.ceil(t0 / _PI - 0.5), math.floor(t1 / _PI - 0.5) + 1)]
    xs = [cx + r * math.cos(t) for t in cand_x]
    ys = [r * math.sin(t) for t in cand_y]
    return (min(xs), max(xs)), (min(ys), max(ys))


def sweep(params: LayupParams, n: int = ASSEMBLY_SAMPLES) -> Sweep:
    """Ranges swept by the exits C and E (container coverage).

    Each exit moves on a circle about its pivot, over the arc of chute angles the
    crank turn produces; the arc's ends are the chute angles at the rocker dead
    centres (exact, :func:`swing_extremes`), widened by ``n`` sampled angles in case
    a geometry gives chute 4 extra turning points. The x and y ranges of the arc
    follow in closed form (including a chute passing straight down, where the
    exit is lowest).

    Parameters
    ----------
    params : LayupParams
        Validated parameters.
    n : int, optional
        Samples per turn.

    Returns
    -------
    Sweep
    """
    st = cached_model(params).arrays(np.arange(n) * (TAU / n), accelerations=False)
    ext = swing_extremes(params)
    xc, yc = _arc_box(st.theta3, [e.point.theta3 for e in ext], params.l3, 0.0)
    xe, ye = _arc_box(st.theta5, [e.point.theta5 for e in ext], params.l5, params.O2O3)
    return Sweep(xc, yc, xe, ye, (min(xc[0], xe[0]), max(xc[1], xe[1])))
