"""One open ``.mcap`` file of a bag (:class:`Segment`), for :class:`folder_line.bag.writer.BagWriter`."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import BinaryIO

import mcap
import numpy as np
from mcap.opcode import Opcode

from folder_line import __version__
from folder_line.bag.mcap_file import McapFile
from folder_line.bag.metadata import MCAP_METADATA_NAME, FileSummary
from folder_line.bag.tick_messages import MESSAGE_HEAD, PackedMessageIndex, Records
from folder_line.bag.types import message_definition

__all__ = ['DEFAULT_CHUNK_SIZE', 'Segment', 'start_mcap']

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


class Segment:
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
                index = indices[channel] = PackedMessageIndex(channel_id=channel, records=[])
            index.records.append((log_ns, chunk.count))
            n = counts[topic]
            counts[topic] = n + 1
            chunk.write(MESSAGE_HEAD.pack(Opcode.MESSAGE, 22 + len(data), channel, n % 2**32, log_ns, publish_ns))
            chunk.write(data)
            per_channel[channel] += 1
        out.took(len(items), log_ns, log_ns)
        out.maybe_end_chunk()
        if self.count == 0:
            self.start_ns = log_ns
        self.end_ns = log_ns
        self.count += len(items)

    def add_records(self, rec: Records, a: int, b: int) -> None:
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

    def _add_records(self, rec: Records, a: int, b: int) -> None:
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
                index = out.indices[channel] = PackedMessageIndex(channel_id=channel, records=[])
            if isinstance(index, PackedMessageIndex):
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
