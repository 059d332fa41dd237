"""The exit speeds of a run drawn over the model's (``exit_speeds.png``): :func:`draw_exit_speeds`.

One drawing for a recorded run (``folder-line analyze``,
:func:`folder_line.analysis.figures.exit_speeds_figure`) and a simulated one (``folder-line simulate
--plots``, :mod:`folder_line.cli.plot_drawing`): the swing speeds ``v_C = ω3 l3``, ``v_E = ω5 l5`` and
the absolute ones ``v_aC``, ``v_aE`` against the crank angle, over the model's curves at nominal speed
(paper L, figs. 4-5, :func:`~folder_line.analysis.paper_curves.exit_speed_curves`); the samples off
speed (the start-up, holds and stops) apart, in grey; the leaves' exits and the belts' ``v_min``.
What the two runs write differently (their words, the titles' sampling) is :class:`ExitSpeedText`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from folder_line.analysis.colours import QUANTITY_COLOURS
from folder_line.analysis.paper_curves import exit_speed_curves

if TYPE_CHECKING:  # matplotlib is imported when a figure is drawn (folder_line.analysis.figures.pyplot)
    from matplotlib.axes import Axes

    from folder_line.core.line.scene import Scene

__all__ = ['ExitSpeedPoints', 'ExitSpeedText', 'draw_exit_speeds']


@dataclass(frozen=True)
class ExitSpeedPoints:
    """The exit speeds of a run at its samples (ticks), one entry a sample.

    Attributes
    ----------
    deg : ndarray
        Crank angle, deg.
    v_c, v_e : ndarray
        Swing speeds across the chutes ``ω3 l3``, ``ω5 l5``, m/s (signed).
    va_c, va_e : ndarray
        Absolute exit speeds ``sqrt(v² + v_belt²)``, m/s.
    off : ndarray of bool
        The sample is off speed: before the drive reached speed, or in a hold or stop.
    later : int
        How many of the samples off speed come after the drive reached speed (holds, stops).
    t_speed : float
        When the drive reached speed, s (``inf``: never).
    """

    deg: np.ndarray
    v_c: np.ndarray
    v_e: np.ndarray
    va_c: np.ndarray
    va_e: np.ndarray
    off: np.ndarray
    later: int
    t_speed: float


@dataclass(frozen=True)
class ExitSpeedText:
    """The words of the figure that tell a recorded run from a simulated one.

    Attributes
    ----------
    source : str
        The points' name in the legend (``'recorded'``, ``'simulated'``).
    sampling : str
        The upper title's second line: what was sampled, over which span.
    belt : str
        The belt speeds, in the lower title (``'no belts'`` without them).
    holds_after : str
        Written after ``N ticks of holds/stops`` in the legend of the samples off speed.
    ticks_drawn : str
        Written after the number of the samples off speed (``': N ticks'``).
    legend_below : bool
        The lower legend stands below the axes (where it hides no point), else where matplotlib finds best.
    """

    source: str
    sampling: str
    belt: str
    holds_after: str = ''
    ticks_drawn: str = ''
    legend_below: bool = False


def _at_speed(ax: Axes, deg: np.ndarray, v_c: np.ndarray, v_e: np.ndarray, names: tuple[str, str], source: str) -> None:
    """Exit speeds at speed: E as hollow squares under C's smaller dots (both visible where equal)."""
    ax.plot(deg, v_c, 'o', ms=2.5, color=QUANTITY_COLOURS['vC'], alpha=0.8, zorder=3, label=f'{source} {names[0]}')
    ax.plot(deg, v_e, 's', ms=4.5, color=QUANTITY_COLOURS['vE'], mfc='none', alpha=0.8, label=f'{source} {names[1]}')


def _off_speed(
    ax: Axes, deg: np.ndarray, v_c: np.ndarray, v_e: np.ndarray, points: ExitSpeedPoints, text: ExitSpeedText
) -> None:
    """Samples off speed: before the drive reached speed and ``points.later`` ones of holds and stops after
    it: grey crosses, one legend entry."""
    if deg.size == 0:
        return
    colour = QUANTITY_COLOURS['start_up']
    later = points.later
    first = deg.size - later
    start_up = f'start-up (before the drive reached speed, t < {points.t_speed:.3g} s)'
    if first and later:
        label = f'{start_up} and {later} ticks of holds/stops{text.holds_after}'
    elif first:
        label = start_up
    else:
        label = 'holds/stops (the drive ramping down or standing still)'
    label += f': {deg.size} ticks{text.ticks_drawn}'
    ax.plot(deg, v_c, 'x', ms=3.5, color=colour, alpha=0.8, label=label)
    ax.plot(deg, v_e, '+', ms=4, color=colour, alpha=0.8)


def draw_exit_speeds(
    axes: tuple[Axes, Axes],
    scene: Scene,
    points: ExitSpeedPoints,
    text: ExitSpeedText,
    leaf_exits: Callable[[Axes], None],
) -> None:
    """Draw a run's exit speeds over the model's on the two axes of ``exit_speeds.png``.

    Parameters
    ----------
    axes : tuple of two matplotlib Axes
        Swing speeds (paper L, fig. 4) and absolute exit speeds (fig. 5), sharing the crank angle.
    scene : Scene
        The run's scene, with the layup (and the ``chute_belts`` effect, if it has belts).
    points : ExitSpeedPoints
        The run's samples.
    text : ExitSpeedText
        The words of the run's kind.
    leaf_exits : callable
        Draws the leaves' exit speeds on the lower axes (after the samples, before ``v_min``).
    """
    ax1, ax2 = axes
    lp = scene.machine('layup')
    belts = scene.has('chute_belts')
    exit_speed_curves(ax1, ax2, lp, float(lp.v_tr) if belts else 0.0, show_swing_on_abs=False)
    off = points.off
    for ax, c, e, names in (
        (ax1, points.v_c, points.v_e, (r'$\omega_3 l_3$', r'$\omega_5 l_5$')),
        (ax2, points.va_c, points.va_e, ('$v_{aC}$', '$v_{aE}$')),
    ):
        _at_speed(ax, points.deg[~off], c[~off], e[~off], names, text.source)
        _off_speed(ax, points.deg[off], c[off], e[off], points, text)
    leaf_exits(ax2)
    if belts:
        vmin = float(scene.effect('chute_belts').v_min)
        ax2.axhline(vmin, color='r', ls='--', lw=1, label=f'v_min = {vmin:g} m/s')
    ax1.set_ylabel('swing speed across the chute, m/s')
    ax1.set_title(f'L: exit speeds (lines: model at nominal speed; paper Fig. 4)\n{text.sampling}', fontsize=10)
    ax1.legend(loc='best', fontsize=7.5)
    ax2.set_ylabel('absolute exit speed, m/s')
    ax2.set_xlabel(r'crank angle $\varphi$, deg')
    ax2.set_title(f'L: absolute exit speeds with the belts ({text.belt}; paper Fig. 5)', fontsize=10)
    if text.legend_below:
        ax2.legend(loc='upper center', bbox_to_anchor=(0.5, -0.11), fontsize=7.5, ncol=2)
    else:
        ax2.legend(loc='best', fontsize=7.5, ncol=2)
