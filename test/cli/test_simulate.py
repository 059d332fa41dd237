"""Issue 3's outcomes on the shipped scenes, through the public API and the CLI."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from folder_line.cli.main import main
from folder_line.config.scenes import load_scene, parse_set
from folder_line.core.line.line_summary import LineSummary
from folder_line.core.line.model import simulate


@pytest.fixture(scope='module')
def folder_hour() -> LineSummary:
    return simulate(load_scene('folder'), 3600.0, sample_rate=0.0).summary()


def test_folder_one_hour_no_violations_one_signature_per_cycle(folder_hour: LineSummary) -> None:
    s = folder_hour
    assert s.violations.count == 0
    assert s.cycles == 50_000  # T = 0.072 s; cycle 49999's knife contact is at 3599.985 s
    f = s.folder
    assert f.sheets_balance_ok and f.sheets_fed == f.sheets_counted + f.sheets_in_machine
    assert s.sheets_counted >= s.cycles - 2  # one per cycle; the last ones are still on the chain
    one = s.min_margin['one_per_cycle']
    assert one.margin == 0 and one.evaluations == s.cycles and one.violations == 0
    assert s.min_margin_s['feed_window'] == pytest.approx(0.0248311759646518 - 0.230 / 9.3, abs=1e-12)


def test_feeding_at_printing_speed_violates_every_cycle(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / 'vd.json'
    assert (
        main(
            [
                'simulate',
                '--scene',
                'folder',
                '--duration',
                '36',
                '--set',
                'feed_transporter.V_tr=5.833326692478048',
                '--json',
                str(out),
            ]
        )
        == 0
    )
    s = json.loads(out.read_text())
    feed = s['min_margin']['feed_window']
    assert feed['violations'] == feed['evaluations'] == s['cycles'] == 500
    expected = 0.0248311759646518 - 0.230 / 5.833326692478048  # t_allowed - L_feed / V_d
    assert feed['margin'] == pytest.approx(expected, abs=1e-12)  # -14.6 ms
    assert s['violations']['first'][0] == {
        'cycle': 0,
        'constraint': 'feed_window',
        'margin': pytest.approx(expected),
        'unit': 's',
    }
    assert s['v_tr_over_v_d'] == pytest.approx(1.0)
    printed = capsys.readouterr().out
    assert 'feed_window' in printed and '-14.59' in printed


def test_layup_exit_speeds_with_and_without_belts() -> None:
    belts = simulate(load_scene('layup'), 120.0).summary().layup
    bare = simulate(load_scene('layup_no_belts'), 120.0).summary().layup
    assert belts.min_exit_speed >= 2.8
    assert bare.min_exit_speed < 0.01  # leaves near the swing extremes leave with almost no speed
    assert bare.max_exit_speed < belts.min_exit_speed


def test_layup_landing_histograms_side_by_side() -> None:
    hb = simulate(load_scene('layup'), 600.0).summary().layup.landing.histogram
    hn = simulate(load_scene('layup_no_belts'), 600.0).summary().layup.landing.histogram
    assert hb.edges == hn.edges and len(hb.counts) == 31
    # What the model shows: belts fill the wall bins that stay empty without them, and even out the layup.
    assert hn.counts[0] == 0 and hb.counts[0] > 0
    assert hb.cv < hn.cv


def test_same_seed_bit_identical_and_seed_matters() -> None:
    over = parse_set(['seed=5'])
    a = simulate(load_scene('line', over), 10.0, sample_rate=50.0)
    b = simulate(load_scene('line', over), 10.0, sample_rate=50.0)
    c = simulate(load_scene('line', parse_set(['seed=6'])), 10.0, sample_rate=50.0)
    assert a.events.tobytes() == b.events.tobytes()
    for node in a.samples:
        assert a.samples[node].position.tobytes() == b.samples[node].position.tobytes()
    assert json.dumps(a.summary().as_json()) == json.dumps(b.summary().as_json())
    assert a.events.tobytes() != c.events.tobytes()  # leaf jitter follows the seed


def test_samples_cover_every_node_and_are_finite() -> None:
    r = simulate(load_scene('line'), 4.0, sample_rate=200.0)
    assert set(r.samples) == {'drive', 'belts', 'feed', 'counter'}
    for js in r.samples.values():
        assert js.t.size == 801 and js.position.shape == (801, len(js.names))
        assert np.all(np.isfinite(js.position)) and np.all(np.isfinite(js.velocity))
    assert r.samples['feed'].effort is not None  # chain_friction listed: sprocket torque
    assert 'knife' in r.samples['drive'].names and 'transporter3' in r.samples['drive'].names
    assert r.samples['counter'].names == ('pile_table',)  # the line has the delivery: the pile


def test_simulate_cli_bad_input(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / 'x.json'
    assert (
        main(
            ['simulate', '--scene', 'folder', '--duration', '1', '--set', 'feed_transporter.V_x=1', '--json', str(out)]
        )
        == 2
    )
    err = capsys.readouterr().err
    assert err.count('\n') == 1 and 'feed_transporter.V_x' in err
    assert not out.exists()
    with pytest.raises(SystemExit) as exc:
        main(['simulate', '--duration', '-3'])
    assert exc.value.code == 2
