"""Only the line feeds the line: a stranger on its ROS domain steers, stops and falsifies nothing.

Every process of a line shares its key (``FOLDER_LINE_KEY``; here the test process's, see
``_ros_env``) and so a DDS partition: the line's readers hear only the writers of that
partition, its writers are heard by everyone (:mod:`folder_line.ros.line_key`).

* A stranger without the key (:mod:`._stranger`) floods every topic the line reads or records
  with NaN, forged acknowledgements stamped ahead, grants, commands, a retune, and calls the
  supervisor's abort. The line ends as a clean run does, its bag holds, message for message and
  byte for byte, what the clean run's holds (``line_clock``'s own diagnostics aside: the
  attacked one names the stranger), and ``analyze`` reports the same. The stranger still hears
  the line's ``/clock``: watching stays open.
* Two ``folder-line run`` started at the same instant, five times, each with a key of its own:
  both run, and each bag is the solo run's.
"""

from __future__ import annotations

import collections
import io
import subprocess
import sys
from pathlib import Path

import pytest
from _ros_env import node_environment, stranger_environment
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from folder_line.config.run_config import BAG_DIR, RunConfig
from folder_line.interfaces import DIAGNOSTICS_TOPIC
from folder_line.ros.run import run_line

from ._line_runs import run_under_attack, start_run

DURATION = 4.0  # s of line time: line_clock looks for strangers every 2 s of wall time, at rtf 1
CLOCK_STATUS = 'folder_line/line_clock/'
Records = collections.Counter[tuple[str, int, int, bytes]]


def line_records(out: Path) -> tuple[Records, list[dict[str, str]]]:
    """Every message of the run's bag as (topic, log ns, publish ns, CDR bytes), but ``line_clock``'s
    diagnostics, which are returned apart (as name/message/values dicts)."""
    records: Records = collections.Counter()
    clock_statuses = []
    for path in sorted((out / BAG_DIR).glob('*.mcap')):
        with path.open('rb') as fh:
            reader = make_reader(fh, decoder_factories=[DecoderFactory()])
            for _, channel, message, ros in reader.iter_decoded_messages():
                if channel.topic == DIAGNOSTICS_TOPIC and any(s.name.startswith(CLOCK_STATUS) for s in ros.status):
                    clock_statuses += [
                        {'name': s.name, 'message': s.message, **{kv.key: kv.value for kv in s.values}}
                        for s in ros.status
                    ]
                    continue
                records[(channel.topic, message.log_time, message.publish_time, bytes(message.data))] += 1
    return records, clock_statuses


def analysis(out: Path, tmp: Path) -> list[str]:
    """``folder-line analyze``'s report lines (not the files it wrote)."""
    done = subprocess.run(
        [sys.executable, '-m', 'folder_line.cli.main', 'analyze', str(out), '--out', str(tmp)],
        env=node_environment(),
        capture_output=True,
        text=True,
        timeout=300,
        check=True,
    )
    return [line for line in done.stdout.splitlines() if not line.startswith('wrote ')]


@pytest.fixture(scope='module')
def clean(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp('clean')
    result = run_line(RunConfig(scene='folder', duration=DURATION, rtf=1.0, out=out), io.StringIO())
    assert result.summary.outcome.ok, result.summary.outcome
    return out


def test_a_stranger_without_the_key_cannot_feed_steer_or_falsify_the_line(clean: Path, tmp_path: Path) -> None:
    result, attack = run_under_attack('_stranger.py', stranger_environment(), tmp_path, DURATION)
    out = tmp_path / 'attacked'
    assert attack['published'] >= 10 * attack['topics'] > 0  # it flooded every topic, many times over
    assert attack['heard'].get('/clock', 0) > 0  # watching the line stays open to anyone
    assert attack['calls'] > 0 and attack['answers'] == []  # no service of the line answered it

    assert result.summary.outcome.ok, result.summary.outcome  # what run's exit code 0 says
    bag = result.summary.bag
    assert bag is not None and bag.lost == dict.fromkeys(bag.lost or {}, 0)
    attacked, statuses = line_records(out)
    reference, _ = line_records(clean)
    assert attacked == reference  # the same messages, byte for byte, at the same log and publish times
    named = [s for s in statuses if s['name'] == CLOCK_STATUS + 'foreign_publishers']
    assert named and '/stranger: ' in named[-1]['publishers'], statuses
    assert 'refused' in named[-1]['message']
    assert analysis(out, tmp_path / 'a1') == analysis(clean, tmp_path / 'a2')


@pytest.mark.parametrize('attempt', range(5))
def test_two_lines_started_at_once_each_run_alone(clean: Path, tmp_path: Path, attempt: int) -> None:
    env = stranger_environment()  # no key: each run makes its own, so each line has a partition of its own
    runs = [start_run(env, tmp_path / f'line{i}', '--duration', str(DURATION), '--rtf', '0') for i in range(2)]
    try:
        codes = [run.wait(timeout=300) for run in runs]
    finally:
        for run in runs:
            run.stop()
    reference, _ = line_records(clean)
    for run, code in zip(runs, codes, strict=True):
        assert code == 0, run.text()
        assert 'FOLDER_LINE_KEY=' in run.stdout.read_text()  # the key it made, for its operators
        assert line_records(run.out)[0] == reference  # nothing of the other line in it
