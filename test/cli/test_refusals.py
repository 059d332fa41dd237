"""Inputs the verbs refused too late, or not at all: each ends in one line naming the option and the value, exit 2,
and nothing touched (issue 25's "smaller faults")."""

from __future__ import annotations

import argparse
import math
import os
from pathlib import Path

import pytest

from folder_line.cli.arg_types import limited
from folder_line.cli.main import main
from folder_line.core.limits import RTF


def one_error_line(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err
    lines = [x for x in err.splitlines() if x.startswith('folder-line')]
    assert len(lines) == 1, err
    return lines[0]


def test_rtf_0_means_no_ceiling_as_the_limits_table_and_the_node_parameter_say() -> None:
    parse = limited('--rtf', RTF, also='max')
    assert parse('0') == parse('0.0') == parse('max') == 0.0
    assert parse('2.5') == 2.5
    with pytest.raises(argparse.ArgumentTypeError, match=r"--rtf='0.0005': must be in \[0.001, 1000\], or 0 or max"):
        parse('0.0005')
    with pytest.raises(argparse.ArgumentTypeError, match='or 0 or max'):
        parse('-0.5')


@pytest.mark.parametrize(
    ('extra', 'expected'),
    [
        (
            ['--marker-rate', '5'],
            'folder-line: error: --marker-rate=5.0: draws the machine into a bag: only with --bag',
        ),
        (
            ['--max-bag-duration', '1'],
            'folder-line: error: --max-bag-duration=1.0: splits a bag: only with --bag',
        ),
        (
            ['--max-bag-size', '100000'],
            'folder-line: error: --max-bag-size=100000: splits a bag: only with --bag',
        ),
        (['--workers', '2'], 'folder-line: error: --workers=2: runs the samples of a Monte Carlo: only with --samples'),
        (['--threads', '3'], 'folder-line: error: --threads=3: runs the samples of a Monte Carlo: only with --samples'),
        (
            ['--scheduler', 'tcp://127.0.0.1:8786'],
            "folder-line: error: --scheduler='tcp://127.0.0.1:8786': runs the samples of a Monte Carlo: only with "
            '--samples',
        ),
    ],
)
def test_an_option_that_would_do_nothing_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: list[str], expected: str
) -> None:
    out = tmp_path / 'summary.json'
    argv = ['simulate', '--scene', 'folder', '--duration', '0.5', '--json', str(out), *extra]
    assert main(argv) == 2
    assert one_error_line(capsys) == expected
    assert not out.exists()


@pytest.mark.parametrize(
    ('option', 'value', 'expected'),
    [
        ('--max-bag-duration', '0.0001', "--max-bag-duration='0.0001': must be 0 (no split) or in [0.001, 1e+07] s"),
        ('--max-bag-duration', 'nan', "--max-bag-duration='nan': must be 0 (no split) or in [0.001, 1e+07] s"),
        ('--max-bag-duration', '-1', "--max-bag-duration='-1': must be 0 (no split) or in [0.001, 1e+07] s"),
        ('--max-bag-size', '10', "--max-bag-size='10': must be 0 (no split) or in [1024, 1e+15] bytes"),
        ('--max-bag-size', '1.5e6', "--max-bag-size='1.5e6': must be a whole number: 0 (no split) or in"),
    ],
)
@pytest.mark.parametrize('verb', ['simulate', 'run'])
def test_a_bag_split_out_of_range_is_refused_before_any_work(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], option: str, value: str, expected: str, verb: str
) -> None:
    out = tmp_path / 'out'
    where = ['--bag', str(out)] if verb == 'simulate' else ['--out', str(out)]
    with pytest.raises(SystemExit) as exited:
        main([verb, '--scene', 'folder', '--duration', '0.5', *where, option, value])
    assert exited.value.code == 2
    line = one_error_line(capsys)
    assert line.startswith('folder-line') and expected in line, line
    assert not out.exists()


def test_the_marker_rate_is_taken_with_a_bag(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = tmp_path / 'bag'
    assert main(['simulate', '--scene', 'folder', '--duration', '0.5', '--bag', str(bag), '--marker-rate', '2']) == 0
    capsys.readouterr()
    meta = (bag / 'metadata.yaml').read_text()
    assert '/line/markers' in meta


@pytest.mark.parametrize(
    ('target', 'expected'),
    [
        (None, "--scene='{p}': a symbolic link that loops (it leads to itself)"),
        ('nowhere.yaml', "--scene='{p}': a broken symbolic link: 'nowhere.yaml' does not exist"),
    ],
)
def test_a_scene_that_is_a_bad_symbolic_link_is_named_as_one(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], target: str | None, expected: str
) -> None:
    link = tmp_path / 'scene'
    os.symlink(link.name if target is None else target, link)
    assert main(['simulate', '--scene', str(link), '--duration', '0.5']) == 2
    assert one_error_line(capsys) == 'folder-line: error: ' + expected.format(p=link)


def test_repair_of_a_folder_that_is_no_bag_touches_nothing(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / 'notes'
    folder.mkdir()
    (folder / 'a.txt').write_text('mine\n')
    os.utime(folder, ns=(1_000_000_000, 1_000_000_000))  # a probe file created and removed would change this
    assert main(['bag', 'repair', str(folder)]) == 2
    assert one_error_line(capsys) == f'folder-line: error: {folder}: no .mcap files: not a rosbag2 bag in MCAP storage'
    assert sorted(p.name for p in folder.iterdir()) == ['a.txt']
    assert folder.stat().st_mtime_ns == 1_000_000_000


def test_a_motor_step_that_would_run_for_hours_is_refused_before_any_work(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``motor_dynamics.h=1e-9`` ran for good (a billion DOPRI5 steps, memory growing): now one line naming the
    key and the least step that would do, exit 2, nothing written."""
    out = tmp_path / 'summary.json'
    argv = ['simulate', '--scene', 'line', '--duration', '1', '--set', 'motor_dynamics.h=1e-9', '--json', str(out)]
    assert main(argv) == 2
    line = one_error_line(capsys)
    assert line.startswith('folder-line: error: effects.motor_dynamics.h=1e-09: asks for ~1.94e+09 steps before')
    assert line.endswith('at most max_steps=20000000: use h >= 9.69e-08 s')
    assert not out.exists()


@pytest.mark.parametrize(
    ('scene', 'setting', 'named'),
    [
        # the issue's: tracebacks (non-finite summary figures, an OverflowError) and a hang
        ('folder', 'cyclogram.D_fc=5e-324', 'cyclogram.D_fc=5e-324: must be in [0.0001, 100] m'),
        ('folder', 'cyclogram.L_feed=1e308', 'cyclogram.L_feed=1e+308: must be in [0.0001, 100] m'),
        ('folder', 'stop_bounce.a_f=5e-324', 'effects.stop_bounce.a_f=5e-324: must be in [1, 1000000] m/s²'),
        ('line', 'chain_friction.r=5e-324', 'effects.chain_friction.r=5e-324: must be in [0.001, 10] m'),
        ('line', 'delivery.Lambda=1e308', 'delivery.Lambda=1e+308: makes the delivery stroke'),
        ('line', 'delivery.Lambda=1e10', 'delivery.Lambda=10000000000.0: makes the delivery stroke 6e+09 m'),
        ('line', 'delivery_chain.pitch=1e308', 'delivery_chain.pitch=1e+308: drives the chain at pitch / T = inf'),
        # found by trying every numeric key at 5e-324, 1e-9, 1e9 and 1e308
        ('line', 'delivery_chain.pitch=1e-4', 'delivery_chain.pitch=0.0001: puts 6653 carriages'),
        ('line', 'delivery_chain.x_max=5e-324', 'delivery_chain.x_max=5e-324: must be in [0.0001, 100] m'),
        ('line', 'delivery.alpha_m_deg=5e-324', 'delivery.alpha_m_deg=5e-324: with delivery.Lambda=0.4'),
        ('line', 'motor_dynamics.J=5e-324', 'effects.motor_dynamics.J=5e-324: must be in [1e-06, 100000] kg m²'),
        ('line', 'motor_dynamics.T_0=1e308', 'effects.motor_dynamics.T_0=1e+308: must be in [0.001, 10000000] N m'),
        ('line', 'motor_dynamics.b=1e308', 'effects.motor_dynamics.b=1e+308: must be in [0, 100000] N m s'),
        ('layup', 'sheets.phase=1e308', 'sheets.phase=1e+308: must be'),
        ('layup', 'layup.l4=1e308', 'a link too extreme (layup.l3=1, layup.l4=1e+308'),
    ],
)
def test_an_extreme_scene_value_is_refused_in_one_line_naming_its_key(
    scene: str, setting: str, named: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bag = tmp_path / 'bag'
    assert main(['simulate', '--scene', scene, '--duration', '1', '--set', setting, '--bag', str(bag)]) == 2
    line = one_error_line(capsys)
    assert line.startswith('folder-line: error: ') and named in line, line
    assert not bag.exists()  # before any work


def _extremes(scene: str) -> list[tuple[str, str]]:
    """Every numeric ``--set`` key of ``scene`` whose range is open at an end, with the most extreme float there."""
    from folder_line.config.keys import scene_keys
    from folder_line.config.scenes import scene_mapping

    out = []
    for info in scene_keys(scene_mapping(scene)):
        if info.choices or not info.has_range or info.whole:
            continue
        if info.lo == 0.0 and info.lo_open:
            out.append((info.key, '5e-324'))
        if info.hi == math.inf:
            out.append((info.key, '1e308'))
    return out


@pytest.mark.parametrize(
    ('scene', 'key', 'value'), [(scene, *kv) for scene in ('folder', 'line', 'layup') for kv in _extremes(scene)]
)
def test_every_extreme_of_an_open_range_runs_clean_or_is_refused_in_one_line(
    scene: str, key: str, value: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """Each scene at the smallest positive and the largest float of each open range of its keys: a run with
    nothing on stderr (no numpy warning, no traceback), or exit 2 with one line that names a key."""
    code = main(['simulate', '--scene', scene, '--duration', '1', '--set', f'{key}={value}'])
    err = capsys.readouterr().err.strip().splitlines()
    assert code in (0, 2), (code, err)
    if code == 0:
        assert err == []
    else:
        (line,) = err
        assert line.startswith('folder-line: error: ') and '=' in line, line
