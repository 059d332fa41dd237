"""The papers' reference values of scene keys: the point a study marks as "paper" on its charts.

From ``/work/shared/spec/MACHINES.md`` (the papers, cleaned up):

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
from collections.abc import Mapping, Sequence

__all__ = ['PAPER_VALUES', 'paper_point']

#: the paper's folding cylinder, m, and speed, rev/h
_D_FC = 0.26738
_N_C = 25000.0
#: the paper's printing speed V_d = pi D_fc n_c / 3600, m/s
_V_D = math.pi * _D_FC * _N_C / 3600.0

#: scene key -> the papers' value, in the key's unit
PAPER_VALUES: Mapping[str, float] = {
    'cyclogram.n_c': _N_C,
    'cyclogram.D_fc': _D_FC,
    'knife.n_k': 2.0 * _N_C,
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


def paper_point(keys: Sequence[str]) -> dict[str, float] | None:
    """The papers' values of ``keys`` (in their units), or None when one of them has none."""
    if not keys or any(k not in PAPER_VALUES for k in keys):
        return None
    return {k: PAPER_VALUES[k] for k in keys}
