"""``analyze`` of a bag written by ``simulate --bag`` gives ``simulate``'s own numbers for the same span."""

from __future__ import annotations

from pathlib import Path

import pytest

from folder_line.analysis import analyze
from folder_line.cli.main import main
from folder_line.config.scenes import load_scene
from folder_line.core.line.model import simulate


@pytest.mark.parametrize(('scene', 'duration'), [('folder', 6.0), ('layup', 6.0)])
def test_analyze_of_a_batch_bag_is_simulate(scene: str, duration: float, tmp_path: Path) -> None:
    bag = tmp_path / 'bag'
    assert main(['simulate', '--scene', scene, '--duration', str(duration), '--bag', str(bag)]) == 0
    result = analyze(bag, tmp_path / 'analysis')
    sim = simulate(load_scene(scene), duration, sample_rate=0.0).summary()
    assert result.summary.cycles == sim.cycles
    assert result.summary.sheets_counted == sim.sheets_counted
    assert result.summary.violations.count == sim.violations.count
    assert set(result.summary.min_margin) == set(sim.min_margin)
    for name, m in sim.min_margin.items():
        got = result.summary.min_margin[name]
        assert (got.evaluations, got.violations) == (m.evaluations, m.violations), name
        # the bag's event times are whole nanoseconds: margins agree to that rounding
        assert got.margin == pytest.approx(m.margin, abs=1e-8), name
