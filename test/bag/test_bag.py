"""Bags: write rclpy messages, read them back with rosbags and with the independent mcap reader.

Everything in ``tmp_path``; no ROS graph except the last test, which runs the line
in-process for 2 s of line time on its own ROS domain and checks the run's bag.
"""

from __future__ import annotations

import array
import json
import os
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState, TimeReference
from std_msgs.msg import Float64, String, UInt64

from folder_line import __version__
from folder_line.bag.markers import marker_specs
from folder_line.bag.metadata import KEY_PUBLISHED, segment_files
from folder_line.bag.reader import read_bag
from folder_line.bag.repair import repair, repair_bag
from folder_line.bag.tick_messages import TickMessages
from folder_line.bag.types import serialize
from folder_line.bag.writer import BagWriter
from folder_line.cli.main import main as cli_main
from folder_line.config.scenes import load_scene
from folder_line.core.line.model import LineModel
from folder_line.core.line.scenery import Scenery
from folder_line.errors import BagError
from folder_line.ros.markers import marker_array
from folder_line.ros.recorder import LINE_TOPICS

JOINTS = '/line/crank_drive/joint_states'
SCENE = (
    'name: test scene\n'
    'description: "quotes: \'single\' and \\"double\\""\n'
    'machines:\n'
    '  knife: {r_k: 0.04}\n'
    '# unicode: φ, ω, ü — and a line with trailing spaces:   \n'
    '---\n'
    '\n'
    '    indented line\n'
)


def stamp(t_ns: int) -> Time:
    return Time(sec=t_ns // 1_000_000_000, nanosec=t_ns % 1_000_000_000)


def sample_messages() -> dict[str, Any]:
    """One rclpy message with non-trivial values for every topic of the line."""
    js = JointState(name=['crank', 'knife φ'], position=[1.5, -2.25], velocity=[1e-300, 3.0e8], effort=[])
    js.header.stamp, js.header.frame_id = stamp(1_234_567_890), 'crank_drive'
    belt = JointState(name=['belt'], position=[0.1], velocity=[2.8], effort=[-4.5])
    belt.header.stamp = stamp(1_250_000_000)
    ev = TimeReference(time_ref=stamp(1_200_000_001), source='knife_contact sheet=3 cycle=4 value=0.5')
    ev.header.stamp, ev.header.frame_id = stamp(1_250_000_000), 'crank_drive'
    diag = DiagnosticArray()
    diag.header.stamp = stamp(1_000_000_000)
    diag.status = [
        DiagnosticStatus(
            level=DiagnosticStatus.ERROR,
            name='folder_line/feed_margin',
            message='violated in cycle 7',
            hardware_id='folder',
            values=[KeyValue(key='margin', value='-0.001'), KeyValue(key='unit', value='s')],
        ),
        DiagnosticStatus(level=DiagnosticStatus.OK, name='folder_line/knife', message='ok', hardware_id='', values=[]),
    ]
    cmd = TimeReference(time_ref=stamp(5_000_000_000), source='hold')
    cmd.header.stamp, cmd.header.frame_id = stamp(4_900_000_000), 'supervisor'
    return {
        '/clock': Clock(clock=stamp(1_250_000_000)),
        JOINTS: js,
        '/line/belt_conveyor/joint_states': belt,
        '/line/feed_transporter/joint_states': JointState(name=[], position=[], velocity=[], effort=[]),
        '/line/events': ev,
        '/diagnostics': diag,
        '/line/supervisor/state': String(data='EXECUTE — ü'),
        '/line/sheet_counter/count': UInt64(data=2**64 - 1),
        '/line/sheet_counter/rate': Float64(data=13.888888888888889),
        '/line/sheet_counter/landing_x': Float64(data=-0.0),
        '/line/supervisor/commands': cmd,
        '/line/sheet_counter/joint_states': JointState(
            name=['pile_table'], position=[-0.0125], velocity=[0.0], effort=[]
        ),
        '/line/participants': String(data='clock=lockstep end=none participants=crank_drive,line_recorder'),
        '/line/markers': _markers(),
    }


def _markers() -> Any:
    """The markers of ``line`` at 0.3 s as the node publishes its first array (a DELETEALL first)."""
    scenery = Scenery(LineModel(load_scene('line', {}), 1.0))
    return marker_array(marker_specs(scenery.at(0.3)), 300_000_000, delete_all=True)


def plain(obj: Any, ref: Any) -> Any:
    """``obj`` (an rclpy, rosbags or mcap_ros2 message) as plain Python, walked along the rclpy ``ref``."""
    if hasattr(ref, 'get_fields_and_field_types'):
        return {name: plain(getattr(obj, name), getattr(ref, name)) for name in ref.get_fields_and_field_types()}
    if isinstance(ref, (list, tuple, array.array, np.ndarray)):
        items = list(obj)
        assert len(items) == len(ref)
        return [plain(o, r) for o, r in zip(items, ref, strict=True)]
    if isinstance(ref, bytes):  # rclpy's byte
        return obj[0] if isinstance(obj, bytes) else int(obj)
    if isinstance(ref, float):
        return float(obj)
    if isinstance(ref, int):
        return int(obj)
    return obj


def write_sample_bag(path: Path, **kwargs: Any) -> dict[str, Any]:
    """Every line message once at line time 1.25 s (after a /clock 0.25 s); returns them."""
    msgs = sample_messages()
    with BagWriter(
        path, scene_source=SCENE, effects=['faults', 'feed_slip'], scene_name='test scene', topics=LINE_TOPICS, **kwargs
    ) as writer:
        writer.write('/clock', Clock(clock=stamp(250_000_000)))
        for topic, msg in msgs.items():
            writer.write(topic, msg, 123)
    return msgs


def test_round_trip_every_line_type_with_rosbags_and_mcap(tmp_path: Path) -> None:
    bag = tmp_path / 'bag'
    msgs = write_sample_bag(bag)
    assert set(msgs) == set(LINE_TOPICS)

    contents = read_bag(bag)
    assert contents.message_count == len(msgs) + 1
    assert {t: s.count for t, s in contents.topics.items()} == {t: 1 + (t == '/clock') for t in LINE_TOPICS}
    got: dict[str, list[tuple[int, Any]]] = {}
    for topic, t_ns, msg in contents.messages():
        got.setdefault(topic, []).append((t_ns, msg))
    for topic, ref in msgs.items():
        t_ns, msg = got[topic][-1]
        assert t_ns == 1_250_000_000  # line time: the latest /clock, the message's own for /clock
        assert plain(msg, ref) == plain(ref, ref), topic
    assert got['/clock'][0][0] == 250_000_000

    # the independent reader: mcap + mcap_ros2's decoder (built from the schema text in the file)
    assert [p.name for p in segment_files(bag)] == ['bag_0.mcap']  # one file, as ros2 bag record writes
    decoded = {}
    for path in segment_files(bag):
        with path.open('rb') as fh:
            reader = make_reader(fh, decoder_factories=[DecoderFactory()])
            decoded.update(
                {
                    channel.topic: (schema.name, message, ros)
                    for schema, channel, message, ros in reader.iter_decoded_messages()
                }
            )
            assert reader.get_header().profile == 'ros2'
    for topic, ref in msgs.items():
        schema, message, ros = decoded[topic]
        assert schema == contents.topics[topic].type
        assert plain(ros, ref) == plain(ref, ref), topic
        assert message.log_time == 1_250_000_000
        header = getattr(ref, 'header', None)
        assert message.publish_time == (
            1_250_000_000 if header is None else header.stamp.sec * 10**9 + header.stamp.nanosec
        )


def test_serialized_bytes_are_canonical_cdr(tmp_path: Path) -> None:
    """The stored CDR re-serializes to the same bytes (rosbags) and matches rclpy's up to its padding."""
    from rclpy.serialization import deserialize_message

    store = get_typestore(Stores.ROS2_KILTED)
    for topic, msg in sample_messages().items():
        msgtype = f'{type(msg).__module__.split(".")[0]}/msg/{type(msg).__name__}'
        data = serialize(msg, msgtype)
        assert bytes(store.serialize_cdr(store.deserialize_cdr(data, msgtype), msgtype)) == data
        back = deserialize_message(data, type(msg))  # rclpy reads what rosbags wrote
        assert plain(back, msg) == plain(msg, msg), topic


def test_a_bag_is_one_file_unless_split_on_request(tmp_path: Path) -> None:
    """By default one ``.mcap`` (as ``ros2 bag record``), whatever the line time; read whole by the independent
    mcap reader and by rosbags."""
    bag = tmp_path / 'one'
    with BagWriter(bag, scene_source=SCENE, effects=[], topics=LINE_TOPICS) as writer:
        for k in range(0, 3600, 7):  # an hour of line time, a message every 7 s
            writer.write('/clock', Clock(clock=stamp(k * 10**9)))
    assert segment_files(bag) == [bag / 'one_0.mcap']
    with (bag / 'one_0.mcap').open('rb') as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        stamps = [ros.clock.sec for _, _, _, ros in reader.iter_decoded_messages(topics=['/clock'])]
    assert stamps == list(range(0, 3600, 7))
    with Reader(bag) as rosbags_reader:
        assert rosbags_reader.message_count == len(stamps)
    assert read_bag(bag).custom['folder_line.max_bag_duration'] == '0.0'


def test_split_by_size_at_a_flush_the_same_tick_by_tick_as_in_windows(tmp_path: Path) -> None:
    """``max_size``: a file that has reached the size is finished at its next flush (every 0.1 s of line
    time), and the next tick starts a new file; ``write_many`` tick by tick and ``write_ticks`` in windows make
    the same files, byte for byte."""
    topic = '/line/sheet_counter/rate'
    ticks = np.arange(0, 3_000_000_000, 5_000_000, dtype=np.int64)  # 3 s at 200 Hz
    payload = [serialize(Float64(data=float(k)), 'std_msgs/msg/Float64') for k in range(len(ticks))]
    one = tmp_path / 'one'
    with BagWriter(one, scene_source=SCENE, effects=[], topics=LINE_TOPICS, max_size=4096, chunk_size=512) as w:
        for t, data in zip(ticks.tolist(), payload, strict=True):
            w.write_many(t, [(topic, data, t)])
    many = tmp_path / 'many'
    with BagWriter(many, scene_source=SCENE, effects=[], topics=LINE_TOPICS, max_size=4096, chunk_size=512) as w:
        for lo in range(0, len(ticks), 137):  # windows that do not line up with the flushes
            window = TickMessages(ticks[lo : lo + 137])
            window.add_each(topic, 0, range(len(window.log_ns)), payload[lo : lo + 137])
            w.write_ticks(window)
    files = segment_files(one)
    assert len(files) > 3
    assert [p.name.replace('one', 'many') for p in files] == [p.name for p in segment_files(many)]
    for a, b in zip(files, segment_files(many), strict=True):
        assert a.read_bytes() == b.read_bytes(), a.name
    for path in files[:-1]:  # each file but the last reached the size; it was finished at a flush after that
        size = path.stat().st_size
        assert size >= 4096, (path.name, size)
        with path.open('rb') as fh:
            first = next(m.log_time for _, _, m in make_reader(fh).iter_messages())
        assert first % 100_000_000 == 0 or path == files[0]
    assert read_bag(one).message_count == len(ticks)


def test_segments_roll_over_at_line_time_boundaries(tmp_path: Path) -> None:
    """``max_duration_s`` (``--max-bag-duration``): a new file at each multiple of it in line time."""
    bag = tmp_path / 'run7'
    times = [0, 250_000_000, 999_999_999, 1_000_000_000, 1_500_000_000, 2_999_999_999, 7_200_000_000, 7_300_000_000]
    with BagWriter(bag, scene_source=SCENE, effects=[], max_duration_s=1.0, topics=LINE_TOPICS) as writer:
        for t in times:
            writer.write('/clock', Clock(clock=stamp(t)))
            writer.write('/line/sheet_counter/rate', Float64(data=t / 1e9))
    files = segment_files(bag)
    assert [f.name for f in files] == ['run7_0.mcap', 'run7_1.mcap', 'run7_2.mcap', 'run7_3.mcap']
    windows = [(0, 1), (1, 2), (2, 3), (7, 8)]  # no empty files for the jump from 3 s to 7.2 s
    per_file: list[list[int]] = []
    for path, (lo, hi) in zip(files, windows, strict=True):
        with path.open('rb') as fh:
            logs = [m.log_time for _, _, m in make_reader(fh).iter_messages()]
        assert logs and all(lo * 10**9 <= t < hi * 10**9 for t in logs), path.name
        per_file.append(logs)
    assert sorted(t for logs in per_file for t in logs) == sorted(times * 2)
    contents = read_bag(bag)
    assert contents.files == tuple(f.name for f in files)
    assert (contents.start_ns, contents.end_ns) == (0, 7_300_000_000)

    half = tmp_path / 'half'
    with BagWriter(half, scene_source=SCENE, effects=[], max_duration_s=0.5) as writer:
        for k in range(10):  # 0 .. 0.9 s every 0.1 s
            writer.write('/clock', Clock(clock=stamp(k * 100_000_000)))
    assert [len(list(make_reader(p.open('rb')).iter_messages())) for p in segment_files(half)] == [5, 5]


def test_a_bag_whose_writing_raised_is_left_partial_not_complete(tmp_path: Path) -> None:
    """Leaving ``with BagWriter(...)`` by an exception abandons the bag (marked partial), as a failed write
    must; leaving it normally closes it (complete)."""
    with (
        pytest.raises(RuntimeError, match='the line failed'),
        BagWriter(tmp_path / 'failed', scene_source=SCENE, effects=[]) as writer,
    ):
        writer.write('/clock', Clock(clock=stamp(0)))
        raise RuntimeError('the line failed')
    assert read_bag(tmp_path / 'failed').custom['folder_line.complete'] == 'false'
    assert read_bag(tmp_path / 'failed').message_count == 1  # what it wrote is kept
    with BagWriter(tmp_path / 'done', scene_source=SCENE, effects=[]) as writer:
        writer.write('/clock', Clock(clock=stamp(0)))
    assert read_bag(tmp_path / 'done').custom['folder_line.complete'] == 'true'


def test_metadata_is_written_at_every_rollover(tmp_path: Path) -> None:
    bag = tmp_path / 'bag'
    writer = BagWriter(
        bag, scene_source=SCENE, effects=['faults'], scene_name='test scene', topics=LINE_TOPICS, max_duration_s=1.0
    )
    empty = read_bag(bag)  # from the start: an empty, readable bag with its topics and custom data
    assert empty.files == () and empty.message_count == 0 and empty.scene_name == 'test scene'
    assert {t: s.count for t, s in empty.topics.items()} == dict.fromkeys(LINE_TOPICS, 0)
    for k in range(26):  # 0 .. 2.5 s
        writer.write('/clock', Clock(clock=stamp(k * 100_000_000)))
    contents = read_bag(bag)  # as a crash would leave it: the two finished segments only
    assert contents.files == ('bag_0.mcap', 'bag_1.mcap')
    assert contents.topics['/clock'].count == 20
    assert contents.scene_source == SCENE and KEY_PUBLISHED not in contents.custom
    writer.close(published={'/clock': 26, JOINTS: 0})
    writer.close()  # idempotent
    contents = read_bag(bag)
    assert contents.files == ('bag_0.mcap', 'bag_1.mcap', 'bag_2.mcap')
    assert contents.topics['/clock'].count == 26
    assert contents.published == {'/clock': 26, JOINTS: 0}
    with pytest.raises(BagError, match='closed'):
        writer.write('/clock', Clock(clock=stamp(0)))


def test_custom_data_in_the_metadata(tmp_path: Path) -> None:
    bag = tmp_path / 'bag'
    write_sample_bag(bag, custom={'folder_line.mode': 'in-process'})
    contents = read_bag(bag)
    assert contents.scene_source == SCENE  # exact, multi-line, unicode, trailing spaces
    assert contents.scene_name == 'test scene'
    assert contents.effects == ['faults', 'feed_slip']
    assert contents.custom['folder_line.version'] == __version__
    assert contents.custom['folder_line.max_bag_duration'] == '0.0'
    assert contents.custom['folder_line.max_bag_size'] == '0'
    assert contents.custom['folder_line.mode'] == 'in-process'
    # the same through rosbags' own reader and through the YAML file itself
    with Reader(bag) as reader:
        assert reader.storage.metadata.custom == contents.custom
        assert reader.ros_distro == 'kilted'
    info = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert info['version'] == 9 and info['storage_identifier'] == 'mcap'
    assert info['custom_data']['folder_line.scene'] == SCENE
    # and in each MCAP file, for repair
    with segment_files(bag)[0].open('rb') as fh:
        (record,) = list(make_reader(fh).iter_metadata())
    assert record.name == 'folder_line' and record.metadata['folder_line.scene'] == SCENE


def test_writer_rejects_bad_input(tmp_path: Path) -> None:
    (tmp_path / 'full').mkdir()
    (tmp_path / 'full' / 'x').write_text('x')
    with pytest.raises(BagError, match='not an empty directory'):
        BagWriter(tmp_path / 'full', scene_source='', effects=[])
    for bad in (1e-9, -1.0, float('nan'), 1e8):
        with pytest.raises(BagError, match=r'max_duration_s=.* must be 0 \(no split\) or in'):
            BagWriter(tmp_path / f'seg{bad}', scene_source='', effects=[], max_duration_s=bad)
    for size in (-1, 1.5):
        with pytest.raises(BagError, match=r'max_size=.* must be 0 \(no split\) or a positive whole number'):
            BagWriter(tmp_path / f'size{size}', scene_source='', effects=[], max_size=size)  # type: ignore[arg-type]
    with pytest.raises(BagError, match='not in the rosbags'):
        BagWriter(tmp_path / 'unknown', scene_source='', effects=[], topics={'/y': 'nope_msgs/msg/Nothing'})
    assert not (tmp_path / 'unknown').exists()  # nothing half-made
    writer = BagWriter(tmp_path / 'ok', scene_source='', effects=[], topics={'/x': 'std_msgs/msg/String'})
    with pytest.raises(BagError, match='not in the rosbags'):
        writer.add_topic('/y', 'nope_msgs/msg/Nothing')
    with pytest.raises(BagError, match='has type std_msgs/msg/String'):
        writer.write('/x', Float64(data=1.0))
    writer.close()


def _copy(src: Path, dst: Path) -> Path:
    shutil.copytree(src, dst)
    return dst


def _many_segments(path: Path) -> None:
    """A bag split every second of line time (``--max-bag-duration 1``): three files."""
    with BagWriter(
        path,
        scene_source=SCENE,
        effects=['faults'],
        scene_name='test scene',
        topics=LINE_TOPICS,
        chunk_size=512,
        max_duration_s=1.0,
    ) as writer:
        for k in range(300):  # 0 .. 2.99 s, 100 per segment
            writer.write('/clock', Clock(clock=stamp(k * 10_000_000)))
            js = JointState(name=['crank'], position=[float(k)], velocity=[], effort=[])
            js.header.stamp = stamp(k * 10_000_000)
            writer.write(JOINTS, js)
        writer.close(published={'/clock': 300, JOINTS: 300})


def _positions(bag: Path) -> list[int]:
    return [int(m.position[0]) for _, _, m in read_bag(bag).messages([JOINTS])]


def test_repair_rebuilds_missing_metadata(tmp_path: Path) -> None:
    bag = tmp_path / 'bag'
    _many_segments(bag)
    before = read_bag(bag)
    kept = _copy(bag, tmp_path / 'kept')
    (bag / 'metadata.yaml').unlink()
    with pytest.raises(BagError, match='bag repair'):
        read_bag(bag)
    assert repair_bag(bag) == bag / 'metadata.yaml'
    after = read_bag(bag)
    assert after.files == before.files and after.topics == before.topics
    assert (after.start_ns, after.end_ns, after.message_count) == (before.start_ns, before.end_ns, before.message_count)
    # custom data from the MCAP files: everything but what is known at close only
    at_close = (KEY_PUBLISHED, 'folder_line.complete', 'folder_line.repair')
    assert {k: v for k, v in after.custom.items() if k not in at_close} == {
        k: v for k, v in before.custom.items() if k not in at_close
    }
    assert after.custom['folder_line.repair'].endswith('nothing dropped')
    assert (before.custom['folder_line.complete'], after.custom['folder_line.complete']) == ('true', 'repaired')
    assert _positions(bag) == list(range(300))
    # with its metadata present, repair keeps its custom data (published counts included)
    repair(kept)
    assert read_bag(kept).published == {'/clock': 300, JOINTS: 300}


def test_repair_salvages_a_truncated_last_file_at_any_cut(tmp_path: Path) -> None:
    """Cut the last file anywhere: repair keeps the other files whole and a prefix of the last."""
    src = tmp_path / 'src'
    _many_segments(src)
    last = segment_files(src)[-1]
    size = last.stat().st_size
    with last.open('rb') as fh:
        last_positions = [
            int(ros.position[0])
            for *_, ros in make_reader(fh, decoder_factories=[DecoderFactory()]).iter_decoded_messages(topics=[JOINTS])
        ]
    assert last_positions == list(range(200, 300))
    salvaged_counts = []
    for cut in sorted({8, 40, 200, 700, 1500, 3000, size // 2, size - 600, size - 100, size - 20, size - 1}):
        bag = _copy(src, tmp_path / f'cut{cut}')
        with (bag / last.name).open('r+b') as fh:
            fh.truncate(cut)
        result = repair(bag)
        positions = _positions(bag)
        assert positions[:200] == list(range(200))
        assert positions == list(range(len(positions))), cut  # a prefix, nothing in between lost
        assert result.dropped[last.name] >= 0
        if last.name in result.removed:
            assert len(positions) == 200 and last.name not in read_bag(bag).files
        else:
            assert result.salvaged[last.name] > 0 and len(positions) > 200
        salvaged_counts.append(len(positions))
    assert salvaged_counts == sorted(salvaged_counts)  # the longer the file, the more is salvaged
    assert salvaged_counts[-1] == 300  # only the footer cut: every chunk is complete


def test_repair_drops_an_unreadable_file_and_rejects_non_bags(tmp_path: Path) -> None:
    bag = tmp_path / 'bag'
    _many_segments(bag)
    (bag / 'bag_3.mcap').write_bytes(os.urandom(1000))
    result = repair(bag)
    assert result.removed == ['bag_3.mcap'] and (bag / 'bag_3.mcap.truncated').is_file()
    assert read_bag(bag).files == ('bag_0.mcap', 'bag_1.mcap', 'bag_2.mcap')
    with pytest.raises(BagError, match='not a directory'):
        repair(tmp_path / 'nothing here')
    (tmp_path / 'empty').mkdir()
    with pytest.raises(BagError, match=r'no \.mcap files'):
        repair(tmp_path / 'empty')


def test_cli_bag_info_and_repair(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = tmp_path / 'bag'
    _many_segments(bag)
    (bag / 'metadata.yaml').unlink()
    assert cli_main(['bag', 'repair', str(bag)]) == 0
    out = capsys.readouterr().out
    assert '3 files, 600 messages; nothing dropped' in out and 'metadata.yaml' in out
    assert cli_main(['bag', 'info', str(bag)]) == 0
    out = capsys.readouterr().out
    assert f'{JOINTS}' in out and 'sensor_msgs/msg/JointState' in out and ' 300' in out
    assert 'folder_line.scene_name: test scene' in out and '0.000 .. 2.990 s' in out
    assert cli_main(['bag', 'info', str(tmp_path)]) == 0  # the run folder that holds bag/ stands for it
    assert capsys.readouterr().out == out
    (tmp_path / 'notes').mkdir()
    (tmp_path / 'notes' / 'a.txt').write_text('not a bag')
    for argv in (
        ['bag', 'repair', str(tmp_path / 'missing')],
        ['bag', 'info', str(tmp_path / 'missing')],
        ['bag', 'repair', str(tmp_path / 'notes')],
    ):
        assert cli_main(argv) == 2
        captured = capsys.readouterr()
        assert captured.err.count('\n') == 1 and captured.err.startswith('folder-line: error: ')


def test_run_line_records_every_message(tmp_path: Path) -> None:
    """In-process run of the folder scene, 2 s at rtf 2: the bag has what the recorder got, nothing lost."""
    import io

    from folder_line.config.run_config import RunConfig
    from folder_line.config.scenes import scene_mapping
    from folder_line.ros.run import run_line

    out = tmp_path / 'out'
    (out / 'bag').mkdir(parents=True)
    (out / 'bag' / 'old_0.mcap').write_bytes(b'a previous run')  # replaced, as run.json is
    result = run_line(RunConfig(scene='folder', duration=2.0, rtf=2.0, out=out), io.StringIO())
    summary = json.loads((out / 'run.json').read_text())
    contents = read_bag(out / 'bag')
    recorded = {t: s.count for t, s in contents.topics.items()}
    assert set(recorded) == set(LINE_TOPICS)
    assert {t: n for t, n in recorded.items() if n} == result.counts
    assert summary['bag']['messages'] == recorded
    assert summary['bag']['files'] == len(contents.files) == 1  # one file, as ros2 bag record writes
    assert summary['lost'] == {t: 0 for t in LINE_TOPICS}
    assert summary['published'] == recorded == contents.published
    assert recorded['/clock'] > 50 and recorded['/line/events'] > 0 and recorded['/diagnostics'] >= 2
    assert contents.end_ns == 2_000_000_000
    assert contents.scene_name == 'folder'
    assert yaml.safe_load(contents.scene_source) == scene_mapping('folder')
    assert not (out / 'bag' / 'old_0.mcap').exists()
