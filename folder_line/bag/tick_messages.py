"""The MCAP Message records of many ticks, built with numpy: :class:`TickMessages`, for
:meth:`folder_line.bag.writer.BagWriter.write_ticks`, and the packed message index that takes them."""

from __future__ import annotations

import struct
from collections.abc import Sequence

import numpy as np
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import MessageIndex

__all__ = ['HEAD_SIZE', 'MESSAGE_HEAD', 'PackedMessageIndex', 'Records', 'TickMessages']

#: an MCAP Message record's opcode, length, channel id, sequence, log time and publish time
MESSAGE_HEAD = struct.Struct('<BQHIQQ')
#: an MCAP MessageIndex record's opcode, length, channel id and the byte length of its records
INDEX_HEAD = struct.Struct('<BQHI')
#: the same record head as a numpy (packed) structure, to write many at once
HEAD_DTYPE = np.dtype(
    [('op', 'u1'), ('length', '<u8'), ('channel', '<u2'), ('sequence', '<u4'), ('log', '<u8'), ('publish', '<u8')]
)
#: bytes of a Message record before its data
HEAD_SIZE = MESSAGE_HEAD.size
#: the rank of a message inside its tick (:class:`TickMessages`) is below this
SLOTS = 1 << 20


class PackedMessageIndex(MessageIndex):
    """A chunk's message index of one channel, written in one piece (the same bytes as ``MessageIndex``,
    which packs each of its ``(log time, offset)`` pairs with two calls).

    ``records`` takes pairs one at a time (:meth:`folder_line.bag.segment.Segment.add_many`),
    :meth:`add_block` many at once as an (n, 2) array (:meth:`~folder_line.bag.segment.Segment.add_records`);
    they are written in the order they came.
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

    def write(self, stream: RecordBuilder) -> None:
        data = b''.join(block.astype('<u8', copy=False).tobytes() for block in self.blocks)
        if self.records:
            data += np.asarray(self.records, dtype='<u8').tobytes()
        # the record: opcode, its length, the channel and the records' length, then the records
        stream.write(INDEX_HEAD.pack(Opcode.MESSAGE_INDEX, 6 + len(data), self.channel_id, len(data)) + data)


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
        self._keys: list[np.ndarray] = []  # per part: tick * SLOTS + slot of each message
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

    def _add(
        self,
        ticks: np.ndarray,
        slot: int,
        topic: np.ndarray,
        lens: np.ndarray,
        publish: np.ndarray | Sequence[int] | None,
        data: np.ndarray,
    ) -> None:
        if not 0 <= slot < SLOTS:
            msg = f'slot {slot} is not in [0, {SLOTS})'
            raise ValueError(msg)
        self._keys.append(ticks * SLOTS + slot)
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

    def records(self) -> Records:
        """The records in bag order, heads not filled yet (the sequence and channel are the writer's)."""
        if not self._keys:
            return Records.empty()
        keys = np.concatenate(self._keys)
        order = np.argsort(keys, kind='stable')
        m = len(order)
        where = np.empty(m, dtype=np.int64)  # the place of each message (in the parts' order) in the bag order
        where[order] = np.arange(m)
        lens = np.concatenate(self._lens)
        starts = np.zeros(m + 1, dtype=np.int64)
        np.cumsum(lens[order] + HEAD_SIZE, out=starts[1:])
        buf = np.empty(int(starts[-1]), dtype=np.uint8)
        first = 0
        for data, part_lens in zip(self._data, self._lens, strict=True):
            k = len(part_lens)
            at = starts[where[first : first + k]] + HEAD_SIZE  # where each message's data goes
            first += k
            if not k:
                continue
            if data.ndim == 2:
                buf[at[:, None] + np.arange(data.shape[1])] = data
            else:
                before = np.zeros(k, dtype=np.int64)
                np.cumsum(part_lens[:-1], out=before[1:])
                buf[np.repeat(at - before, part_lens) + np.arange(len(data))] = data
        tick = keys[order] // SLOTS
        return Records(
            buf,
            starts,
            self.log_ns[tick],
            np.concatenate(self._publish)[order],
            np.concatenate(self._topic)[order],
            list(self.topics),
        )


class Records:
    """:class:`TickMessages` in bag order: message i's record is ``buf[starts[i]:starts[i + 1]]``, its
    head (``HEAD_SIZE`` bytes, to fill) then its data."""

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
    def empty(cls) -> Records:
        none = np.zeros(0, dtype=np.int64)
        return cls(np.zeros(0, dtype=np.uint8), np.zeros(1, dtype=np.int64), none, none, none, [])

    def __len__(self) -> int:
        return len(self.log_ns)

    def fill_heads(self, a: int, b: int, channels: np.ndarray, sequence: np.ndarray) -> None:
        """Write the heads of records ``a:b``: ``channels`` by topic index, ``sequence`` of each record."""
        k = b - a
        if not k:
            return
        head = np.empty(k, dtype=HEAD_DTYPE)
        head['op'] = int(Opcode.MESSAGE)
        head['length'] = self.starts[a + 1 : b + 1] - self.starts[a:b] - 9  # after the opcode and the length
        self.channel[a:b] = channels[self.topic[a:b]]
        head['channel'] = self.channel[a:b]
        head['sequence'] = sequence[a:b] % 2**32
        head['log'] = self.log_ns[a:b]
        head['publish'] = self.publish_ns[a:b]
        self.buf[self.starts[a:b, None] + np.arange(HEAD_SIZE)] = head.view(np.uint8).reshape(k, HEAD_SIZE)
