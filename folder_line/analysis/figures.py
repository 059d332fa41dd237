"""Figures: the papers' curves, shared by ``folder-line report`` and ``folder-line analyze``, and the
figures of a recorded run.

The papers' figures are drawn once -- the layup's exit speeds against the crank
angle (paper L, figs. 4-5, :func:`~folder_line.analysis.paper_curves.exit_speed_curves`), the
delivery's efficiency and carriage speed along the stroke (paper D, fig. 2,
:func:`~folder_line.analysis.paper_curves.stroke_curves`; both in
:mod:`folder_line.analysis.paper_curves`), the colours of the cyclogram's phases (paper F,
figs. 1-2, :data:`~folder_line.analysis.colours.PHASE_COLOURS`) -- so that the model curves of the report
of the defaults (:mod:`folder_line.cli.report`) and the curves the recorded points of a run are
drawn against are the same.

:func:`draw_figures` draws a recorded run's figures (:data:`FIGURES`, those the scene has):

``exit_speeds.png`` (scenes with the layup)
    the chutes' exit speeds ``v_C = ω3 l3``, ``v_E = ω5 l5`` and the absolute ones
    ``v_aC``, ``v_aE`` with the recorded belt speed against the recorded crank angle,
    over the model's curves (paper L, figs. 4-5), with the leaves' exit speeds
    (:func:`~folder_line.analysis.figure_data.exit_speed_data`); the samples before the
    drive reached speed (:func:`~folder_line.analysis.figure_data.at_speed_time`) apart, as
    the start-up;
``efficiency.png`` (scenes with the delivery)
    the efficiency ``η`` and the carriage speed ratio ``K_v`` at the recorded carriage
    positions along the stroke, over the model's curves (paper D, fig. 2), and the
    recorded sprocket torque (``chain_friction``; :func:`~folder_line.analysis.figure_data.efficiency_data`);
``cyclogram.png`` (scenes with the folder)
    the first cycles as a Gantt chart of the operations А (feed: hand-over -> at the
    stops), Б (settle and dwell: at the stops -> settled -> knife contact), В (knife:
    contact -> exit) and Г (delivery: knife exit -> released on the pile), each cycle
    annotated with its margins (paper F, figs. 1-2; :func:`~folder_line.analysis.figure_data.cycle_rows`);
``margins.png``
    a histogram of each constraint's margins over all cycles, violations in red (the margins binned as
    the evaluation's windows pass, on a binary grid regrouped into the bars: :func:`margin_bars`,
    :class:`folder_line.analysis.streaming.MarginHistogram`);
``landing.png`` (scenes with ``leaf_flight``)
    where the leaves landed across the container (``leaf_landed`` events, the container's bins added
    up slice by slice of the events: exact), with the spilled ones
    (:func:`~folder_line.analysis.figure_data.landing_data`).

Every quantity has one colour, that of :data:`~folder_line.analysis.colours.QUANTITY_COLOURS`,
here and in ``folder-line report``.

Figures are written atomically (:func:`save_figure`). matplotlib is imported when the
first figure is drawn, with the Agg back end (:func:`pyplot`).
"""

from __future__ import annotations

import io
import math
import os
from collections.abc import Callable, Mapping, Sequence
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from folder_line.analysis.colours import PHASE_COLOURS, QUANTITY_COLOURS
from folder_line.analysis.efficiency_drawing import EfficiencyPoints, EfficiencyText, draw_efficiency, efficiency_rows
from folder_line.analysis.exit_speed_points import ExitSpeedPoints, ExitSpeedText, draw_exit_speeds
from folder_line.analysis.figure_data import (
    GANTT_CYCLES,
    CycleRow,
    at_speed_time,
    cycle_rows,
    efficiency_data,
    exit_speed_data,
    landing_data,
    leaf_exit_data,
    off_speed,
)
from folder_line.analysis.landing_drawing import LandingText, draw_landing
from folder_line.analysis.margin_drawing import MarginLook, MarginPanel, draw_margins, margins_size
from folder_line.analysis.recording import RecordedJoints, Recording
from folder_line.analysis.replay import ConstraintMargins, Evaluation
from folder_line.core.line.margin_text import CONSTRAINT_UNITS, MARGIN_LABELS, format_margin
from folder_line.core.mechanisms.cyclogram import CycleTiming
from folder_line.files.atomic import write_bytes_atomic
from folder_line.interfaces import NODE_OF_UNIT

if TYPE_CHECKING:  # matplotlib is imported when a figure is drawn (pyplot)
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = [
    'DPI',
    'FIGURES',
    'OPERATIONS',
    'cyclogram_figure',
    'draw_figures',
    'efficiency_figure',
    'exit_speeds_figure',
    'margin_bars',
    'pyplot',
    'save_figure',
]

#: figure file -> what it shows (the captions of report.md)
FIGURES: dict[str, str] = {
    'exit_speeds.png': 'L: exit speeds against the crank angle, recorded (points) over the model (lines); '
    'paper L figs. 4-5',
    'efficiency.png': 'D: efficiency, carriage speed ratio and sprocket torque at the recorded carriage '
    'positions along the stroke; paper D fig. 2',
    'cyclogram.png': 'F: the first cycles as a Gantt chart of the operations А, Б, В, Г with their margins; '
    'paper F figs. 1-2',
    'margins.png': 'margins of every constraint over all cycles (violations in red)',
    'landing.png': 'L: where the leaves landed across the container',
}

#: resolution of the PNGs, dots per inch
DPI = 110


# --------------------------------------------------------------------------- drawing


def pyplot() -> Any:  # the module matplotlib.pyplot: a module is no type
    """``matplotlib.pyplot`` on the non-interactive Agg back end (no display needed)."""
    # imported here, not with the module: matplotlib takes a while to import and its back end
    # must be chosen before pyplot is imported; importing the analysis does neither
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig: Figure, path: str | os.PathLike[str], dpi: int = DPI) -> Path:
    """Write ``fig`` as a PNG to ``path`` atomically (:func:`folder_line.files.atomic.write_bytes_atomic`)
    and close it; a failure leaves no partial file behind."""
    try:
        buf = io.BytesIO()
        fig.savefig(buf, format='png', dpi=dpi)
        return write_bytes_atomic(path, buf.getvalue())
    finally:
        pyplot().close(fig)


# --------------------------------------------------------------------------- figures of a recorded run


def _sampling(joints: RecordedJoints, drawn: int | None = None) -> str:
    """``N recorded samples`` and, where the reading sampled them, how many are drawn and how."""
    text = f'{joints.count} recorded samples'
    shown = joints.t.size if drawn is None else drawn
    if joints.fraction < 1.0:
        text += f' ({shown} drawn: the ticks of a pseudo-random 1/{round(1 / joints.fraction)})'
    elif shown != joints.count:
        text += f' ({shown} drawn)'
    return text


def _leaf_exits(ax: Axes, rec: Recording, ev: Evaluation) -> None:
    """The leaves' exit speeds at their crank angles; those off speed (start-up, holds) hollow
    (:func:`~folder_line.analysis.figure_data.leaf_exit_data`: every exit counted, at most
    :data:`~folder_line.analysis.figure_data.LEAF_POINTS` drawn)."""
    data = leaf_exit_data(rec, ev)
    if data is None:
        return
    drawn = '' if data.fraction >= 1.0 else f'; a pseudo-random 1/{round(1 / data.fraction)} drawn'
    for at_e, exit_name, marker in ((False, 'C', 'v'), (True, 'E', '^')):
        tally = data.tally[exit_name]
        mine = data.at_e == at_e
        early = data.off
        colour = QUANTITY_COLOURS[f'leaf_exit_{exit_name}']
        n_early, n_start = tally.off_speed, tally.start_up
        where = [f'{n_start} in the start-up'] if n_start else []
        where += [f'{n_early - n_start} in holds/stops'] if n_early > n_start else []
        label = f'leaf exits at {exit_name} ({tally.count}'
        label += f'; hollow: {", ".join(where)}' if n_early else ''
        label += drawn + ')'
        ax.plot(data.deg[mine & ~early], data.value[mine & ~early], marker, ms=6, color=colour, label=label)
        if n_early:
            ax.plot(data.deg[mine & early], data.value[mine & early], marker, ms=6, color=colour, mfc='none')


def exit_speeds_figure(rec: Recording, ev: Evaluation) -> Figure | None:
    """The figure of ``exit_speeds.png``: the recorded exit speeds over the model's, or None without a layup.

    The samples taken before the drive reached speed (:func:`~folder_line.analysis.figure_data.at_speed_time`)
    are drawn apart, as the start-up: off the model's curves at nominal speed, below ``v_min`` at first.

    Returns
    -------
    matplotlib Figure or None
        Two axes: swing speeds (paper L fig. 4), absolute exit speeds (fig. 5).
    """
    data = exit_speed_data(rec)
    if data is None:
        return None
    t_speed = at_speed_time(rec, ev)
    early = off_speed(rec, ev, data['t'])
    later = int(np.count_nonzero(early & (data['t'] >= t_speed)))
    points = ExitSpeedPoints(
        np.degrees(data['phi']), data['vC'], data['vE'], data['vaC'], data['vaE'], early, later, t_speed
    )
    belts = rec.joints.get(NODE_OF_UNIT['belts'])
    if rec.scene.has('chute_belts') and belts is not None and 'chute_belts' in belts.names and belts.count:
        lo, hi = belts.extent('chute_belts', 'velocity')  # over every recorded sample, not only those drawn
        belt = f'recorded belt speed {lo:.3f}..{hi:.3f} m/s'
    else:
        belt = 'no belts'
    sampling = f'{_sampling(rec.joints[NODE_OF_UNIT["drive"]], data["t"].size)} over {rec.t_end:.3f} s'
    text = ExitSpeedText('recorded', sampling, belt, holds_after=' after it')
    fig: Figure
    fig, (ax1, ax2) = pyplot().subplots(2, 1, figsize=(9, 8), sharex=True)
    draw_exit_speeds((ax1, ax2), rec.scene, points, text, lambda ax: _leaf_exits(ax, rec, ev))
    fig.tight_layout()
    return fig


def _plot_exit_speeds(rec: Recording, ev: Evaluation, out: Path) -> Path | None:
    fig = exit_speeds_figure(rec, ev)
    return None if fig is None else save_figure(fig, out / 'exit_speeds.png')


def efficiency_figure(rec: Recording, ev: Evaluation) -> Figure | None:
    """The figure of ``efficiency.png``: η, ``K_v`` (and the sprocket torque) at the recorded carriage
    positions over the model's curves, or None without a delivery.

    Returns
    -------
    matplotlib Figure or None
        Axes: efficiency, carriage speed ratio, and the torque with ``chain_friction``.
    """
    data = efficiency_data(rec, ev)
    if data is None:
        return None
    plan = ev.plan
    assert plan is not None  # efficiency data comes from a delivery
    points = EfficiencyPoints(data['u'], data['eta'], data['K_v'], data['moving'], data['torque'])
    sampling = f'{_sampling(rec.joints[NODE_OF_UNIT["feed"]])} over {rec.t_end:.3f} s'
    text = EfficiencyText('recorded', 'drawn', 'the drawn samples', sampling, 'recorded (effort on chain)', 10)
    rows = efficiency_rows(points)
    fig: Figure
    fig, axes = pyplot().subplots(rows, 1, figsize=(9, 3.1 * rows + 0.6), sharex=True)
    draw_efficiency(axes, rec.scene, plan, points, text)
    fig.tight_layout()
    return fig


def _plot_efficiency(rec: Recording, ev: Evaluation, out: Path) -> Path | None:
    fig = efficiency_figure(rec, ev)
    return None if fig is None else save_figure(fig, out / 'efficiency.png')


#: the operations of the cyclogram (paper F): letter, label, colour
OPERATIONS = (
    ('А', 'feed: hand-over -> at the stops', 'tab:green'),
    ('Б', 'settle + dwell: at the stops -> settled -> knife contact', 'tab:blue'),
    ('В', 'knife: contact -> exit', 'tab:red'),
    ('Г', 'delivery: knife exit -> released on the pile', 'tab:purple'),
)


def _margin_text(margins: Mapping[str, float]) -> str:
    """A cycle's margins, as the text shows them (:mod:`folder_line.core.line.margin_text`)."""
    parts = []
    for name, m in margins.items():
        value = format_margin(m, CONSTRAINT_UNITS.get(name, ''), name, precision=3, fixed=False, short=True)
        parts.append(value if name == 'one_per_cycle' else f'{MARGIN_LABELS.get(name, name)} {value}')
    return ' | '.join(parts)


def _plot_cyclogram(rec: Recording, ev: Evaluation, out: Path, n: int) -> Path | None:
    rows = cycle_rows(rec, ev, n)
    timing = ev.timing
    if timing is None:
        return None
    shown = (
        f'the first {len(rows)}'
        if [r.cycle for r in rows] == list(range(len(rows)))
        else f'the first {n} and the first violated'
    )
    title = (
        f'F: cyclogram of {shown} of {ev.cycles} cycles (paper F figs. 1-2), '
        f'T = {timing.T * 1e3:.1f} ms; hatched: bouncing at the stops'
    )
    return save_figure(cyclogram_figure(rows, timing, title), out / 'cyclogram.png')


def cyclogram_figure(rows: Sequence[CycleRow], timing: CycleTiming, title: str, unjudged: str = '') -> Figure:
    """The cyclogram of the cycles ``rows`` (:func:`~folder_line.analysis.figure_data.cycle_rows`'s) under
    the nominal cycle of ``timing`` (a :class:`~folder_line.core.mechanisms.cyclogram.CycleTiming`), titled
    ``title``; ``unjudged`` is written for a cycle without margins."""
    plt = pyplot()
    ms = 1e3
    fig: Figure
    fig, ax = plt.subplots(figsize=(12, 2.2 + 0.55 * (len(rows) + 1)))
    colours = {letter: colour for letter, _, colour in OPERATIONS}
    x_max = timing.T * ms
    for ph in timing.timeline:  # the nominal cycle of the paper's cyclogram, from the knife exit
        a = (ph.t_start - timing.knife.t_out) % timing.T
        b = a + ph.duration
        for lo, hi in ((a, min(b, timing.T)), (0.0, b - timing.T)) if b > timing.T else ((a, b),):
            if hi > lo:
                ax.barh(-1, (hi - lo) * ms, left=lo * ms, height=0.5, color=PHASE_COLOURS[ph.name], alpha=0.35)
        ax.text((a + min(b, timing.T)) / 2 * ms, -1, ph.name, ha='center', va='center', fontsize=7)
    ax.axvline(timing.t_allowed * ms, color='k', ls=':', lw=1)
    for i, row in enumerate(rows):
        x_max = max(x_max, _cycle_bars(ax, i, row, colours))
    text_x = x_max * 1.03
    for i, row in enumerate(rows):
        bad = any(m < 0.0 for m in row.margins.values())
        text = _margin_text(row.margins) or unjudged
        ax.text(text_x, i, text, va='center', fontsize=7.5, color='r' if bad else 'k')
    ax.text(text_x, -1, 'margins of the cycle', va='center', fontsize=8, style='italic')
    ax.set_yticks([-1, *range(len(rows))], ['nominal'] + [f'cycle {r.cycle}' for r in rows])
    for i, (label, row) in enumerate(zip(ax.get_yticklabels()[1:], rows, strict=True)):
        if any(m < 0.0 for m in row.margins.values()):
            label.set_color('r')
        if i and row.cycle != rows[i - 1].cycle + 1:  # cycles left out
            ax.axhline(i - 0.5, color='grey', ls='--', lw=0.8)
    ax.invert_yaxis()
    ax.set_xlim(0, x_max * 1.9)
    ticks = plt.MaxNLocator(nbins=8).tick_values(0.0, x_max)
    ax.set_xticks(ticks[(ticks >= 0.0) & (ticks <= x_max)])
    ax.axvline(x_max * 1.015, color='grey', lw=0.5)
    ax.set_xlabel('time from the start of the cycle (the knife exit of the cycle before), ms')
    handles = [plt.Rectangle((0, 0), 1, 1, color=c, alpha=0.8) for _, _, c in OPERATIONS]
    labels = [f'{letter}: {label}' for letter, label, _ in OPERATIONS]
    handles.append(plt.Line2D([0], [0], color='k', lw=2))
    labels.append('feed deadline of the cycle (window start + t_allowed)')
    fig.legend(handles, labels, loc='lower center', ncol=2, fontsize=8, frameon=False)
    ax.set_title(title, fontsize=10)
    ax.grid(axis='x', alpha=0.3)
    fig.tight_layout(rect=(0.0, 0.85 / fig.get_figheight(), 1.0, 1.0))
    return fig


def _cycle_bars(ax: Axes, i: int, row: CycleRow, colours: Mapping[str, str]) -> float:
    """The operations of one cycle drawn on row ``i``; the latest time drawn, ms from the cycle's start."""
    ms = 1e3
    t0 = row.start
    x_max = 0.0
    h = 0.6 / max(len(row.sheets), 1)
    for j, s in enumerate(row.sheets):
        y = i - 0.3 + h * (j + 0.5)
        settled = s.settled if s.settled is not None and s.settled <= row.contact else None
        segs: list[tuple[str, float | None, float | None, str | None]] = [
            ('А', s.handover, s.at_stops, None),
            ('Б', s.at_stops, s.settled, '////'),
            ('Б', s.settled, row.contact if settled is not None else None, None),
        ]
        if s.release is not None and row.exit is not None:
            segs.append(('Г', row.exit, s.release, None))
        for letter, a, b, hatch in segs:
            if a is None or b is None or b < a:
                continue
            ax.barh(
                y,
                (b - a) * ms,
                left=(a - t0) * ms,
                height=h * 0.9,
                color=colours[letter],
                alpha=0.45 if hatch else 0.8,
                hatch=hatch,
                edgecolor='white' if hatch else None,
            )
            x_max = max(x_max, (b - t0) * ms)
    if not row.sheets:
        ax.text(1.0, i, 'no signature (missing)', va='center', fontsize=8, color='r')
    if row.exit is not None:
        ax.barh(
            i,
            (row.exit - row.contact) * ms,
            left=(row.contact - t0) * ms,
            height=0.6,
            color=colours['В'],
            alpha=0.8,
        )
        x_max = max(x_max, (row.exit - t0) * ms)
    ax.plot([(row.deadline - t0) * ms] * 2, [i - 0.38, i + 0.38], color='k', lw=2)
    return max(x_max, float((row.deadline - t0) * ms))


def _margin_bins(low: float, high: float, unit: str, bins: int = 30) -> np.ndarray:
    """Histogram edges for margins from ``low`` to ``high``: whole numbers for ``sheets``; one bin about the
    value where the margins are equal to rounding (relative spread <= 1e-6)."""
    lo, hi = float(low), float(high)
    if unit == 'sheets':
        return np.arange(math.floor(lo) - 0.5, math.ceil(hi) + 1.0)
    if hi - lo <= 1e-6 * max(abs(lo), abs(hi)):
        mid = 0.5 * (lo + hi)
        half = max(abs(mid) * 0.02, 1e-12)
        return np.array([mid - half, mid + half])
    return np.linspace(lo, hi, bins + 1)


def margin_bars(margins: ConstraintMargins) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The bars of one constraint in ``margins.png``: ``(edges, passed, violated)``, edges in the margin's SI
    unit (:func:`_margin_bins` over the smallest to the largest margin; empty without a margin).

    The counts are the streamed histogram's regrouped (:meth:`~folder_line.analysis.streaming.MarginHistogram.counts`):
    exact, but for margins within one bin of the binary grid (1/2048 of the range at most) of a bar's edge,
    which may be counted in the bar beside.
    """
    h = margins.histogram
    if h.count == 0:
        return np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    edges = _margin_bins(h.low, h.high, margins.unit)
    if edges.size == 2:  # equal margins (to rounding): one bar holds them all
        return edges, np.array([h.count - h.violations]), np.array([h.violations])
    passed, violated = h.counts(edges)
    return edges, passed, violated


#: the layout of a recorded run's ``margins.png``
_MARGINS = MarginLook(5.2, 3.0, 0.4, pad=None, one_bar_pad=1.0)


def _margin_hist(margins: ConstraintMargins, ax: Axes, scale: float) -> np.ndarray:
    """One constraint's bars (:func:`margin_bars`), passed and violated stacked; their edges, display unit."""
    nv = margins.histogram.violations
    edges, passed, violated = margin_bars(margins)
    edges = edges * scale
    centres = 0.5 * (edges[:-1] + edges[1:])
    ax.hist(
        [centres, centres],
        bins=edges.tolist(),  # the same edges, as the sequence matplotlib's types ask for
        weights=[passed, violated],
        stacked=True,
        color=['C0', 'tab:red'],
        label=['passed', f'violated ({nv})' if nv else '_nolegend_'],
    )
    return edges


def _plot_margins(ev: Evaluation, out: Path) -> Path:
    panels = [
        MarginPanel(
            c.name, c.unit, c.histogram.count, c.histogram.violations, c.histogram.low, partial(_margin_hist, c)
        )
        for c in ev.margins.values()
    ]
    fig = pyplot().figure(figsize=margins_size(len(panels), _MARGINS))
    draw_margins(fig, panels, _MARGINS)
    return save_figure(fig, out / 'margins.png')


def _plot_landing(rec: Recording, out: Path) -> Path | None:
    data = landing_data(rec)
    if data is None:
        return None
    fig, ax = pyplot().subplots(figsize=(9, 4.5))
    thinned = data.fraction < 1.0
    text = LandingText(
        spilled=f'spilled over a wall ({data.spilled_count})',
        rug=f'landing x of a pseudo-random 1/{round(1 / data.fraction)} of the leaves'
        if thinned
        else 'landing x of each leaf',
        span=f' over {rec.t_end:.3f} s',
    )
    draw_landing(ax, data, text)
    fig.tight_layout()
    return save_figure(fig, out / 'landing.png')


def draw_figures(rec: Recording, ev: Evaluation, out: Path, gantt_cycles: int = GANTT_CYCLES) -> dict[str, Path]:
    """Draw the figures of :data:`FIGURES` the scene has into ``out``.

    Parameters
    ----------
    rec : Recording
    ev : Evaluation
        ``rec`` judged (:func:`folder_line.analysis.replay.evaluate`).
    out : Path
        An existing directory.
    gantt_cycles : int
        Cycles in the cyclogram.

    Returns
    -------
    dict of str to Path
        Figure file name -> the file written, in the order of :data:`FIGURES`.
    """
    figures: dict[str, Path] = {}
    drawers: tuple[tuple[str, Callable[[], Path | None]], ...] = (
        ('exit_speeds.png', lambda: _plot_exit_speeds(rec, ev, out)),
        ('efficiency.png', lambda: _plot_efficiency(rec, ev, out)),
        ('cyclogram.png', lambda: _plot_cyclogram(rec, ev, out, gantt_cycles)),
        ('margins.png', lambda: _plot_margins(ev, out)),
        ('landing.png', lambda: _plot_landing(rec, out)),
    )
    for name, draw in drawers:
        written = draw()
        if written is not None:
            figures[name] = written
    return figures
