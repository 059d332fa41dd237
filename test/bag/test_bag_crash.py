"""Crash safety of the bag writer: SIGKILL the writing process, then open and repair the bag.

The subject is ``test/bag/_bag_crash_writer.py`` (a real process with a fake line clock,
``dt`` = 10 ms per step, three messages per five steps... see its docstring). What is
promised: a bag is one ``.mcap`` file unless split on request; after SIGKILL ``repair`` makes
the open file readable, in rosbags and in the independent ``mcap`` reader, and what is
missing is at most the tail after its last flush (0.1 s of line time). A bag split on
request (``--max-bag-duration 1``) opens with rosbags as it is, with every message of every
finished file, each of which opens with the ``mcap`` reader.
"""

from __future__ import annotations

import os
import random
import re
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from folder_line.bag.metadata import segment_files
from folder_line.bag.reader import bag_info_lines, read_bag
from folder_line.bag.repair import repair
from folder_line.cli.main import main as cli_main
from folder_line.errors import BagError

REPO = Path(__file__).resolve().parents[2]
SCRIPT = REPO / 'test' / 'bag' / '_bag_crash_writer.py'
DT_NS = 10_000_000  # 10 ms of line time per step
SEGMENT_S = 1.0
SEGMENT_NS = 1_000_000_000
JOINTS = '/line/crank_drive/joint_states'
EVENTS = '/line/events'


def _start(bag: Path, *extra: str, chunk_size: int = 2048, split: bool = False) -> subprocess.Popen[str]:
    """The writer in a process of its own; ``split``: a new file every :data:`SEGMENT_S` of line time."""
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join(p for p in (str(REPO), env.get('PYTHONPATH', '')) if p)
    return subprocess.Popen(
        [
            sys.executable,
            str(SCRIPT),
            str(bag),
            '--dt-ns',
            str(DT_NS),
            *(('--max-bag-duration', str(SEGMENT_S)) if split else ()),
            '--chunk-size',
            str(chunk_size),
            *extra,
        ],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )


def _kill(proc: subprocess.Popen[str]) -> None:
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=10)
    assert proc.returncode == -signal.SIGKILL


def _read_line(proc: subprocess.Popen[str]) -> str:
    assert proc.stdout is not None
    line = proc.stdout.readline()
    if not line:
        assert proc.stderr is not None
        raise AssertionError(f'writer ended early: {proc.stderr.read()}')
    return line.strip()


def _kill_after(proc: subprocess.Popen[str], step: int) -> int:
    """SIGKILL the free-running writer once it reports a step at or after ``step``; return the step reported
    (it went on writing after that)."""
    try:
        while True:
            reported = int(_read_line(proc).split()[1])  # the writer has written this step
            if reported >= step:
                return reported
    finally:
        _kill(proc)


def _expected(steps: range) -> dict[str, int]:
    return {'/clock': len(steps), JOINTS: len(steps), EVENTS: sum(1 for i in steps if i % 5 == 0)}


def _joint_steps(bag: Path) -> list[int]:
    """Steps of the joint-state messages in the bag, in order, checked against their stamps."""
    steps = []
    for _topic, t_ns, msg in read_bag(bag).messages([JOINTS]):
        i = int(msg.position[0])
        assert t_ns == i * DT_NS
        assert msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec == i * DT_NS
        steps.append(i)
    return steps


def _mcap_steps(path: Path) -> list[int]:
    """Steps in one ``.mcap`` file, read with the mcap library and decoded by mcap_ros2."""
    with path.open('rb') as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        assert reader.get_summary() is not None  # a finished file
        return [int(ros.position[0]) for _, channel, message, ros in reader.iter_decoded_messages(topics=[JOINTS])]


def _finished_with_mcap(path: Path) -> bool:
    try:
        with path.open('rb') as fh:
            return make_reader(fh).get_summary() is not None
    except (McapError, OSError, EOFError, ValueError):  # varies with where the file ends
        return False


def test_sigkill_mid_segment_keeps_every_finished_segment(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A bag split every second: the files finished before the kill are whole as they are."""
    bag = tmp_path / 'bag'
    n_steps = 345  # t = 0 .. 3.44 s: segments [0,1), [1,2), [2,3) finished, [3,4) open
    proc = _start(bag, '--block-after', str(n_steps), split=True)
    try:
        assert _read_line(proc) == f'blocked {n_steps}'
    finally:
        _kill(proc)
    t_last = (n_steps - 1) * DT_NS
    boundary = t_last // SEGMENT_NS * SEGMENT_NS  # start of the open segment
    complete = range(boundary // DT_NS)  # steps 0..299

    # as it is: rosbags opens it, with every message of the finished segments and nothing else
    files = segment_files(bag)
    assert [f.name for f in files] == ['bag_0.mcap', 'bag_1.mcap', 'bag_2.mcap', 'bag_3.mcap']
    contents = read_bag(bag)
    assert contents.files == ('bag_0.mcap', 'bag_1.mcap', 'bag_2.mcap')
    assert {t: s.count for t, s in contents.topics.items() if s.count} == _expected(complete)
    assert _joint_steps(bag) == list(complete)
    assert contents.scene_name == 'crash' and contents.effects == ['faults']
    # the finished segments open with the independent mcap reader too, each with its second of steps
    for k, path in enumerate(files[:3]):
        assert _mcap_steps(path) == list(range(k * 100, (k + 1) * 100))
    assert not _finished_with_mcap(files[3])

    # repair: the open segment's complete chunks are salvaged, the rest is a tail of at most one segment
    result = repair(bag)
    assert result.salvaged.get('bag_3.mcap', 0) > 0 and result.dropped['bag_3.mcap'] >= 0
    assert (bag / 'bag_3.mcap.truncated').is_file()
    steps = _joint_steps(bag)
    m = len(steps)
    assert steps == list(range(m))  # a prefix: nothing missing in between
    assert boundary // DT_NS < m < n_steps
    lost = range(m, n_steps)
    assert all(i * DT_NS >= boundary for i in lost)
    assert t_last - lost[0] * DT_NS < SEGMENT_NS  # at most one segment of line time lost
    assert _mcap_steps(bag / 'bag_3.mcap') == list(range(300, m))
    repaired = read_bag(bag)
    assert repaired.files == ('bag_0.mcap', 'bag_1.mcap', 'bag_2.mcap', 'bag_3.mcap')
    assert repaired.scene_source == 'name: crash\n'
    assert 'salvaged' in repaired.custom['folder_line.repair']

    # repairing again changes nothing; the CLI says so with exit 0
    assert cli_main(['bag', 'repair', str(bag)]) == 0
    assert 'nothing dropped' in capsys.readouterr().out
    assert _joint_steps(bag) == steps


def test_sigkill_while_writing_loses_at_most_the_open_segment(tmp_path: Path) -> None:
    bag = tmp_path / 'bag'
    proc = _start(bag, split=True)
    reported = _kill_after(proc, 520)
    # the writer went on after `reported`; every segment finished before its end must be whole
    contents = read_bag(bag)
    finished = len(contents.files)
    assert finished >= reported * DT_NS // SEGMENT_NS  # >= 5
    complete = range(finished * SEGMENT_NS // DT_NS)
    assert {t: s.count for t, s in contents.topics.items() if s.count} == _expected(complete)
    assert _joint_steps(bag) == list(complete)
    for path in segment_files(bag)[:finished]:
        assert _finished_with_mcap(path)

    repair(bag)
    steps = _joint_steps(bag)
    assert steps == list(range(len(steps)))
    assert len(steps) >= len(complete) and len(steps) > reported - SEGMENT_NS // DT_NS


def test_sigkill_in_the_first_segment(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = tmp_path / 'bag'
    proc = _start(bag, '--block-after', '60', chunk_size=1024 * 1024)  # the recorder's chunk size
    try:
        assert _read_line(proc) == 'blocked 60'
    finally:
        _kill(proc)
    contents = read_bag(bag)  # opens: no finished segment yet, metadata from the start
    assert contents.message_count == 0 and contents.files == ()
    assert contents.scene_name == 'crash'
    assert contents.custom['folder_line.complete'] == 'false'  # marked partial: its writer never closed it
    assert any(
        line.startswith('state      INCOMPLETE') and 'folder-line bag repair' in line
        for line in bag_info_lines(contents)
    )
    # the run folder (tmp_path, which holds bag/) stands for its bag, and the command bag info advises works
    assert cli_main(['bag', 'info', str(tmp_path)]) == 0
    advised = re.search(r'folder-line (bag repair \S+)', capsys.readouterr().out)
    assert advised is not None
    assert cli_main(advised.group(1).split()) == 0
    assert 'salvaged' in capsys.readouterr().out
    assert read_bag(bag).custom['folder_line.complete'] == 'repaired'
    assert cli_main(['bag', 'repair', str(tmp_path)]) == 0  # again, through the run folder: nothing more
    assert 'nothing dropped' in capsys.readouterr().out
    assert cli_main(['bag', 'info', str(tmp_path)]) == 0
    assert 'repaired' in capsys.readouterr().out
    steps = _joint_steps(bag)
    # flushed every 0.1 s of line time: steps up to 0.5 s are on disk although no chunk was full
    assert steps == list(range(len(steps))) and 50 <= len(steps) < 60


FLUSH_NS = 100_000_000  # the writer's default flush_s, 0.1 s
GOAL_NS = 200_000_000  # at most 0.2 s of line time lost to a SIGKILL


def test_sigkill_at_ten_random_moments_loses_at_most_the_flush_interval(tmp_path: Path) -> None:
    """A one-file bag (the default), killed at ten moments: repaired, it lacks at most 0.2 s of line time."""
    rng = random.Random(20261124)  # fixed: the same ten moments in every run
    lost_ns = []
    for k in range(10):
        n_steps = rng.randrange(2, 1000)  # a moment within 10 s of line time
        bag = tmp_path / f'bag{k}'
        proc = _start(bag, '--block-after', str(n_steps), chunk_size=1024 * 1024)
        try:
            assert _read_line(proc) == f'blocked {n_steps}'
        finally:
            _kill(proc)
        try:
            repair(bag)
        except BagError:  # killed before the first flush: nothing on disk, and repair changes nothing
            steps = []
        else:
            steps = _joint_steps(bag)
            # one file, as ros2 bag record writes it; repaired, it opens whole in the independent reader
            assert segment_files(bag) == [bag / f'{bag.name}_0.mcap']
            assert _mcap_steps(bag / f'{bag.name}_0.mcap') == steps
        assert steps == list(range(len(steps)))  # a prefix: nothing missing in between
        lost = (n_steps - len(steps)) * DT_NS  # line time written but not in the repaired bag
        assert 0 <= lost <= FLUSH_NS + DT_NS, (n_steps, steps[-1])
        lost_ns.append(lost)
    print(
        f'line time lost to SIGKILL after repair, 10 moments: worst {max(lost_ns) / 1e6:g} ms, '
        f'mean {sum(lost_ns) / len(lost_ns) / 1e6:g} ms'
    )
    assert max(lost_ns) <= GOAL_NS


def test_repair_of_a_bag_with_nothing_to_salvage_changes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bag = tmp_path / 'bag'
    proc = _start(bag, '--block-after', '1', chunk_size=1024 * 1024)  # killed before its first flush
    try:
        assert _read_line(proc) == 'blocked 1'
    finally:
        _kill(proc)
    before = {p.name: p.read_bytes() for p in bag.iterdir()}
    assert 'bag_0.mcap' in before
    with pytest.raises(BagError, match='holds a readable message'):
        repair(bag)
    assert cli_main(['bag', 'repair', str(bag)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and 'nothing was changed' in err
    assert {p.name: p.read_bytes() for p in bag.iterdir()} == before


def test_a_one_file_bag_killed_while_writing_fast_loses_at_most_the_flush_interval(tmp_path: Path) -> None:
    """The writer at full speed (not blocked at a step), killed: one file, repaired to a prefix that ends
    at most a flush interval (and the step being written) before the last step it reported."""
    bag = tmp_path / 'bag'
    proc = _start(bag, chunk_size=1024 * 1024)
    reported = _kill_after(proc, 520)
    assert [p.name for p in segment_files(bag)] == ['bag_0.mcap']
    assert read_bag(bag).files == ()  # as it is: the file is open, the metadata lists no finished file
    repair(bag)
    steps = _joint_steps(bag)
    assert steps == list(range(len(steps)))
    assert (reported - len(steps) + 1) * DT_NS <= GOAL_NS
    assert _mcap_steps(bag / 'bag_0.mcap') == steps
