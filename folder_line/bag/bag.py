"""Bags: the line's messages as a rosbag2 directory in MCAP storage, written in segments.

Bag I/O only (no analysis). A bag directory ``DIR`` is a rosbag2 bag, metadata
version 9, storage ``mcap``, split by line time as ``ros2 bag record`` splits by
size or duration::

    DIR/metadata.yaml    rosbag2 metadata: topics with types and counts, the files
                         (start, duration, count each), custom_data (see below)
    DIR/DIR_0.mcap       messages of line time [0, segment_s)
    DIR/DIR_1.mcap       the next segment of line time, and so on

Each ``.mcap`` file uses the ``ros2`` MCAP profile (schemas ``ros2msg`` from the
rosbags typestore of ROS 2 kilted, channels ``cdr``, zstd chunks, summary and
footer) and carries the bag's custom data again as an MCAP metadata record named
``folder_line``, so that :func:`repair` can restore it without ``metadata.yaml``.

Timestamps are line time (sim time, ns), as ``ros2 bag record --use-sim-time``
stamps them: a message's log time is the latest ``/clock`` the writer has seen (a
``/clock`` message is stamped with its own time); its publish time is its
``header.stamp`` when it has one, else the log time. The wall time of reception is
not stored. The MCAP ``sequence`` of a message is its index on its topic in the bag.

Crash safety. The writer rolls over to the next file when the line time reaches
the next multiple of ``segment_s``: it finishes the open file (chunks, summary,
footer), closes it and rewrites ``metadata.yaml`` (atomically) listing the finished
files only. So after a SIGKILL of the writing process the directory opens with
``rosbags`` as it is, with every message of every finished segment. Within the open
segment the writer closes the current chunk and hands it to the operating system
every ``flush_s`` of line time (default 0.1 s), so :func:`repair` salvages the open
file up to its last flushed chunk: a SIGKILL loses at most ``flush_s`` of line time
plus the messages of the tick being written. :func:`repair` rebuilds
``metadata.yaml`` from the files present. Files are not fsynced: this protects
against a crash of the process, not of the operating system.

``custom_data`` (rosbag2 allows strings only): ``folder_line.scene`` (the complete
scene as YAML), ``folder_line.scene_name``, ``folder_line.effects`` (JSON list),
``folder_line.version``, ``folder_line.segment_s``, any extra keys given to the
writer, ``folder_line.published`` (JSON ``{topic: count}``, publisher-side counts,
written at close when known), ``folder_line.repair`` (what :func:`repair` did) and
``folder_line.complete`` (``false`` while the writer has the bag open -- so a bag left by a
crash or a failed write is marked partial --, ``true`` once closed, ``repaired`` after
:func:`repair`).
"""

from __future__ import annotations

import functools
import json
import os
import re
import shutil
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np
import yaml

from folder_line import __version__
from folder_line.errors import FolderLineError
from folder_line.files.atomic import write_text_atomic
from folder_line.interfaces import NS_PER_S

__all__ = [
    'KEY_COMPLETE',
    'KEY_EFFECTS',
    'KEY_PUBLISHED',
    'KEY_REPAIR',
    'KEY_SCENE',
    'KEY_SCENE_NAME',
    'KEY_SEGMENT_S',
    'KEY_VERSION',
    'BagContents',
    'BagError',
    'BagWriter',
    'FileSummary',
    'RepairResult',
    'TopicSummary',
    'bag_info_lines',
    'msgtype_of',
    'read_bag',
    'repair',
    'repair_bag',
    'segment_files',
    'serialize',
]

ROSBAG2_VERSION = 9
STORAGE_ID = 'mcap'
ROS_DISTRO = 'kilted'
METADATA_FILE = 'metadata.yaml'
MCAP_METADATA_NAME = 'folder_line'
TRUNCATED_SUFFIX = '.truncated'

KEY_SCENE = 'folder_line.scene'
KEY_SCENE_NAME = 'folder_line.scene_name'
KEY_EFFECTS = 'folder_line.effects'
KEY_VERSION = 'folder_line.version'
KEY_SEGMENT_S = 'folder_line.segment_s'
KEY_PUBLISHED = 'folder_line.published'
KEY_REPAIR = 'folder_line.repair'
#: ``'false'`` while the writer has the bag open, ``'true'`` once it closed it, ``'repaired'`` after :func:`repair`
KEY_COMPLETE = 'folder_line.complete'

_SPLIT = re.compile(r'_(\d+)\.mcap$')


class BagError(FolderLineError):
    """A bag cannot be written, read or repaired; the message names the path and the reason."""


# ---------------------------------------------------------------------------- types


@functools.lru_cache(maxsize=1)
def _typestore() -> Any:
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_KILTED)


@functools.lru_cache(maxsize=64)
def _definition(msgtype: str) -> tuple[str, str]:
    """``(ros2msg definition text, RIHS01 hash)`` of ``msgtype`` from the kilted typestore."""
    store = _typestore()
    if msgtype not in store.types:
        msg = f'message type {msgtype!r} is not in the rosbags ROS 2 kilted typestore'
        raise BagError(msg)
    text, _ = store.generate_msgdef(msgtype, ros_version=2)
    return text, store.hash_rihs01(msgtype)


@functools.lru_cache(maxsize=64)
def msgtype_of(cls: type) -> str:
    """``'sensor_msgs/msg/JointState'`` for the rclpy message class ``sensor_msgs.msg.JointState``."""
    package, kind = cls.__module__.split('.')[:2]
    return f'{package}/{kind}/{cls.__name__}'


def _time_ns(stamp: Any) -> int:
    return int(stamp.sec) * NS_PER_S + int(stamp.nanosec)


# Messages are serialized by the rosbags typestore, not by ``rclpy.serialization``:
# rmw_fastrtps_cpp's serialize_message (kilted wheels) returns some messages with 4 or
# 8 extra bytes at the end, which rosbags rejects ("CDR message size mismatch"), and
# leaves alignment padding uninitialised, so a bag's bytes would depend on memory.

_NUMPY_DTYPES: dict[str, str] = {
    'bool': 'bool',
    'byte': 'uint8',
    'char': 'uint8',
    'octet': 'uint8',
    'int8': 'int8',
    'uint8': 'uint8',
    'int16': 'int16',
    'uint16': 'uint16',
    'int32': 'int32',
    'uint32': 'uint32',
    'int64': 'int64',
    'uint64': 'uint64',
    'float32': 'float32',
    'float64': 'float64',
}


def _base_converter(name: str) -> Callable[[Any], Any]:
    if name in ('string', 'wstring'):
        return str
    if name in ('byte', 'char', 'octet'):  # rclpy gives a byte as bytes of length 1
        return lambda v: v[0] if isinstance(v, (bytes, bytearray)) else int(v)
    if name == 'bool':
        return bool
    if name.startswith('float'):
        return float
    return int


def _field_converter(desc: tuple[Any, Any]) -> Callable[[Any], Any]:
    from rosbags.typesys.base import Nodetype

    kind, detail = desc
    if kind == Nodetype.BASE:
        return _base_converter(detail[0])
    if kind == Nodetype.NAME:
        return _converter(detail)
    (sub_kind, sub_detail), _ = detail  # ARRAY or SEQUENCE of one element type
    if sub_kind == Nodetype.BASE and sub_detail[0] in _NUMPY_DTYPES:
        dtype = np.dtype(_NUMPY_DTYPES[sub_detail[0]])

        def to_array(v: Any) -> np.ndarray:
            if isinstance(v, (bytes, bytearray)):
                return np.frombuffer(bytes(v), dtype=np.uint8).copy()
            if isinstance(v, list) and v and isinstance(v[0], (bytes, bytearray)):
                return np.frombuffer(b''.join(v), dtype=np.uint8).copy()
            return np.asarray(v, dtype=dtype)

        return to_array
    element = _field_converter((sub_kind, sub_detail))
    return lambda v: [element(x) for x in v]


@functools.lru_cache(maxsize=64)
def _converter(msgtype: str) -> Callable[[Any], Any]:
    """rclpy message of ``msgtype`` -> the rosbags typestore's message (same field values)."""
    store = _typestore()
    cls = store.types[msgtype]
    fields = [(name, _field_converter(desc)) for name, desc in store.fielddefs[msgtype][1]]

    def convert(msg: Any) -> Any:
        return cls(**{name: conv(getattr(msg, name)) for name, conv in fields})

    return convert


def serialize(msg: Any, msgtype: str) -> bytes:
    """CDR (little endian) of an rclpy message, serialized by the rosbags typestore as ``msgtype``."""
    _definition(msgtype)
    return bytes(_typestore().serialize_cdr(_converter(msgtype)(msg), msgtype, little_endian=True))


# ---------------------------------------------------------------------------- metadata.yaml


@dataclass(frozen=True)
class FileSummary:
    """One finished ``.mcap`` file of a bag.

    Attributes
    ----------
    path : str
        File name, relative to the bag directory.
    start_ns, end_ns : int
        Log times of its first and last message, ns of line time (0 and 0 if empty).
    count : int
        Messages in the file.
    """

    path: str
    start_ns: int
    end_ns: int
    count: int

    def entry(self) -> dict[str, Any]:
        """The file's entry of ``files`` in ``metadata.yaml``."""
        return {
            'path': self.path,
            'starting_time': {'nanoseconds_since_epoch': self.start_ns},
            'duration': {'nanoseconds': self.end_ns - self.start_ns},
            'message_count': self.count,
        }


@dataclass(frozen=True)
class TopicSummary:
    """A topic of a bag: its message type, RIHS01 type hash and message count."""

    type: str
    count: int
    type_hash: str = ''


class _Dumper(yaml.SafeDumper):
    """Safe YAML with multi-line strings (the scene) as literal blocks where YAML allows it."""


def _str_representer(dumper: yaml.SafeDumper, data: str) -> yaml.Node:
    return dumper.represent_scalar('tag:yaml.org,2002:str', data, style='|' if '\n' in data else None)


_Dumper.add_representer(str, _str_representer)


def _dump(document: Any, indent: int) -> str:
    text = yaml.dump(document, Dumper=_Dumper, sort_keys=False, default_flow_style=False, allow_unicode=True)
    pad = ' ' * indent
    return ''.join(pad + line if line.strip() else line for line in text.splitlines(keepends=True))


class _Metadata:
    """Builds ``metadata.yaml``; each finished file's entry is rendered once, so that rewriting
    the metadata at every rollover stays cheap however many segments the bag has."""

    def __init__(self) -> None:
        self.files: list[FileSummary] = []
        self._paths: list[str] = []
        self._entries: list[str] = []

    def add_file(self, summary: FileSummary) -> None:
        self.files.append(summary)
        self._paths.append(_dump([summary.path], 2))
        self._entries.append(_dump([summary.entry()], 2))

    def render(self, topics: Mapping[str, TopicSummary], custom: Mapping[str, str]) -> str:
        counted = [f for f in self.files if f.count]
        start = min((f.start_ns for f in counted), default=0)
        end = max((f.end_ns for f in counted), default=0)
        head = {
            'version': ROSBAG2_VERSION,
            'storage_identifier': STORAGE_ID,
            'duration': {'nanoseconds': end - start},
            'starting_time': {'nanoseconds_since_epoch': start},
            'message_count': sum(f.count for f in self.files),
            'topics_with_message_count': [
                {
                    'topic_metadata': {
                        'name': name,
                        'type': t.type,
                        'serialization_format': 'cdr',
                        'offered_qos_profiles': [],
                        'type_description_hash': t.type_hash,
                    },
                    'message_count': t.count,
                }
                for name, t in topics.items()
            ],
            'compression_format': '',
            'compression_mode': '',
            'custom_data': dict(custom),
            'ros_distro': ROS_DISTRO,
        }
        parts = ['rosbag2_bagfile_information:\n', _dump(head, 2)]
        parts.append('  relative_file_paths:\n' if self._paths else '  relative_file_paths: []\n')
        parts.extend(self._paths)
        parts.append('  files:\n' if self._entries else '  files: []\n')
        parts.extend(self._entries)
        return ''.join(parts)


def segment_files(directory: str | os.PathLike[str]) -> list[Path]:
    """The ``.mcap`` files of a bag directory in split order (``<name>_<i>.mcap`` by ``i``)."""

    def key(path: Path) -> tuple[int, str]:
        m = _SPLIT.search(path.name)
        return (int(m.group(1)) if m else -1, path.name)

    return sorted((p for p in Path(directory).glob('*.mcap') if p.is_file()), key=key)


# ---------------------------------------------------------------------------- writer


class _Segment:
    """One open ``.mcap`` file."""

    def __init__(self, path: Path, chunk_size: int, custom: Mapping[str, str], flush_ns: int) -> None:
        import mcap
        from mcap.writer import CompressionType, Writer

        self.path = path
        self.stream: BinaryIO = path.open('xb')
        self.writer = Writer(self.stream, chunk_size=chunk_size, compression=CompressionType.ZSTD)
        # python mcap's Writer ends a chunk only by size or at finish(); its chunk-ending method is
        # private (name-mangled). Checked here, so that a changed library fails at once, not at a crash.
        self._end_chunk: Callable[[], None] = self.writer._Writer__finalize_chunk
        self.flush_ns = flush_ns
        self._next_flush_ns: int | None = None
        self.writer.start(profile='ros2', library=f'folder_line {__version__} (python mcap {mcap.__version__})')
        self.writer.add_metadata(MCAP_METADATA_NAME, dict(custom))
        self.schemas: dict[str, int] = {}
        self.channels: dict[str, int] = {}
        self.count = 0
        self.start_ns = 0
        self.end_ns = 0

    def add_channel(self, topic: str, msgtype: str) -> None:
        if msgtype not in self.schemas:
            text, _ = _definition(msgtype)
            self.schemas[msgtype] = self.writer.register_schema(msgtype, 'ros2msg', text.encode())
        _, rihs01 = _definition(msgtype)
        self.channels[topic] = self.writer.register_channel(
            topic, 'cdr', self.schemas[msgtype], {'offered_qos_profiles': '[]', 'topic_type_hash': rihs01}
        )

    def add(self, topic: str, log_ns: int, publish_ns: int, data: bytes, sequence: int) -> None:
        if self._next_flush_ns is None:
            self._next_flush_ns = log_ns + self.flush_ns
        elif log_ns >= self._next_flush_ns:  # the messages before this tick go to disk (a SIGKILL keeps them)
            self.flush()
            self._next_flush_ns = log_ns + self.flush_ns
        self.writer.add_message(self.channels[topic], log_ns, data, publish_ns, sequence)
        if self.count == 0:
            self.start_ns = log_ns
        self.end_ns = log_ns
        self.count += 1

    def flush(self) -> None:
        """End the current chunk and hand the file's bytes to the operating system."""
        self._end_chunk()
        self.stream.flush()

    def finish(self) -> FileSummary:
        self.writer.finish()
        self.stream.close()
        return FileSummary(self.path.name, self.start_ns, self.end_ns, self.count)


class BagWriter:
    """Writes the line's messages to a rosbag2 directory in MCAP storage, one file per segment.

    Usable as the :class:`folder_line.ros.recorder.LineRecorder` sink (``writer.write_serialized``)
    and as a context manager. See the module docstring for the layout, timestamps and
    crash safety.

    Parameters
    ----------
    directory : path-like
        The bag directory; created (with its parents). It must not exist or be empty.
    scene_source : str
        The scene as YAML text (stored as ``folder_line.scene``).
    effects : list of str
        The scene's effects (stored as ``folder_line.effects``, JSON).
    segment_s : float
        Line time per file, s, in [1e-6, 1e6] (default 1).
    flush_s : float
        Line time between two flushes of the open file, s, in [1e-6, 1e6] (default 0.1): a
        SIGKILL loses at most this much (and the tick being written), after :func:`repair`.
    scene_name : str
        Stored as ``folder_line.scene_name``.
    topics : mapping of str to type or str, optional
        Topics known up front (topic -> rclpy message class or ``'pkg/msg/Type'``):
        every file gets a channel for each, even when no message arrives on it.
        Other topics are added at their first message.
    custom : mapping of str to str, optional
        Extra ``custom_data`` entries.
    clock_topic : str
        Topic of ``rosgraph_msgs/Clock`` messages that carry the line time.
    chunk_size : int
        Uncompressed bytes per MCAP chunk, > 0 (default 1 MiB); smaller chunks let
        :func:`repair` salvage more of an unfinished file.

    Raises
    ------
    BagError
        ``directory`` exists and is not an empty directory, or a parameter is out of range.
    """

    def __init__(
        self,
        directory: str | os.PathLike[str],
        *,
        scene_source: str,
        effects: Sequence[str],
        segment_s: float = 1.0,
        scene_name: str = '',
        topics: Mapping[str, type | str] | None = None,
        custom: Mapping[str, str] | None = None,
        clock_topic: str = '/clock',
        chunk_size: int = 1024 * 1024,
        flush_s: float = 0.1,
    ) -> None:
        self.path = Path(directory)
        for name, value in (('segment_s', segment_s), ('flush_s', flush_s)):
            if not (isinstance(value, (int, float)) and 1e-6 <= value <= 1e6):
                msg = f'{self.path}: {name}={value!r} must be in [1e-6, 1e6] s'
                raise BagError(msg)
        if not (isinstance(chunk_size, int) and chunk_size > 0):
            msg = f'{self.path}: chunk_size={chunk_size!r} must be a positive whole number of bytes'
            raise BagError(msg)
        if self.path.exists() and (not self.path.is_dir() or any(self.path.iterdir())):
            msg = f'{self.path}: exists and is not an empty directory; a bag is written to a new one'
            raise BagError(msg)
        self.segment_ns = round(float(segment_s) * NS_PER_S)
        self.flush_ns = round(float(flush_s) * NS_PER_S)
        self.clock_topic = clock_topic
        self.chunk_size = chunk_size
        self.custom: dict[str, str] = {
            KEY_SCENE_NAME: str(scene_name),
            KEY_SCENE: str(scene_source),
            KEY_EFFECTS: json.dumps([str(e) for e in effects]),
            KEY_VERSION: __version__,
            KEY_SEGMENT_S: repr(float(segment_s)),
            KEY_COMPLETE: 'false',
        }
        for key, value in (custom or {}).items():
            if not isinstance(value, str):
                msg = f'{self.path}: custom data {key}={value!r} must be a string'
                raise BagError(msg)
            self.custom[str(key)] = value
        declared = {
            topic: kind if isinstance(kind, str) else msgtype_of(kind) for topic, kind in (topics or {}).items()
        }
        for msgtype in declared.values():
            _definition(msgtype)  # an unknown type fails before anything is written
        self.types: dict[str, str] = dict(declared)
        self.counts: dict[str, int] = dict.fromkeys(declared, 0)  # messages per topic, all files
        self._complete: dict[str, int] = dict.fromkeys(declared, 0)  # messages per topic, finished files
        self._meta = _Metadata()
        self._t_ns = 0
        self._boundary_ns = self.segment_ns
        self._closed = False
        self.path.mkdir(parents=True, exist_ok=True)
        self._write_metadata()
        self._segment: _Segment | None = self._open_segment(0)

    # ------------------------------------------------------------------ public

    @property
    def files(self) -> list[FileSummary]:
        """The finished files (all of them after :meth:`close`)."""
        return list(self._meta.files)

    @property
    def segments(self) -> int:
        """Number of files written so far, the open one included."""
        return len(self._meta.files) + (self._segment is not None)

    @property
    def line_time_ns(self) -> int:
        """Latest line time seen on the clock topic, ns."""
        return self._t_ns

    def add_topic(self, topic: str, kind: type | str) -> None:
        """Declare ``topic`` with a message class or ``'pkg/msg/Type'`` (every later file gets its channel)."""
        msgtype = kind if isinstance(kind, str) else msgtype_of(kind)
        self._check_open()
        if topic in self.types:
            if self.types[topic] != msgtype:
                msg = f'{self.path}: topic {topic} has type {self.types[topic]}, not {msgtype}'
                raise BagError(msg)
            return
        _definition(msgtype)  # fails early on an unknown type
        self.types[topic] = msgtype
        self.counts[topic] = 0
        self._complete[topic] = 0
        assert self._segment is not None
        self._segment.add_channel(topic, msgtype)

    def write(self, topic: str, msg: Any, receive_time_ns: int | None = None) -> None:
        """Record one rclpy message (the recorder sink).

        Parameters
        ----------
        topic : str
            Topic name.
        msg : rclpy message
            Converted to the rosbags typestore's message and serialized as CDR (:func:`serialize`).
        receive_time_ns : int, optional
            Wall time of reception; accepted for the sink signature, not stored
            (the bag's timestamps are line time).
        """
        self._check_open()
        msgtype = msgtype_of(type(msg))
        if topic not in self.types:
            self.add_topic(topic, msgtype)
        elif self.types[topic] != msgtype:
            text = f'{self.path}: topic {topic} has type {self.types[topic]}, not {msgtype}'
            raise BagError(text)
        if topic == self.clock_topic:
            self._t_ns = max(self._t_ns, _time_ns(msg.clock))
        header = getattr(msg, 'header', None)
        publish_ns = _time_ns(header.stamp) if header is not None else self._t_ns
        self.write_serialized(topic, serialize(msg, self.types[topic]), self._t_ns, publish_ns)

    def write_serialized(self, topic: str, data: bytes, log_ns: int, publish_ns: int | None = None) -> None:
        """Record one CDR-serialized message of a declared topic at line time ``log_ns``.

        Reaching the next multiple of ``segment_s`` finishes the open file first; an
        earlier ``log_ns`` goes into the open file.
        """
        self._check_open()
        if topic not in self.types:
            msg = f'{self.path}: topic {topic} was not declared (add_topic) before a serialized write'
            raise BagError(msg)
        try:
            if log_ns >= self._boundary_ns:
                self._roll(log_ns)
            assert self._segment is not None
            self._segment.add(
                topic, log_ns, log_ns if publish_ns is None else publish_ns, data, self.counts[topic] % 2**32
            )
        except OSError as exc:
            if exc.filename is None:  # a write into the open file: name it
                where = self._segment.path if self._segment is not None else self.path
                raise OSError(exc.errno, exc.strerror, str(where)) from exc
            raise
        self.counts[topic] += 1

    def close(self, published: Mapping[str, int] | None = None) -> None:
        """Finish the open file and write the final ``metadata.yaml``.

        Parameters
        ----------
        published : mapping of str to int, optional
            Publisher-side message counts per topic, stored as ``folder_line.published``.
        """
        if self._closed:
            return
        if published is not None:
            self.custom[KEY_PUBLISHED] = json.dumps({str(k): int(v) for k, v in sorted(published.items())})
        self._finish_segment()
        self._closed = True
        self.custom[KEY_COMPLETE] = 'true'
        self._write_metadata()

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ internals

    def _check_open(self) -> None:
        if self._closed:
            msg = f'{self.path}: the bag is closed'
            raise BagError(msg)

    def _open_segment(self, index: int) -> _Segment:
        segment = _Segment(self.path / f'{self.path.name}_{index}.mcap', self.chunk_size, self.custom, self.flush_ns)
        for topic, msgtype in self.types.items():
            segment.add_channel(topic, msgtype)
        return segment

    def _finish_segment(self) -> None:
        if self._segment is None:
            return
        counts = self._segment_counts()
        self._meta.add_file(self._segment.finish())
        self._segment = None
        for topic, n in counts.items():
            self._complete[topic] += n

    def _segment_counts(self) -> dict[str, int]:
        return {t: self.counts[t] - self._complete[t] for t in self.types}

    def _roll(self, log_ns: int) -> None:
        index = len(self._meta.files) + 1
        self._finish_segment()
        self._write_metadata()
        self._boundary_ns = (log_ns // self.segment_ns + 1) * self.segment_ns
        self._segment = self._open_segment(index)

    def _write_metadata(self) -> None:
        topics = {t: TopicSummary(self.types[t], self._complete[t], _definition(self.types[t])[1]) for t in self.types}
        write_text_atomic(self.path / METADATA_FILE, self._meta.render(topics, self.custom))


# ---------------------------------------------------------------------------- reader


@dataclass(frozen=True)
class BagContents:
    """What a bag holds (from ``metadata.yaml``); :meth:`messages` reads the messages.

    Attributes
    ----------
    path : Path
        The bag directory.
    topics : dict of str to TopicSummary
        Topic -> type and count.
    custom : dict of str to str
        rosbag2 ``custom_data``.
    files : tuple of str
        The ``.mcap`` files, in order.
    message_count : int
        Messages in the bag.
    start_ns, end_ns : int
        Log times of the first and the last message, ns of line time (0, 0 if empty).
    """

    path: Path
    topics: dict[str, TopicSummary]
    custom: dict[str, str]
    files: tuple[str, ...]
    message_count: int
    start_ns: int
    end_ns: int

    @property
    def duration_ns(self) -> int:
        """``end_ns - start_ns``."""
        return self.end_ns - self.start_ns

    @property
    def scene_source(self) -> str:
        """The scene YAML stored in the bag ('' if none)."""
        return self.custom.get(KEY_SCENE, '')

    @property
    def scene_name(self) -> str:
        """The scene's name ('' if none)."""
        return self.custom.get(KEY_SCENE_NAME, '')

    @property
    def effects(self) -> list[str]:
        """The scene's effects."""
        return list(json.loads(self.custom.get(KEY_EFFECTS, '[]')))

    @property
    def published(self) -> dict[str, int] | None:
        """Publisher-side counts per topic, or None if the writer did not know them."""
        text = self.custom.get(KEY_PUBLISHED)
        return None if text is None else {str(k): int(v) for k, v in json.loads(text).items()}

    def messages(self, topics: Sequence[str] | None = None) -> Iterator[tuple[str, int, Any]]:
        """``(topic, log time ns, message)`` in file order and, within a file, log-time order.

        Messages are deserialized by the rosbags typestore (ROS 2 kilted): dataclasses
        with the fields of the ROS message, float arrays as numpy arrays; no rclpy needed.
        """
        from rosbags.rosbag2 import Reader

        store = _typestore()
        with _OpenReader(Reader, self.path) as reader:
            wanted = [c for c in reader.connections if topics is None or c.topic in topics]
            if not wanted:
                return
            for conn, t_ns, raw in reader.messages(connections=wanted):
                yield conn.topic, t_ns, store.deserialize_cdr(raw, conn.msgtype)


class _OpenReader:
    """``with _OpenReader(Reader, path) as reader``: rosbags errors become BagError."""

    def __init__(self, reader_cls: Any, path: Path) -> None:
        self.reader = reader_cls(path)

    def __enter__(self) -> Any:
        try:
            self.reader.open()
        except Exception as exc:  # rosbags raises ReaderError, FileNotFoundError, KeyError ...
            msg = f'{self.reader.path}: cannot open the bag: {exc}'
            raise BagError(msg) from exc
        return self.reader

    def __exit__(self, *exc: object) -> None:
        self.reader.close()


def read_bag(path: str | os.PathLike[str]) -> BagContents:
    """Open a bag directory with rosbags and summarise it.

    Raises
    ------
    BagError
        Not a directory, no ``metadata.yaml`` (``folder-line bag repair DIR`` rebuilds
        it), or rosbags cannot open the bag.
    """
    from rosbags.rosbag2 import Reader

    directory = Path(path)
    if not directory.is_dir():
        msg = f'{directory}: not a bag directory'
        raise BagError(msg)
    meta = directory / METADATA_FILE
    if not os.path.lexists(meta):
        msg = f'{directory}: no {METADATA_FILE}; rebuild it with: folder-line bag repair {directory}'
        raise BagError(msg)
    if not meta.is_file():
        from folder_line.files.atomic import describe_path

        msg = f'{meta}: {describe_path(meta)}, not a regular file'
        raise BagError(msg)
    data = _read_metadata(directory)  # bounded, strict YAML before rosbags parses it
    if not isinstance(data, dict) or not isinstance(data.get('rosbag2_bagfile_information'), dict):
        msg = (
            f'{meta}: line 1, column 1: not rosbag2 metadata (a mapping with rosbag2_bagfile_information); '
            f'rebuild it with: folder-line bag repair {directory}'
        )
        raise BagError(msg)
    with _OpenReader(Reader, directory) as reader:
        topics = {
            name: TopicSummary(
                info.msgtype or '', info.msgcount, info.connections[0].digest if info.connections else ''
            )
            for name, info in reader.topics.items()
        }
        count = reader.message_count
        start, end = (reader.start_time, reader.end_time - 1) if count else (0, 0)
        custom = dict(reader.storage.metadata.custom or {})
        files = tuple(Path(p).name for p in _relative_paths(directory))
    return BagContents(
        path=directory, topics=topics, custom=custom, files=files, message_count=count, start_ns=start, end_ns=end
    )


def _read_metadata(directory: Path) -> Any:
    """``metadata.yaml`` read by :func:`folder_line.files.yamlio.load_yaml_file` (size, aliases, tags and
    duplicate keys bounded); a :class:`~folder_line.errors.ParameterError` names the line and column."""
    from folder_line.files.yamlio import METADATA_LIMIT, load_yaml_file

    return load_yaml_file(directory / METADATA_FILE, 'bag metadata', METADATA_LIMIT, max_nodes=1_000_000)


def _relative_paths(directory: Path) -> list[str]:
    data = _read_metadata(directory)
    return list(data['rosbag2_bagfile_information'].get('relative_file_paths') or [])


def bag_info_lines(contents: BagContents) -> list[str]:
    """Human-readable summary of a bag (``folder-line bag info``)."""
    names = ', '.join(contents.files[:3]) + (', ...' if len(contents.files) > 3 else '')
    span = (
        f'{contents.start_ns / NS_PER_S:.3f} .. {contents.end_ns / NS_PER_S:.3f} s '
        f'({contents.duration_ns / NS_PER_S:.3f} s)'
    )
    state = contents.custom.get(KEY_COMPLETE)
    state_text = {
        'true': 'complete (closed by its writer)',
        'false': 'INCOMPLETE: its writer did not close it (killed, or a write failed); the files listed '
        'are whole, the rest is salvaged by: folder-line bag repair DIR',
        'repaired': 'repaired after its writer stopped (see folder_line.repair)',
    }.get(state or '', 'not recorded (written before folder_line.complete existed)')
    lines = [
        f'bag        {contents.path}',
        f'state      {state_text}',
        f'files      {len(contents.files)} ({names})',
        f'line time  {span}',
        f'messages   {contents.message_count}',
        'topics:',
    ]
    published = contents.published
    for name, t in contents.topics.items():
        extra = '' if published is None else f'  (published {published.get(name, "?")})'
        lines.append(f'  {name:<40} {t.type:<36} {t.count:>9}{extra}')
    lines.append('custom data:')
    for key, value in contents.custom.items():
        rows = value.splitlines() or ['']
        more = f'  ... ({len(rows)} lines)' if len(rows) > 1 else ''
        lines.append(f'  {key}: {rows[0][:100]}{more}')
    return lines


# ---------------------------------------------------------------------------- repair


@dataclass
class RepairResult:
    """What :func:`repair` did.

    Attributes
    ----------
    metadata : Path
        The rebuilt ``metadata.yaml``.
    files : list of FileSummary
        The files listed in it.
    salvaged : dict of str to int
        Unfinished file -> messages salvaged from its complete chunks (it was rewritten
        with a summary and footer; the original is kept as ``<file>.truncated``).
    dropped : dict of str to int
        Unfinished file -> bytes of its tail that could not be read (an incomplete chunk).
    removed : list of str
        Unfinished files with nothing to salvage, renamed to ``<file>.truncated`` and
        not listed.
    """

    metadata: Path
    files: list[FileSummary] = field(default_factory=list)
    salvaged: dict[str, int] = field(default_factory=dict)
    dropped: dict[str, int] = field(default_factory=dict)
    removed: list[str] = field(default_factory=list)

    def describe(self) -> str:
        """One line: what was listed, salvaged and dropped."""
        parts = [f'{len(self.files)} files, {sum(f.count for f in self.files)} messages']
        for name, n in self.salvaged.items():
            parts.append(f'{name} unfinished: salvaged {n} messages, dropped {self.dropped.get(name, 0)} bytes')
        for name in self.removed:
            parts.append(f'{name} unfinished: nothing to salvage, dropped {self.dropped.get(name, 0)} bytes')
        if not self.salvaged and not self.removed:
            parts.append('nothing dropped')
        return '; '.join(parts)


@dataclass
class _Scan:
    """Schemas, channels, counts and times of one ``.mcap`` file."""

    schemas: dict[int, Any] = field(default_factory=dict)
    channels: dict[int, Any] = field(default_factory=dict)
    counts: dict[int, int] = field(default_factory=dict)
    start_ns: int = 0
    end_ns: int = 0
    custom: dict[str, str] | None = None

    @property
    def count(self) -> int:
        return sum(self.counts.values())


# what the mcap reader raises on a file that ends early or has garbage at its end
def _read_errors() -> tuple[type[BaseException], ...]:
    import struct

    from mcap.exceptions import McapError

    return McapError, EOFError, ValueError, struct.error, IndexError, KeyError, OSError


def _scan_finished(path: Path) -> _Scan | None:
    """The summary of a finished file (footer and statistics), or None if it has none."""
    from mcap.reader import make_reader

    try:
        with path.open('rb') as fh:
            reader = make_reader(fh)
            summary = reader.get_summary()
            if summary is None or summary.statistics is None:
                return None
            stats = summary.statistics
            scan = _Scan(
                schemas=dict(summary.schemas),
                channels=dict(summary.channels),
                counts=dict(stats.channel_message_counts),
                start_ns=stats.message_start_time if stats.message_count else 0,
                end_ns=stats.message_end_time if stats.message_count else 0,
            )
            for record in reader.iter_metadata():
                if record.name == MCAP_METADATA_NAME:
                    scan.custom = dict(record.metadata)
            return scan
    except _read_errors():
        return None


def _salvage(path: Path) -> tuple[_Scan, list[Any], list[Any], int]:
    """Read an unfinished file record by record up to its first incomplete record.

    Returns the scan, the complete messages, the metadata records and the number of
    bytes read successfully.
    """
    from mcap.records import Channel, Message, Metadata, Schema
    from mcap.stream_reader import StreamReader

    scan = _Scan()
    messages: list[Any] = []
    metadata: list[Any] = []
    good = 0
    with path.open('rb') as fh:
        try:
            for record in StreamReader(fh).records:
                if isinstance(record, Schema):
                    scan.schemas[record.id] = record
                elif isinstance(record, Channel):
                    scan.channels[record.id] = record
                elif isinstance(record, Message):
                    messages.append(record)
                elif isinstance(record, Metadata):
                    metadata.append(record)
                    if record.name == MCAP_METADATA_NAME:
                        scan.custom = dict(record.metadata)
                good = fh.tell()
        except _read_errors():
            pass
    messages = [m for m in messages if m.channel_id in scan.channels]
    for m in messages:
        scan.counts[m.channel_id] = scan.counts.get(m.channel_id, 0) + 1
    if messages:
        scan.start_ns = min(m.log_time for m in messages)
        scan.end_ns = max(m.log_time for m in messages)
    return scan, messages, metadata, good


def _rewrite(path: Path, scan: _Scan, messages: list[Any], metadata: list[Any]) -> None:
    """Write the salvaged records as a finished file in place of ``path``; keep the original
    as ``<path>.truncated`` (hard link first, so that a crash in between loses nothing)."""
    import mcap
    from mcap.writer import CompressionType, Writer

    tmp = path.with_name(f'.{path.name}.salvage.tmp')
    with tmp.open('wb') as fh:
        writer = Writer(fh, compression=CompressionType.ZSTD)
        writer.start(profile='ros2', library=f'folder_line {__version__} repair (python mcap {mcap.__version__})')
        for record in metadata:
            writer.add_metadata(record.name, dict(record.metadata))
        schema_ids = {sid: writer.register_schema(s.name, s.encoding, s.data) for sid, s in scan.schemas.items()}
        channel_ids = {
            cid: writer.register_channel(c.topic, c.message_encoding, schema_ids.get(c.schema_id, 0), dict(c.metadata))
            for cid, c in scan.channels.items()
        }
        for m in messages:
            writer.add_message(channel_ids[m.channel_id], m.log_time, m.data, m.publish_time, m.sequence)
        writer.finish()
    keep = path.with_name(path.name + TRUNCATED_SUFFIX)
    keep.unlink(missing_ok=True)
    try:
        os.link(path, keep)
    except OSError:
        shutil.copy2(path, keep)
    os.replace(tmp, path)
    # the channel ids of the rewritten file follow the order of scan.channels
    scan.channels = {channel_ids[cid]: c for cid, c in scan.channels.items()}
    scan.counts = {channel_ids[cid]: n for cid, n in scan.counts.items()}


def repair(directory: str | os.PathLike[str]) -> RepairResult:
    """Rebuild a bag's ``metadata.yaml`` from the ``.mcap`` files present.

    Finished files are listed as they are. An unfinished file (no footer, as a SIGKILL
    leaves the open segment) is read up to its first incomplete chunk; if that yields
    messages it is rewritten as a finished file (the original kept as
    ``<file>.truncated``), else it is renamed to ``<file>.truncated``. ``custom_data``
    comes from the old ``metadata.yaml`` if it is readable, else from the files' MCAP
    metadata records; ``folder_line.repair`` records what was done. The result is
    checked by opening the bag with rosbags.

    Raises
    ------
    BagError
        ``directory`` is not a directory, holds no ``.mcap`` file, or no file holds a readable
        message (then nothing is changed).
    """
    from rosbags.rosbag2 import Reader

    bag = Path(directory)
    if not bag.is_dir():
        msg = f'{bag}: not a directory'
        raise BagError(msg)
    paths = segment_files(bag)
    if not paths:
        msg = f'{bag}: no .mcap files: not a rosbag2 bag in MCAP storage'
        raise BagError(msg)
    result = RepairResult(metadata=bag / METADATA_FILE)
    # read everything first: a bag with nothing to salvage is left exactly as it was
    found: list[tuple[Path, _Scan, tuple[list[Any], list[Any], int] | None]] = []
    for path in paths:
        scan = _scan_finished(path)
        if scan is not None:
            found.append((path, scan, None))
        else:
            scan, messages, metadata, good = _salvage(path)
            found.append((path, scan, (messages, metadata, good)))
    if not any(salvage is None or salvage[0] for _, _, salvage in found):
        msg = f'{bag}: none of the {len(paths)} .mcap files holds a readable message (nothing was changed)'
        raise BagError(msg)
    scans: list[tuple[Path, _Scan]] = []
    for path, scan, salvage in found:
        if salvage is not None:
            messages, metadata, good = salvage
            result.dropped[path.name] = path.stat().st_size - good
            if messages:
                _rewrite(path, scan, messages, metadata)
                result.salvaged[path.name] = len(messages)
            else:
                os.replace(path, path.with_name(path.name + TRUNCATED_SUFFIX))
                result.removed.append(path.name)
                continue
        scans.append((path, scan))

    custom = _old_custom(bag)
    if custom is None:
        custom = next((dict(s.custom) for _, s in scans if s.custom is not None), {})
    topics: dict[str, TopicSummary] = {}
    meta = _Metadata()
    for path, scan in scans:
        for cid, channel in scan.channels.items():
            schema = scan.schemas.get(channel.schema_id)
            msgtype = schema.name if schema is not None else ''
            old = topics.get(channel.topic)
            type_hash = dict(channel.metadata).get('topic_type_hash', '') or (old.type_hash if old else '')
            topics[channel.topic] = TopicSummary(
                msgtype, (old.count if old else 0) + scan.counts.get(cid, 0), type_hash
            )
        meta.add_file(FileSummary(path.name, scan.start_ns, scan.end_ns, scan.count))
    result.files = list(meta.files)
    if custom.get(KEY_COMPLETE) != 'true':
        custom[KEY_COMPLETE] = 'repaired'
    custom[KEY_REPAIR] = result.describe()
    write_text_atomic(result.metadata, meta.render(topics, custom))
    with _OpenReader(Reader, bag):
        pass
    return result


def _old_custom(bag: Path) -> dict[str, str] | None:
    try:
        data = _read_metadata(bag)
        custom = data['rosbag2_bagfile_information'].get('custom_data')
    except (FolderLineError, KeyError, TypeError, AttributeError):
        return None
    return {str(k): str(v) for k, v in custom.items()} if isinstance(custom, dict) else None


def repair_bag(directory: str | os.PathLike[str]) -> Path:
    """:func:`repair` and return the path of the rebuilt ``metadata.yaml``."""
    return repair(directory).metadata
