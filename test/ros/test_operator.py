"""``folder-line hold|unhold|...`` against a running line: the supervisor's services without the ``ros2`` CLI.

A live ``folder-line run`` of ``folder`` in lockstep on this test process's ROS domain:
``hold`` is accepted and the line is HELD after the next cycle boundary, ``unhold`` brings
it back to EXECUTE, a second ``unhold`` is refused with the reason (exit 1); the run ends
with exit 0 and ``analyze`` replays its bag to the same transitions. With no line on the
domain a command says so in one line and exits 3.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from _ros_env import DOMAIN_ID

from folder_line.analysis import analyze
from folder_line.cli.main import main
from folder_line.config.scenes import load_scene
from folder_line.core.line.model import LineModel

from ._line_runs import line_with_states
from .conftest import Ros

DURATION = 12.0  # s of line time


def test_no_line_on_the_domain_is_one_line_and_exit_3(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(['hold', '--timeout', '0.5']) == 3
    out = capsys.readouterr()
    assert out.out == ''
    (line,) = out.err.strip().splitlines()
    assert line.startswith('folder-line: error: hold: no supervisor answered /line/supervisor/hold')
    assert f'ROS domain {DOMAIN_ID} within 0.5 s' in line


def test_a_bad_timeout_is_refused(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(['abort', '--timeout', '0'])
    assert exc.value.code == 2
    assert '--timeout' in capsys.readouterr().err


def test_hold_unhold_and_a_refusal_against_a_running_line(
    ros: Ros, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / 'run'
    with line_with_states(ros, out, DURATION) as line:
        now = line.state
        assert ros.spin_until(lambda: now() == 'EXECUTE', timeout=120.0), now()
        capsys.readouterr()

        assert main(['hold']) == 0
        said = capsys.readouterr().out.strip()
        m = re.fullmatch(
            r'hold: accepted: hold: HOLDING, drive hold effective at ([0-9.]+) s \(the next cycle boundary\)', said
        )
        assert m, said
        t_hold = float(m.group(1))
        # the effective time is the start of a machine cycle of the line's model (printed to the µs)
        model = LineModel(load_scene('folder'), DURATION + 1.0)
        assert model.next_cycle_boundary(t_hold - 2e-6) == pytest.approx(t_hold, abs=1e-6)
        assert ros.spin_until(lambda: now() == 'HELD', timeout=120.0), now()

        assert main(['unhold']) == 0
        assert capsys.readouterr().out.startswith('unhold: accepted: unhold: UNHOLDING, drive unhold effective at ')
        assert ros.spin_until(lambda: now() == 'EXECUTE', timeout=120.0), now()

        assert main(['unhold']) == 1  # illegal in EXECUTE
        refused = capsys.readouterr().out.strip()
        assert refused.startswith('unhold: refused: ') and 'EXECUTE' in refused, refused

        _, err = line.proc.communicate(timeout=180)
        assert line.proc.returncode == 0, err
    result = analyze(out, tmp_path / 'analysis')
    targets = [t.target for t in result.summary.transitions]
    assert targets[-4:] == ['HOLDING', 'HELD', 'UNHOLDING', 'EXECUTE'], targets
    assert result.summary.replay_matches is True
