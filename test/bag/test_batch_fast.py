"""The fast paths of ``simulate --bag`` give the bytes of the plain ones.

* ``/line/markers`` CDR (:func:`folder_line.bag.markers.markers_cdr`, packed with :mod:`struct`) is
  byte for byte what the rosbags typestore serializes from the same fields;
* the ``/line/events`` CDR of a window (``batch.event_cdrs``, numpy) is
  :func:`~folder_line.bag.cdr.time_reference_cdr` of :func:`~folder_line.interfaces.event_source`;
  the per-window columns of ``/clock``, counts and rates are the per-message CDR;
* a window of ticks written at once (:meth:`folder_line.bag.writer.BagWriter.write_ticks`) makes
  the same ``.mcap`` files as :meth:`~folder_line.bag.writer.BagWriter.write_many` tick by tick;
* ``metadata.yaml``'s file entries formatted directly are what YAML writes;
* :meth:`folder_line.core.line.scenery.Scenery.at_times` is :meth:`~folder_line.core.line.scenery.Scenery.at`,
  shape for shape, bit for bit.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from folder_line.bag import batch, cdr
from folder_line.bag.markers import ACTION_DELETEALL, MARKERS_TYPE, MarkerSpec, marker_specs, markers_cdr
from folder_line.bag.metadata import FileSummary, MetadataBuilder, _dump, segment_files
from folder_line.bag.tick_messages import TickMessages
from folder_line.bag.types import typestore
from folder_line.bag.writer import BagWriter
from folder_line.config.scenes import load_scene
from folder_line.core.line.scenery import LINE_FRAME, Scenery
from folder_line.core.line.stream import LineStream
from folder_line.core.types.events import EVENT_DTYPE
from folder_line.interfaces import EVENT_KINDS, LINE_TOPIC_TYPES, NS_PER_S, event_source


def _typestore_marker(types: Any, header: Any, s: MarkerSpec | None) -> Any:
    point, vec, rgba = (
        types['geometry_msgs/msg/Point'],
        types['geometry_msgs/msg/Vector3'],
        types['std_msgs/msg/ColorRGBA'],
    )
    pose = types['geometry_msgs/msg/Pose'](
        position=point(x=0.0, y=0.0, z=0.0) if s is None else point(x=s.position[0], y=s.position[1], z=s.position[2]),
        orientation=types['geometry_msgs/msg/Quaternion'](x=0.0, y=0.0, z=0.0, w=1.0),
    )
    return types['visualization_msgs/msg/Marker'](
        header=header,
        ns='' if s is None else s.ns,
        id=0 if s is None else s.id,
        type=0 if s is None else s.type,
        action=ACTION_DELETEALL if s is None else s.action,
        pose=pose,
        scale=vec(x=0.0, y=0.0, z=0.0) if s is None else vec(x=s.scale[0], y=s.scale[1], z=s.scale[2]),
        color=rgba(r=0.0, g=0.0, b=0.0, a=0.0)
        if s is None
        else rgba(r=s.color[0], g=s.color[1], b=s.color[2], a=s.color[3]),
        lifetime=types['builtin_interfaces/msg/Duration'](sec=0, nanosec=0),
        frame_locked=False,
        points=[] if s is None else [point(x=float(x), y=float(y), z=float(z)) for x, y, z in s.points],
        colors=[],
        texture_resource='',
        texture=types['sensor_msgs/msg/CompressedImage'](
            header=types['std_msgs/msg/Header'](
                stamp=types['builtin_interfaces/msg/Time'](sec=0, nanosec=0), frame_id=''
            ),
            format='',
            data=np.zeros(0, dtype=np.uint8),
        ),
        uv_coordinates=[],
        text='',
        mesh_resource='',
        mesh_file=types['visualization_msgs/msg/MeshFile'](filename='', data=np.zeros(0, dtype=np.uint8)),
        mesh_use_embedded_materials=False,
    )


def typestore_markers_cdr(specs: list[MarkerSpec], stamp_ns: int, *, delete_all: bool = False) -> bytes:
    """The reference: the message built field by field and serialized by the rosbags typestore."""
    types = typestore().types
    header = types['std_msgs/msg/Header'](
        stamp=types['builtin_interfaces/msg/Time'](sec=stamp_ns // NS_PER_S, nanosec=stamp_ns % NS_PER_S),
        frame_id=LINE_FRAME,
    )
    markers = [_typestore_marker(types, header, s) for s in specs]
    if delete_all:
        markers.insert(0, _typestore_marker(types, header, None))
    msg = types[MARKERS_TYPE](markers=markers)
    return bytes(typestore().serialize_cdr(msg, MARKERS_TYPE, little_endian=True))


def test_markers_cdr_is_the_typestores_for_any_fields() -> None:
    rng = np.random.default_rng(3)
    for trial in range(300):
        specs = []
        for i in range(int(rng.integers(0, 6))):
            n = int(rng.integers(0, 5))
            ns = ''.join(rng.choice(list('abcdefgh_'), size=int(rng.integers(0, 10))))
            specs.append(
                MarkerSpec(
                    ns,
                    int(rng.integers(-5, 40)) + i,
                    int(rng.choice([1, 4, 5, 7])),
                    int(rng.choice([0, 2])),
                    (float(rng.normal()), float(rng.normal()), -0.0),
                    (float(rng.random()), 1e-6, float(rng.normal())),
                    tuple(float(np.float32(c)) for c in rng.random(4)),  # type: ignore[arg-type]
                    rng.normal(size=(n, 3)),
                )
            )
        stamp = int(rng.integers(0, 10**13))
        delete_all = bool(trial % 3 == 0)
        assert markers_cdr(specs, stamp, delete_all=delete_all) == typestore_markers_cdr(
            specs, stamp, delete_all=delete_all
        ), trial


@pytest.mark.parametrize('scene', ['folder', 'line', 'layup'])
def test_markers_cdr_is_the_typestores_for_the_scenery(scene: str) -> None:
    line = LineStream(load_scene(scene))
    line.advance(2.0)
    scenery = Scenery(line)
    for i, t in enumerate(np.linspace(1.0, 2.0, 23)):
        specs = marker_specs(scenery.at(float(t)))
        stamp = round(float(t) * NS_PER_S)
        assert markers_cdr(specs, stamp, delete_all=i == 0) == typestore_markers_cdr(specs, stamp, delete_all=i == 0)


def _files(bag: Path) -> list[bytes]:
    return [p.read_bytes() for p in segment_files(bag)]


@pytest.mark.parametrize('chunk_size', [300, 4096, 1 << 20])
def test_write_ticks_is_write_many(tmp_path: Path, chunk_size: int) -> None:
    """The same ``.mcap`` files, byte for byte: records, chunks (cut by flush time and size), indices."""
    rng = np.random.default_rng(17)
    step = 5_000_000
    windows = [(0, 1), (1, 201), (201, 260), (260, 401), (401, 700)]  # cut anywhere, across the 1 s files
    ticks: list[tuple[int, list[tuple[str, bytes, int]]]] = []
    batches = []
    for a, b in windows:
        stamps = np.arange(a, b, dtype=np.int64) * step
        rates = rng.normal(size=b - a)
        states = [
            (i, cdr.string_cdr('x' * int(rng.integers(0, 9))))
            for i in range(b - a)
            for _ in range(int(rng.integers(0, 3)))
        ]
        mixed = [
            (i, '/line/sheet_counter/count', cdr.uint64_cdr(i))
            if rng.random() < 0.5
            else (i, '/diagnostics', b'\x00\x01\x00\x00abc')
            for i in range(b - a)
            if rng.random() < 0.2
        ]
        batch = TickMessages(stamps)
        batch.add_each(
            '/line/supervisor/state',
            3,
            [i for i, _ in states],
            [d for _, d in states],
            [stamps[i] + 7 for i, _ in states],
        )
        batch.add_rows('/line/sheet_counter/rate', 5, cdr.float64_rows(rates))
        batch.add_each([tp for _, tp, _ in mixed], 9, [i for i, _, _ in mixed], [d for _, _, d in mixed])
        batch.add_rows('/clock', 0, cdr.clock_rows(stamps))
        batches.append(batch)
        for i in range(b - a):  # the same, tick by tick in slot order
            stamp = int(stamps[i])
            items = [('/clock', cdr.clock_cdr(stamp), stamp)]
            items += [('/line/supervisor/state', d, stamp + 7) for j, d in states if j == i]
            items.append(('/line/sheet_counter/rate', cdr.float64_cdr(float(rates[i])), stamp))
            items += [(tp, d, stamp) for j, tp, d in mixed if j == i]
            ticks.append((stamp, items))
    out = {}
    for how in ('many', 'ticks'):
        bag = tmp_path / how / 'bag'
        with BagWriter(
            bag,
            scene_source='name: x\n',
            effects=[],
            topics=LINE_TOPIC_TYPES,
            chunk_size=chunk_size,
            max_duration_s=1.0,  # split every second of line time: the windows cross the splits
        ) as writer:
            writer.write_serialized('/line/participants', cdr.string_cdr('hello'), 0, 0)
            if how == 'many':
                for stamp, items in ticks:
                    writer.write_many(stamp, items)
            else:
                for batch in batches:
                    writer.write_ticks(batch)
        out[how] = (_files(bag), (bag / 'metadata.yaml').read_text())
    assert len(out['many'][0]) == 4
    assert out['many'] == out['ticks']


def test_event_cdrs_are_time_reference_cdrs() -> None:
    rng = np.random.default_rng(8)
    n = 2000
    rows = np.zeros(n, dtype=EVENT_DTYPE)
    rows['t'] = np.sort(rng.random(n) * 3600.0)
    rows['t'][:5] = [0.0, -1e-12, 1e-10, 0.5e-9, 1.5e-9]  # clipped at 0, rounded half to even
    rows['value'] = rng.normal(size=n) * 10.0 ** rng.integers(-20, 20, n)
    rows['value'][:4] = [np.inf, -np.inf, np.nan, -0.0]
    rows['kind'] = rng.integers(0, len(EVENT_KINDS), n)
    rows['sheet'] = rng.integers(-1, 10**6, n)
    rows['cycle'] = rng.integers(-1, 10**6, n)
    stamps = np.sort(rng.integers(0, 3600 * NS_PER_S, n))
    for node in ('crank_drive', 'belt_conveyor', 'feed_transporter', 'sheet_counter', 'x'):
        data, lens = batch.event_cdrs(node, stamps, rows)
        want = [
            cdr.time_reference_cdr(
                int(s),
                node,
                max(0, round(float(r['t']) * NS_PER_S)),
                event_source(EVENT_KINDS[r['kind']], r['sheet'], r['cycle'], r['value']),
            )
            for s, r in zip(stamps, rows, strict=True)
        ]
        assert lens.tolist() == [len(w) for w in want] and bytes(data) == b''.join(want), node


def test_cdr_rows_are_the_messages() -> None:
    stamps = np.array([0, 5_000_000, 999_999_999, 3_600 * NS_PER_S + 995_000_000])
    assert [bytes(r) for r in cdr.clock_rows(stamps)] == [cdr.clock_cdr(int(s)) for s in stamps]
    counts = np.array([0, 3, 2**40, 2**63 + 5], dtype=np.uint64)
    assert [bytes(r) for r in cdr.uint64_rows(counts)] == [cdr.uint64_cdr(int(c)) for c in counts]
    rates = np.array([0.0, -0.0, -0.1, 1e300, np.inf, np.nan])
    assert [bytes(r) for r in cdr.float64_rows(rates)] == [cdr.float64_cdr(float(x)) for x in rates]


def test_metadata_entries_are_yamls() -> None:
    names = ['folder', 'bag', 'x', 'true', 'null', 'yes', 'on', 'Folder_Line-2', 'a.b', '_', 'no', 'e1', 'inf']
    names += ['nan', 'y', 'N', 'a' * 55, 'a' * 70, 'x-1', 'False', 'ü', '1', '.x', 'a b', 'a:b', '#', '-x']
    for name in names:
        for i in (0, 7, 3600, 123456):
            path = f'{name}_{i}.mcap'
            for start, end, count in (
                (0, 0, 0),
                (5 * NS_PER_S, 6 * NS_PER_S - 5, 17),
                (3600 * NS_PER_S, 3600 * NS_PER_S, 1),
            ):
                summary = FileSummary(path, start, end, count)
                builder = MetadataBuilder()
                builder.add_file(summary)
                text = builder.render({}, {})
                assert text.count(_dump([path], 2)) == 1, path  # the file's path, as yaml writes it
                assert text.count(_dump([summary.entry()], 2)) == 1, path  # and its entry


@pytest.mark.parametrize('scene', ['folder', 'line', 'folder_faults'])
def test_scenery_at_times_is_at(scene: str) -> None:
    line = LineStream(load_scene(scene))
    scenery = None
    for w in range(1, 5):
        line.advance(float(w))
        scenery = scenery or Scenery(line)
        times = [w - 1 + i / 7 for i in range(1, 8)]
        for shapes, t in zip(scenery.at_times(times), times, strict=True):
            one = scenery.at(t)
            assert len(shapes) == len(one)
            for a, b in zip(shapes, one, strict=True):
                assert (a.machine, a.part, a.kind, a.width, a.rgba) == (b.machine, b.part, b.kind, b.width, b.rgba)
                assert a.points.dtype == b.points.dtype and a.points.tobytes() == b.points.tobytes()


def test_diagnostic_array_cdr_is_the_typestores() -> None:
    types = typestore().types
    rng = np.random.default_rng(4)
    words = ['', 'a', 'folder_line/supervisor/violation', 'θ ≤ 5°', 'x' * 13, 'late sheet: 3 ms', '0.1']
    for trial in range(200):
        statuses = [
            (
                int(rng.integers(0, 4)),
                str(rng.choice(words)),
                str(rng.choice(words)),
                str(rng.choice(words)),
                tuple((str(rng.choice(words)), str(rng.choice(words))) for _ in range(int(rng.integers(0, 4)))),
            )
            for _ in range(int(rng.integers(0, 5)))
        ]
        stamp = int(rng.integers(0, 10**13))
        frame = str(rng.choice(['supervisor', '', 'ab']))
        msg = types['diagnostic_msgs/msg/DiagnosticArray'](
            header=types['std_msgs/msg/Header'](
                stamp=types['builtin_interfaces/msg/Time'](sec=stamp // NS_PER_S, nanosec=stamp % NS_PER_S),
                frame_id=frame,
            ),
            status=[
                types['diagnostic_msgs/msg/DiagnosticStatus'](
                    level=level,
                    name=name,
                    message=message,
                    hardware_id=hw,
                    values=[types['diagnostic_msgs/msg/KeyValue'](key=k, value=v) for k, v in values],
                )
                for level, name, message, hw, values in statuses
            ],
        )
        want = bytes(typestore().serialize_cdr(msg, 'diagnostic_msgs/msg/DiagnosticArray', little_endian=True))
        assert cdr.diagnostic_array_cdr(stamp, frame, statuses) == want, trial


@pytest.mark.parametrize(('scene', 'duration'), [('folder_faults', 40.0), ('folder_jitter', 20.0), ('line', 10.0)])
def test_the_supervisor_evaluating_a_window_ahead_decides_as_tick_by_tick(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, scene: str, duration: float
) -> None:
    """``simulate --bag`` shows the supervisor each window's events ahead (``Supervisor.preview``); the
    bag is byte for byte the one of a supervisor that evaluates each cycle when it is due. folder_faults
    over 40 s has a violation and a hold, missing, late and double sheets (two releases in a cycle)."""
    from folder_line.core.supervision.supervisor import Supervisor

    ahead = batch.write_batch_bag(tmp_path / 'ahead' / 'bag', load_scene(scene), duration)
    monkeypatch.setattr(Supervisor, 'preview', lambda self, rows: None)
    plain = batch.write_batch_bag(tmp_path / 'plain' / 'bag', load_scene(scene), duration)
    assert ahead.commands == plain.commands and ahead.state == plain.state
    if scene == 'folder_faults':
        assert ahead.commands  # the hold
    files = segment_files(tmp_path / 'plain' / 'bag')
    assert [p.name for p in files] == [p.name for p in segment_files(tmp_path / 'ahead' / 'bag')]
    for p in files:
        assert (tmp_path / 'ahead' / 'bag' / p.name).read_bytes() == p.read_bytes(), p.name
