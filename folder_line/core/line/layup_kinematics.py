"""The layup six-bar geared to the master drive: crank angle, crank cycle and chute kinematics at line times.

The crank turns through ``φ = ω Θ(t)``, ``ω = 2π n_kr/60``, Θ the master phase
(:mod:`folder_line.core.mechanisms.drive`); it is computed as ``2π · frac(n_kr/60 · Θ)`` in
[0, 2π), and the crank cycle of an event is ``floor(n_kr/60 · Θ(t))``. Chute angles
from :class:`folder_line.core.mechanisms.layup.LayupModel`; velocities and accelerations at the
drive's speed factor λ = dΘ/dt follow by linearity from the nominal ones:
``ω3 = λ ω3⁰``, ``ε3 = λ² ε3⁰ + λ' ω3⁰``; likewise for chute 4.
"""

from __future__ import annotations

import math

import numpy as np

from folder_line.core.mechanisms.drive import Drive
from folder_line.core.mechanisms.layup import LayupModel, LayupParams
from folder_line.core.mechanisms.layup_angles import TAU
from folder_line.core.mechanisms.layup_state import LayupState

__all__ = ['EXTREME_WINDOW', 'PHASE_BINS', 'LayupKinematics']

#: half-width of the crank-angle window about a swing extreme for the summary, rad (5°)
EXTREME_WINDOW = math.radians(5.0)
#: crank-angle bins of the summary's exit speed by phase
PHASE_BINS = 36


class LayupKinematics:
    """Crank angle and chute kinematics at line times, geared to the master drive.

    Parameters
    ----------
    params : LayupParams
        The six-bar.
    drive : Drive
        The master drive.
    """

    def __init__(self, params: LayupParams, drive: Drive) -> None:
        self.params = params
        self.model = LayupModel(params)
        self.drive = drive
        self.turns_rate = params.n_kr / 60.0  # crank turns per nominal second
        self.omega = params.omega  # nominal crank speed, rad/s
        self._r = params.O2B / params.l3

    def turns(self, t: np.ndarray) -> np.ndarray:
        """Crank turns ``n_kr/60 · Θ(t)``."""
        return np.asarray(self.drive.theta(t), dtype=float) * self.turns_rate

    def cycle(self, t: np.ndarray) -> np.ndarray:
        """Crank cycle index ``floor(n_kr/60 · Θ(t))``."""
        cycles: np.ndarray = np.floor(self.turns(np.asarray(t, dtype=float))).astype(np.int64)
        return cycles

    @staticmethod
    def wrap(turns: np.ndarray) -> np.ndarray:
        """Crank angle in [0, 2π) of a number of turns."""
        phi = TAU * (turns - np.floor(turns))
        return np.where(phi >= TAU, 0.0, phi)

    def state(self, t: np.ndarray) -> tuple[np.ndarray, LayupState, np.ndarray, np.ndarray]:
        """(φ in [0, 2π), nominal LayupState with accelerations, λ, λ') at times t."""
        t = np.asarray(t, dtype=float)
        phi = self.wrap(self.turns(t))
        st = self.model.arrays(phi)
        return phi, st, np.asarray(self.drive.rate(t), dtype=float), np.asarray(self.drive.rate_dot(t), dtype=float)

    def chute(self, t: np.ndarray, chute: np.ndarray) -> dict[str, np.ndarray]:
        """Per-leaf chute quantities at times t (chute 0: transporter 3, exit C; 1: transporter 4, exit E).

        Returns
        -------
        dict
            ``phi`` (rad), ``x``, ``y`` (exit point, m), ``sin``, ``cos`` (of the chute
            angle θ' from the downward vertical; t̂ = (sin, −cos)), ``omega``, ``eps``
            (rad/s, rad/s², at the drive's speed), ``v_perp`` (exit speed across the
            chute, m/s, signed), ``lam`` (λ).
        """
        p = self.params
        phi, st, lam, lamd = self.state(t)
        c4 = np.asarray(chute) == 1
        x = np.where(c4, st.xE, st.xC)
        y = np.where(c4, st.yE, st.yC)
        sin = np.where(c4, (st.xE - p.O2O3) / p.l5, st.xC / p.l3)
        cos = np.where(c4, -st.yE / p.l5, -st.yC / p.l3)
        w0 = np.where(c4, st.omega5, st.omega3)
        assert st.eps3 is not None and st.eps5 is not None  # :meth:`state` computes the accelerations
        e0 = np.where(c4, st.eps5, st.eps3)
        omega = w0 * lam
        eps = e0 * lam * lam + w0 * lamd
        length = np.where(c4, p.l5, p.l3)
        return {
            'phi': phi,
            'x': x,
            'y': y,
            'sin': sin,
            'cos': cos,
            'omega': omega,
            'eps': eps,
            'v_perp': omega * length,
            'lam': lam,
        }

    def chute_scalar(self, t: float, chute: int) -> tuple[float, float, float, float]:
        """(sin θ', cos θ', ω, ε) of one chute at one time (pure ``math``, a few µs)."""
        p = self.params
        d = self.drive
        ta = np.asarray(float(t))
        turns = float(d.theta(ta)) * self.turns_rate
        phi = TAU * (turns - math.floor(turns))
        lam = float(d.rate(ta))
        lamd = float(d.rate_dot(ta))
        pt = self.model.point(phi)
        w = self.omega
        c, s = math.cos(phi), math.sin(phi)
        R = p.R_kr
        rc, rs = R * c, R * s
        xA, yA = p.a + rc, p.b + rs
        xB, yB = pt.xC * self._r, pt.yC * self._r
        w3 = pt.omega3
        ux, uy = xB - xA, yB - yA
        rvx, rvy = -w3 * yB + w * rs, w3 * xB - w * rc
        num = w3 * w3 * (xB * ux + yB * uy) - w * w * (ux * rc + uy * rs) - (rvx * rvx + rvy * rvy)
        e3 = num / (xA * yB - yA * xB)
        if chute == 0:
            return (pt.xC / p.l3, -pt.yC / p.l3, w3 * lam, e3 * lam * lam + w3 * lamd)
        xC, yC = pt.xC, pt.yC
        wx, wy = pt.xE - p.O2O3, pt.yE
        w5 = pt.omega5
        ux, uy = pt.xE - xC, pt.yE - yC
        cdd = e3 * (uy * xC - ux * yC) - w3 * w3 * (ux * xC + uy * yC)
        rvx, rvy = -w5 * wy + w3 * yC, w5 * wx - w3 * xC
        num = w5 * w5 * (ux * wx + uy * wy) + cdd - (rvx * rvx + rvy * rvy)
        e5 = num / ((xC - p.O2O3) * wy - yC * wx)
        return (wx / p.l5, -wy / p.l5, w5 * lam, e5 * lam * lam + w5 * lamd)
