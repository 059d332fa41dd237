"""The figures of ``simulate --plots`` drawn from a streamed run's :class:`folder_line.cli.plots.FigureData`.

What each figure keeps of the line, and so what it shows, is told in :mod:`folder_line.cli.plots`.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from folder_line.analysis.colours import QUANTITY_COLOURS
from folder_line.analysis.exit_speed_points import ExitSpeedPoints, ExitSpeedText, draw_exit_speeds
from folder_line.analysis.figures import (
    DISPLAY_UNITS,
    cyclogram_figure,
    pyplot,
    save_figure,
)
from folder_line.analysis.paper_curves import stroke_curves
from folder_line.core.effects import chain_friction, leaf_flight
from folder_line.core.line.delivery_plan import delivery_plan
from folder_line.core.line.margin_text import format_margin
from folder_line.core.mechanisms import delivery
from folder_line.core.mechanisms.cyclogram import cycle_timing

if TYPE_CHECKING:
    from folder_line.cli.plots import FigureData

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


def _leaf_exits(ax: Any, data: FigureData) -> None:
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
    plt = pyplot()
    rows = 3 if torque.size else 2
    fig, axes = plt.subplots(rows, 1, figsize=(9, 3.1 * rows + 0.6), sharex=True)
    ax_eta, ax_kv = axes[0], axes[1]
    stroke_curves(ax_eta, ax_kv, plan.params, ('geometric',), pairs=True)
    ax_eta.plot(u, eta, 'o', ms=3, color='k', alpha=0.6, label=f'at the simulated carriage positions ({u.size} ticks)')
    ax_kv.plot(u[moving], kv[moving], 'o', ms=3, color='k', alpha=0.6, label='simulated carriage speed / chain speed')
    release = QUANTITY_COLOURS['release']
    for ax in axes:
        ax.axvline(plan.u_rel, color=release, ls='--', lw=1)
    ax_eta.text(plan.u_rel, ax_eta.get_ylim()[0], ' release', color=release, va='bottom', fontsize=8)
    ax_eta.set_ylabel('efficiency $\\eta$')
    title = 'D: efficiency along the stroke (paper Fig. 2)'
    if eta.size:
        title += (
            f'; min eta at the ticks drawn {eta.min():.3f}, of the model '
            f'{delivery.stroke_minimum(plan.params, "eta")[1]:.3f}\n'
            f'simulated at {data.ticks.text(int(t.size))}, {u.size} of them with a carriage on the stroke; '
            f'{_span(data)}'
        )
    ax_eta.set_title(title, fontsize=9)
    ax_eta.legend(fontsize=8, loc='lower left')
    ax_kv.set_ylabel('carriage speed ratio $K_v$')
    ax_kv.legend(fontsize=8, loc='lower left')
    if torque.size:
        ax_t = axes[2]
        sch = plan.schedule
        theta = sch.theta_enter0 + np.linspace(0.0, sch.T, 4001, endpoint=False)
        a0, slack = sch.stroke_travel(theta)
        stroke = a0 <= sch.S + slack
        u_m = plan.path.position(np.clip(a0[stroke], 0.0, sch.S))
        tq = np.asarray(chain_friction.sprocket_torque(scene, theta[stroke]), dtype=float)
        order = np.argsort(u_m)
        ax_t.plot(u_m[order], tq[order], color=QUANTITY_COLOURS['torque'], label='model: all carriages on the stroke')
        ax_t.plot(u, torque, 'o', ms=3, color='k', alpha=0.6, label='simulated (effort on the chain)')
        ax_t.set_ylabel('sprocket torque $M_1$, N m')
        ax_t.legend(fontsize=8, loc='upper right')
        ax_t.grid(alpha=0.3)
    axes[-1].set_xlabel('stroke position u of the newest carriage (deceleration 0..1, acceleration 1..2)')
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


def _margins(data: FigureData, out: Path) -> Path:
    plt = pyplot()
    names = list(data.margins)
    n = max(len(names), 1)
    cols = 2 if n > 1 else 1
    nrows = math.ceil(n / cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(5.4 * cols, 3.1 * nrows + 0.7), squeeze=False)
    for ax in axes.ravel()[len(names) :]:
        ax.axis('off')
    if not names:
        axes[0, 0].text(0.5, 0.5, 'no constraint evaluated in this scene', ha='center', va='center')
    for ax, name in zip(axes.ravel(), names, strict=False):
        h = data.margins[name]
        unit_in = data.units[name]
        scale, unit = DISPLAY_UNITS.get(unit_in, (1.0, unit_in))
        nv = h.violated
        ax.set_title(f'{name}: {h.count} evaluations, {nv} violated', fontsize=9, color='tab:red' if nv else 'k')
        ax.set_xlabel(f'margin, {unit}' if unit not in ('', '1') else 'margin (dimensionless)')
        ax.set_ylabel('count')
        if h.count == 0:
            ax.text(0.5, 0.5, 'no evaluation', ha='center', va='center', transform=ax.transAxes)
            continue
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
            ax.bar(
                edges[:-1], failed, width=width, bottom=passed, align='edge', color='tab:red', label=f'violated ({nv})'
            )
        if edges[0] <= 0.0 <= edges[-1]:
            ax.axvline(0.0, color='k', lw=1)
        low = h.low * scale
        ax.axvline(low, color='tab:orange', ls='--', lw=1, label=f'min {low:.4g}')
        ax.legend(fontsize=7)
        ax.ticklabel_format(axis='x', style='sci', scilimits=(-3, 4), useOffset=False)
        span = edges[-1] - edges[0]
        ax.set_xlim(edges[0] - 0.05 * span, edges[-1] + 0.05 * span)
    fig.suptitle(
        f'margins of every constraint judged in {_span(data)}: exact counts in bins of a streamed histogram '
        '(widths double as the range grows)',
        fontsize=9,
    )
    fig.tight_layout()
    return save_figure(fig, out / 'margins.png')


def _landing(data: FigureData, out: Path) -> Path | None:
    cont = data.container
    if cont is None:
        return None
    hist = leaf_flight.histogram_of_counts(data.landed, cont.x_left, cont.x_right)
    edges, counts = np.asarray(hist.edges), np.asarray(hist.counts)
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(9, 4.5))
    ax.bar(
        edges[:-1],
        counts,
        width=np.diff(edges),
        align='edge',
        color='C0',
        edgecolor='white',
        label=f'landed ({int(counts.sum())})',
    )
    spilled = data.spilled_x.column('x')
    if data.spilled_x.count:
        drawn = '' if spilled.size == data.spilled_x.count else f'; {spilled.size} drawn'
        ax.plot(
            spilled,
            np.zeros(spilled.size),
            'x',
            color='tab:red',
            ms=8,
            mew=2,
            label=f'spilled over a wall ({data.spilled_x.count}{drawn})',
        )
    x = data.landed_x.column('x')
    rug = (
        'landing x of each leaf'
        if x.size == data.landed_x.count
        else f'landing x of {x.size} leaves (a pseudo-random sample)'
    )
    ax.plot(x, np.full(x.size, -0.04 * max(counts.max(initial=1), 1)), '|', color='k', ms=10, label=rug)
    for wall in (cont.x_left, cont.x_right):
        ax.axvline(wall, color='k', lw=3)
    width = cont.x_right - cont.x_left
    ax.set_xlim(cont.x_left - 0.1 * width, cont.x_right + 0.1 * width)
    cv = 'n/a' if hist.cv is None else f'{hist.cv:.3f}'
    ax.set_title(
        f'L: leaf landing across the container ({len(counts)} bins, CV of the counts {cv}), {_span(data)}',
        fontsize=10,
    )
    ax.set_xlabel('x on the container floor, m (thick lines: the walls)')
    ax.set_ylabel('leaves per bin')
    ax.yaxis.set_major_locator(plt.MaxNLocator(integer=True))
    ax.legend(fontsize=8, loc='upper right')
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
