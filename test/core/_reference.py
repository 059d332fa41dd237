"""Independent references for the core's hard numerical cases (not a test module).

The hard cases (dead centres and toggles at +-1e-12 rad, 1e9 crank turns and line times of
1e7 s, ...) sit in the test files of the modules they test; what they compare against is
here, independent of the code under test: mpmath at 40 digits re-implements the loop
closures (:func:`mp_circle`, :func:`mp_sixbar`) and takes their derivatives
(:func:`mp_rate`), ``fractions.Fraction`` does the long-time arithmetic exactly (pi to 50
digits where the crank angle enters, :data:`PI_50`), and exact rational arithmetic decides
whether a four-bar's input link turns fully (:func:`crank_turns_fully`). pytest.ini turns
RuntimeWarning into errors, so every such test also proves "no numpy warning".
"""

from __future__ import annotations

import math
from collections.abc import Callable
from fractions import Fraction
from typing import Any

import mpmath as mp
import numpy as np

from folder_line.core.mechanisms.layup import LayupParams
from folder_line.core.mechanisms.layup_angles import TAU

EPS = float(np.finfo(float).eps)
#: the offsets from a dead centre or toggle, rad
DELTAS = (-1e-12, 1e-12)
#: pi to 50 digits, for exact-rational references of angles
PI_50 = Fraction('3.14159265358979323846264338327950288419716939937510')


def ulp(x: float) -> float:
    """Unit in the last place of ``x``."""
    return math.ulp(abs(x))


# ---- independent mpmath models (40 digits) ---------------------------------------------


def mp_circle(x0: Any, y0: Any, r0: Any, x1: Any, y1: Any, r1: Any, branch: int) -> tuple[Any, Any]:
    """Circle-circle intersection left (+1) or right (-1) of c0 -> c1, in mpmath."""
    dx, dy = x1 - x0, y1 - y0
    d2 = dx * dx + dy * dy
    along = mp.mpf(1) / 2 + (r0 * r0 - r1 * r1) / (2 * d2)
    across = mp.sqrt(r0 * r0 / d2 - along * along) * branch
    return x0 + along * dx - across * dy, y0 + along * dy + across * dx


def mp_sixbar(p: LayupParams, phi: Any) -> dict[str, Any]:
    """L six-bar at crank angle ``phi`` (mpmath), from the definitions of docs/machines.md, section L."""
    R, a, b, l2, q, l3, l4, l5, d0 = (mp.mpf(v) for v in (p.R_kr, p.a, p.b, p.l2, p.O2B, p.l3, p.l4, p.l5, p.O2O3))
    ax, ay = a + R * mp.cos(phi), b + R * mp.sin(phi)
    bx, by = mp_circle(0, 0, q, ax, ay, l2, 1)
    cx, cy = bx * l3 / q, by * l3 / q
    ex, ey = mp_circle(d0, 0, l5, cx, cy, l4, 1)
    return {'theta3': mp.atan2(cy, cx), 'theta5': mp.atan2(ey, ex - d0), 'C': (cx, cy), 'E': (ex, ey)}


def mp_rate(f: Callable[[Any], Any], x: float, order: int = 1) -> float:
    """d^order f / dphi^order at the float ``x`` (taken exactly), 40 digits."""
    with mp.workdps(40):
        return float(mp.diff(f, mp.mpf(x), order))


# ---- exact rational arithmetic ------------------------------------------------------------


def crank_turns_fully(ground: float, crank: float, coupler: float, rocker: float) -> bool:
    """The input link turns fully: the dyad (coupler, rocker) closes at every |A - O2| in
    [|ground - crank|, ground + crank] (exact rational arithmetic on the float lengths)."""
    g, c, cl, r = (Fraction(x) for x in (ground, crank, coupler, rocker))
    return g + c <= cl + r and abs(g - c) >= abs(cl - r)


def exact_frac_turns(t: float, rev_per_s: Fraction) -> Fraction:
    """Fractional crank turn at the float time ``t`` (taken exactly), exact."""
    x = Fraction(t) * rev_per_s
    return x - math.floor(x)


def angle_diff(a: float, b: float) -> float:
    """|a - b| modulo 2 pi, rad."""
    return abs(math.remainder(a - b, TAU))
