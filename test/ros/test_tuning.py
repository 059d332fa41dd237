"""Live tuning: ``folder-line tune`` (a node parameter, as ``ros2 param set``) on a running line.

A live ``folder-line run`` of ``folder`` in lockstep: once it runs, the feed transporter's
speed is lowered below its minimum (V_tr,min = 9.2625 m/s) with ``folder-line tune
feed_transporter.V_tr=8.0``. The supervisor times the change at a machine cycle boundary,
publishes it with that effective time and records it; the first cycle it then judges
violated is the first cycle ``simulate`` says is violated under the same change at the
same effective time, and it holds the line. ``analyze`` replays the bag to the same
transitions. A tunable the scene does not have is refused by the node with its reason
(exit 1).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from folder_line.analysis import analyze
from folder_line.analysis.recording import read_recording
from folder_line.cli.main import main
from folder_line.config.scenes import load_scene
from folder_line.core.line.model import LineModel, simulate
from folder_line.core.line.tuning import Tuning

from ._line_runs import line_with_states
from .conftest import Ros

DURATION = 10.0  # s of line time
SLOW = 8.0  # m/s, below V_tr,min = 9.2625 m/s


def test_lowering_v_tr_holds_at_the_cycle_simulate_says(
    ros: Ros, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / 'run'
    with line_with_states(ros, out, DURATION) as line:
        now = line.state
        assert ros.spin_until(lambda: now() == 'EXECUTE', timeout=120.0), now()
        capsys.readouterr()
        # the folder scene has no layup: its belt_conveyor declares no chute belt speed, and says so
        assert main(['tune', 'layup.v_tr=3.0']) == 1
        refused = capsys.readouterr().out.strip()
        assert refused.startswith('tune: refused: /belt_conveyor chute_belt_speed=3.0: '), refused
        assert main(['tune', f'feed_transporter.V_tr={SLOW}']) == 0
        said = capsys.readouterr().out.strip()
        assert said.startswith(f'tune: accepted: /feed_transporter V_tr = {SLOW!r} m/s'), said
        assert ros.spin_until(lambda: now() == 'HELD', timeout=120.0), now()
        _, err = line.proc.communicate(timeout=180)
        assert 'feed_window violated' in err, err[-2000:]
        # held as simulate under the same change expects: the line did what it should, exit 0
        assert line.proc.returncode == 0, err[-2000:]

    rec = read_recording(out / 'bag')
    (tuning,) = [c for c in rec.commands if isinstance(c, Tuning)]
    assert (tuning.key, tuning.value) == ('feed_transporter.V_tr', SLOW)
    scene = load_scene('folder')
    # effective at a machine cycle boundary of the line's model
    model = LineModel(scene, DURATION + 1.0)
    assert model.next_cycle_boundary(tuning.t - 1e-9) == pytest.approx(tuning.t, abs=1e-9)

    live = [v for _, name, v in rec.supervisor_status if name.endswith('/violation')]
    assert live, 'the supervisor recorded no violation'
    first_live = min(live, key=lambda v: float(v['t']))
    batch = simulate(scene, DURATION, sample_rate=0.0, commands=[tuning])
    cycles = [int(c.cycle[np.flatnonzero(c.violated)[0]]) for c in batch.constraints if c.violated.any()]
    assert cycles, 'simulate under the same change finds no violation'
    assert (first_live['constraint'], int(first_live['cycle'])) == ('feed_window', min(cycles))
    assert first_live['action'] == 'hold'
    # without the change the same span has no violation: the change is what the line was held for
    assert not any(c.violated.any() for c in simulate(scene, DURATION, sample_rate=0.0).constraints)

    summary = json.loads((out / 'run.json').read_text())
    assert summary['tunings'] == [{'t': tuning.t, 'key': 'feed_transporter.V_tr', 'value': SLOW}]
    assert summary['outcome']['ok'] is True
    assert summary['outcome']['message'].startswith(
        f"line ended HELD as the scene expects with the operator's tunings: feed_window in cycle {min(cycles)} at "
    )

    result = analyze(out, tmp_path / 'analysis')
    targets = [t.target for t in result.summary.transitions]
    assert targets[-2:] == ['HOLDING', 'HELD'], targets
    assert result.summary.replay_matches is True
