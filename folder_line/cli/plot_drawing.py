"""The figures of ``simulate --plots`` drawn from a streamed run's :class:`folder_line.cli.plots.FigureData`.

What each figure keeps of the line, and so what it shows, is told in :mod:`folder_line.cli.plots`.
"""

from __future__ import annotations

import math
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from folder_line.analysis.colours import QUANTITY_COLOURS
from folder_line.analysis.efficiency_drawing import EfficiencyPoints, EfficiencyText, draw_efficiency, efficiency_rows
from folder_line.analysis.exit_speed_points import ExitSpeedPoints, ExitSpeedText, draw_exit_speeds
from folder_line.analysis.figure_data import Landings
from folder_line.analysis.figures import cyclogram_figure, pyplot, save_figure
from folder_line.analysis.landing_drawing import LandingText, draw_landing
from folder_line.analysis.margin_drawing import MarginLook, MarginPanel, draw_margins, margins_size
from folder_line.core.effects import leaf_flight
from folder_line.core.line.delivery_plan import delivery_plan
from folder_line.core.line.margin_text import format_margin
from folder_line.core.mechanisms import delivery
from folder_line.core.mechanisms.cyclogram import cycle_timing

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from folder_line.cli.plots import FigureData, StreamedHistogram

__all__ = ['draw']


def _span(data: FigureData) -> str:
    return f'line time {data.start:g}..{data.end:g} s'


def _exit_speeds(data: FigureData, out: Path) -> Path | None:
    t = data.joint('t')
    if not data.layup or t.size == 0:
        return None
    lp = data.scene.machine('layup')
    off = data.joint('off').astype(bool)
    t_speed = data.start if data.t_speed is None else data.t_speed
    v_c, v_e = data.joint('w3') * lp.l3, data.joint('w5') * lp.l5
    belt = data.joint('v_belt')
    points = ExitSpeedPoints(
        np.degrees(data.joint('phi')),
        v_c,
        v_e,
        np.sqrt(v_c * v_c + belt * belt),
        np.sqrt(v_e * v_e + belt * belt),
        off,
        int(np.count_nonzero(off & (t >= t_speed))),
        math.inf if data.t_speed is None else data.t_speed,
    )
    belt_text = f'belt speed {data.belt_low:.3f}..{data.belt_high:.3f} m/s at every tick' if data.belts else 'no belts'
    sampling = f'simulated at {data.ticks.text(int(t.size))}; {_span(data)}'
    text = ExitSpeedText('simulated', sampling, belt_text, ticks_drawn=' drawn', legend_below=True)
    fig, (ax1, ax2) = pyplot().subplots(2, 1, figsize=(9, 9.5), sharex=True)
    draw_exit_speeds((ax1, ax2), data.scene, points, text, lambda ax: _leaf_exits(ax, data))
    fig.tight_layout()
    return save_figure(fig, out / 'exit_speeds.png')


def _leaf_exits(ax: Axes, data: FigureData) -> None:
    for name, marker in (('C', 'v'), ('E', '^')):
        n = data.exit_counts[name]
        if not n['all']:
            continue
        at, off = data.exits[name, False], data.exits[name, True]
        colour = QUANTITY_COLOURS[f'leaf_exit_{name}']
        where = [f'{n["start_up"]} in the start-up'] if n['start_up'] else []
        where += [f'{n["early"] - n["start_up"]} in holds/stops'] if n['early'] > n['start_up'] else []
        drawn_at, drawn_off = at.column('v').size, off.column('v').size
        label = f'leaf exits at {name} ({n["all"]}'
        label += f'; {drawn_at} of the {at.count} at speed drawn' if drawn_at < at.count else ''
        label += f'; hollow: {", ".join(where)}' if n['early'] else ''
        label += f', {drawn_off} drawn)' if drawn_off < off.count else ')'
        ax.plot(at.column('deg'), at.column('v'), marker, ms=6, color=colour, label=label)
        if drawn_off:
            ax.plot(off.column('deg'), off.column('v'), marker, ms=6, color=colour, mfc='none')


def _efficiency(data: FigureData, out: Path) -> Path | None:
    t = data.joint('t')
    scene = data.scene
    if not data.delivery or t.size == 0:
        return None
    timing = cycle_timing(scene.machine('cyclogram'), scene.machine('knife'))
    plan = delivery_plan(scene, timing)
    if plan is None:
        return None
    x, v, v_chain = data.joint('x'), data.joint('v'), data.joint('v_chain')
    on = (x > 0.0) | (v > 0.0)  # a carriage on the stroke
    u_grid = np.linspace(0.0, 2.0, 20001)
    st = delivery.evaluate_stroke(plan.params, u_grid, return_section='geometric')
    x_grid = u_grid * plan.chain.x_max + plan.rod * (1.0 - np.cos(st.alpha))
    u = np.interp(x[on], x_grid, u_grid)
    eta = delivery.evaluate_stroke(plan.params, u, return_section='geometric').eta
    moving = v_chain[on] > 0.0
    kv = np.divide(v[on], v_chain[on], out=np.zeros(u.size), where=moving)
    torque = data.joint('torque')[on] if 'torque' in data.joints else np.zeros(0)
    points = EfficiencyPoints(u, eta, kv, moving, torque)
    sampling = (
        f'simulated at {data.ticks.text(int(t.size))}, {u.size} of them with a carriage on the stroke; {_span(data)}'
    )
    text = EfficiencyText('simulated', 'ticks', 'the ticks drawn', sampling, 'simulated (effort on the chain)', 9)
    rows = efficiency_rows(points)
    fig, axes = pyplot().subplots(rows, 1, figsize=(9, 3.1 * rows + 0.6), sharex=True)
    draw_efficiency(axes, scene, plan, points, text)
    fig.tight_layout()
    return save_figure(fig, out / 'efficiency.png')


def _cyclogram(data: FigureData, out: Path) -> Path | None:
    cg = data.cyclogram
    if cg is None:
        return None
    rows = cg.done()
    firsts = [r for r in rows if r.cycle in cg.first]
    shown = f'the first {len(firsts)}' + (' and the first violated' if len(firsts) < len(rows) else '')
    if not rows:
        shown = 'no cycle'
    title = (
        f'F: cyclogram of {shown} of {cg.cycles} cycles judged at the knife in {_span(data)} '
        f'(paper F figs. 1-2)\nT = {cg.timing.T * 1e3:.1f} ms; hatched: bouncing at the stops'
    )
    fig = cyclogram_figure(rows, cg.timing, title, unjudged='not judged in the span')
    return save_figure(fig, out / 'cyclogram.png')


def _bars(h: StreamedHistogram, name: str, unit_in: str, ax: Axes, scale: float) -> np.ndarray:
    """One constraint's bars: passed and violated stacked, one bar about the value where the margins are
    equal to rounding (said on the panel), a log count axis where a bin would not show; their edges."""
    nv = h.violated
    edges = h.edges * scale
    flat = unit_in != 'sheets' and h.high - h.low <= 1e-6 * max(abs(h.low), abs(h.high))
    if flat:  # equal to rounding: one bar about the value
        mid = 0.5 * (h.low + h.high) * scale
        half = max(abs(mid) * 0.02, 1e-12)
        edges = np.array([mid - half, mid + half])
        passed, failed = np.array([h.count - nv]), np.array([nv])
        ax.text(
            0.5,
            0.5,
            f'all {h.count} equal to {format_margin(h.low, unit_in, name)}\n(to rounding: one bar about it)',
            ha='center',
            va='center',
            transform=ax.transAxes,
            fontsize=8,
            bbox={'facecolor': 'white', 'alpha': 0.8, 'edgecolor': 'none'},
        )
    else:
        passed, failed = h.passed, h.failed
    width = np.diff(edges)
    nonzero = np.concatenate((passed, failed))
    nonzero = nonzero[nonzero > 0]
    if nonzero.size and nonzero.min() * 100 < nonzero.max():  # a bin under 1 % of the tallest: invisible
        ax.set_yscale('log')
        ax.set_ylabel('count (log scale)')
    ax.bar(edges[:-1], passed, width=width, align='edge', color='C0', label='passed')
    if nv:
        ax.bar(edges[:-1], failed, width=width, bottom=passed, align='edge', color='tab:red', label=f'violated ({nv})')
    return edges


def _margins(data: FigureData, out: Path) -> Path:
    panels = [
        MarginPanel(name, data.units[name], h.count, h.violated, h.low, partial(_bars, h, name, data.units[name]))
        for name, h in data.margins.items()
    ]
    look = MarginLook(
        5.4,
        3.1,
        0.7,
        pad=0.05,
        one_bar_pad=0.05,
        title=f'margins of every constraint judged in {_span(data)}: exact counts in bins of a streamed histogram '
        '(widths double as the range grows)',
    )
    fig = pyplot().figure(figsize=margins_size(len(panels), look))
    draw_margins(fig, panels, look)
    return save_figure(fig, out / 'margins.png')


def _drawn(count: int, drawn: int) -> float:
    """The fraction of ``count`` items ``drawn`` (1 of none)."""
    return drawn / count if count else 1.0


def _landing(data: FigureData, out: Path) -> Path | None:
    cont = data.container
    if cont is None:
        return None
    hist = leaf_flight.histogram_of_counts(data.landed, cont.x_left, cont.x_right)
    x, spilled = data.landed_x.column('x'), data.spilled_x.column('x')
    landings = Landings(
        x=x,
        spilled=spilled,
        landed=data.landed_x.count,
        spilled_count=data.spilled_x.count,
        fraction=min(_drawn(data.landed_x.count, x.size), _drawn(data.spilled_x.count, spilled.size)),
        edges=np.asarray(hist.edges),
        counts=np.asarray(hist.counts),
        cv=hist.cv,
        x_left=cont.x_left,
        x_right=cont.x_right,
    )
    drawn = '' if spilled.size == data.spilled_x.count else f'; {spilled.size} drawn'
    rug = (
        'landing x of each leaf'
        if x.size == data.landed_x.count
        else f'landing x of {x.size} leaves (a pseudo-random sample)'
    )
    text = LandingText(f'spilled over a wall ({data.spilled_x.count}{drawn})', rug, f', {_span(data)}')
    fig, ax = pyplot().subplots(figsize=(9, 4.5))
    draw_landing(ax, landings, text)
    fig.tight_layout()
    return save_figure(fig, out / 'landing.png')


def draw(data: FigureData, out: Path) -> dict[str, Path]:
    """Draw the figures of :data:`~folder_line.analysis.figures.FIGURES` the scene has into ``out``.

    Returns
    -------
    dict of str to Path
        Figure file name -> the file written, in the order of ``FIGURES``.
    """
    figures: dict[str, Path] = {}
    for name, fn in (
        ('exit_speeds.png', _exit_speeds),
        ('efficiency.png', _efficiency),
        ('cyclogram.png', _cyclogram),
        ('margins.png', _margins),
        ('landing.png', _landing),
    ):
        written = fn(data, out)
        if written is not None:
            figures[name] = written
    return figures
