"""``simulate --plots DIR``: analyze's figures from the batch model, without ROS, pixel for pixel."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from matplotlib.image import imread

from folder_line.analysis.figures import FIGURES
from folder_line.cli.main import main


@pytest.mark.parametrize(('scene', 'figures'), [('line', set(FIGURES)), ('layup', {'exit_speeds.png', 'landing.png'})])
def test_the_plots_are_analyze_s_of_the_run_s_bag(
    scene: str, figures: set[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    plots, bag, analysis = tmp_path / 'plots', tmp_path / 'bag', tmp_path / 'analysis'
    assert main(['simulate', '--scene', scene, '--duration', '4', '--plots', str(plots)]) == 0
    out = capsys.readouterr().out
    assert main(['simulate', '--scene', scene, '--duration', '4', '--bag', str(bag)]) == 0
    assert main(['analyze', str(bag), '--out', str(analysis)]) == 0
    drawn = {p.name for p in plots.iterdir()}
    assert figures <= drawn <= set(FIGURES)
    for name in drawn:
        assert f'wrote {plots / name}' in out
        assert np.array_equal(imread(plots / name), imread(analysis / name)), name
    assert 'cycles' in out or 'leaves' in out  # the summary is printed as without --plots


def test_plots_with_bag_draws_that_bag(tmp_path: Path) -> None:
    plots, bag = tmp_path / 'plots', tmp_path / 'bag'
    assert main(['simulate', '--scene', 'folder', '--duration', '2', '--bag', str(bag), '--plots', str(plots)]) == 0
    assert (bag / 'metadata.yaml').is_file()
    assert {p.name for p in plots.iterdir()} == {'efficiency.png', 'cyclogram.png', 'margins.png'}


@pytest.mark.parametrize(
    ('args', 'option'),
    [
        (['--samples', '3'], '--samples'),
        (['--list-keys'], '--plots'),
        (['--duration', '1.0001'], '--duration'),
    ],
)
def test_a_bad_combination_is_one_line_and_nothing_written(
    args: list[str], option: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    plots = tmp_path / 'plots'
    argv = ['simulate', '--scene', 'folder', '--duration', '1', '--plots', str(plots), *args]
    assert main(argv) == 2
    out = capsys.readouterr()
    (line,) = out.err.strip().splitlines()
    assert line.startswith('folder-line: error: ') and option in line, line
    assert out.out == ''
    assert not plots.exists()


def test_a_plots_path_that_is_a_file_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    plots = tmp_path / 'plots'
    plots.write_text('mine\n')
    assert main(['simulate', '--scene', 'folder', '--duration', '1', '--plots', str(plots)]) == 2
    out = capsys.readouterr()
    assert '--plots' in out.err and out.out == ''
    assert plots.read_text() == 'mine\n'


def test_a_figure_name_taken_by_a_folder_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    plots = tmp_path / 'plots'
    (plots / 'margins.png').mkdir(parents=True)
    assert main(['simulate', '--scene', 'folder', '--duration', '1', '--plots', str(plots)]) == 2
    out = capsys.readouterr()
    assert '--plots' in out.err and 'margins.png' in out.err and out.out == ''
    assert [p.name for p in plots.iterdir()] == ['margins.png']
