"""A run's bag is one ``.mcap`` file, and every ``bag`` verb takes the run folder, after a normal end and after
a SIGKILL of ``folder-line run`` (the repaired file opens in the independent ``mcap`` reader)."""

from __future__ import annotations

import re
import shlex
import signal
import subprocess
import sys
from pathlib import Path

from _ros_env import node_environment
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.rosbag2 import Reader

from folder_line.bag.reader import read_bag

from ._line_runs import REPO, start_run, wait_for_line_time


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, '-m', 'folder_line.cli.main', *args],
        capture_output=True,
        text=True,
        env=node_environment(),
        cwd=REPO,
        timeout=300,
    )


def _mcap_count(path: Path) -> int:
    """Messages of one finished ``.mcap`` file, each decoded by the independent reader."""
    with path.open('rb') as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        assert reader.get_summary() is not None
        return sum(1 for _ in reader.iter_decoded_messages())


def test_bag_verbs_take_the_run_folder_after_a_normal_end(tmp_path: Path) -> None:
    out = tmp_path / 'out'
    run = start_run(node_environment(), out, '--scene', 'folder', '--duration', '1', '--rtf', 'max')
    assert run.wait(240) == 0, run.text()
    assert sorted(p.name for p in (out / 'bag').iterdir()) == ['bag_0.mcap', 'metadata.yaml']
    assert 'wrote' in run.text() and '(1 .mcap file)' in run.text()
    info = _cli('bag', 'info', str(out))
    assert info.returncode == 0, info.stderr
    assert 'complete' in info.stdout
    with Reader(out / 'bag') as reader:  # rosbags, and the independent mcap reader: every message, one file
        assert _mcap_count(out / 'bag' / 'bag_0.mcap') == reader.message_count == read_bag(out / 'bag').message_count
    play = _cli('bag', 'play', str(out), '--rtf', 'max')
    assert play.returncode == 0, play.stderr


def test_bag_verbs_take_the_run_folder_after_a_sigkill(tmp_path: Path) -> None:
    out = tmp_path / 'out'
    # not on a terminal, the progress line is printed at each tenth of the duration: 2 s of line time here
    run = start_run(node_environment(), out, '--scene', 'folder', '--duration', '20', '--rtf', '1')
    try:
        wait_for_line_time(run, 4.0)
        shown = run.line_time()
        run.proc.send_signal(signal.SIGKILL)
        run.proc.wait(timeout=30)
    finally:
        run.stop()
    assert run.proc.returncode == -signal.SIGKILL
    assert sorted(p.name for p in (out / 'bag').iterdir()) == ['bag_0.mcap', 'metadata.yaml']

    info = _cli('bag', 'info', str(out))
    assert info.returncode == 0, info.stderr
    assert 'INCOMPLETE' in info.stdout
    advised = re.search(r'folder-line (bag repair \S+)', info.stdout)
    assert advised is not None, info.stdout
    repaired = _cli(*shlex.split(advised.group(1)))  # the command bag info gives, as a user would paste it
    assert repaired.returncode == 0, repaired.stderr
    assert 'salvaged' in repaired.stdout
    again = _cli('bag', 'repair', str(out))  # the run folder stands for its bag; nothing more to do
    assert again.returncode == 0 and 'nothing dropped' in again.stdout, again.stderr

    contents = read_bag(out / 'bag')
    assert contents.files == ('bag_0.mcap',) and contents.custom['folder_line.complete'] == 'repaired'
    assert _mcap_count(out / 'bag' / 'bag_0.mcap') == contents.message_count > 0
    # the line time the run had shown (a lower bound of where it was when killed) is in the bag, but for what
    # its last flush (every 0.1 s of line time) had not written yet
    lost = shown - contents.end_ns / 1e9
    print(f'run killed at shown line time {shown:.3f} s; the repaired bag ends at {contents.end_ns / 1e9:.3f} s')
    assert lost <= 0.2, (shown, contents.end_ns)
    info = _cli('bag', 'info', str(out))
    assert info.returncode == 0 and 'repaired' in info.stdout, info.stderr
    play = _cli('bag', 'play', str(out), '--rtf', 'max')
    assert play.returncode == 0, play.stderr
