"""``folder-line sweep``: the table, its independence of the workers, refused points, the plot, bad input."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest
from dask.distributed import LocalCluster
from studies._closed_form import feed_margin

from folder_line.cli.main import main
from folder_line.config.scenes import scene_mapping
from folder_line.studies.montecarlo import monte_carlo
from folder_line.studies.runner import Cluster

#: a 4 x 2 grid over the feed speed (one value refused: V_tr must be > 0) and the knife speed, 0.2 s per point
GRID = [
    'sweep',
    '--scene',
    'folder',
    '--vary',
    'feed_transporter.V_tr=-2:13:4',
    '--vary',
    'press.n_c=22500:27500:2',
    '--metric',
    'feed_window',
    '--metric',
    'violations.count',
    '--duration',
    '0.2',
]


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open(newline='') as fh:
        return list(csv.DictReader(fh))


@pytest.fixture(scope='module')
def one_worker(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp('sweep') / 'w1'
    assert main([*GRID, '--out', str(out), '--workers', '1']) == 0
    return out


def test_the_table_has_a_column_per_key_and_metric_and_a_row_per_point(one_worker: Path) -> None:
    rows = _rows(one_worker / 'sweep.csv')
    assert list(rows[0]) == [
        'feed_transporter.V_tr',
        'press.n_c',
        'min_margin_s.feed_window',
        'violations.count',
        'status',
    ]
    assert [(float(r['feed_transporter.V_tr']), float(r['press.n_c'])) for r in rows] == [
        (v, n) for v in (-2.0, 3.0, 8.0, 13.0) for n in (22500.0, 27500.0)
    ]
    for r in rows[2:]:  # each margin is the closed form at its point
        v, n = float(r['feed_transporter.V_tr']), 2.0 * float(r['press.n_c'])  # the knife at twice the cylinder
        assert r['status'] == 'ok'
        assert float(r['min_margin_s.feed_window']) == pytest.approx(feed_margin(n, v), abs=1e-12)
    for r in rows[:2]:  # V_tr = -2 m/s: refused by the model, the sweep goes on
        assert r['min_margin_s.feed_window'] == r['violations.count'] == ''
        assert r['status'] == 'refused: feed_transporter.V_tr=-2: must be in [0.001, 1000] m/s'


def test_the_json_names_the_command_keys_units_and_the_marked_points(one_worker: Path) -> None:
    doc = json.loads((one_worker / 'sweep.json').read_text())
    assert doc['command'].startswith('folder-line sweep --scene folder --vary feed_transporter.V_tr=-2:13:4')
    assert doc['points'] == 8 and doc['refused'] == 2
    key = {k['key']: k for k in doc['keys']}
    assert key['feed_transporter.V_tr']['unit'] == 'm/s' and key['press.n_c']['unit'] == 'rev/h'
    assert key['feed_transporter.V_tr']['scene_value'] == 9.3 and key['press.n_c']['scene_value'] == 25000.0
    assert key['press.n_c']['paper_value'] == 25000.0
    assert key['feed_transporter.V_tr']['paper_value'] == pytest.approx(1.6 * 3.14159265358979 * 0.26738 * 25000 / 3600)
    assert [m['unit'] for m in doc['metrics']] == ['s', '']
    assert doc['files'] == ['sweep.csv', 'sweep.json', 'sweep.png']
    assert (one_worker / 'sweep.png').read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


@pytest.mark.parametrize('where', [['--workers', '2'], ['--workers', '1', '--threads', '2']])
def test_the_table_does_not_depend_on_the_workers(one_worker: Path, tmp_path: Path, where: list[str]) -> None:
    assert main([*GRID, '--out', str(tmp_path), *where]) == 0
    assert (tmp_path / 'sweep.csv').read_bytes() == (one_worker / 'sweep.csv').read_bytes()


def test_an_existing_scheduler_runs_it_too(one_worker: Path, tmp_path: Path) -> None:
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=':0') as cluster:
        assert main([*GRID, '--out', str(tmp_path), '--scheduler', cluster.scheduler_address]) == 0
    assert (tmp_path / 'sweep.csv').read_bytes() == (one_worker / 'sweep.csv').read_bytes()


def test_one_key_draws_curves(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    args = ['sweep', '--vary', 'feed_transporter.V_tr=9:9.5:3', '--duration', '0.5', '--workers', '1']
    assert main([*args, '--out', str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "sweep of scene 'folder': 3 points over feed_transporter.V_tr" in out
    assert f'wrote {tmp_path / "sweep.png"}' in out
    rows = _rows(tmp_path / 'sweep.csv')
    assert [c for c in rows[0] if c.startswith('min_margin.')] == [  # the default metrics: every margin
        'min_margin.feed_window.margin',
        'min_margin.settled_before_knife.margin',
        'min_margin.one_per_cycle.margin',
        'min_margin.rebound.margin',
        'min_margin.release_at_min_speed.margin',
    ]
    assert 'violations.count' in rows[0]


@pytest.mark.parametrize(
    ('extra', 'message'),
    [
        (['--vary', 'feed_transporter.V_tr=1:2'], "--vary='feed_transporter.V_tr=1:2': must be KEY=START:STOP:N"),
        (['--vary', 'layup.R_kr=0.05:0.1:3'], "--vary='layup.R_kr': scene 'folder' has no machine 'layup'"),
        (['--vary', 'press.n_c=1:2:2', '--vary', 'press.n_c=3:4:2'], "--vary='press.n_c': is varied twice"),
        (['--vary', 'press.n_c=1:2:2', '--metric', 'nothing'], "--metric='nothing': is not a metric of this scene"),
        (['--vary', 'press.n_c=1:2:2', '--set', 'knife.r_k=-1'], 'knife.r_k=-1'),
        (['--vary', 'press.n_c=1:2:2', '--threads', '0'], '--threads=0: must be a whole number in [1, 512]'),
    ],
)
def test_bad_input_is_one_line_exit_2_and_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: list[str], message: str
) -> None:
    out = tmp_path / 'new'
    assert main(['sweep', '--duration', '0.1', '--out', str(out), '--workers', '1', *extra]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith('folder-line: error:') and message in err[0]
    assert not out.exists()


def test_an_output_folder_that_is_a_file_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    target = tmp_path / 'file'
    target.write_text('keep')
    assert main(['sweep', '--vary', 'press.n_c=1:2:2', '--out', str(target)]) == 2
    assert '--out=' in capsys.readouterr().err and target.read_text() == 'keep'


def test_sweep_samples_pool_each_point_as_simulate_samples_does(tmp_path: Path) -> None:
    """``sweep --samples``: each point's violation probability is the Monte Carlo of that point's scene,
    and it falls as the feed speed rises past the jitter's reach."""
    out = tmp_path / 'mc'
    argv = ['sweep', '--scene', 'folder_jitter', '--vary', 'feed_transporter.V_tr=9.25:9.35:3', '--samples', '12']
    assert main([*argv, '--metric', 'feed_window', '--duration', '1', '--workers', '2', '--out', str(out)]) == 0
    rows = _rows(out / 'sweep.csv')
    p = [float(r['p_violation.feed_window']) for r in rows]
    # margin 0.1 ms = 0.93 mm at 9.3 m/s (sigma 0.5 mm); 9.35 m/s keeps 0.23 ms = 2.2 mm, 4.3 sigma
    assert p[0] > p[1] > p[2] == 0.0
    for r in rows:
        assert float(r['p_violation_lo.feed_window']) <= float(r['p_violation.feed_window'])
        assert float(r['p_violation.feed_window']) <= float(r['p_violation_hi.feed_window'])
    middle = scene_mapping('folder_jitter', {'feed_transporter.V_tr': 9.3})
    alone = monte_carlo(middle, 1.0, 12, Cluster(workers=1)).aggregate.constraints['feed_window'].p_cycle
    assert float(rows[1]['p_violation.feed_window']) == alone.p
    assert (float(rows[1]['p_violation_lo.feed_window']), float(rows[1]['p_violation_hi.feed_window'])) == alone.ci95
    assert json.loads((out / 'sweep.json').read_text())['statistic'] == 'mean over 12 samples'
