"""``simulate --list-keys/--list-metrics``, ``scenes``, the new summary lines, ``report --set/--params``."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from folder_line.cli.main import main
from folder_line.cli.report import REPORT_FILES, report_params
from folder_line.config.keys import scene_keys
from folder_line.config.params import config_dir, read_yaml_mapping
from folder_line.config.scenes import list_scenes, scene_mapping
from folder_line.core.line.metrics import flatten_metrics
from folder_line.core.mechanisms.cyclogram import cycle_timing


def _run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def test_list_keys_prints_every_key_with_unit_value_and_range(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = _run(['simulate', '--scene', 'folder', '--set', 'press.n_c=30000', '--list-keys'], capsys)
    assert code == 0 and not err
    rows = {line.split()[0]: line.split() for line in out.splitlines()[2:] if line and not line.startswith(' ')}
    for info in scene_keys(scene_mapping('folder', {'press.n_c': 30000})):
        assert info.key in rows, info.key
    assert rows['press.n_c'][1:4] == ['rev/h', '30000', '[1,'] and rows['knife.n_k'][2] == '60000'  # --set applied
    assert rows['feed_transporter.V_tr'][1:3] == ['m/s', '9.3']
    assert 'not read in this scene' in out and '  sheets.jitter: ' in out and 'sheets.jitter' not in rows


def test_list_metrics_prints_every_metric_of_the_summary(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = _run(['simulate', '--scene', 'folder', '--duration', '1', '--list-metrics'], capsys)
    assert code == 0
    listed = {line.split()[0]: line.split()[1:] for line in out.splitlines()[1:]}
    code, _, _ = _run(['simulate', '--scene', 'folder', '--duration', '1', '--json', str(tmp_path / 's.json')], capsys)
    metrics = flatten_metrics(json.loads((tmp_path / 's.json').read_text()))
    assert set(listed) == set(metrics)
    for path, value in metrics.items():
        assert float(listed[path][0]) == pytest.approx(value, rel=1e-9, abs=1e-300), path
    assert listed['min_margin_s.feed_window'][1] == 's' and listed['folder.V_tr_min'][1] == 'm/s'
    assert listed['folder.delivery.sprocket_torque_peak_Nm'][1:] == ['N', 'm']


def test_listing_is_refused_with_json(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        main(['simulate', '--list-keys', '--json', 'x.json'])
    assert info.value.code == 2 and 'not allowed with' in capsys.readouterr().err


def test_scenes_lists_every_shipped_scene_with_its_description(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = _run(['scenes'], capsys)
    assert code == 0
    names = [line for line in out.splitlines() if line and not line.startswith(' ')]
    assert names == list_scenes()
    for name in names:
        words = str(read_yaml_mapping(config_dir() / 'scenes' / f'{name}.yaml', name)['description']).split()
        assert ' '.join(words) in out


def _number(pattern: str, text: str) -> float:
    m = re.search(pattern, text)
    assert m is not None, (pattern, text)
    return float(m.group(1))


def test_simulate_prints_the_design_figures(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = _run(['simulate', '--duration', '1', '--json', str(tmp_path / 's.json')], capsys)
    assert code == 0
    folder = json.loads((tmp_path / 's.json').read_text())['folder']
    assert _number(r'V_tr min = ([\d.]+) m/s', out) == pytest.approx(folder['V_tr_min'], abs=1e-4)
    assert _number(r'= ([\d.]+) V_d', out) == pytest.approx(folder['V_tr_min_over_V_d'], abs=1e-4)
    assert _number(r'knife window: ([\d.]+) ms', out) == pytest.approx(1e3 * folder['knife_window_s'], abs=1e-4)
    dl = folder['delivery']
    assert _number(r'efficiency minimum ([\d.]+)', out) == pytest.approx(dl['eta_min'], abs=1e-4)
    assert _number(r'stroke position u = ([\d.]+)', out) == pytest.approx(dl['eta_min_u'], abs=1e-4)
    code, out, _ = _run(['simulate', '--scene', 'layup', '--duration', '3'], capsys)
    assert code == 0 and re.search(r'leaves: \d+ entered, \d+ landed, \d+ spilled, \d+ damaged', out)


def test_a_value_that_does_nothing_is_one_line_exit_2(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = _run(['simulate', '--duration', '1', '--set', 'sheets.jitter=0.3'], capsys)
    assert code == 2 and not out and len(err.splitlines()) == 1
    assert err.startswith("folder-line: error: sheets.jitter=0.3: does nothing in scene 'folder'")
    code, _, err = _run(['simulate', '--duration', '1', '--set', 'knife.n_k=60000'], capsys)
    assert code == 2 and 'knife.n_k=60000' in err and 'cyclogram.n_c=25000.0' in err and len(err.splitlines()) == 1


def test_report_at_another_press_speed(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = _run(['report', '--set', 'press.n_c=30000', '--out', str(tmp_path)], capsys)
    assert code == 0, err
    p = report_params(None, {'press.n_c': 30000}).params
    v_min = cycle_timing(p['cyclogram'], p['knife']).V_tr_min
    assert v_min == pytest.approx(11.115, abs=5e-4)  # the hand bisection at 60000 rev/h
    head = out.splitlines()[:6]
    assert '- `press.n_c=30000`' in head
    assert _number(r'minimum feed speed V_tr = ([\d.]+) m/s', out) == pytest.approx(v_min, abs=1e-4)
    assert _number(r'minimum 2nd-transporter speed V_tr \| ~9.2 m/s \| ([\d.]+) m/s', out) == pytest.approx(
        v_min, abs=1e-3
    )
    assert '- `press.n_c=30000`' in (tmp_path / 'report.md').read_text()
    knife_csv = (tmp_path / 'knife.csv').read_text().splitlines()
    assert len(knife_csv) == 361  # the tables are written for the values given too


def test_report_params_file_and_set(tmp_path: Path) -> None:
    params = tmp_path / 'p.yaml'
    params.write_text('press: {n_c: 30000}\ndelivery: {f_A: 0.2}\n')
    inputs = report_params(str(params), {'delivery.f_A': 0.25})
    assert inputs.params['knife'].n_k == 60000.0 and inputs.params['delivery'].f_A == 0.25  # --set last
    assert inputs.given == ('press.n_c=30000', 'delivery.f_A=0.2', 'delivery.f_A=0.25')
    assert report_params().given == ()


@pytest.mark.parametrize(
    ('argv', 'words'),
    [
        (['--set', 'knife.n_k=60000'], 'knife.n_k=60000.0: must be 2 x cyclogram.n_c=25000.0'),
        (['--set', 'feed_slip.mu=0.3'], 'feed_slip.mu=0.3: must be SECTION.KEY with a section of the report'),
        (['--set', 'delivery.f_X=0.3'], 'delivery.f_X=0.3: unknown delivery parameter'),
        (['--set', 'press.n_c=0'], 'press.n_c=0: must be in [1, 100000] rev/h'),
    ],
)
def test_report_refuses_bad_values_before_writing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], words: str
) -> None:
    out_dir = tmp_path / 'rep'
    code, _, err = _run(['report', *argv, '--out', str(out_dir)], capsys)
    assert code == 2 and len(err.splitlines()) == 1 and words in err, err
    assert not any((out_dir / name).exists() for name in REPORT_FILES)
