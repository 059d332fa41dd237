"""``sweep.png`` from results made by hand (no simulation): what is drawn, and sweeps with every point refused."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from folder_line.studies import sweep_plot
from folder_line.studies.grid import Vary, grid_points
from folder_line.studies.points import OK, PointResult
from folder_line.studies.sweep import SweepPlan, SweepResult
from folder_line.studies.sweep_plot import plot_sweep, plotted_keys

PNG = b'\x89PNG\r\n\x1a\n'


def _result(varies: tuple[Vary, ...], value: object) -> SweepResult:
    points = tuple(grid_points(varies))
    keys = tuple(v.key for v in varies)
    plan = SweepPlan(
        scene='folder',
        source={},
        duration=1.0,
        varies=varies,
        points=points,
        metrics=('min_margin_s.feed_window', 'violations.count'),
        units={
            'feed_transporter.V_tr': 'm/s',
            'knife.n_k': 'rev/h',
            'min_margin_s.feed_window': 's',
            'violations.count': '',
        },
        scene_point={'feed_transporter.V_tr': 9.3, 'knife.n_k': 50000.0},
        scene_metrics=(1e-4, 0.0),
        paper_point={'feed_transporter.V_tr': 9.33, 'knife.n_k': 50000.0} if len(keys) == 2 else None,
    )
    results = []
    for p in points:
        if value is None:
            results.append(PointResult((None, None), 'refused: made up'))
        else:
            m = 0.0248 * p.get('knife.n_k', 50000.0) / 50000.0 - 0.230 / p['feed_transporter.V_tr']
            results.append(PointResult((m, float(m < 0)), OK))
    return SweepResult(plan, tuple(results))


V = Vary('feed_transporter.V_tr', 8.0, 11.0, 4)
N = Vary('knife.n_k', 40000.0, 60000.0, 3)


@pytest.mark.parametrize('varies', [(V,), (V, N), (Vary('knife.n_k', 5e4, 5e4, 1), V)])
@pytest.mark.parametrize('value', [1.0, None])
def test_curves_and_heat_maps_are_drawn_even_when_every_point_is_refused(
    tmp_path: Path, varies: tuple[Vary, ...], value: object
) -> None:
    result = _result(varies, value)
    with np.errstate(all='raise'):
        path = plot_sweep(result, tmp_path / 'sweep.png')
    assert path is not None and path.read_bytes()[:8] == PNG


def test_what_is_plotted() -> None:
    assert plotted_keys(_result((Vary('knife.n_k', 5e4, 5e4, 1), V), 1.0)) == ('feed_transporter.V_tr',)
    three = (V, N, Vary('cyclogram.n_c', 1.0, 2.0, 2))
    assert plot_sweep(_result(three, 1.0), Path('/nonexistent/never.png')) is None  # nothing drawn, nothing written


def test_margins_are_drawn_in_the_units_of_the_text(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """rebound in mm, feed in ms; one_per_cycle on whole sheets with what 0 means in its title."""
    drawn: list[Any] = []

    def keep(fig: Any, path: Path) -> Path:
        drawn.append(fig)
        return path

    monkeypatch.setattr(sweep_plot, 'save_figure', keep)
    base = _result((V,), 1.0)
    metrics = ('min_margin_s.feed_window', 'min_margin.rebound.margin', 'min_margin.one_per_cycle.margin')
    plan = dataclasses.replace(
        base.plan,
        metrics=metrics,
        units={**base.plan.units, 'min_margin.rebound.margin': 'm', 'min_margin.one_per_cycle.margin': 'sheets'},
        scene_metrics=(1e-4, 9e-4, 0.0),
    )
    results = tuple(PointResult((1e-4 * k, 9e-4, -float(k == 2)), OK) for k in range(V.n))
    plot_sweep(SweepResult(plan, results), tmp_path / 'sweep.png')
    (fig,) = drawn
    feed, rebound, sheets = fig.axes[:3]
    assert feed.get_ylabel() == 'margin, ms' and list(feed.lines[0].get_ydata()) == pytest.approx([0.0, 0.1, 0.2, 0.3])
    assert rebound.get_ylabel() == 'margin, mm' and list(rebound.lines[0].get_ydata()) == pytest.approx([0.9] * 4)
    assert sheets.get_ylabel() == 'margin, sheets'
    assert sheets.get_title(loc='left') == 'min_margin.one_per_cycle.margin  (0: 1 sheet per cycle, the best possible)'
    ticks = [t for t in sheets.get_yticks() if sheets.get_ylim()[0] <= t <= sheets.get_ylim()[1]]
    assert ticks == [-1.0, 0.0]  # whole sheets only
    assert feed.get_title(loc='left') == 'min_margin_s.feed_window'
