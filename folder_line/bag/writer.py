"""The bag writer: the line's messages to a rosbag2 directory in MCAP storage, one file per segment.

The bag is split by line time as ``ros2 bag record`` splits by size or duration
(layout and ``custom_data``: :mod:`folder_line.bag.metadata`). Each ``.mcap`` file
uses the ``ros2`` MCAP profile (schemas ``ros2msg`` from the rosbags typestore of
ROS 2 kilted, channels ``cdr``, zstd chunks, summary and footer).

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
every ``flush_s`` of line time (default 0.1 s), so :func:`folder_line.bag.repair.repair`
salvages the open file up to its last flushed chunk: a SIGKILL loses at most ``flush_s``
of line time plus the messages of the tick being written. Repair rebuilds
``metadata.yaml`` from the files present. Files are not fsynced: this protects
against a crash of the process, not of the operating system.
"""

from __future__ import annotations

import contextlib
import json
import os
import struct
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any, BinaryIO

import mcap
import numpy as np
from mcap.opcode import Opcode
from mcap.records import MessageIndex
from mcap.writer import CompressionType, Writer

from folder_line import __version__
from folder_line.bag.metadata import (
    KEY_COMPLETE,
    KEY_EFFECTS,
    KEY_PUBLISHED,
    KEY_SCENE,
    KEY_SCENE_NAME,
    KEY_SEGMENT_S,
    KEY_VERSION,
    MCAP_METADATA_NAME,
    METADATA_FILE,
    FileSummary,
    MetadataBuilder,
    TopicSummary,
    segment_path,
)
from folder_line.bag.types import message_definition, msgtype_of, serialize
from folder_line.errors import BagError
from folder_line.files.atomic import write_text_atomic
from folder_line.interfaces import CLOCK_TOPIC, NS_PER_S

__all__ = ['DEFAULT_CHUNK_SIZE', 'BagWriter', 'start_mcap']

#: an MCAP Message record's opcode, length, channel id, sequence, log time and publish time
_MESSAGE_HEAD = struct.Struct('<BQHIQQ')

#: uncompressed bytes per MCAP chunk unless told otherwise (python mcap's default too)
DEFAULT_CHUNK_SIZE = 1024 * 1024


def start_mcap(stream: BinaryIO, *, chunk_size: int = DEFAULT_CHUNK_SIZE, role: str = '') -> Writer:
    """A python mcap ``Writer`` on ``stream``, started: ``ros2`` profile, zstd chunks.

    Parameters
    ----------
    stream : binary file
        Where the MCAP bytes go.
    chunk_size : int
        Uncompressed bytes per chunk.
    role : str
        Added to the file's ``library`` after folder_line's version (``'repair'``), or ''.
    """
    writer = Writer(stream, chunk_size=chunk_size, compression=CompressionType.ZSTD)
    who = f'folder_line {__version__} {role}' if role else f'folder_line {__version__}'
    writer.start(profile='ros2', library=f'{who} (python mcap {mcap.__version__})')
    return writer


def _time_ns(stamp: Any) -> int:
    """ns of a ``builtin_interfaces/Time``."""
    return int(stamp.sec) * NS_PER_S + int(stamp.nanosec)


class _PackedMessageIndex(MessageIndex):
    """A chunk's message index of one channel, written in one piece (the same bytes as ``MessageIndex``,
    which packs each of its ``(log time, offset)`` pairs with two calls)."""

    def write(self, stream: Any) -> None:
        stream.start_record(Opcode.MESSAGE_INDEX)
        stream.write2(self.channel_id)
        stream.write4(len(self.records) * 16)
        stream.write(np.asarray(self.records, dtype='<u8').tobytes())
        stream.finish_record()


class _Segment:
    """One open ``.mcap`` file."""

    def __init__(self, path: Path, chunk_size: int, custom: Mapping[str, str], flush_ns: int) -> None:
        self.path = path
        self.stream: BinaryIO = path.open('xb')
        self.writer = start_mcap(self.stream, chunk_size=chunk_size)
        # python mcap's Writer ends a chunk only by size or at finish(); its chunk-ending method is
        # private (name-mangled). Checked here, so that a changed library fails at once, not at a crash.
        self._end_chunk: Callable[[], None] = self.writer._Writer__finalize_chunk  # type: ignore[attr-defined]
        # the same for the batched path (add_many): the open chunk and the file's statistics
        self._chunk: Any = self.writer._Writer__chunk_builder  # type: ignore[attr-defined]
        self._stats: Any = self.writer._Writer__statistics  # type: ignore[attr-defined]
        self._maybe_end_chunk: Callable[[], None] = self.writer._Writer__maybe_finalize_chunk  # type: ignore[attr-defined]
        self._records: Any = self._chunk.record_writer
        self._indices: dict[int, MessageIndex] = self._chunk.message_indices
        self.flush_ns = flush_ns
        self._next_flush_ns: int | None = None
        self.writer.add_metadata(MCAP_METADATA_NAME, dict(custom))
        self.schemas: dict[str, int] = {}
        self.channels: dict[str, int] = {}
        self.count = 0
        self.start_ns = 0
        self.end_ns = 0

    def add_channel(self, topic: str, msgtype: str) -> None:
        text, rihs01 = message_definition(msgtype)
        if msgtype not in self.schemas:
            self.schemas[msgtype] = self.writer.register_schema(msgtype, 'ros2msg', text.encode())
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

    def add_many(self, log_ns: int, items: Sequence[tuple[str, bytes, int]], counts: dict[str, int]) -> None:
        """Messages ``(topic, data, publish_ns)`` all logged at ``log_ns``; ``counts`` (per topic) gives
        each its sequence and is advanced. The records go straight into the open chunk (what
        ``Writer.add_message`` does, without a ``Message`` object and stream calls per message)."""
        if not items:
            return
        if self._next_flush_ns is None:
            self._next_flush_ns = log_ns + self.flush_ns
        elif log_ns >= self._next_flush_ns:
            self.flush()
            self._next_flush_ns = log_ns + self.flush_ns
        buffer = self._records._buffer
        per_channel = self._stats.channel_message_counts
        chunk = self._chunk
        for topic, data, publish_ns in items:
            channel = self.channels[topic]
            index = self._indices.get(channel)
            if index is None:
                index = self._indices[channel] = _PackedMessageIndex(channel_id=channel, records=[])
            index.records.append((log_ns, buffer.tell()))
            n = counts[topic]
            counts[topic] = n + 1
            buffer.write(_MESSAGE_HEAD.pack(Opcode.MESSAGE, 22 + len(data), channel, n % 2**32, log_ns, publish_ns))
            buffer.write(data)
            per_channel[channel] += 1
        stats = self._stats
        if stats.message_count == 0:
            stats.message_start_time = log_ns
        else:
            stats.message_start_time = min(stats.message_start_time, log_ns)
        stats.message_end_time = max(stats.message_end_time, log_ns)
        stats.message_count += len(items)
        if chunk.num_messages == 0:
            chunk.message_start_time = log_ns
        else:
            chunk.message_start_time = min(chunk.message_start_time, log_ns)
        chunk.message_end_time = max(chunk.message_end_time, log_ns)
        chunk.num_messages += len(items)
        self._maybe_end_chunk()
        if self.count == 0:
            self.start_ns = log_ns
        self.end_ns = log_ns
        self.count += len(items)

    def flush(self) -> None:
        """End the current chunk and hand the file's bytes to the operating system."""
        self._end_chunk()
        self.stream.flush()

    def finish(self) -> FileSummary:
        self.writer.finish()  # type: ignore[no-untyped-call]  # mcap leaves Writer.finish unannotated (-> None)
        self.stream.close()
        return FileSummary(self.path.name, self.start_ns, self.end_ns, self.count)


class BagWriter:
    """Writes the line's messages to a rosbag2 directory in MCAP storage, one file per segment.

    Usable as the :class:`folder_line.ros.recorder.LineRecorder` sink (``writer.write_serialized``)
    and as a context manager. See :mod:`folder_line.bag.writer` for the timestamps and
    crash safety, :mod:`folder_line.bag.metadata` for the layout.

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
        SIGKILL loses at most this much (and the tick being written), after
        :func:`~folder_line.bag.repair.repair`.
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
        :func:`~folder_line.bag.repair.repair` salvage more of an unfinished file.
    rewrite_metadata : bool
        Rewrite ``metadata.yaml`` at every rollover (default) so that a killed writer leaves a bag
        that opens as it is; False: only at the start (marked partial) and at :meth:`close`, for a
        writer that makes thousands of files fast (``simulate --bag``); a bag it leaves unfinished
        opens after :func:`~folder_line.bag.repair.repair`.

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
        clock_topic: str = CLOCK_TOPIC,
        chunk_size: int = DEFAULT_CHUNK_SIZE,
        flush_s: float = 0.1,
        rewrite_metadata: bool = True,
    ) -> None:
        self.path = Path(directory)
        self.rewrite_metadata = bool(rewrite_metadata)
        for name, seconds in (('segment_s', segment_s), ('flush_s', flush_s)):
            if not (isinstance(seconds, (int, float)) and 1e-6 <= seconds <= 1e6):
                msg = f'{self.path}: {name}={seconds!r} must be in [1e-6, 1e6] s'
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
            message_definition(msgtype)  # an unknown type fails before anything is written
        self.types: dict[str, str] = dict(declared)
        self.counts: dict[str, int] = dict.fromkeys(declared, 0)  # messages per topic, all files
        self._complete: dict[str, int] = dict.fromkeys(declared, 0)  # messages per topic, finished files
        self._meta = MetadataBuilder()
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
        """Declare ``topic`` with a message class or ``'pkg/msg/Type'`` (every later file gets its channel).

        Raises
        ------
        BagError
            The bag is closed, ``topic`` has another type already, or the type is not in the typestore.
        """
        msgtype = kind if isinstance(kind, str) else msgtype_of(kind)
        self._check_open()
        if topic in self.types:
            if self.types[topic] != msgtype:
                msg = f'{self.path}: topic {topic} has type {self.types[topic]}, not {msgtype}'
                raise BagError(msg)
            return
        message_definition(msgtype)  # fails early on an unknown type
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
            Topic name; declared with the message's type at its first message.
        msg : rclpy message
            Converted to the rosbags typestore's message and serialized as CDR
            (:func:`folder_line.bag.types.serialize`).
        receive_time_ns : int, optional
            Wall time of reception; accepted for the sink signature, not stored
            (the bag's timestamps are line time).
        """
        self._check_open()
        # a class is hashable; mypy checks type[...] against lru_cache's Hashable wrongly (python/typeshed#4638)
        self.add_topic(topic, msgtype_of(type(msg)))  # type: ignore[arg-type]  # declares a new topic, refuses another type
        if topic == self.clock_topic:
            self._t_ns = max(self._t_ns, _time_ns(msg.clock))
        header = getattr(msg, 'header', None)
        publish_ns = _time_ns(header.stamp) if header is not None else self._t_ns
        self.write_serialized(topic, serialize(msg, self.types[topic]), self._t_ns, publish_ns)

    def write_serialized(self, topic: str, data: bytes, log_ns: int, publish_ns: int | None = None) -> None:
        """Record one CDR-serialized message of a declared topic at line time ``log_ns``.

        Reaching the next multiple of ``segment_s`` finishes the open file first; an
        earlier ``log_ns`` goes into the open file. ``publish_ns`` defaults to ``log_ns``.
        """
        self._check_declared((topic,))
        with self._naming_the_file():
            self._segment_at(log_ns).add(
                topic, log_ns, log_ns if publish_ns is None else publish_ns, data, self.counts[topic] % 2**32
            )
        self.counts[topic] += 1

    def _check_declared(self, topics: Iterable[str]) -> None:
        """The bag is open and every topic of a serialized write was declared (BagError otherwise)."""
        self._check_open()
        for topic in topics:
            if topic not in self.types:
                msg = f'{self.path}: topic {topic} was not declared (add_topic) before a serialized write'
                raise BagError(msg)

    def _segment_at(self, log_ns: int) -> _Segment:
        """The file a record at line time ``log_ns`` goes into: the next one from a segment boundary on."""
        if log_ns >= self._boundary_ns:
            self._roll(log_ns)
        assert self._segment is not None
        return self._segment

    @contextlib.contextmanager
    def _naming_the_file(self) -> Iterator[None]:
        """An OS error of a write into the open file (which has no file name) names the file."""
        try:
            yield
        except OSError as exc:
            if exc.filename is None:
                where = self._segment.path if self._segment is not None else self.path
                raise OSError(exc.errno, exc.strerror, str(where)) from exc
            raise

    def write_many(self, log_ns: int, items: Sequence[tuple[str, bytes, int]]) -> None:
        """Record CDR-serialized messages ``(topic, data, publish_ns)`` of declared topics, all at line
        time ``log_ns`` (one tick): :meth:`write_serialized` for each, in one call."""
        self._check_declared(topic for topic, _, _ in items)
        with self._naming_the_file():
            self._segment_at(log_ns).add_many(log_ns, items, self.counts)

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

    def abandon(self) -> None:
        """Finish the open file and write ``metadata.yaml`` listing every file, the bag still marked
        partial (``folder_line.complete`` stays ``false``): for a writer that failed or was interrupted."""
        if self._closed:
            return
        self._finish_segment()
        self._closed = True
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
        segment = _Segment(segment_path(self.path, index), self.chunk_size, self.custom, self.flush_ns)
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
        if self.rewrite_metadata:
            self._write_metadata()
        self._boundary_ns = (log_ns // self.segment_ns + 1) * self.segment_ns
        self._segment = self._open_segment(index)

    def _write_metadata(self) -> None:
        topics = {
            t: TopicSummary(self.types[t], self._complete[t], message_definition(self.types[t])[1]) for t in self.types
        }
        write_text_atomic(self.path / METADATA_FILE, self._meta.render(topics, self.custom))
