"""The bag writer: the line's messages to a rosbag2 directory in MCAP storage, one ``.mcap`` file.

As ``ros2 bag record``, the writer makes one file unless told to split it, by line time
(``max_duration_s``) or by size (``max_size``); layout and ``custom_data``:
:mod:`folder_line.bag.metadata`. Each ``.mcap`` file
uses the ``ros2`` MCAP profile (schemas ``ros2msg`` from the rosbags typestore of
ROS 2 kilted, channels ``cdr``, zstd chunks, summary and footer).

Timestamps are line time (sim time, ns), as ``ros2 bag record --use-sim-time``
stamps them: a message's log time is the latest ``/clock`` the writer has seen (a
``/clock`` message is stamped with its own time); its publish time is its
``header.stamp`` when it has one, else the log time. The wall time of reception is
not stored. The MCAP ``sequence`` of a message is its index on its topic in the bag.

Many messages at once. :meth:`BagWriter.write_many` records one tick's serialized messages in
one call; :meth:`BagWriter.write_ticks` records a whole window of ticks gathered column by column
(:class:`TickMessages`: the records built with numpy, straight into the open chunk), the same
files byte for byte as :meth:`~BagWriter.write_many` tick by tick (``simulate --bag``).

Splitting. With ``max_duration_s`` the next file starts at each multiple of it in line
time (``--max-bag-duration``); with ``max_size`` a file that has reached that many bytes
is finished at the next flush (below), and the next tick starts a new file
(``--max-bag-size``); with both, whichever comes first. At each split the writer
finishes the open file (chunks, summary, footer) and rewrites ``metadata.yaml``
(atomically) listing the finished files.

Crash safety. The writer closes the current chunk and hands it to the operating system
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
from collections.abc import Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any, BinaryIO

import mcap
import numpy as np
from mcap.opcode import Opcode
from mcap.records import MessageIndex

from folder_line import __version__
from folder_line.bag.mcap_file import McapFile
from folder_line.bag.metadata import (
    KEY_COMPLETE,
    KEY_EFFECTS,
    KEY_MAX_BAG_DURATION,
    KEY_MAX_BAG_SIZE,
    KEY_PUBLISHED,
    KEY_SCENE,
    KEY_SCENE_NAME,
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
from folder_line.interfaces import CLOCK_TOPIC, NS_PER_S, stamp_ns

__all__ = ['DEFAULT_CHUNK_SIZE', 'BagWriter', 'TickMessages', 'start_mcap']

#: an MCAP Message record's opcode, length, channel id, sequence, log time and publish time
_MESSAGE_HEAD = struct.Struct('<BQHIQQ')
#: an MCAP MessageIndex record's opcode, length, channel id and the byte length of its records
_INDEX_HEAD = struct.Struct('<BQHI')
#: the same record head as a numpy (packed) structure, to write many at once
_HEAD_DTYPE = np.dtype(
    [('op', 'u1'), ('length', '<u8'), ('channel', '<u2'), ('sequence', '<u4'), ('log', '<u8'), ('publish', '<u8')]
)
_HEAD = _MESSAGE_HEAD.size
#: the rank of a message inside its tick (:class:`TickMessages`) is below this
_SLOTS = 1 << 20

#: a line time no bag reaches, ns: the split time of a bag not split by time
_NEVER = 2**63 - 1
#: uncompressed bytes per MCAP chunk unless told otherwise (python mcap's default too)
DEFAULT_CHUNK_SIZE = 1024 * 1024


def start_mcap(stream: BinaryIO, *, chunk_size: int = DEFAULT_CHUNK_SIZE, role: str = '') -> McapFile:
    """An MCAP file on ``stream``, started: ``ros2`` profile, zstd chunks.

    Parameters
    ----------
    stream : binary file
        Where the MCAP bytes go.
    chunk_size : int
        Uncompressed bytes per chunk.
    role : str
        Added to the file's ``library`` after folder_line's version (``'repair'``), or ''.
    """
    who = f'folder_line {__version__} {role}' if role else f'folder_line {__version__}'
    return McapFile(stream, chunk_size=chunk_size, profile='ros2', library=f'{who} (python mcap {mcap.__version__})')


class _PackedMessageIndex(MessageIndex):
    """A chunk's message index of one channel, written in one piece (the same bytes as ``MessageIndex``,
    which packs each of its ``(log time, offset)`` pairs with two calls).

    ``records`` takes pairs one at a time (:meth:`_Segment.add_many`), :meth:`add_block` many at once
    as an (n, 2) array (:meth:`_Segment.add_records`); they are written in the order they came.
    """

    def __init__(self, channel_id: int, records: list[tuple[int, int]]) -> None:
        super().__init__(channel_id=channel_id, records=records)
        self.blocks: list[np.ndarray] = []

    def add_block(self, pairs: np.ndarray) -> None:
        """Append the ``(log time, offset)`` rows of ``pairs``."""
        if self.records:
            self.blocks.append(np.asarray(self.records, dtype='<u8'))
            self.records.clear()
        self.blocks.append(pairs)

    def write(self, stream: Any) -> None:
        data = b''.join(block.astype('<u8', copy=False).tobytes() for block in self.blocks)
        if self.records:
            data += np.asarray(self.records, dtype='<u8').tobytes()
        # the record: opcode, its length, the channel and the records' length, then the records
        stream.write(_INDEX_HEAD.pack(Opcode.MESSAGE_INDEX, 6 + len(data), self.channel_id, len(data)) + data)


class TickMessages:
    """The messages of consecutive ticks, gathered a column at a time, for :meth:`BagWriter.write_ticks`.

    Every message belongs to one tick (logged at its line time) and has a ``slot``, its rank in
    the tick: the bag gets the ticks in order and, in each, the messages by slot; those of one
    slot in the order they were added. Each message becomes its MCAP record (head and CDR) in
    one buffer, built with numpy, so that a window of ticks costs a few array operations
    instead of a few calls per message.

    Parameters
    ----------
    log_ns : array of int, shape (n,)
        The ticks' line times (log times), ns, ascending.
    """

    def __init__(self, log_ns: np.ndarray) -> None:
        self.log_ns = np.asarray(log_ns, dtype=np.int64).reshape(-1)
        self.topics: list[str] = []  # the topics, by their index here
        self._topic_index: dict[str, int] = {}
        self._keys: list[np.ndarray] = []  # per part: tick * _SLOTS + slot of each message
        self._topic: list[np.ndarray] = []
        self._lens: list[np.ndarray] = []
        self._publish: list[np.ndarray] = []
        self._data: list[np.ndarray] = []  # per part: (k, size) uint8 rows, or (bytes,) uint8 concatenated

    def _index(self, topic: str) -> int:
        i = self._topic_index.get(topic)
        if i is None:
            i = self._topic_index[topic] = len(self.topics)
            self.topics.append(topic)
        return i

    def _ticks(self, ticks: np.ndarray | Sequence[int] | None, k: int) -> np.ndarray:
        out = np.arange(len(self.log_ns)) if ticks is None else np.asarray(ticks, dtype=np.int64).reshape(-1)
        if len(out) != k:
            msg = f'{k} messages for {len(out)} ticks'
            raise ValueError(msg)
        return out

    def _add(self, ticks: np.ndarray, slot: int, topic: np.ndarray, lens: np.ndarray, publish: Any, data: Any) -> None:
        if not 0 <= slot < _SLOTS:
            msg = f'slot {slot} is not in [0, {_SLOTS})'
            raise ValueError(msg)
        self._keys.append(ticks * _SLOTS + slot)
        self._topic.append(topic)
        self._lens.append(lens)
        pub = self.log_ns[ticks] if publish is None else np.asarray(publish, dtype=np.int64).reshape(-1)
        if len(pub) != len(ticks):
            msg = f'{len(pub)} publish times for {len(ticks)} messages'
            raise ValueError(msg)
        self._publish.append(pub)
        self._data.append(data)

    def add_rows(
        self,
        topic: str,
        slot: int,
        rows: np.ndarray,
        ticks: np.ndarray | Sequence[int] | None = None,
        publish_ns: np.ndarray | Sequence[int] | None = None,
    ) -> None:
        """Messages of ``topic`` of one size: ``rows`` (k, size) of bytes (uint8), one message each.

        ``ticks``: the index of each one's tick (default: one per tick, k = n); ``publish_ns``: their
        publish times (default: the tick's log time).
        """
        data = np.asarray(rows, dtype=np.uint8)
        if data.ndim != 2:
            msg = f'rows of shape {data.shape}: expected (messages, bytes)'
            raise ValueError(msg)
        ticks_ = self._ticks(ticks, len(data))
        topic_ = np.full(len(data), self._index(topic), dtype=np.int64)
        self._add(ticks_, slot, topic_, np.full(len(data), data.shape[1], dtype=np.int64), publish_ns, data)

    def add_each(
        self,
        topics: str | Sequence[str],
        slot: int,
        ticks: np.ndarray | Sequence[int],
        blobs: Sequence[bytes],
        publish_ns: np.ndarray | Sequence[int] | None = None,
    ) -> None:
        """Messages of any size: ``blobs[i]`` of ``topics`` (one topic, or one each) at tick ``ticks[i]``."""
        ticks_ = self._ticks(ticks, len(blobs))
        if isinstance(topics, str):
            topic_ = np.full(len(blobs), self._index(topics), dtype=np.int64)
        else:
            topic_ = np.array([self._index(t) for t in topics], dtype=np.int64).reshape(-1)
            if len(topic_) != len(blobs):
                msg = f'{len(topic_)} topics for {len(blobs)} messages'
                raise ValueError(msg)
        lens = np.fromiter((len(b) for b in blobs), dtype=np.int64, count=len(blobs))
        data = np.frombuffer(b''.join(blobs), dtype=np.uint8)
        self._add(ticks_, slot, topic_, lens, publish_ns, data)

    def add_packed(
        self,
        topic: str,
        slot: int,
        ticks: np.ndarray | Sequence[int],
        data: np.ndarray,
        lens: np.ndarray | Sequence[int],
        publish_ns: np.ndarray | Sequence[int] | None = None,
    ) -> None:
        """Messages of ``topic`` of any size given as one buffer: ``data`` (uint8) holds them one after
        the other, ``lens[i]`` bytes for the one at tick ``ticks[i]``."""
        lens_ = np.asarray(lens, dtype=np.int64).reshape(-1)
        buf = np.asarray(data, dtype=np.uint8).reshape(-1)
        if int(lens_.sum()) != len(buf):
            msg = f'{len(buf)} bytes for messages of {int(lens_.sum())}'
            raise ValueError(msg)
        ticks_ = self._ticks(ticks, len(lens_))
        self._add(ticks_, slot, np.full(len(lens_), self._index(topic), dtype=np.int64), lens_, publish_ns, buf)

    def records(self) -> _Records:
        """The records in bag order, heads not filled yet (the sequence and channel are the writer's)."""
        if not self._keys:
            return _Records.empty()
        keys = np.concatenate(self._keys)
        order = np.argsort(keys, kind='stable')
        m = len(order)
        where = np.empty(m, dtype=np.int64)  # the place of each message (in the parts' order) in the bag order
        where[order] = np.arange(m)
        lens = np.concatenate(self._lens)
        starts = np.zeros(m + 1, dtype=np.int64)
        np.cumsum(lens[order] + _HEAD, out=starts[1:])
        buf = np.empty(int(starts[-1]), dtype=np.uint8)
        first = 0
        for data, part_lens in zip(self._data, self._lens, strict=True):
            k = len(part_lens)
            at = starts[where[first : first + k]] + _HEAD  # where each message's data goes
            first += k
            if not k:
                continue
            if data.ndim == 2:
                buf[at[:, None] + np.arange(data.shape[1])] = data
            else:
                before = np.zeros(k, dtype=np.int64)
                np.cumsum(part_lens[:-1], out=before[1:])
                buf[np.repeat(at - before, part_lens) + np.arange(len(data))] = data
        tick = keys[order] // _SLOTS
        return _Records(
            buf,
            starts,
            self.log_ns[tick],
            np.concatenate(self._publish)[order],
            np.concatenate(self._topic)[order],
            list(self.topics),
        )


class _Records:
    """:class:`TickMessages` in bag order: message i's record is ``buf[starts[i]:starts[i + 1]]``, its
    head (``_HEAD`` bytes, to fill) then its data."""

    def __init__(
        self,
        buf: np.ndarray,
        starts: np.ndarray,
        log_ns: np.ndarray,
        publish_ns: np.ndarray,
        topic: np.ndarray,
        topics: list[str],
    ) -> None:
        self.buf = buf
        self.starts = starts
        self.log_ns = log_ns
        self.publish_ns = publish_ns
        self.topic = topic
        self.topics = topics
        self.channel = np.zeros(len(log_ns), dtype=np.int64)  # of each record, set with its head
        # message indices where a tick starts (a new log time), and the end
        cut = np.flatnonzero(np.diff(log_ns)) + 1
        self.tick_ends = np.concatenate((cut, [len(log_ns)])).astype(np.int64)

    @classmethod
    def empty(cls) -> _Records:
        none = np.zeros(0, dtype=np.int64)
        return cls(np.zeros(0, dtype=np.uint8), np.zeros(1, dtype=np.int64), none, none, none, [])

    def __len__(self) -> int:
        return len(self.log_ns)

    def fill_heads(self, a: int, b: int, channels: np.ndarray, sequence: np.ndarray) -> None:
        """Write the heads of records ``a:b``: ``channels`` by topic index, ``sequence`` of each record."""
        k = b - a
        if not k:
            return
        head = np.empty(k, dtype=_HEAD_DTYPE)
        head['op'] = int(Opcode.MESSAGE)
        head['length'] = self.starts[a + 1 : b + 1] - self.starts[a:b] - 9  # after the opcode and the length
        self.channel[a:b] = channels[self.topic[a:b]]
        head['channel'] = self.channel[a:b]
        head['sequence'] = sequence[a:b] % 2**32
        head['log'] = self.log_ns[a:b]
        head['publish'] = self.publish_ns[a:b]
        self.buf[self.starts[a:b, None] + np.arange(_HEAD)] = head.view(np.uint8).reshape(k, _HEAD)


class _Segment:
    """One open ``.mcap`` file."""

    def __init__(self, path: Path, chunk_size: int, custom: Mapping[str, str], flush_ns: int) -> None:
        self.path = path
        self.stream: BinaryIO = path.open('xb')
        self.chunk_size = chunk_size
        self.writer = start_mcap(self.stream, chunk_size=chunk_size)
        self.flush_ns = flush_ns
        self.next_flush_ns: int | None = None
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
        self._flush_before(log_ns)
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
        self._flush_before(log_ns)
        out = self.writer
        chunk = out.chunk
        indices = out.indices
        per_channel = out.statistics.channel_message_counts
        for topic, data, publish_ns in items:
            channel = self.channels[topic]
            index = indices.get(channel)
            if index is None:
                index = indices[channel] = _PackedMessageIndex(channel_id=channel, records=[])
            index.records.append((log_ns, chunk.count))
            n = counts[topic]
            counts[topic] = n + 1
            chunk.write(_MESSAGE_HEAD.pack(Opcode.MESSAGE, 22 + len(data), channel, n % 2**32, log_ns, publish_ns))
            chunk.write(data)
            per_channel[channel] += 1
        out.took(len(items), log_ns, log_ns)
        out.maybe_end_chunk()
        if self.count == 0:
            self.start_ns = log_ns
        self.end_ns = log_ns
        self.count += len(items)

    def add_records(self, rec: _Records, a: int, b: int) -> None:
        """Records ``a:b`` of ``rec`` (heads filled), whole ticks: what :meth:`add_many` does tick by tick
        (the flushes, a chunk ended after the tick that takes it over its size), a chunk's worth at a time."""
        log = rec.log_ns
        ends = rec.tick_ends
        starts = rec.starts
        while a < b:
            log_a = int(log[a])
            next_flush_ns = self._flush_before(log_a)
            g = min(b, int(np.searchsorted(log, next_flush_ns, side='left')))  # the ticks before the flush
            while a < g:
                room = self.chunk_size - self.writer.chunk.count
                tick_ends = ends[np.searchsorted(ends, a, side='right') : np.searchsorted(ends, g, side='right')]
                over = int(np.searchsorted(starts[tick_ends] - starts[a], room, side='right'))
                e = int(tick_ends[over]) if over < len(tick_ends) else g
                self._add_records(rec, a, e)
                if over < len(tick_ends):
                    self.writer.end_chunk()
                a = e

    def _add_records(self, rec: _Records, a: int, b: int) -> None:
        """Records ``a:b`` into the open chunk: its bytes, its message indices and the statistics."""
        out = self.writer
        base = out.chunk.count - int(rec.starts[a])
        out.chunk.write(rec.buf[int(rec.starts[a]) : int(rec.starts[b])].data)
        channels = rec.channel[a:b]
        log = rec.log_ns[a:b]
        # the (log time, offset) pairs channel by channel, the channels in the order they come
        by_channel = np.argsort(channels, kind='stable')
        sorted_channels = channels[by_channel]
        cut = np.flatnonzero(sorted_channels[1:] != sorted_channels[:-1]) + 1
        pairs = np.empty((b - a, 2), dtype='<u8')
        pairs[:, 0] = log[by_channel]
        pairs[:, 1] = rec.starts[a:b][by_channel] + base
        heads = np.concatenate(([0], cut))
        ends = np.concatenate((cut, [b - a])).tolist()
        firsts = heads.tolist()
        per_channel = out.statistics.channel_message_counts
        for j in np.argsort(by_channel[heads], kind='stable').tolist():
            channel = int(sorted_channels[firsts[j]])
            group = pairs[firsts[j] : ends[j]]
            index = out.indices.get(channel)
            if index is None:
                index = out.indices[channel] = _PackedMessageIndex(channel_id=channel, records=[])
            if isinstance(index, _PackedMessageIndex):
                index.add_block(group)
            else:  # made by McapFile.add_message (write_serialized)
                index.records.extend(map(tuple, group.tolist()))
            per_channel[channel] += len(group)
        k = b - a
        lo, hi = int(log[0]), int(log[-1])
        out.took(k, lo, hi)
        if self.count == 0:
            self.start_ns = lo
        self.end_ns = hi
        self.count += k

    def _flush_before(self, log_ns: int) -> int:
        """Make the flush due before a record at ``log_ns`` (the messages before it go to disk: a SIGKILL keeps
        them; the first record sets the first flush time); return the next flush time, ns."""
        if self.next_flush_ns is None:
            self.next_flush_ns = log_ns + self.flush_ns
        elif log_ns >= self.next_flush_ns:
            self.flush_at(log_ns)
        return self.next_flush_ns

    def flush_due(self, log_ns: int) -> bool:
        """A record at line time ``log_ns`` would flush the file first."""
        return self.next_flush_ns is not None and log_ns >= self.next_flush_ns

    def flush_at(self, log_ns: int) -> None:
        """The flush a record at ``log_ns`` would make first, made now; the next is ``flush_s`` later."""
        self.flush()
        self.next_flush_ns = log_ns + self.flush_ns

    def size(self) -> int:
        """Bytes written to the file so far (up to the last flush, the open chunk not counted)."""
        return self.stream.tell()

    def flush(self) -> None:
        """End the current chunk and hand the file's bytes to the operating system."""
        self.writer.flush()

    def finish(self) -> FileSummary:
        self.writer.finish()
        self.stream.close()
        return FileSummary(self.path.name, self.start_ns, self.end_ns, self.count)


class BagWriter:
    """Writes the line's messages to a rosbag2 directory in MCAP storage: one file, or split on request.

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
    max_duration_s : float
        Line time per file, s: 0 (default) no split by time, else in [1e-6, 1e7].
    max_size : int
        Bytes per file: 0 (default) no split by size, else a file of at least this size is
        finished at its next flush.
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
        max_duration_s: float = 0.0,
        max_size: int = 0,
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
        if not (isinstance(flush_s, (int, float)) and 1e-6 <= flush_s <= 1e6):
            msg = f'{self.path}: flush_s={flush_s!r} must be in [1e-6, 1e6] s'
            raise BagError(msg)
        if not (isinstance(max_duration_s, (int, float)) and (max_duration_s == 0 or 1e-6 <= max_duration_s <= 1e7)):
            msg = f'{self.path}: max_duration_s={max_duration_s!r} must be 0 (no split) or in [1e-6, 1e7] s'
            raise BagError(msg)
        if not (isinstance(max_size, int) and max_size >= 0):
            msg = f'{self.path}: max_size={max_size!r} must be 0 (no split) or a positive whole number of bytes'
            raise BagError(msg)
        if not (isinstance(chunk_size, int) and chunk_size > 0):
            msg = f'{self.path}: chunk_size={chunk_size!r} must be a positive whole number of bytes'
            raise BagError(msg)
        if self.path.exists() and (not self.path.is_dir() or any(self.path.iterdir())):
            msg = f'{self.path}: exists and is not an empty directory; a bag is written to a new one'
            raise BagError(msg)
        self.max_duration_ns = round(float(max_duration_s) * NS_PER_S)
        self.max_size = max_size
        self.flush_ns = round(float(flush_s) * NS_PER_S)
        self.clock_topic = clock_topic
        self.chunk_size = chunk_size
        self.custom: dict[str, str] = {
            KEY_SCENE_NAME: str(scene_name),
            KEY_SCENE: str(scene_source),
            KEY_EFFECTS: json.dumps([str(e) for e in effects]),
            KEY_VERSION: __version__,
            KEY_MAX_BAG_DURATION: repr(float(max_duration_s)),
            KEY_MAX_BAG_SIZE: str(max_size),
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
        self._boundary_ns = self.max_duration_ns or _NEVER
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
            self._t_ns = max(self._t_ns, stamp_ns(msg.clock))
        header = getattr(msg, 'header', None)
        publish_ns = stamp_ns(header.stamp) if header is not None else self._t_ns
        self.write_serialized(topic, serialize(msg, self.types[topic]), self._t_ns, publish_ns)

    def write_serialized(self, topic: str, data: bytes, log_ns: int, publish_ns: int | None = None) -> None:
        """Record one CDR-serialized message of a declared topic at line time ``log_ns``.

        A split due (see :mod:`folder_line.bag.writer`) finishes the open file first; an
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
        """The file a record at line time ``log_ns`` goes into: a new one when a split is due.

        A split by size is judged at a flush (every ``flush_s``), on the bytes the file then has: the same
        place whether the ticks come one at a time or many (:meth:`write_ticks` stops at each flush).
        """
        assert self._segment is not None
        if log_ns >= self._boundary_ns:
            self._roll(log_ns)
        elif self.max_size and self._segment.flush_due(log_ns):
            self._segment.flush_at(log_ns)
            if self._segment.size() >= self.max_size:
                self._roll(log_ns)
        assert self._segment is not None
        return self._segment

    def _split_before(self, segment: _Segment, log_ns: int) -> int:
        """Line time before which records from ``log_ns`` on go into ``segment``: its split by time, or with a
        split by size its next flush (where the size is judged)."""
        if not self.max_size:
            return self._boundary_ns
        flush_ns = segment.next_flush_ns if segment.next_flush_ns is not None else log_ns + segment.flush_ns
        return min(self._boundary_ns, flush_ns)

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

    def write_ticks(self, messages: TickMessages) -> None:
        """Record the messages of ticks gathered in ``messages`` (CDR, declared topics): the same
        as :meth:`write_many` once per tick with that tick's messages in their order, in a few
        array operations. A tick with no message writes nothing."""
        rec = messages.records()
        self._check_declared(rec.topics)
        m = len(rec)
        if not m:
            return
        # each record's sequence: its index on its topic in the bag
        by_topic = np.argsort(rec.topic, kind='stable')
        sorted_topic = rec.topic[by_topic]
        first = np.searchsorted(sorted_topic, np.arange(len(rec.topics)), side='left')
        base = np.array([self.counts[t] for t in rec.topics], dtype=np.int64)
        sequence = np.empty(m, dtype=np.int64)
        sequence[by_topic] = base[sorted_topic] + np.arange(m) - first[sorted_topic]
        a = 0
        with self._naming_the_file():
            while a < m:
                log_a = int(rec.log_ns[a])
                segment = self._segment_at(log_a)
                b = max(a + 1, int(np.searchsorted(rec.log_ns, self._split_before(segment, log_a), side='left')))
                channels = np.array([segment.channels[t] for t in rec.topics], dtype=np.int64)
                rec.fill_heads(a, b, channels, sequence)
                segment.add_records(rec, a, b)
                for i, n in enumerate(np.bincount(rec.topic[a:b], minlength=len(rec.topics)).tolist()):
                    self.counts[rec.topics[i]] += n
                a = b

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

    def __exit__(self, exc_type: type[BaseException] | None, *exc: object) -> None:
        """Close the bag, or, when the block raised, :meth:`abandon` it: a bag whose writing failed is not
        marked complete."""
        if exc_type is None:
            self.close()
        else:
            self.abandon()

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
        if self.max_duration_ns:
            self._boundary_ns = (log_ns // self.max_duration_ns + 1) * self.max_duration_ns
        self._segment = self._open_segment(index)

    def _write_metadata(self) -> None:
        topics = {
            t: TopicSummary(self.types[t], self._complete[t], message_definition(self.types[t])[1]) for t in self.types
        }
        write_text_atomic(self.path / METADATA_FILE, self._meta.render(topics, self.custom))
