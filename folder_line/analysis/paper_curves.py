"""The papers' model curves, drawn once for ``folder-line report`` and ``folder-line analyze``.

The layup's exit speeds against the crank angle (paper L, figs. 4-5, :func:`exit_speed_curves`)
and the delivery's efficiency and carriage speed along the stroke (paper D, fig. 2,
:func:`stroke_curves`) are drawn here, so that the model curves of the report of the defaults
(:mod:`folder_line.cli.report`) and the curves the recorded points of a run are drawn against
(:mod:`folder_line.analysis.figures`) are the same. Two curves that coincide at a figure's
scale are said to in the legend (:func:`coincidence`). Each quantity has its colour of
:data:`~folder_line.analysis.colours.QUANTITY_COLOURS`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from folder_line.analysis.colours import QUANTITY_COLOURS
from folder_line.core.mechanisms import delivery, layup, layup_reach
from folder_line.core.mechanisms.delivery_results import DeliverySamples
from folder_line.core.mechanisms.layup_state import LayupState

if TYPE_CHECKING:  # matplotlib is imported when a figure is drawn (folder_line.analysis.figures.pyplot)
    from matplotlib.axes import Axes

__all__ = ['COINCIDE_FRACTION', 'coincidence', 'exit_speed_curves', 'stroke_curves']


#: two curves closer than this fraction of their peak are drawn as coinciding (and said to be)
COINCIDE_FRACTION = 0.01


def coincidence(a: np.ndarray, b: np.ndarray) -> float | None:
    """The largest ``|a - b|`` if the curves ``a`` and ``b`` coincide at a figure's scale, else None.

    Parameters
    ----------
    a, b : ndarray
        Two curves on the same abscissae, same unit.

    Returns
    -------
    float or None
        ``max |a - b|`` (unit of ``a``) when it is at most :data:`COINCIDE_FRACTION` of the larger
        peak ``max(|a|, |b|)``: one curve would hide the other.
    """
    gap = float(np.max(np.abs(a - b), initial=0.0))
    peak = float(max(np.max(np.abs(a), initial=0.0), np.max(np.abs(b), initial=0.0)))
    return gap if gap <= COINCIDE_FRACTION * peak else None


def _within(gap: float | None, other: str) -> str:
    """The legend's note that a curve coincides with ``other`` (empty if it does not)."""
    return '' if gap is None else f'; coincides with {other} (within {gap * 1e3:.2g} mm/s)'


def exit_speed_curves(
    ax_swing: Axes,
    ax_abs: Axes,
    params: layup.LayupParams,
    v_tr: float,
    *,
    n: int = 721,
    show_swing_on_abs: bool = True,
) -> LayupState:
    """The layup's exit speeds against the crank angle at nominal speed (paper L, figs. 4-5).

    Draws ``v_C``, ``v_E`` (m/s, signed: the exits' swing speed across the chutes) on
    ``ax_swing`` and the absolute exit speeds ``v_aC``, ``v_aE`` with belts at
    ``v_tr`` on ``ax_abs``; both with the swing extremes (dotted) and the crank angle
    in degrees on [0, 360]. The exit C is a wide pale line with circles, the exit E a
    dashed line with squares between the circles, so that both stay visible where
    they coincide; the legend then says so (:func:`coincidence`).

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
    phi = np.linspace(0.0, 2.0 * math.pi, n)
    st = layup.LayupModel(params).arrays(phi, accelerations=False)
    deg = np.degrees(phi)
    va_c = np.sqrt(st.vC * st.vC + v_tr * v_tr)
    va_e = np.sqrt(st.vE * st.vE + v_tr * v_tr)
    every = max(n // 24, 2)  # a marker every 15 deg; E's halfway between C's
    for ax, c, e, c_name, c_label, e_label in (
        (ax_swing, st.vC, st.vE, '$v_C$', '$v_C$ (exit of transporter 3)', '$v_E$ (exit of transporter 4)'),
        (ax_abs, va_c, va_e, '$v_{aC}$', r'$v_{aC}=\sqrt{v_C^2+v_{tr}^2}$', r'$v_{aE}=\sqrt{v_E^2+v_{tr}^2}$'),
    ):
        ax.plot(
            deg,
            c,
            markevery=(0, every),
            label=c_label,
            color=QUANTITY_COLOURS['vC'],
            lw=3.5,
            alpha=0.55,
            marker='o',
            ms=6,
        )
        ax.plot(
            deg,
            e,
            markevery=(every // 2, every),
            label=e_label + _within(coincidence(c, e), c_name),
            color=QUANTITY_COLOURS['vE'],
            ls='--',
            lw=1.4,
            marker='s',
            ms=4,
        )
    ax_swing.axhline(0.0, color='k', lw=0.5)
    if show_swing_on_abs:
        ax_abs.plot(deg, np.abs(st.vC), color=QUANTITY_COLOURS['vC_no_belts'], lw=0.8, label='$|v_C|$ without belts')
    ax_abs.axhline(v_tr, color='k', lw=0.5)
    for e in layup_reach.swing_extremes(params):
        for ax in (ax_swing, ax_abs):
            ax.axvline(math.degrees(e.phi), color='grey', ls=':', lw=1)
    ax_abs.set_xlim(0, 360)
    return st


def stroke_curves(
    ax_eta: Axes,
    ax_kv: Axes | None,
    params: delivery.DeliveryParams,
    modes: Sequence[delivery.ReturnSection] = ('paper_mirror', 'geometric'),
    *,
    n: int = 2001,
    pairs: bool = True,
) -> DeliverySamples | None:
    """The delivery's efficiency (and carriage speed ratio) along the stroke (paper D, fig. 2).

    Draws ``eta(u)`` for each return-section mode on ``ax_eta`` (with ``eta_A``,
    ``eta_B`` of the first mode dotted if ``pairs``) and ``K_v(u)`` on ``ax_kv``;
    ``u`` in [0, 2]: the deceleration section 0..1, the acceleration section 1..2.
    Each mode, ``eta_A`` and ``eta_B`` has its colour of
    :data:`~folder_line.analysis.colours.QUANTITY_COLOURS`, whatever the modes drawn.

    Returns
    -------
    DeliverySamples or None
        The first mode's curve (None without a mode).
    """
    u = np.linspace(0.0, 2.0, n)
    styles = ('-', '--', '-.', ':')
    first = None
    for mode, style in zip(modes, styles, strict=False):
        ev = delivery.evaluate_stroke(params, u, return_section=mode)
        first = ev if first is None else first
        colour = QUANTITY_COLOURS[mode]
        ax_eta.plot(u, ev.eta, style, color=colour, label=f'eta ({mode} return section)')
        if ax_kv is not None:
            ax_kv.plot(u, ev.K_v, style, color=colour, label=f'K_v ({mode})')
    if pairs and first is not None:
        ax_eta.plot(u, first.eta_A, ':', lw=1, color=QUANTITY_COLOURS['eta_A'], label=f'eta_A ({modes[0]})')
        ax_eta.plot(u, first.eta_B, ':', lw=1, color=QUANTITY_COLOURS['eta_B'], label=f'eta_B ({modes[0]})')
    for ax in (ax_eta, ax_kv):
        if ax is not None:
            ax.axvline(1.0, color='grey', lw=0.8)
            ax.grid(alpha=0.3)
    return first
