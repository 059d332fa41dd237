"""``simulate --tune ... --bag``: the batch bag holds the tuning as a live run's does and replays to its transitions."""

from __future__ import annotations

from pathlib import Path

import pytest

from folder_line.analysis import analyze
from folder_line.analysis.recording import read_recording
from folder_line.bag.batch import write_batch_bag
from folder_line.cli.main import main
from folder_line.config.scenes import load_scene
from folder_line.core.line.tuning import Tuning


def test_a_tuned_batch_bag_replays_to_its_own_transitions(tmp_path: Path) -> None:
    tuning = Tuning(3.0, 'feed_transporter.V_tr', 8.0)
    write_batch_bag(tmp_path / 'bag', load_scene('folder'), 6.0, tunings=[tuning])
    rec = read_recording(tmp_path / 'bag')
    assert tuning in rec.commands
    (status,) = [v for _, name, v in rec.supervisor_status if name.endswith('/tuning')]
    assert float(status['effective']) == 3.0 and float(status['t']) < 3.0
    result = analyze(tmp_path / 'bag', tmp_path / 'analysis')
    assert [t.target for t in result.summary.transitions][-2:] == ['HOLDING', 'HELD']
    assert result.summary.replay_matches is True


def test_simulate_refuses_a_tuning_the_scene_cannot_take(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(['simulate', '--scene', 'folder', '--duration', '2', '--tune', '1:layup.v_tr=3']) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["folder-line: error: layup.v_tr=3.0: scene 'folder' has no layup device"]
    assert main(['simulate', '--scene', 'folder', '--duration', '2', '--tune', '3:feed_transporter.V_tr=8']) == 2
    assert '--tune' in capsys.readouterr().err
