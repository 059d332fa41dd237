"""``folder-line simulate --samples N``: the table, the aggregate in --json, bad input in one line."""

from __future__ import annotations

import io
import json
from pathlib import Path

import pytest

import folder_line.studies.montecarlo as mc
from folder_line.cli.main import main
from folder_line.cli.montecarlo import print_table
from folder_line.config.scenes import scene_mapping
from folder_line.studies.runner import Cluster


def test_samples_print_the_table_and_write_the_aggregate(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / 'mc.json'
    argv = ['simulate', '--scene', 'folder_jitter', '--duration', '2', '--samples', '4', '--workers', '1']
    assert main([*argv, '--set', 'arrival_jitter.sigma=2', '--json', str(out)]) == 0
    text = capsys.readouterr().out
    assert 'p per cycle' in text and 'feed_window' in text and 'ms' in text
    data = json.loads(out.read_text())
    fw = data['constraints']['feed_window']
    assert data['samples'] == 4 and len(data['seeds']) == 4
    assert (
        fw['p_cycle']['n'] == 4 * data['metrics']['cycles']['mean'] and 0 < fw['p_cycle']['k'] < fw['p_cycle']['n']
    )  # σ 2 mm > margin 0.93 mm
    assert fw['p_cycle']['ci95'][0] <= fw['p_cycle']['p'] <= fw['p_cycle']['ci95'][1]
    assert fw['unit'] == 's' and fw['margin']['std'] > 0.0


def test_without_samples_simulate_is_unchanged(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(['simulate', '--scene', 'folder', '--duration', '1']) == 0
    assert 'p per cycle' not in capsys.readouterr().out


@pytest.mark.parametrize(
    ('args', 'word'),
    [
        (['--samples', '0'], '--samples'),
        (['--samples', 'x'], '--samples'),
        (['--samples', '2', '--workers', '0'], '--workers'),
        (['--samples', '2', '--set', 'arrival_jitter.sigma=-1'], 'effects.arrival_jitter.sigma'),
    ],
)
def test_bad_input_is_one_line_and_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], word: str
) -> None:
    out = tmp_path / 'mc.json'
    argv = ['simulate', '--scene', 'folder_jitter', '--duration', '1', *args, '--json', str(out)]
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse's own usage error
        code = int(exc.code or 0)
    assert code == 2
    err = capsys.readouterr().err
    assert err.count('\n') == 1 and word in err
    assert not out.exists()


def test_an_output_that_cannot_be_written_is_refused_before_any_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ['simulate', '--scene', 'folder_jitter', '--duration', '1', '--samples', '2', '--json', str(tmp_path)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert '--json' in err and 'samples' not in err  # no progress line: nothing ran


def test_the_table_says_when_the_quantiles_are_of_a_sample(monkeypatch: pytest.MonkeyPatch) -> None:
    """Past MARGIN_SAMPLE margins pooled, the quantiles are of a uniform sample: --json and the table say so."""
    monkeypatch.setattr(mc, 'MARGIN_SAMPLE', 50)  # the pool's, in this process (the workers' keep theirs)
    result = mc.monte_carlo(scene_mapping('folder_jitter'), 2.0, 3, Cluster(workers=1))
    fw = result.aggregate.constraints['feed_window'].margin
    assert fw.kept == 50 < fw.count and fw.method.startswith('a uniform random sample of 50 of the')
    assert sum(fw.histogram.counts) == 50
    text = io.StringIO()
    print_table(result, text)
    assert 'margin quantiles of feed_window' in text.getvalue()
    assert 'uniform random sample of 50 margins' in text.getvalue()
