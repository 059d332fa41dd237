"""``folder-line solve``: the minimum feed speed equals what ``report`` prints and the closed form."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from studies._closed_form import v_tr_min

from folder_line.cli.main import main

FIND = ['solve', '--scene', 'folder', '--find', 'feed_transporter.V_tr', '--where', 'min_margin_s.feed_window>=0']
TOL = 1e-6


def test_minimum_feed_speed_equals_the_report_and_the_closed_form(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(['report', '--out', str(tmp_path / 'report')]) == 0
    printed = re.search(r'minimum 2nd-transporter speed V_tr \| [^|]+\| ([0-9.]+) m/s', capsys.readouterr().out)
    assert printed is not None
    report_value = float(printed[1])  # printed to 1 mm/s

    out = tmp_path / 'v.json'
    assert main([*FIND, '--duration', '0.5', '--tol', str(TOL), '--workers', '1', '--json', str(out)]) == 0
    doc = json.loads(out.read_text())
    assert doc['key'] == 'feed_transporter.V_tr' and doc['condition'] == 'min_margin_s.feed_window>=0'
    assert doc['tolerance'] == TOL and doc['holds'] == 'above' and doc['unit'] == 'm/s'
    assert abs(doc['value'] - v_tr_min(50000.0)) <= TOL
    assert abs(doc['value'] - report_value) <= 0.0005 + TOL
    assert doc['evaluations'] > 1 + 9  # the scene, the 9-value scan, then the refinement
    assert f'feed_transporter.V_tr = {doc["value"]:.9g} m/s' in capsys.readouterr().out


def test_minimum_feed_speed_at_60000_rev_h(tmp_path: Path) -> None:
    """The issue's 11.115 m/s: the cycle is 50000/60000 as long, so the allowed feed time is too."""
    out = tmp_path / 'v.json'
    args = ['--set', 'press.n_c=30000', '--duration', '0.5', '--tol', str(TOL)]  # the knife at 60000 rev/h
    assert main([*FIND, *args, '--workers', '2', '--json', str(out)]) == 0
    value = json.loads(out.read_text())['value']
    assert abs(value - v_tr_min(60000.0)) <= TOL
    assert abs(value - 1.2 * v_tr_min(50000.0)) <= 2 * TOL
    assert round(value, 3) == 11.115


@pytest.mark.parametrize(
    ('extra', 'message'),
    [
        (['--where', 'feed_window=0'], "--where='feed_window=0': must be METRIC OP NUMBER"),
        (['--where', 'no_such_metric>=0'], "--where='no_such_metric': is not a metric of this scene"),
        (['--find', 'feed_transporter.Vtr'], "--find='feed_transporter.Vtr': feed_transporter has no parameter"),
        (['--between', '20:10'], "--between='20:10': LO must be below HI"),
        (['--tol', '5', '--between', '9:12'], '--tol=5.0: must be > 0 and below the range width 3'),
        (['--between', '10:20'], "--between='10:20': min_margin_s.feed_window>=0 holds everywhere in the range"),
        (['--workers', '0'], '--workers=0: must be a whole number in [1, 512]'),
    ],
)
def test_bad_input_is_one_line_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: list[str], message: str
) -> None:
    out = tmp_path / 'v.json'
    args = [*FIND, '--duration', '0.1', '--scan', '3', '--workers', '1', '--json', str(out), *extra]
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len([line for line in err if line.startswith('folder-line: error:')]) == 1
    assert message in err[-1]
    assert not out.exists()


def test_an_output_that_cannot_be_written_is_refused_before_any_work(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main([*FIND, '--json', str(tmp_path)]) == 2  # a folder, not a file
    assert capsys.readouterr().err.startswith(f"folder-line: error: --json='{tmp_path}': is a directory")
