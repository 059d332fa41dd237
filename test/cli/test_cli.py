"""The ``folder-line kinematics`` and ``report`` verbs, as a user runs them."""

from __future__ import annotations

import csv
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from _loaded import ros_modules_loaded

from folder_line.cli.main import main
from folder_line.cli.tables import COLUMNS


def _read(path: Path) -> tuple[list[str], list[list[str]]]:
    with path.open(newline='') as fh:
        rows = list(csv.reader(fh))
    return rows[0], rows[1:]


@pytest.mark.parametrize('mechanism', ['layup', 'knife', 'delivery'])
def test_csv_has_exactly_the_contract_columns(tmp_path: Path, mechanism: str) -> None:
    dest = tmp_path / 'sub' / f'{mechanism}.csv'
    assert main(['kinematics', mechanism, '--samples', '37', '--csv', str(dest)]) == 0
    header, rows = _read(dest)
    assert header == list(COLUMNS[mechanism])
    assert len(rows) == 37
    assert not list(dest.parent.glob('.*.tmp'))


def test_layup_csv_values(tmp_path: Path) -> None:
    dest = tmp_path / 'l.csv'
    assert main(['kinematics', 'layup', '--samples', '720', '--csv', str(dest)]) == 0
    header, rows = _read(dest)
    data = np.array(rows, dtype=float)
    col = {h: data[:, i] for i, h in enumerate(header)}
    np.testing.assert_allclose(col['phi'], 2 * math.pi * np.arange(720) / 720)
    assert col['vaC'].min() >= 2.8 and col['vaE'].min() >= 2.8  # belts at the default 2.8 m/s
    np.testing.assert_allclose(col['vaC'], np.hypot(col['vC'], 2.8), rtol=1e-15)
    np.testing.assert_allclose(col['vC'], col['omega3'] * 1.0, rtol=1e-15)  # l3 = 1.0 m
    assert np.all(np.isfinite(data))


def test_params_file_subset_and_delivery_states(tmp_path: Path) -> None:
    params = tmp_path / 'p.yaml'
    params.write_text('alpha_m_deg: 89.9999\nf_Bp: 0.3\n')
    dest = tmp_path / 'd.csv'
    assert main(['kinematics', 'delivery', '--params', str(params), '--samples', '1001', '--csv', str(dest)]) == 0
    header, rows = _read(dest)
    states = [r[header.index('state')] for r in rows]
    assert states[0] == 'ok' and states[-1] == 'self_locking'
    eta = np.array([float(r[header.index('eta')]) for r in rows])
    assert np.all(np.isfinite(eta)) and eta.min() == 0.0


def test_knife_window_column(tmp_path: Path) -> None:
    dest = tmp_path / 'k.csv'
    assert main(['kinematics', 'knife', '--samples', '7200', '--csv', str(dest)]) == 0
    header, rows = _read(dest)
    inside = np.array([int(r[header.index('in_window')]) for r in rows])
    s = np.array([float(r[header.index('s')]) for r in rows])
    assert np.array_equal(inside == 1, s >= 0.1656)
    assert inside.mean() == pytest.approx(0.030 / 0.072, abs=2e-3)  # the paper's 0.03 s of 0.072 s


BAD = [
    ('layup', 'R_kr: -0.08\n', 'layup.R_kr=-0.08'),
    ('layup', 'l2: .nan\n', 'layup.l2=nan'),
    ('layup', 'bogus: 1.0\n', 'layup.bogus=1.0: unknown layup parameter'),
    ('layup', 'l4: 0.3\n', 'cannot be assembled at phi=2.07'),
    ('layup', 'R_kr: 0.2\n', 'Grashof boundary'),
    ('knife', 'L_k: 0.0\n', 'knife.L_k=0.0'),
    ('knife', 's_clear: 0.5\n', 'knife.s_clear=0.5'),
    ('delivery', 'law: parabolic\n', "delivery.law='parabolic'"),
    ('delivery', 'Lambda: -1\n', 'delivery.Lambda=-1'),
    ('delivery', 'f_A: "x"\n', "delivery.f_A='x'"),
    ('delivery', '- 1\n- 2\n', 'must be a YAML mapping'),
]


@pytest.mark.parametrize(('mechanism', 'text', 'expected'), BAD)
def test_bad_input_is_one_line_exit_2_and_no_csv(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], mechanism: str, text: str, expected: str
) -> None:
    params = tmp_path / 'bad.yaml'
    params.write_text(text)
    dest = tmp_path / 'out.csv'
    assert main(['kinematics', mechanism, '--params', str(params), '--csv', str(dest)]) == 2
    err = capsys.readouterr().err
    assert err.count('\n') == 1 and err.startswith('folder-line: error: ')
    assert expected in err
    assert not dest.exists()
    assert list(tmp_path.iterdir()) == [params]


def test_existing_csv_is_left_alone_on_error(tmp_path: Path) -> None:
    dest = tmp_path / 'out.csv'
    dest.write_text('previous\n')
    params = tmp_path / 'bad.yaml'
    params.write_text('n_kr: 0\n')
    assert main(['kinematics', 'layup', '--params', str(params), '--csv', str(dest)]) == 2
    assert dest.read_text() == 'previous\n'


@pytest.mark.parametrize(
    'argv',
    [
        ['kinematics', 'layup', '--samples', '1'],
        ['kinematics', 'layup', '--samples', 'many'],
        ['kinematics', 'gearbox'],
    ],
)
def test_bad_arguments_exit_2(argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    assert 'error' in capsys.readouterr().err


def test_installed_command_runs_as_a_process(tmp_path: Path) -> None:
    missing = tmp_path / 'missing.yaml'
    proc = subprocess.run(
        [sys.executable, '-m', 'folder_line.cli.main', 'kinematics', 'knife', '--params', str(missing)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2
    assert proc.stderr.strip().startswith('folder-line: error: --params=')
    assert proc.stdout == ''


def test_only_the_ros_verbs_load_dds(tmp_path: Path) -> None:
    """``simulate`` runs without rclpy or a message package; ``monitor`` (and ``run``) load them on use."""
    code = (
        'from folder_line.cli.main import main\n'
        f"print(main(['simulate', '--duration', '0.5', '--json', {str(tmp_path / 's.json')!r}]))"
    )
    assert ros_modules_loaded(code) == ('0', [])


def test_report_writes_every_file_and_reproduces_the_papers(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(['report', '--out', str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert '10 of 10 published results reproduced.' in out
    for name in (
        'report.md',
        'layup.csv',
        'knife.csv',
        'delivery.csv',
        'layup_speeds.png',
        'layup_geometry.png',
        'knife_cyclogram.png',
        'delivery_efficiency.png',
    ):
        path = tmp_path / name
        assert path.stat().st_size > 1000 or name.endswith('.csv'), name
    assert (tmp_path / 'layup_speeds.png').read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    assert '| NO |' not in (tmp_path / 'report.md').read_text()


def test_published_checks_can_fail() -> None:
    from folder_line.cli.report import published_checks
    from folder_line.config.params import load_params

    p = {k: load_params(k) for k in ('layup', 'knife', 'delivery', 'cyclogram')}
    assert all(c.agrees for c in published_checks(p))
    p['delivery'] = load_params('delivery', overrides={'f_O': 0.3})
    p['cyclogram'] = load_params('cyclogram', overrides={'dwell_frac': 0.1})
    failed = {c.quantity for c in published_checks(p) if not c.agrees}
    assert 'eta at constant carriage speed (xi = 0)' in failed
    assert 'minimum 2nd-transporter speed V_tr' in failed


def test_a_closed_stdout_ends_the_verb_quietly_with_141(tmp_path: Path) -> None:
    """`folder-line simulate ... | head`: the reader is gone; no error line blames an output option."""
    read_end, write_end = os.pipe()
    os.close(read_end)  # every write to stdout now fails with EPIPE, from the first one
    try:
        proc = subprocess.run(
            [sys.executable, '-m', 'folder_line.cli.main', 'simulate', '--duration', '1'],
            stdout=write_end,
            stderr=subprocess.PIPE,
            text=True,
            check=False,
            timeout=120,
        )
    finally:
        os.close(write_end)
    assert proc.returncode == 141
    assert 'error' not in proc.stderr and 'Traceback' not in proc.stderr
