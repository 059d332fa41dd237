"""``simulate --bag``: the bag of a live lockstep run, written without DDS, is the live bag.

The proof: the same scene and duration run live (``run_line`` in process, lockstep, ``--rtf
max``, on this test process's own ROS domain) and written by ``folder-line simulate --bag``
give the same messages -- topic, publisher, log time, publish time, header stamps and every
field -- read with the independent ``mcap`` + ``mcap-ros2-support`` reader
(``make_reader`` with ``mcap_ros2``'s ``DecoderFactory``, decoding from the schema text in each file). ``folder`` runs
clean; ``folder_faults`` makes the supervisor judge a late sheet, publish a violation and
command a hold, which changes what every machine publishes from then on; ``line`` adds the
belts, the layup and its leaves' landings.

The fast-path CDR (:mod:`folder_line.bag.cdr`) is checked byte for byte against the rosbags
typestore, and ``--bag`` refuses a folder that holds something, before any work.
"""

from __future__ import annotations

import io
import os
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
import yaml
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.rosbag2 import Reader

from folder_line.bag import cdr
from folder_line.bag.batch import announcement
from folder_line.bag.metadata import segment_files
from folder_line.bag.types import typestore
from folder_line.cli.main import main as cli_main
from folder_line.config.run_config import RunConfig
from folder_line.interfaces import KNOWN_PARTICIPANTS, LINE_TOPIC_TYPES
from folder_line.ros.lockstep_messages import Announcement, format_announcement
from folder_line.ros.run import run_line
from folder_line.ros.signing import open_text

NS = 1_000_000_000


def plain(obj: Any) -> Any:
    """A decoded mcap_ros2 message as nested tuples of (field, value)."""
    if isinstance(obj, SimpleNamespace) and hasattr(obj, '__slots__'):
        return (type(obj).__name__, tuple((k, plain(getattr(obj, k))) for k in obj.__slots__ if not k.startswith('_')))
    if isinstance(obj, (list, tuple)):
        return tuple(plain(x) for x in obj)
    return obj


def read_independently(bag: Path) -> dict[tuple[str, str], list[tuple[int, int, Any]]]:
    """(topic, publisher) -> [(log ns, publish ns, message)] in file order, by ``mcap_ros2`` alone."""
    out: dict[tuple[str, str], list[tuple[int, int, Any]]] = {}
    files = segment_files(bag)
    assert files
    for path in files:
        with path.open('rb') as fh:
            reader = make_reader(fh, decoder_factories=[DecoderFactory()])
            for _, channel, message, ros in reader.iter_decoded_messages(log_time_order=False):
                header = getattr(ros, 'header', None)
                key = (channel.topic, '' if header is None else header.frame_id)
                out.setdefault(key, []).append((message.log_time, message.publish_time, plain(ros)))
    return out


def custom_data(bag: Path) -> dict[str, str]:
    meta = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    return dict(meta['custom_data'])


def topic_entries(bag: Path) -> list[tuple[str, str, Any, str, int]]:
    meta = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    return sorted(
        (
            t['topic_metadata']['name'],
            t['topic_metadata']['type'],
            t['topic_metadata']['offered_qos_profiles'],
            t['topic_metadata']['type_description_hash'],
            t['message_count'],
        )
        for t in meta['topics_with_message_count']
    )


@pytest.mark.parametrize(('scene', 'duration'), [('folder', 2.0), ('folder_faults', 5.0), ('line', 3.0)])
def test_simulate_bag_is_the_live_bag(tmp_path: Path, scene: str, duration: float) -> None:
    live = tmp_path / 'live'
    run_line(RunConfig(scene=scene, duration=duration, rtf=0.0, out=live), io.StringIO())
    batch = tmp_path / 'batch'
    assert cli_main(['simulate', '--scene', scene, '--duration', str(duration), '--bag', str(batch)]) == 0

    a, b = read_independently(live / 'bag'), read_independently(batch)
    assert sorted(a) == sorted(b)  # no topic or publisher left out
    unused = {'/line/supervisor/commands'} if scene != 'folder_faults' else set()
    unused |= {'/line/sheet_counter/landing_x'} if scene != 'line' else set()  # leaves land in the layup only
    assert {topic for topic, _ in a} == set(LINE_TOPIC_TYPES) - unused
    for key in sorted(a):
        assert len(a[key]) == len(b[key]), key
        for i, (x, y) in enumerate(zip(a[key], b[key], strict=True)):
            assert x == y, (key, i, x, y)
    n_ticks = round(duration * 200) + 1
    assert len(a[('/clock', '')]) == n_ticks and a[('/clock', '')][-1][0] == round(duration * NS)
    assert sum(map(len, a.values())) > 8 * n_ticks

    # the same metadata: topics, types, QoS, type hashes, counts; custom data but the documented keys
    assert topic_entries(live / 'bag') == topic_entries(batch)
    ca, cb = custom_data(live / 'bag'), custom_data(batch)
    assert (ca.pop('folder_line.mode'), cb.pop('folder_line.mode')) == ('in-process', 'batch')
    assert yaml.safe_load(ca.pop('folder_line.published')) == yaml.safe_load(cb.pop('folder_line.published'))
    assert ca == cb

    if scene == 'folder_faults':  # the supervisor acted: a violation, a hold, the line held
        commands = [v for _, _, v in b[('/line/supervisor/commands', 'supervisor')]]
        assert len(commands) == 1 and commands[0][1][-1] == ('source', 'hold')
        statuses = [s for _, _, v in b[('/diagnostics', 'supervisor')] for s in v[1][1][1]]
        assert any(('name', 'folder_line/supervisor/violation') in s[1] for s in statuses)
        states = [v[1][0][1] for _, _, v in b[('/line/supervisor/state', '')]]
        assert states[-1] == 'HELD' and 'HOLDING' in states

    # rosbags opens it too, every message of every topic
    with Reader(batch) as reader:
        assert sum(1 for _ in reader.messages()) == sum(map(len, b.values()))


def test_announcement_is_the_clocks() -> None:
    """What line_clock announces, as the recorder records it: without the signature of the line's key."""
    expect = format_announcement(Announcement('lockstep', 7 * NS, tuple(KNOWN_PARTICIPANTS)))
    assert announcement(7 * NS) == open_text(expect, 'announcement')


def _ser(msg: Any, msgtype: str) -> bytes:
    return bytes(typestore().serialize_cdr(msg, msgtype, little_endian=True))


def test_fast_cdr_is_the_typestores() -> None:
    types = typestore().types
    time, header = types['builtin_interfaces/msg/Time'], types['std_msgs/msg/Header']
    rng = np.random.default_rng(5)
    assert cdr.clock_cdr(3 * NS + 7) == _ser(
        types['rosgraph_msgs/msg/Clock'](clock=time(sec=3, nanosec=7)), 'rosgraph_msgs/msg/Clock'
    )
    assert cdr.uint64_cdr(2**40 + 3) == _ser(types['std_msgs/msg/UInt64'](data=2**40 + 3), 'std_msgs/msg/UInt64')
    assert cdr.float64_cdr(-0.1) == _ser(types['std_msgs/msg/Float64'](data=-0.1), 'std_msgs/msg/Float64')
    for text in ('', 'EXECUTE', 'HELD', 'clock=lockstep end=1'):
        assert cdr.string_cdr(text) == _ser(types['std_msgs/msg/String'](data=text), 'std_msgs/msg/String')
    for frame, source in (('crank_drive', 'knife_contact sheet=3 cycle=4 value=0.25'), ('supervisor', 'hold')):
        msg = types['sensor_msgs/msg/TimeReference'](
            header=header(stamp=time(sec=12, nanosec=5_000_000), frame_id=frame),
            time_ref=time(sec=12, nanosec=1),
            source=source,
        )
        assert cdr.time_reference_cdr(12 * NS + 5_000_000, frame, 12 * NS + 1, source) == _ser(
            msg, 'sensor_msgs/msg/TimeReference'
        )
    for frame, names, with_effort in (
        ('feed_transporter', ['feed_belt', 'chain', 'carriage'], True),
        ('crank_drive', ['knife_crank', 'knife'], True),
        ('sheet_counter', ['pile_table'], False),
        ('x', ['ab', 'c', 'def', 'g'], False),
    ):
        j = len(names)
        stamps = np.array([0, 5_000_000, 3_600 * NS + 995_000_000])
        pos, vel = rng.normal(size=(3, j)), rng.normal(size=(3, j))
        eff = rng.normal(size=(3, j)) if with_effort else None
        layout = cdr.JointStateLayout.of(frame, names, (j, j, j if with_effort else 0))
        blob, size = layout.many(stamps, pos, vel, eff), len(layout.template)
        for i, s in enumerate(stamps):
            msg = types['sensor_msgs/msg/JointState'](
                header=header(stamp=time(sec=int(s) // NS, nanosec=int(s) % NS), frame_id=frame),
                name=names,
                position=pos[i],
                velocity=vel[i],
                effort=eff[i] if eff is not None else np.zeros(0),
            )
            assert blob[i * size : (i + 1) * size] == _ser(msg, 'sensor_msgs/msg/JointState'), (frame, i)


def test_bag_refuses_a_folder_that_holds_something(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    full = tmp_path / 'full'
    full.mkdir()
    (full / 'notes.txt').write_text('mine')
    before = sorted(os.listdir(full))
    assert cli_main(['simulate', '--duration', '1', '--bag', str(full)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and '--bag' in err[0] and str(full) in err[0] and 'not empty' in err[0], err
    assert sorted(os.listdir(full)) == before and (full / 'notes.txt').read_text() == 'mine'

    a_file = tmp_path / 'file'
    a_file.write_text('x')
    assert cli_main(['simulate', '--duration', '1', '--bag', str(a_file)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and '--bag' in err[0], err
    assert a_file.read_text() == 'x'

    off_grid = tmp_path / 'off_grid'
    assert cli_main(['simulate', '--duration', '1.0025', '--bag', str(off_grid)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and '--duration' in err[0] and '1.0025' in err[0], err
    assert not off_grid.exists()

    empty = tmp_path / 'empty'
    empty.mkdir()
    assert cli_main(['simulate', '--duration', '0.5', '--bag', str(empty)]) == 0
    assert (empty / 'metadata.yaml').is_file() and len(segment_files(empty)) == 1
    capsys.readouterr()


def test_write_many_is_write_serialized(tmp_path: Path) -> None:
    """The batched path (``BagWriter.write_many``) records what one ``write_serialized`` per message does."""
    from folder_line.bag.writer import BagWriter

    rng = np.random.default_rng(11)
    ticks = []
    for k in range(700):  # 3.5 s: four files, many chunks of 4 KiB
        stamp = k * 5_000_000
        items = [('/clock', cdr.clock_cdr(stamp), stamp)]
        items += [('/line/sheet_counter/rate', cdr.float64_cdr(x), stamp) for x in rng.normal(size=k % 3)]
        items.append(('/line/supervisor/state', cdr.string_cdr('EXECUTE' if k % 5 else 'HELD'), stamp + 7))
        ticks.append((stamp, items))
    bags = {}
    for how in ('one', 'many'):
        bag = tmp_path / how
        with BagWriter(
            bag, scene_source='name: x\n', effects=[], topics=LINE_TOPIC_TYPES, chunk_size=4096, max_duration_s=1.0
        ) as writer:
            for stamp, items in ticks:
                if how == 'many':
                    writer.write_many(stamp, items)
                else:
                    for topic, data, publish in items:
                        writer.write_serialized(topic, data, stamp, publish)
        records = []
        for path in segment_files(bag):
            with path.open('rb') as fh:
                reader = make_reader(fh, decoder_factories=[DecoderFactory()])
                for _, channel, m, ros in reader.iter_decoded_messages(log_time_order=False):
                    records.append((channel.topic, m.log_time, m.publish_time, m.sequence, plain(ros)))
        bags[how] = (records, topic_entries(bag), len(segment_files(bag)))
    assert bags['one'] == bags['many']
    assert len(bags['one'][0]) == sum(len(items) for _, items in ticks) and bags['one'][2] == 4


def test_an_interrupted_bag_is_marked_partial(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Ctrl-C in the middle: the files written stay readable and the bag says it is partial."""
    from folder_line.bag import batch
    from folder_line.config.run_config import RATE
    from folder_line.config.scenes import load_scene

    calls = []
    original = batch.WindowWriter.write

    def interrupted(*args: Any) -> None:
        calls.append(1)
        if len(calls) == 3:
            raise KeyboardInterrupt
        original(*args)

    monkeypatch.setattr(batch.WindowWriter, 'write', interrupted)
    with pytest.raises(KeyboardInterrupt):
        batch.write_batch_bag(tmp_path / 'bag', load_scene('folder'), 20.0)
    assert custom_data(tmp_path / 'bag')['folder_line.complete'] == 'false'
    got = read_independently(tmp_path / 'bag')
    # the windows written, whole: tick 0, then the ticks up to the first diagnostics stamp (1 s)
    assert len(got[('/clock', '')]) == 1 + round(RATE / batch.DIAG_RATE)


def test_packed_message_index_is_mcaps() -> None:
    from mcap.data_stream import RecordBuilder
    from mcap.records import MessageIndex

    from folder_line.bag.tick_messages import PackedMessageIndex

    records = [(5_000_000 * k, 97 * k + 3) for k in range(50)] + [(2**63 + 1, 2**40)]
    out = []
    for cls in (MessageIndex, PackedMessageIndex):
        builder = RecordBuilder()
        cls(channel_id=7, records=records).write(builder)
        out.append(builder.end())
    assert out[0] == out[1] and len(out[0]) == 1 + 8 + 2 + 4 + 16 * len(records)
