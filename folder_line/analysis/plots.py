"""Plotting shared by the report of the defaults (:mod:`folder_line.cli.report`) and the
analysis of a recorded run (:mod:`folder_line.analysis.analysis`).

The papers' figures are drawn once here -- the layup's exit speeds against the
crank angle (paper L, figs. 4-5), the delivery's efficiency and carriage speed along
the stroke (paper D, fig. 2), the colours of the cyclogram's phases (paper F,
figs. 1-2) -- so that the model curves of the report and the curves the recorded
points of a run are drawn against are the same. Figures are written atomically
(:func:`save_figure`). matplotlib is imported lazily, with the Agg back end.
"""

from __future__ import annotations

import io
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from folder_line.files.atomic import write_bytes_atomic

__all__ = ['PHASE_COLOURS', 'exit_speed_curves', 'pyplot', 'save_figure', 'stroke_curves']

#: colours of the cyclogram's phases (knife over the table, feed, dwell at the stops)
PHASE_COLOURS: dict[str, str] = {'knife': 'tab:red', 'feed': 'tab:green', 'dwell': 'tab:blue'}

#: resolution of the PNGs, dots per inch
DPI = 110


def pyplot() -> Any:
    """``matplotlib.pyplot`` on the non-interactive Agg back end (no display needed)."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig: Any, path: str | os.PathLike[str], dpi: int = DPI) -> Path:
    """Write ``fig`` as a PNG to ``path`` atomically (:func:`folder_line.files.atomic.write_bytes_atomic`)
    and close it; a failure leaves no partial file behind."""
    try:
        buf = io.BytesIO()
        fig.savefig(buf, format='png', dpi=dpi)
        return write_bytes_atomic(path, buf.getvalue())
    finally:
        pyplot().close(fig)


def exit_speed_curves(
    ax_swing: Any, ax_abs: Any, params: Any, v_tr: float, *, n: int = 721, show_swing_on_abs: bool = True
) -> Any:
    """The layup's exit speeds against the crank angle at nominal speed (paper L, figs. 4-5).

    Draws ``v_C``, ``v_E`` (m/s, signed: the exits' swing speed across the chutes) on
    ``ax_swing`` and the absolute exit speeds ``v_aC``, ``v_aE`` with belts at
    ``v_tr`` on ``ax_abs``; both with the swing extremes (dotted) and the crank angle
    in degrees on [0, 360].

    Parameters
    ----------
    ax_swing, ax_abs : matplotlib Axes
    params : LayupParams
        The six-bar.
    v_tr : float
        Belt speed, m/s (0: no belts, ``v_aC = |v_C|``).
    n : int
        Crank angles on [0, 2π].
    show_swing_on_abs : bool
        Also draw ``|v_C|`` on ``ax_abs`` for comparison.

    Returns
    -------
    LayupState
        The curves' kinematics (``phi`` in rad).
    """
    from folder_line.core.mechanisms import layup

    phi = np.linspace(0.0, 2.0 * math.pi, n)
    st = layup.LayupModel(params).arrays(phi, accelerations=False)
    deg = np.degrees(phi)
    va_c = np.sqrt(st.vC * st.vC + v_tr * v_tr)
    va_e = np.sqrt(st.vE * st.vE + v_tr * v_tr)
    ax_swing.plot(deg, st.vC, label='$v_C$ (exit of transporter 3)')
    ax_swing.plot(deg, st.vE, '--', label='$v_E$ (exit of transporter 4)')
    ax_swing.axhline(0.0, color='k', lw=0.5)
    ax_abs.plot(deg, va_c, label=r'$v_{aC}=\sqrt{v_C^2+v_{tr}^2}$')
    ax_abs.plot(deg, va_e, '--', label=r'$v_{aE}$')
    if show_swing_on_abs:
        ax_abs.plot(deg, np.abs(st.vC), color='C2', lw=0.8, label='$|v_C|$ without belts')
    ax_abs.axhline(v_tr, color='k', lw=0.5)
    for e in layup.swing_extremes(params):
        for ax in (ax_swing, ax_abs):
            ax.axvline(math.degrees(e.phi), color='grey', ls=':', lw=1)
    ax_abs.set_xlim(0, 360)
    return st


def stroke_curves(
    ax_eta: Any,
    ax_kv: Any | None,
    params: Any,
    modes: Sequence[str] = ('paper_mirror', 'geometric'),
    *,
    n: int = 2001,
    pairs: bool = True,
) -> Any:
    """The delivery's efficiency (and carriage speed ratio) along the stroke (paper D, fig. 2).

    Draws ``eta(u)`` for each return-section mode on ``ax_eta`` (with ``eta_A``,
    ``eta_B`` of the first mode dotted if ``pairs``) and ``K_v(u)`` on ``ax_kv``;
    ``u`` in [0, 2]: the deceleration section 0..1, the acceleration section 1..2.

    Returns
    -------
    DeliverySamples
        The first mode's curve.
    """
    from folder_line.core.mechanisms import delivery

    u = np.linspace(0.0, 2.0, n)
    styles = ('-', '--', '-.', ':')
    first = None
    for mode, style in zip(modes, styles, strict=False):
        ev = delivery.evaluate_stroke(params, u, return_section=mode)
        first = ev if first is None else first
        ax_eta.plot(u, ev.eta, style, label=f'eta ({mode} return section)')
        if ax_kv is not None:
            ax_kv.plot(u, ev.K_v, style, label=f'K_v ({mode})')
    if pairs and first is not None:
        ax_eta.plot(u, first.eta_A, ':', lw=1, label='eta_A')
        ax_eta.plot(u, first.eta_B, ':', lw=1, label='eta_B')
    for ax in (ax_eta, ax_kv):
        if ax is not None:
            ax.axvline(1.0, color='grey', lw=0.8)
            ax.grid(alpha=0.3)
    return first
