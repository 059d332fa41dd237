"""Where a run's leaves landed across the container (``landing.png``): :func:`draw_landing`.

One drawing for a recorded run (``folder-line analyze``, :mod:`folder_line.analysis.figures`) and a
simulated one (``folder-line simulate --plots``, :mod:`folder_line.cli.plot_drawing`): the leaves
landed per bin of the container (exact counts), the spilled ones and a rug of the landings drawn,
between the walls. What the two runs write differently is :class:`LandingText`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # matplotlib is imported when a figure is drawn (folder_line.analysis.figures.pyplot)
    from matplotlib.axes import Axes

    from folder_line.analysis.figure_data import Landings

__all__ = ['LandingText', 'draw_landing']


@dataclass(frozen=True)
class LandingText:
    """The words of the figure that tell a recorded run from a simulated one.

    Attributes
    ----------
    spilled : str
        The spilled leaves' name in the legend.
    rug : str
        The landings drawn one by one, in the legend.
    span : str
        Ends the title: the line time of the run.
    """

    spilled: str
    rug: str
    span: str


def draw_landing(ax: Axes, data: Landings, text: LandingText) -> None:
    """Draw a run's landings on the axes of ``landing.png``.

    Parameters
    ----------
    ax : matplotlib Axes
    data : Landings
        The run's landings.
    text : LandingText
        The words of the run's kind.
    """
    edges, counts = data.edges, data.counts
    ax.bar(
        edges[:-1],
        counts,
        width=np.diff(edges),
        align='edge',
        color='C0',
        edgecolor='white',
        label=f'landed ({int(counts.sum())})',
    )
    if data.spilled.size:
        ax.plot(data.spilled, np.zeros(data.spilled.size), 'x', color='tab:red', ms=8, mew=2, label=text.spilled)
    ax.plot(data.x, np.full(data.x.size, -0.04 * max(counts.max(initial=1), 1)), '|', color='k', ms=10, label=text.rug)
    for wall in (data.x_left, data.x_right):
        ax.axvline(wall, color='k', lw=3)
    width = data.x_right - data.x_left
    ax.set_xlim(data.x_left - 0.1 * width, data.x_right + 0.1 * width)
    cv = 'n/a' if data.cv is None else f'{data.cv:.3f}'
    ax.set_title(
        f'L: leaf landing across the container ({len(counts)} bins, CV of the counts {cv}){text.span}', fontsize=10
    )
    ax.set_xlabel('x on the container floor, m (thick lines: the walls)')
    ax.set_ylabel('leaves per bin')
    from matplotlib.ticker import MaxNLocator

    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax.legend(fontsize=8, loc='upper right')
