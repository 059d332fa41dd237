"""Bags that other tools open, ``bag info``'s rates, and bad bags refused in one line by every verb that reads one."""

from __future__ import annotations

import hashlib
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from _ros_env import REPO, node_environment
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore

from folder_line.bag.metadata import segment_files
from folder_line.cli.main import main

FOLDER_BAG = REPO / 'test' / 'data' / 'folder_run' / 'bag'


def _digest(path: Path) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(path.rglob('*')) if p.is_file()}


def test_every_mcap_file_carries_its_definitions_and_the_mcap_reader_decodes_it() -> None:
    """The independent ``mcap`` + ``mcap-ros2-support`` reader decodes every message from the file alone."""
    files = segment_files(FOLDER_BAG)
    assert files
    total = 0
    for path in files:
        with path.open('rb') as fh:
            reader = make_reader(fh, decoder_factories=[DecoderFactory()])
            summary = reader.get_summary()
            assert summary is not None
            for channel in summary.channels.values():
                schema = summary.schemas[channel.schema_id]
                assert schema.encoding == 'ros2msg' and schema.data, channel.topic
                assert channel.message_encoding == 'cdr'
            n = 0
            for schema, channel, message, decoded in reader.iter_decoded_messages():
                assert schema is not None and schema.id == channel.schema_id
                if channel.topic == '/clock':
                    assert decoded.clock.sec * 1_000_000_000 + decoded.clock.nanosec == message.log_time
                n += 1
            assert n == sum(summary.statistics.channel_message_counts.values())
            total += n
    meta = yaml.safe_load((FOLDER_BAG / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert total == meta['message_count']


def test_rosbags_reads_every_message() -> None:
    store = get_typestore(Stores.ROS2_KILTED)
    with Reader(FOLDER_BAG) as reader:
        n = sum(1 for conn, _, raw in reader.messages() if store.deserialize_cdr(raw, conn.msgtype) is not None)
        assert n == reader.message_count > 0


def test_bag_info_prints_counts_rates_and_span(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(['bag', 'info', str(FOLDER_BAG)]) == 0
    out = capsys.readouterr().out
    meta = yaml.safe_load((FOLDER_BAG / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    span = meta['duration']['nanoseconds'] / 1e9
    assert f'({span:.3f} s)' in out
    for entry in meta['topics_with_message_count']:
        name, count = entry['topic_metadata']['name'], entry['message_count']
        line = next(row for row in out.splitlines() if row.split()[:1] == [name])
        fields = line.split()
        assert int(fields[2]) == count
        assert float(fields[3]) == pytest.approx(count / span, rel=1e-3)


def _truncated(tmp: Path) -> Path:
    bag = tmp / 'truncated'
    shutil.copytree(FOLDER_BAG, bag)
    last = segment_files(bag)[-1]
    data = last.read_bytes()
    last.write_bytes(data[: len(data) // 2])
    return bag


def _not_a_bag(tmp: Path) -> Path:
    folder = tmp / 'notabag'
    folder.mkdir()
    (folder / 'notes.txt').write_text('not a bag\n')
    return folder


def _later_version(tmp: Path) -> Path:
    bag = tmp / 'later'
    shutil.copytree(FOLDER_BAG, bag)
    meta = bag / 'metadata.yaml'
    text = meta.read_text()
    assert 'folder_line.version: 0.1.0' in text
    meta.write_text(text.replace('folder_line.version: 0.1.0', 'folder_line.version: 99.0.0'))
    return bag


@pytest.mark.parametrize(('make', 'says'), [(_truncated, 'cannot open'), (_not_a_bag, ''), (_later_version, '99.0.0')])
@pytest.mark.parametrize('verb', [['bag', 'info'], ['analyze'], ['bag', 'play']])
def test_a_bad_bag_is_one_line_exit_2_and_left_untouched(
    tmp_path: Path, make: object, says: str, verb: list[str]
) -> None:
    bag = make(tmp_path)  # type: ignore[operator]
    before = _digest(bag)
    extra = ['--out', str(tmp_path / 'out')] if verb == ['analyze'] else ['--rtf', 'max'] if verb[-1] == 'play' else []
    proc = subprocess.run(
        [sys.executable, '-m', 'folder_line.cli.main', *verb, str(bag), *extra],
        capture_output=True,
        text=True,
        env=node_environment(),
        cwd=REPO,
        timeout=60,
    )
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith('folder-line: error: ') and str(bag) in lines[0], proc.stderr
    assert says in lines[0]
    assert proc.stdout == ''
    assert _digest(bag) == before
    assert not (tmp_path / 'out').exists()


def test_a_bag_of_more_files_than_the_open_file_limit_is_read(tmp_path: Path) -> None:
    """An hour's bag split every second (``--max-bag-duration 1``) is 3601 files; the usual limit is 1024 open
    files. The files are opened one at a time, so ``bag info`` and ``analyze`` read a bag of 81 files under a
    limit of 40 open files."""
    import resource

    bag = tmp_path / 'bag'
    assert (
        main(['simulate', '--scene', 'folder', '--duration', '80', '--bag', str(bag), '--max-bag-duration', '1']) == 0
    )
    assert len(segment_files(bag)) == 81

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_NOFILE, (40, 40))

    for verb in (['bag', 'info', str(bag)], ['analyze', str(bag), '--out', str(tmp_path / 'a'), '--from', '79']):
        proc = subprocess.run(
            [sys.executable, '-m', 'folder_line.cli.main', *verb],
            capture_output=True,
            text=True,
            env=node_environment(),
            cwd=REPO,
            timeout=120,
            preexec_fn=limit,
        )
        assert proc.returncode == 0, proc.stderr
    assert (tmp_path / 'a' / 'report.md').is_file()


@pytest.mark.parametrize(
    ('split', 'files'),
    # by duration: [0, 0.5) .. [1.5, 2) and the last tick, at 2 s
    [([], 1), (['--max-bag-duration', '0.5'], 5), (['--max-bag-size', '100000'], None)],
    ids=['one file', 'by duration', 'by size'],
)
def test_simulate_bag_is_one_file_unless_split_and_both_readers_read_it_whole(
    tmp_path: Path, split: list[str], files: int | None
) -> None:
    """``simulate --bag`` writes one ``.mcap`` as ``ros2 bag record`` does; split on request, the same messages
    in more files. The independent mcap reader and rosbags each read every message."""
    bag = tmp_path / 'bag'
    assert main(['simulate', '--scene', 'folder', '--duration', '2', '--bag', str(bag), *split]) == 0
    paths = segment_files(bag)
    if files is not None:
        assert len(paths) == files
    else:
        assert len(paths) > 1 and all(p.stat().st_size >= 100000 for p in paths[:-1])
    per_topic: dict[str, int] = {}
    for path in paths:
        with path.open('rb') as fh:
            for _, channel, _, _ in make_reader(fh, decoder_factories=[DecoderFactory()]).iter_decoded_messages():
                per_topic[channel.topic] = per_topic.get(channel.topic, 0) + 1
    with Reader(bag) as reader:
        by_rosbags: dict[str, int] = {}
        for connection, _, _ in reader.messages():
            by_rosbags[connection.topic] = by_rosbags.get(connection.topic, 0) + 1
    assert per_topic == by_rosbags and sum(per_topic.values()) > 1000
