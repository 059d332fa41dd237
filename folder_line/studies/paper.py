"""The papers' reference values of scene keys: the point a study marks as "paper" on its charts.

From the papers (their physics in our words, and the papers cited: docs/machines.md):

* F (paper 001): the ДАВР-62 folding cylinder, ``D_fc = 267.38 mm`` at ``n_c = 25000`` rev/h,
  the knife crank at twice that, ``n_k = 50000`` rev/h; the 2nd transporter at
  ``V_tr = 1.6 V_d`` (eq. 6) with ``V_d = pi D_fc n_c / 3600 = 5.833`` m/s, i.e. 9.333 m/s.
* D (paper 002, Fig. 2): ``Lambda = 0.4``, ``alpha_m = 60 deg``, ``f_Ap = f_Bp = 0.1``,
  ``f_A = f_B = f_O = 0.15``, ``r_A = r_B = r_O = 0.1``.
* L (paper 000): chute belts at ``v_tr = 2.8`` m/s (the paper's optimum), the crank at
  30 rev/min. The prototype's link lengths are not legible in the scan: no paper value.

A point is the paper's only when every varied key has a paper value.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence

import numpy as np

from folder_line.core.mechanisms.cyclogram import KNIFE_PER_CYLINDER

__all__ = ['PAPER_NOTES', 'PAPER_VALUES', 'paper_point', 'paper_rule']

#: the paper's folding cylinder, m, and speed, rev/h
_D_FC = 0.26738
_N_C = 25000.0
#: the paper's printing speed V_d = pi D_fc n_c / 3600, m/s
_V_D = math.pi * _D_FC * _N_C / 3600.0

#: scene key -> the papers' value, in the key's unit
PAPER_VALUES: Mapping[str, float] = {
    'cyclogram.n_c': _N_C,
    'cyclogram.D_fc': _D_FC,
    'knife.n_k': KNIFE_PER_CYLINDER * _N_C,
    'press.n_c': _N_C,
    'cyclogram.L_feed': 0.230,
    'cyclogram.L_a': 0.420,
    'cyclogram.reserve': 0.10,
    'feed_transporter.V_tr': 1.6 * _V_D,
    'delivery.Lambda': 0.4,
    'delivery.alpha_m_deg': 60.0,
    'delivery.f_Ap': 0.1,
    'delivery.f_Bp': 0.1,
    'delivery.f_A': 0.15,
    'delivery.f_B': 0.15,
    'delivery.f_O': 0.15,
    'delivery.r_A': 0.1,
    'delivery.r_B': 0.1,
    'delivery.r_O': 0.1,
    'layup.v_tr': 2.8,
    'layup.n_kr': 30.0,
}


#: scene key -> where its paper value comes from, for the charts' legends
PAPER_NOTES: Mapping[str, str] = {
    'feed_transporter.V_tr': '1.6 V_d, paper F eq. 6',
    'knife.n_k': '2 n_c, paper F',
    'cyclogram.n_c': 'paper F',
    'press.n_c': 'paper F',
    'layup.v_tr': "paper L's optimum",
}

#: press-speed keys -> V_d per unit of the key, (m/s) / (rev/h), with the paper's cylinder
_V_D_PER_SPEED: Mapping[str, float] = {
    'cyclogram.n_c': math.pi * _D_FC / 3600.0,
    'press.n_c': math.pi * _D_FC / 3600.0,
    'knife.n_k': math.pi * _D_FC / 3600.0 / KNIFE_PER_CYLINDER,  # the knife turns twice per cylinder turn
}


def paper_rule(x_key: str, y_key: str) -> tuple[str, Callable[[np.ndarray], np.ndarray]] | None:
    """The paper's rule ``V_tr = 1.6 V_d`` as a curve ``x(y)`` when ``x_key`` is the feed speed and ``y_key``
    a press speed (rev/h): its label and ``V_tr`` (m/s) as a function of the press speed; None otherwise."""
    if x_key != 'feed_transporter.V_tr' or y_key not in _V_D_PER_SPEED:
        return None
    per = _V_D_PER_SPEED[y_key]
    return ('paper F: V_tr = 1.6 V_d at every press speed', lambda n: 1.6 * per * np.asarray(n, dtype=float))


def paper_point(keys: Sequence[str]) -> dict[str, float] | None:
    """The papers' values of ``keys`` (in their units), or None when one of them has none."""
    if not keys or any(k not in PAPER_VALUES for k in keys):
        return None
    return {k: PAPER_VALUES[k] for k in keys}
