"""``analyze --from/--to``: a window of line time, checked against ``simulate`` and against the whole run."""

from __future__ import annotations

import csv
import shutil
from pathlib import Path

import numpy as np
import pytest
from _ros_env import REPO

from folder_line.analysis import analyze, csv_name
from folder_line.cli.main import main
from folder_line.core.line.model import simulate
from folder_line.interfaces import DIAGNOSTICS_TOPIC, EVENTS_TOPIC

FOLDER_RUN = REPO / 'test' / 'data' / 'folder_run'


@pytest.fixture(scope='module')
def run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    dest = tmp_path_factory.mktemp('window') / 'folder_run'
    shutil.copytree(FOLDER_RUN, dest)
    return dest


def test_to_is_the_run_that_ended_there(run: Path, tmp_path: Path) -> None:
    """A bag read up to 1 s gives simulate's numbers for 1 s (the line's determinism)."""
    result = analyze(run, tmp_path / 'a', t_to=1.0)
    assert result.recording.t_end == 1.0
    sim = simulate(result.recording.scene, 1.0, commands=result.recording.commands, sample_rate=0.0).summary()
    assert result.summary.cycles == sim.cycles
    assert result.summary.sheets_counted == sim.sheets_counted
    for name, m in sim.min_margin.items():
        assert result.summary.min_margin[name].evaluations == m.evaluations, name
        assert result.summary.min_margin[name].margin == pytest.approx(m.margin, abs=1e-9), name


def test_from_and_to_split_the_run(run: Path, tmp_path: Path) -> None:
    """[0, 1] and [1, end] together count what the whole run counts; the figures' events stay in the window."""
    whole = analyze(run, tmp_path / 'w')
    first = analyze(run, tmp_path / 'f', t_to=1.0)
    rest = analyze(run, tmp_path / 'r', t_from=1.0, csv=True)
    assert first.summary.cycles + rest.summary.cycles == whole.summary.cycles
    assert first.summary.sheets_counted + rest.summary.sheets_counted == whole.summary.sheets_counted
    for name, m in whole.summary.min_margin.items():
        n = first.summary.min_margin[name].evaluations + rest.summary.min_margin[name].evaluations
        assert n == m.evaluations, name
    assert 'window analysed: 1 .. 2 s' in rest.report.read_text()
    for topic in (EVENTS_TOPIC, DIAGNOSTICS_TOPIC, '/line/crank_drive/joint_states'):
        with (rest.out / 'csv' / csv_name(topic)).open(newline='') as fh:
            rows = list(csv.reader(fh))[1:]
        assert rows and min(float(r[0]) for r in rows) >= 1.0, topic
    joints = whole.recording.joints['crank_drive']
    with (rest.out / 'csv' / csv_name('/line/crank_drive/joint_states')).open(newline='') as fh:
        n_rows = len(list(csv.reader(fh))) - 1
    assert n_rows == int(np.count_nonzero(joints.t >= 1.0))


@pytest.mark.parametrize(
    ('args', 'option'),
    [(['--from', '1.5', '--to', '1.0'], '--to'), (['--from', '9'], '--from'), (['--to', 'x'], '--to')],
)
def test_a_bad_window_is_one_line(
    run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], option: str
) -> None:
    try:
        code = main(['analyze', str(run), '--out', str(tmp_path / 'o'), *args])
    except SystemExit as exc:  # argparse refuses the value
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and option in err[0]
    assert not (tmp_path / 'o').exists()
