"""``folder-line run``: the line over DDS for a few seconds, then ``run.json`` against ``simulate``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from folder_line.cli import main
from folder_line.core.line import simulate
from folder_line.nodes.common import (
    CLOCK_TOPIC,
    EVENTS_TOPIC,
    SHEET_COUNT_TOPIC,
    SHEET_RATE_TOPIC,
    SUPERVISOR_STATE_TOPIC,
    joint_states_topic,
)
from folder_line.scenes import load_scene

JOINT_TOPICS = [joint_states_topic(n) for n in ('crank_drive', 'belt_conveyor', 'feed_transporter')]
TICK_TOPICS = JOINT_TOPICS + [SHEET_COUNT_TOPIC, SHEET_RATE_TOPIC, SUPERVISOR_STATE_TOPIC]
RATE = 200.0  # the nodes' default, Hz of sim time
#: least share of the ticks a node must publish here: rates are measured in bench/bench_nodes.py; with both
#: cores busy elsewhere (a loaded CI box) a node in these runs published 69-73 % of its ticks
MIN_TICKS = 0.5


def test_run_in_process(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    duration, rtf = 2.5, 1.0  # at rtf 2 one Python executor loses ~5 % of the ticks here (bench/bench_nodes.py)
    assert main(['run', '--duration', str(duration), '--rtf', str(rtf), '--out', str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert 'sheets counted' in out and f'wrote {tmp_path / "run.json"}' in out
    summary = json.loads((tmp_path / 'run.json').read_text())
    assert summary['mode'] == 'in-process' and not summary['interrupted']
    assert summary['sim_time_reached_s'] == duration
    assert summary['rtf_achieved'] == pytest.approx(rtf, rel=0.2)
    messages = summary['messages']
    # one message per node tick: rate x duration of sim time (a tick lost to load costs one)
    expected = RATE * duration
    for topic in TICK_TOPICS:
        assert MIN_TICKS * expected <= messages[topic] <= expected + 1, (topic, messages[topic])
    assert MIN_TICKS * expected <= messages[CLOCK_TOPIC] <= expected + 1  # /clock at rate x rtf per wall second
    batch = simulate(load_scene('folder'), duration, sample_rate=0.0).summary()
    assert summary['sheets_counted'] == batch['sheets_counted'] == summary['expected_from_simulate']['sheets_counted']
    assert summary['sheets_counted'] > 0
    assert summary['events_received'] == batch['events']
    assert messages[EVENTS_TOPIC] == sum(batch['events'].values())
    assert summary['supervisor_state'] == 'EXECUTE'


def test_run_with_one_process_per_node(tmp_path: Path) -> None:
    duration = 1.5
    # half speed: six processes on two cores, each must stay within the supervisor's stale window (see
    # test_processes.py); at rtf 1 a lagging process could get the line held
    assert main(['run', '--processes', '--duration', str(duration), '--rtf', '0.5', '--out', str(tmp_path)]) == 0
    summary = json.loads((tmp_path / 'run.json').read_text())
    assert summary['mode'] == 'processes'
    assert summary['exit_codes'] == dict.fromkeys(
        ['crank_drive', 'belt_conveyor', 'feed_transporter', 'sheet_counter', 'supervisor', 'line_clock'], 0)
    # the clock starts once every process hears it, so the first ticks are not lost to discovery
    for topic in TICK_TOPICS:
        assert summary['messages'][topic] >= MIN_TICKS * RATE * duration, (topic, summary['messages'])
    assert summary['sheets_counted'] == summary['expected_from_simulate']['sheets_counted'] > 0
    logs = sorted((tmp_path / 'logs').iterdir())
    assert len(logs) == 6
    for log in logs:
        assert 'Traceback' not in log.read_text(), log.read_text()


@pytest.mark.parametrize(('item', 'line'), [
    ('feed_transporter.V_tr=-1', 'folder-line: error: feed_transporter.V_tr=-1: must be in (0, 1000]'),
    ('V_tr', "folder-line: error: --set='V_tr': must be KEY=VALUE, e.g. feed_transporter.V_tr=5.833"),
])
def test_run_refuses_a_bad_set_with_one_line(tmp_path: Path, capfd: pytest.CaptureFixture[str], item: str,
                                             line: str) -> None:
    out = tmp_path / 'out'
    assert main(['run', '--duration', '1', '--set', item, '--out', str(out)]) == 2
    captured = capfd.readouterr()
    assert captured.err == line + '\n'
    assert not out.exists()  # nothing started, nothing written
