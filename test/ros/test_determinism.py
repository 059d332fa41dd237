"""Lockstep determinism over real DDS: the bag of a run is the batch model, whatever runs where.

``folder-line run`` at ``--rtf max`` records the line in lockstep: ``line_clock`` publishes
tick ``k + 1`` only after every participant, the recorder included, acknowledged tick ``k``.
So the same short run of the ``folder`` scene, once with every node on one executor and
once with one process per node, gives the same bag message for message -- topic,
publishing node, log time, publish time, header stamps and every value, read back with the
independent ``mcap`` reader -- and that bag is the batch model
(:class:`folder_line.core.line.model.LineModel`) tick by tick. A short ``line`` scene run (belts
and leaves too) is the model as well.
"""

from __future__ import annotations

import io
import json
from pathlib import Path

import pytest

from folder_line.config.run_config import RunConfig
from folder_line.interfaces import MACHINE_NODES
from folder_line.ros.run import run_line

from ._line_runs import assert_bag_is_model, read_bag_mcap

#: the issue's runs: 20 s of the folder scene, 10 s of the whole line
FOLDER_DURATION = 20.0
LINE_DURATION = 10.0
RATE = 200.0


def n_ticks(duration: float) -> int:
    """Ticks at 0, 5 ms, ..., ``duration``."""
    return round(duration * RATE) + 1


def run(out: Path, scene: str, processes: bool, duration: float) -> dict:
    result = run_line(RunConfig(scene=scene, duration=duration, rtf=0.0, out=out, processes=processes), io.StringIO())
    summary = json.loads((out / 'run.json').read_text())
    assert summary == json.loads(json.dumps(result.summary.as_json()))
    return summary


@pytest.fixture(scope='module')
def folder_runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The same run of the folder scene in process and with one process per node."""
    outs = {}
    for mode in ('in-process', 'processes'):
        outs[mode] = tmp_path_factory.mktemp(mode)
        run(outs[mode], 'folder', mode == 'processes', FOLDER_DURATION)
    return outs


def check_summary(summary: dict, scene: str, mode: str, duration: float) -> None:
    assert summary['outcome'] == {
        'ok': True,
        'expected_state': 'EXECUTE',
        'state': 'EXECUTE',
        'message': 'line ended EXECUTE as the scene expects',
    }
    assert summary['scene'] == scene and summary['mode'] == mode and summary['clock'] == 'lockstep'
    assert summary['sim_time_reached_s'] == duration and not summary['interrupted']
    assert summary['lost_participants'] == {} and summary['cause'] is None
    assert summary['rtf_requested'] == 'max'
    messages = summary['messages']
    for topic in (
        '/clock',
        '/line/supervisor/state',
        '/line/sheet_counter/count',
        '/line/sheet_counter/rate',
        *(f'/line/{n}/joint_states' for n in ('crank_drive', 'belt_conveyor', 'feed_transporter', 'sheet_counter')),
    ):
        assert messages[topic] == n_ticks(duration), (topic, messages[topic])
    assert messages['/line/participants'] == 1 and messages['/diagnostics'] == int(duration) + 1
    assert summary['events_received'] == summary['expected_from_simulate']['events']
    assert summary['sheets_counted'] == summary['expected_from_simulate']['sheets_counted'] > 0
    assert summary['bag']['messages'] == {**dict.fromkeys(summary['bag']['messages'], 0), **messages}


def test_in_process_and_processes_record_the_same_bag(folder_runs: dict[str, Path]) -> None:
    summaries = {mode: json.loads((out / 'run.json').read_text()) for mode, out in folder_runs.items()}
    for mode, summary in summaries.items():
        check_summary(summary, 'folder', mode, FOLDER_DURATION)
    assert summaries['in-process']['published'] == summaries['in-process']['bag']['messages']
    assert set(summaries['in-process']['lost'].values()) == {0}
    assert summaries['processes']['published'] is None  # not collected across processes
    assert summaries['processes']['exit_codes'] == dict.fromkeys((*MACHINE_NODES, 'line_clock'), 0)
    for log in (folder_runs['processes'] / 'logs').iterdir():
        assert 'Traceback' not in log.read_text() and 'ERROR' not in log.read_text(), log.read_text()

    bags = {mode: read_bag_mcap(out / 'bag') for mode, out in folder_runs.items()}
    a, b = bags['in-process'], bags['processes']
    assert sorted(a) == sorted(b)
    assert sum(map(len, a.values())) == sum(summaries['in-process']['messages'].values()) > 8 * n_ticks(FOLDER_DURATION)
    for key in sorted(a):
        assert len(a[key]) == len(b[key]), key
        for i, (x, y) in enumerate(zip(a[key], b[key], strict=True)):
            assert (x.log_ns, x.publish_ns, x.value) == (y.log_ns, y.publish_ns, y.value), (key, i)


@pytest.mark.parametrize('mode', ['in-process', 'processes'])
def test_folder_run_is_the_batch_model(folder_runs: dict[str, Path], mode: str) -> None:
    assert_bag_is_model(read_bag_mcap(folder_runs[mode] / 'bag'), 'folder', FOLDER_DURATION, RATE)


def test_line_scene_run_is_the_batch_model(tmp_path: Path) -> None:
    summary = run(tmp_path, 'line', processes=False, duration=LINE_DURATION)
    check_summary(summary, 'line', 'in-process', LINE_DURATION)
    assert summary['messages']['/line/sheet_counter/landing_x'] > 0  # the layup's leaves land
    assert summary['published'] == summary['bag']['messages']
    assert_bag_is_model(read_bag_mcap(tmp_path / 'bag'), 'line', LINE_DURATION, RATE)
