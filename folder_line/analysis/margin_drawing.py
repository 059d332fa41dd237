"""Every constraint's margins in a run (``margins.png``): :func:`draw_margins`.

One figure for a recorded run (``folder-line analyze``, :mod:`folder_line.analysis.figures`) and a
simulated one (``folder-line simulate --plots``, :mod:`folder_line.cli.plot_drawing`): a panel a
constraint, titled with its count of evaluations and violations, its margins in the display unit
(:data:`DISPLAY_UNITS`), zero and the smallest margin marked. The bars are the run's own
(:attr:`MarginPanel.bars`: the two runs bin their margins differently); how the figure is laid out
is :class:`MarginLook`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # matplotlib is imported when a figure is drawn (folder_line.analysis.figures.pyplot)
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ['DISPLAY_UNITS', 'MarginLook', 'MarginPanel', 'draw_margins', 'margins_size']

#: a quantity's display scale and unit, by its SI unit
DISPLAY_UNITS = {'s': (1e3, 'ms'), 'm': (1e3, 'mm')}


@dataclass(frozen=True)
class MarginPanel:
    """One constraint's margins in a run.

    Attributes
    ----------
    name : str
        The constraint.
    unit : str
        The margins' SI unit.
    count, violated : int
        Margins evaluated, and of them negative.
    low : float
        The smallest margin, SI unit.
    bars : callable
        ``bars(ax, scale)`` draws the margins' bars on ``ax`` in the display unit (SI times ``scale``)
        and returns their edges, display unit; called only where ``count`` is not 0.
    """

    name: str
    unit: str
    count: int
    violated: int
    low: float
    bars: Callable[[Axes, float], np.ndarray]


@dataclass(frozen=True)
class MarginLook:
    """How a run's ``margins.png`` is laid out.

    Attributes
    ----------
    width, height : float
        Size of a panel, in.
    extra : float
        Height added to the figure's, in.
    pad, one_bar_pad : float or None
        The space left and right of the bars, a fraction of their span (None: matplotlib's); the
        second where there is one bar.
    title : str
        The figure's title ('' for none).
    """

    width: float
    height: float
    extra: float
    pad: float | None
    one_bar_pad: float | None
    title: str = ''


def _grid(panels: int) -> tuple[int, int]:
    """(rows, columns) of the panels: two columns for more than one."""
    n = max(panels, 1)
    cols = 2 if n > 1 else 1
    return math.ceil(n / cols), cols


def margins_size(panels: int, look: MarginLook) -> tuple[float, float]:
    """The size of the figure of ``panels`` panels, in (``figsize`` of a matplotlib figure)."""
    rows, cols = _grid(panels)
    return look.width * cols, look.height * rows + look.extra


def _panel(ax: Axes, panel: MarginPanel, look: MarginLook) -> None:
    """One constraint's panel."""
    scale, unit = DISPLAY_UNITS.get(panel.unit, (1.0, panel.unit))
    nv = panel.violated
    ax.set_title(f'{panel.name}: {panel.count} evaluations, {nv} violated', fontsize=9, color='tab:red' if nv else 'k')
    ax.set_xlabel(f'margin, {unit}' if unit not in ('', '1') else 'margin (dimensionless)')
    ax.set_ylabel('count')
    if panel.count == 0:
        ax.text(0.5, 0.5, 'no evaluation', ha='center', va='center', transform=ax.transAxes)
        return
    edges = panel.bars(ax, scale)
    if edges[0] <= 0.0 <= edges[-1]:
        ax.axvline(0.0, color='k', lw=1)
    low = panel.low * scale
    ax.axvline(low, color='tab:orange', ls='--', lw=1, label=f'min {low:.4g}')
    ax.legend(fontsize=7)
    ax.ticklabel_format(axis='x', style='sci', scilimits=(-3, 4), useOffset=False)
    pad = look.one_bar_pad if edges.size == 2 else look.pad
    if pad is not None:
        span = edges[-1] - edges[0]
        ax.set_xlim(edges[0] - pad * span, edges[-1] + pad * span)


def draw_margins(fig: Figure, panels: Sequence[MarginPanel], look: MarginLook) -> None:
    """Draw a run's margins on ``fig`` (a figure of :func:`margins_size`), a panel a constraint.

    Parameters
    ----------
    fig : matplotlib Figure
        Empty.
    panels : sequence of MarginPanel
        The constraints evaluated, in the order drawn.
    look : MarginLook
        The layout.
    """
    rows, cols = _grid(len(panels))
    axes = fig.subplots(rows, cols, squeeze=False)
    for ax in axes.ravel()[len(panels) :]:
        ax.axis('off')
    if not panels:
        axes[0, 0].text(0.5, 0.5, 'no constraint evaluated in this scene', ha='center', va='center')
    for ax, panel in zip(axes.ravel(), panels, strict=False):
        _panel(ax, panel, look)
    if look.title:
        fig.suptitle(look.title, fontsize=9)
    fig.tight_layout()
