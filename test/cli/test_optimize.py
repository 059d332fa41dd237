"""``folder-line optimize``: the geometry it returns is confirmed by ``simulate`` and by the model's own checks."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from folder_line.cli.main import main
from folder_line.config.scenes import load_scene
from folder_line.core.mechanisms.layup import LayupModel, LayupParams
from folder_line.core.mechanisms.layup_angles import TAU, classify_fourbar

DURATION = '60'
MIN_TRANSMISSION = 40.0


@pytest.fixture(scope='module')
def optimized(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    out = tmp_path_factory.mktemp('opt') / 'out'
    argv = ['optimize', '--scene', 'layup', '--duration', DURATION, '--maxiter', '5', '--popsize', '5']
    argv += ['--min-transmission', str(MIN_TRANSMISSION), '--out', str(out)]
    with pytest.MonkeyPatch.context() as mp:
        lines: list[str] = []
        mp.setattr('builtins.print', lambda *a, **k: lines.append(' '.join(str(x) for x in a)))
        assert main(argv) == 0
    return out, '\n'.join(lines)


def _simulate(scene: str, tmp: Path, name: str) -> dict:
    dest = tmp / f'{name}.json'
    assert main(['simulate', '--scene', scene, '--duration', DURATION, '--json', str(dest)]) == 0
    return json.loads(dest.read_text())['layup']


def test_simulate_confirms_every_constraint_and_a_cv_no_worse_than_the_start(
    optimized: tuple[Path, str], tmp_path: Path
) -> None:
    out, _ = optimized
    scene_file = out / 'scene.yaml'
    before = _simulate('layup', tmp_path, 'before')
    after = _simulate(str(scene_file), tmp_path, 'after')
    # no leaf spilled or damaged, and every leaf that exited landed
    assert after['leaves_spilled'] == 0 and after['leaves_damaged'] == 0
    assert after['leaves_landed'] > 0.9 * before['leaves_landed']
    assert after['landing_cv'] <= before['landing_cv']
    doc = json.loads((out / 'optimize.json').read_text())
    # this seeded budget does move the geometry (else the checks below would only re-check the shipped scene)
    assert doc['improved'] and doc['best']['values'] != doc['start']['values']
    assert doc['best']['landing_cv'] == after['landing_cv']  # the file holds exactly the geometry judged
    assert doc['start']['landing_cv'] == before['landing_cv']

    scene = load_scene(scene_file)  # validation: a Grashof crank-rocker that assembles all turn
    lp = scene.machine('layup')
    assert isinstance(lp, LayupParams)
    assert classify_fourbar(math.hypot(lp.a, lp.b), lp.R_kr, lp.l2, lp.O2B) == 'crank-rocker'
    # transmission angle and exits over the turn, from the model's kinematics (not the optimiser's formulas)
    st = LayupModel(lp).arrays(np.arange(100_000) * (TAU / 100_000), accelerations=False)
    worst = math.degrees(math.asin(min(st.margin1.min(), st.margin2.min())))  # margin = sin μ
    assert worst >= MIN_TRANSMISSION
    cont = scene.machine('container')
    xs = np.concatenate([st.xC, st.xE])
    assert cont.x_left <= xs.min() and xs.max() <= cont.x_right
    assert min(st.yC.min(), st.yE.min()) > cont.y_floor
    # only the layup's links changed
    start = load_scene('layup')
    assert scene.machine('container') == start.machine('container') and scene.sheets == start.sheets
    assert (lp.n_kr, lp.v_tr, lp.a, lp.b) == (start.machine('layup').n_kr, 2.8, -0.6, -0.25)


def test_optimize_reports_both_histograms_and_writes_a_png(optimized: tuple[Path, str]) -> None:
    out, text = optimized
    assert 'before (cv' in text and 'after (cv' in text
    assert text.count(' m  ') >= 31  # one row per bin
    assert 'landing cv' in text or 'could not be beaten' in text
    assert (out / 'landing.png').read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


@pytest.mark.parametrize(
    ('argv', 'option'),
    [
        (['--vary', 'layup.n_kr=20:40'], '--vary'),
        (['--vary', 'layup.l4=0.7:0.5'], '--vary'),
        (['--scene', 'folder'], '--scene'),
        (['--min-transmission', '95'], '--min-transmission'),
        (['--set', 'layup.l4=abc'], 'layup.l4'),
    ],
)
def test_bad_input_is_one_line_exit_2_and_nothing_written(
    argv: list[str], option: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / 'out'
    with pytest.raises(SystemExit) if option == '--min-transmission' else _no_exit() as exc:
        rc = main(['optimize', '--duration', '10', '--maxiter', '1', '--popsize', '2', '--out', str(out), *argv])
    if option == '--min-transmission':
        rc = exc.value.code  # type: ignore[union-attr]
    assert rc == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and option in err
    assert not out.exists()


def test_an_output_folder_that_is_a_file_is_refused_before_any_work(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    target = tmp_path / 'out'
    target.write_text('mine')
    assert main(['optimize', '--out', str(target)]) == 2
    assert '--out' in capsys.readouterr().err
    assert target.read_text() == 'mine'


class _no_exit:
    """A context manager that expects no exception (the counterpart of ``pytest.raises``)."""

    def __enter__(self) -> None:
        return None

    def __exit__(self, *exc: object) -> bool:
        return False
