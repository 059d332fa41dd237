"""``sweep.png``: a sweep's metrics as curves over one key, or as a heat map over two.

* One varied key (with more than one value): one panel per metric against the key, the zero
  line of each constraint margin, refused points as grey crosses on the axis.
* Two: a heat map of the first metric, the boundary where it is zero (a margin's feasible side
  is where it is >= 0), and, when several constraints are swept, the boundary of the region
  where all of them hold (margins >= 0, no violation); refused points in grey.

Both mark the scene's own point and the papers' point (:mod:`folder_line.studies.paper`) where
there is one. Seconds are shown as ms, and margins in their units of the text
(:func:`folder_line.core.line.margin_text.shown_unit`: metres as mm). Three or more keys: no plot.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from folder_line.analysis.figures import pyplot, save_figure
from folder_line.core.line.margin_text import MARGIN_AXIS_NOTES, margin_constraint, shown_unit
from folder_line.studies.paper import PAPER_NOTES, paper_rule
from folder_line.studies.points import OK
from folder_line.studies.sweep import SweepPlan, SweepResult

if TYPE_CHECKING:  # matplotlib is imported when a plot is drawn (folder_line.analysis.figures.pyplot)
    from matplotlib.artist import Artist
    from matplotlib.axes import Axes

__all__ = ['plot_sweep', 'plotted_keys']

#: unit of a value that is not a margin -> (factor, unit shown) on the charts
_SHOWN = {'s': (1e3, 'ms')}


def plotted_keys(result: SweepResult) -> tuple[str, ...]:
    """The varied keys with more than one value: one is drawn as curves, two as a heat map, more not at all."""
    return tuple(v.key for v in result.plan.varies if v.n > 1)


def _shown(metric: str, unit: str) -> tuple[float, str]:
    return shown_unit(unit) if _is_margin(metric) else _SHOWN.get(unit, (1.0, unit))


def _is_margin(metric: str) -> bool:
    return metric.startswith(('min_margin.', 'min_margin_s.'))


def _label(name: str, unit: str) -> str:
    return f'{name}, {unit}' if unit else f'{name} (dimensionless)'


def _values(result: SweepResult, i: int) -> np.ndarray:
    return np.array([np.nan if r.values[i] is None else r.values[i] for r in result.results], dtype=float)


def _feasible(result: SweepResult) -> np.ndarray | None:
    """Per point: every swept constraint holds (margins >= 0, no violation); None when none is swept."""
    plan = result.plan
    checks = [i for i, m in enumerate(plan.metrics) if _is_margin(m) or m == 'violations.count']
    if not checks:
        return None
    ok = np.array([r.status == OK for r in result.results])
    for i in checks:
        v = _values(result, i)
        with np.errstate(invalid='ignore'):
            ok &= (v == 0.0) if plan.metrics[i] == 'violations.count' else (v >= 0.0)
    return ok.astype(float)


def _y_label(metric: str, unit: str) -> str:
    if _is_margin(metric):
        return f'margin, {unit}' if unit else 'margin (dimensionless)'
    if metric.endswith('count'):
        return 'count'
    return f'value, {unit}' if unit else 'value (dimensionless)'


def _note(metric: str) -> str | None:
    """What a margin's value means, where its number alone misleads (a count, a tolerance); else None."""
    return MARGIN_AXIS_NOTES.get(margin_constraint(metric)) if _is_margin(metric) else None


def _title(metric: str) -> str:
    """A panel's title: the metric, with its :func:`_note`."""
    note = _note(metric)
    return f'{metric}  ({note})' if note else metric


def _mark_text(key: str, value: object, unit: str) -> str:
    return f'{key} = {value:.6g} {unit}'.rstrip() if isinstance(value, int | float) else f'{key} = {value}'


def plot_sweep(result: SweepResult, path: Path) -> Path | None:
    """Draw ``sweep.png`` at ``path`` (atomically); None when there is nothing to draw (no key with several
    values, or more than two)."""
    keys = plotted_keys(result)
    if len(keys) == 1:
        return _curves(result, keys[0], path)
    if len(keys) == 2:
        return _heat_map(result, keys, path)
    return None


def _curves(result: SweepResult, key: str, path: Path) -> Path:
    plt = pyplot()
    plan = result.plan
    x = np.array([p[key] for p in plan.points], dtype=float)
    ok = np.array([r.status == OK for r in result.results])
    n = max(len(plan.metrics), 1)
    fig, axes = plt.subplots(n, 1, figsize=(7.0, 1.2 + 2.1 * n), sharex=True, squeeze=False)
    scene_x, paper = plan.scene_point.get(key), plan.paper_point
    key_unit = plan.units[key]
    legend: dict[str, Artist] = {}
    for i, (ax, metric) in enumerate(zip(axes[:, 0], plan.metrics, strict=False)):
        factor, unit = _shown(metric, plan.units[metric])
        y = _values(result, i) * factor
        step = {'drawstyle': 'steps-mid'} if unit == '' and metric.endswith('count') else {}
        ax.plot(x, y, 'o-', ms=3, color='C0', label='_nolegend_', **step)
        ax.set_title(_title(metric), fontsize=9, loc='left')
        if unit == 'sheets':  # whole sheets: 0 is one per cycle, -1 one off
            ax.yaxis.set_major_locator(plt.matplotlib.ticker.MaxNLocator(integer=True))
            ax.set_ylim(min(float(np.nanmin(y, initial=0.0)), -1.0) - 0.5, 0.5)
        if _is_margin(metric):
            ax.axhline(0.0, color='k', lw=0.9, label='margin = 0 (below: violated)')
            with np.errstate(invalid='ignore'):
                bad = y < 0.0
            if bad.any():
                ax.plot(x[bad], y[bad], 'o', ms=4, color='tab:red', label='violated')
        if (~ok).any():
            ax.plot(
                x[~ok],
                np.zeros(int((~ok).sum())),
                'x',
                color='grey',
                transform=ax.get_xaxis_transform(),
                clip_on=False,
                label='refused by the model',
            )
        if isinstance(scene_x, int | float):
            ax.axvline(
                float(scene_x), color='tab:green', ls='--', lw=1.2, label=f'scene: {_mark_text(key, scene_x, key_unit)}'
            )
        if paper is not None:
            note = PAPER_NOTES.get(key, 'paper')
            ax.axvline(
                paper[key],
                color='tab:purple',
                ls=':',
                lw=1.5,
                label=f'paper: {_mark_text(key, paper[key], key_unit)} ({note})',
            )
        ax.set_ylabel(_y_label(metric, unit), fontsize=8)
        ax.grid(True, alpha=0.3)
        for handle, text in zip(*ax.get_legend_handles_labels(), strict=True):
            legend.setdefault(text, handle)
    axes[-1, 0].set_xlabel(_label(key, key_unit))
    fig.suptitle(
        f'sweep of scene {plan.scene!r}: {len(plan.points)} points, {plan.duration:g} s of line time each', fontsize=10
    )
    top = 1.0 - (0.35 + 0.18 * math.ceil(len(legend) / 2)) / fig.get_figheight()
    fig.tight_layout(rect=(0.0, 0.0, 1.0, top))
    fig.legend(
        list(legend.values()),
        list(legend),
        loc='upper center',
        ncol=2,
        fontsize=7,
        bbox_to_anchor=(0.5, top + 0.005),
        bbox_transform=fig.transFigure,
        frameon=False,
    )
    return save_figure(fig, path)


def _pair(result_plan: SweepPlan, keys: Sequence[str], values: Mapping[str, object]) -> str:
    """``'V_tr 9.3 m/s, n_k 50000 rev/h'``: a point's two values by the keys' short names."""
    return ', '.join(f'{k.rpartition(".")[2]} {values[k]:.6g} {result_plan.units[k]}'.rstrip() for k in keys)


def _edges(values: np.ndarray) -> np.ndarray:
    """Cell edges around grid values (halfway between neighbours)."""
    mid = 0.5 * (values[1:] + values[:-1])
    return np.concatenate([[values[0] - (mid[0] - values[0])], mid, [values[-1] + (values[-1] - mid[-1])]])


def _grid(result: SweepResult, keys: Sequence[str], values: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``values`` (one per point) on the (key 2 rows, key 1 columns) grid of the two plotted keys."""
    plan = result.plan
    xs = np.array(sorted({float(p[keys[0]]) for p in plan.points}))
    ys = np.array(sorted({float(p[keys[1]]) for p in plan.points}))
    z = np.full((ys.size, xs.size), np.nan)
    for p, v in zip(plan.points, values, strict=True):
        z[np.searchsorted(ys, float(p[keys[1]])), np.searchsorted(xs, float(p[keys[0]]))] = v
    return xs, ys, z


def _marks(ax: Axes, result: SweepResult, keys: Sequence[str], xs: np.ndarray, ys: np.ndarray) -> list[Artist]:
    """Drawn over the heat map: the points where a swept constraint is violated and the paper's rule;
    their legend handles."""
    plan = result.plan
    handles: list[Artist] = []
    feasible = _feasible(result)
    if feasible is not None:
        bad = [p for p, f, r in zip(plan.points, feasible, result.results, strict=True) if f < 0.5 and r.status == OK]
        if bad:
            handles.append(
                ax.plot(
                    [p[keys[0]] for p in bad],
                    [p[keys[1]] for p in bad],
                    'x',
                    ms=4,
                    color='k',
                    alpha=0.6,
                    label='a swept constraint is violated here',
                )[0]
            )
    rule = paper_rule(keys[0], keys[1])
    if rule is not None:
        text, fn = rule
        y_line = np.linspace(_edges(ys)[0], _edges(ys)[-1], 50)
        handles.append(ax.plot(fn(y_line), y_line, ':', color='tab:purple', lw=2.0, label=text)[0])
        ax.set_xlim(_edges(xs)[0], _edges(xs)[-1])
    return handles


def _points(ax: Axes, plan: SweepPlan, keys: Sequence[str]) -> list[Artist]:
    """The scene's point and the paper's, drawn over the heat map; their legend handles."""
    handles: list[Artist] = []
    scene = plan.scene_point
    x, y = scene.get(keys[0]), scene.get(keys[1])
    if isinstance(x, int | float) and isinstance(y, int | float):
        handles.append(
            ax.plot(
                x,
                y,
                '*',
                ms=16,
                mfc='tab:green',
                mec='k',
                label=f'scene: {_pair(plan, keys, scene)}',
            )[0]
        )
    if plan.paper_point is not None:
        pp = plan.paper_point
        handles.append(
            ax.plot(
                pp[keys[0]], pp[keys[1]], 'D', ms=9, mfc='tab:purple', mec='k', label=f'paper: {_pair(plan, keys, pp)}'
            )[0]
        )
    return handles


def _heat_map(result: SweepResult, keys: Sequence[str], path: Path) -> Path:
    plt = pyplot()
    from_colors = plt.matplotlib.colors
    plan = result.plan
    metric = plan.metrics[0]
    factor, unit = _shown(metric, plan.units[metric])
    xs, ys, z = _grid(result, keys, _values(result, 0) * factor)
    fig, ax = plt.subplots(figsize=(8.0, 6.0))
    finite = z[np.isfinite(z)]
    lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (-1.0, 1.0)
    if lo < 0.0 < hi:
        norm = from_colors.TwoSlopeNorm(vcenter=0.0, vmin=lo, vmax=hi)
        cmap = plt.get_cmap('RdBu')
    else:
        norm = from_colors.Normalize(vmin=lo, vmax=hi if hi > lo else lo + 1.0)
        cmap = plt.get_cmap('viridis')
    cmap = cmap.with_extremes(bad='lightgrey')
    mesh = ax.pcolormesh(_edges(xs), _edges(ys), np.ma.masked_invalid(z), cmap=cmap, norm=norm, shading='flat')
    bar = fig.colorbar(mesh, ax=ax)
    bar.set_label(_label(metric, unit))
    if unit == 'sheets':  # whole sheets
        bar.locator = plt.matplotlib.ticker.MaxNLocator(integer=True)
        bar.update_ticks()
    handles: list[Artist] = []
    line = plt.matplotlib.lines.Line2D
    if finite.size and lo < 0.0 < hi:
        ax.contour(xs, ys, z, levels=[0.0], colors='k', linewidths=2.0)
        handles.append(
            line(
                [],
                [],
                color='k',
                lw=2.0,
                label=f'{metric} = 0 (feasible side: >= 0)' if _is_margin(metric) else f'{metric} = 0',
            )
        )
    handles += _marks(ax, result, keys, xs, ys)
    if np.isnan(z).any():
        handles.append(plt.matplotlib.patches.Patch(color='lightgrey', label='refused by the model'))
    handles += _points(ax, plan, keys)
    ax.set_xlabel(_label(keys[0], plan.units[keys[0]]))
    ax.set_ylabel(_label(keys[1], plan.units[keys[1]]))
    ax.set_title(
        f'{metric} over {keys[0]} x {keys[1]}\n{_note(metric) or ""}{"; " if _note(metric) else ""}'
        f'scene {plan.scene!r}, {plan.duration:g} s of line time per point',
        fontsize=10,
    )
    if handles:
        ax.legend(handles=handles, fontsize=8, loc='best', framealpha=0.9)
    if finite.size == 0:
        ax.text(0.5, 0.5, 'every point refused', ha='center', transform=ax.transAxes)
    fig.tight_layout()
    return save_figure(fig, path)
