"""The feed's closed form (paper F), written out here from the shipped defaults, independent of the model code."""

from __future__ import annotations

import math

#: config/knife.yaml, config/cyclogram.yaml
R_K, L_K, S_CLEAR = 0.04, 0.16, 0.1656
L_FEED, RESERVE, DWELL_FRAC = 0.230, 0.10, 0.2


def allowed_feed_time(n_k: float) -> float:
    """``(1 - reserve) (T - t_knife - dwell_frac T)``, s, for the central crank-slider knife at ``n_k`` rev/h.

    The knife is over the table while ``s(phi) = r cos phi + sqrt(L^2 - r^2 sin^2 phi) >= s_clear``: the window
    ends where ``cos phi = (s^2 - L^2 + r^2) / (2 s r)``, symmetric about phi = 0.
    """
    omega = 2.0 * math.pi * n_k / 3600.0
    period = 2.0 * math.pi / omega
    phi = math.acos((S_CLEAR**2 - L_K**2 + R_K**2) / (2.0 * S_CLEAR * R_K))
    return (1.0 - RESERVE) * (period - 2.0 * phi / omega - DWELL_FRAC * period)


def v_tr_min(n_k: float) -> float:
    """Slowest feed transporter that feeds in time, m/s: ``L_feed / t_allowed``."""
    return L_FEED / allowed_feed_time(n_k)


def feed_margin(n_k: float, v_tr: float) -> float:
    """Feed-window margin ``t_allowed - L_feed / V_tr``, s."""
    return allowed_feed_time(n_k) - L_FEED / v_tr
