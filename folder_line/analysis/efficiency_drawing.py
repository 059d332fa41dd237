"""The delivery's efficiency at a run's carriage positions (``efficiency.png``): :func:`draw_efficiency`.

One drawing for a recorded run (``folder-line analyze``,
:func:`folder_line.analysis.figures.efficiency_figure`) and a simulated one (``folder-line simulate
--plots``, :mod:`folder_line.cli.plot_drawing`): the efficiency ``η`` and the carriage speed ratio
``K_v`` at the run's carriage positions along the stroke over the model's curves (paper D, fig. 2,
:func:`~folder_line.analysis.paper_curves.stroke_curves`), the release, and the sprocket torque over
the model's where the run has it. What the two runs write differently is :class:`EfficiencyText`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from folder_line.analysis.colours import QUANTITY_COLOURS
from folder_line.analysis.paper_curves import stroke_curves
from folder_line.core.effects import chain_friction
from folder_line.core.mechanisms import delivery

if TYPE_CHECKING:  # matplotlib is imported when a figure is drawn (folder_line.analysis.figures.pyplot)
    from matplotlib.axes import Axes

    from folder_line.core.line.delivery_plan import DeliveryPlan
    from folder_line.core.line.scene import Scene

__all__ = ['EfficiencyPoints', 'EfficiencyText', 'draw_efficiency', 'efficiency_rows']


@dataclass(frozen=True)
class EfficiencyPoints:
    """A run's samples with a carriage on the stroke, one entry a sample.

    Attributes
    ----------
    u : ndarray
        Stroke position of the newest carriage (deceleration 0..1, acceleration 1..2).
    eta : ndarray
        The model's efficiency at ``u``.
    k_v : ndarray
        Carriage speed / chain speed (0 where the chain stood).
    moving : ndarray of bool
        The chain moved.
    torque : ndarray
        Sprocket torque, N m; empty where the run has none.
    """

    u: np.ndarray
    eta: np.ndarray
    k_v: np.ndarray
    moving: np.ndarray
    torque: np.ndarray


@dataclass(frozen=True)
class EfficiencyText:
    """The words of the figure that tell a recorded run from a simulated one.

    Attributes
    ----------
    source : str
        The points' kind in the legends (``'recorded'``, ``'simulated'``).
    counted : str
        What the number of points in the legend counts (``'drawn'``, ``'ticks'``).
    at : str
        The points the title's smallest efficiency is of (``'the drawn samples'``).
    sampling : str
        The title's second line: what was sampled, over which span.
    torque : str
        The torque points' name in the legend.
    title_size : float
        The title's font size, pt.
    """

    source: str
    counted: str
    at: str
    sampling: str
    torque: str
    title_size: float


def efficiency_rows(points: EfficiencyPoints) -> int:
    """Axes of the figure: efficiency, carriage speed ratio and, with a torque, the torque."""
    return 3 if points.torque.size else 2


def _torque(ax: Axes, scene: Scene, plan: DeliveryPlan, points: EfficiencyPoints, text: EfficiencyText) -> None:
    """The sprocket torque with all carriages on the stroke (model) and the run's."""
    sch = plan.schedule
    theta = sch.theta_enter0 + np.linspace(0.0, sch.T, 4001, endpoint=False)
    a0, slack = sch.stroke_travel(theta)
    on = a0 <= sch.S + slack
    u_m = plan.path.position(np.clip(a0[on], 0.0, sch.S))
    tq = np.asarray(chain_friction.sprocket_torque(scene, theta[on]), dtype=float)
    order = np.argsort(u_m)
    ax.plot(u_m[order], tq[order], color=QUANTITY_COLOURS['torque'], label='model: all carriages on the stroke')
    ax.plot(points.u, points.torque, 'o', ms=3, color='k', alpha=0.6, label=text.torque)
    ax.set_ylabel('sprocket torque $M_1$, N m')
    ax.legend(fontsize=8, loc='upper right')
    ax.grid(alpha=0.3)


def draw_efficiency(
    axes: Sequence[Axes], scene: Scene, plan: DeliveryPlan, points: EfficiencyPoints, text: EfficiencyText
) -> None:
    """Draw a run's efficiency over the model's on the axes of ``efficiency.png``.

    Parameters
    ----------
    axes : sequence of matplotlib Axes
        :func:`efficiency_rows` of them, sharing the stroke position.
    scene : Scene
        The run's scene (with the delivery).
    plan : DeliveryPlan
        Its delivery's plan.
    points : EfficiencyPoints
        The run's samples.
    text : EfficiencyText
        The words of the run's kind.
    """
    ax_eta, ax_kv = axes[0], axes[1]
    stroke_curves(ax_eta, ax_kv, plan.params, ('geometric',), pairs=True)
    u, eta, m = points.u, points.eta, points.moving
    label = f'at the {text.source} carriage positions ({u.size} {text.counted})'
    ax_eta.plot(u, eta, 'o', ms=3, color='k', alpha=0.6, label=label)
    label = f'{text.source} carriage speed / chain speed'
    ax_kv.plot(u[m], points.k_v[m], 'o', ms=3, color='k', alpha=0.6, label=label)
    release = QUANTITY_COLOURS['release']
    for ax in axes:
        ax.axvline(plan.u_rel, color=release, ls='--', lw=1)
    ax_eta.text(plan.u_rel, ax_eta.get_ylim()[0], ' release', color=release, va='bottom', fontsize=8)
    ax_eta.set_ylabel('efficiency $\\eta$')
    title = 'D: efficiency along the stroke (paper Fig. 2)'
    if eta.size:
        title += (
            f'; min eta at {text.at} {eta.min():.3f}, of the model '
            f'{delivery.stroke_minimum(plan.params, "eta")[1]:.3f}\n{text.sampling}'
        )
    ax_eta.set_title(title, fontsize=text.title_size)
    ax_eta.legend(fontsize=8, loc='lower left')
    ax_kv.set_ylabel('carriage speed ratio $K_v$')
    ax_kv.legend(fontsize=8, loc='lower left')
    if points.torque.size:
        _torque(axes[2], scene, plan, points, text)
    axes[-1].set_xlabel('stroke position u of the newest carriage (deceleration 0..1, acceleration 1..2)')
