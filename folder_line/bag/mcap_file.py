"""An MCAP file written from python mcap's public records, with chunks its user ends: :class:`McapFile`.

python mcap's ``Writer`` ends a chunk when it is full or at ``flush()``, one message at a time. The
bag writer also ends chunks on a tick's edge and fills them a window of ticks at a time, straight
from numpy (:mod:`folder_line.bag.writer`). So this class keeps the open chunk itself: a
``RecordBuilder`` (:attr:`McapFile.chunk`) that the bag writer may write whole Message records
into, the chunk's message indices and times, and the file's statistics. The records, the summary
and the footer are python mcap's ``mcap.records``, written as its ``Writer.finish`` writes them: a
file that the ``mcap`` reader, rosbags and Foxglove open indexed.
"""

from __future__ import annotations

import struct
import zlib
from collections import defaultdict
from collections.abc import Mapping
from typing import BinaryIO

import zstandard
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (
    Channel,
    Chunk,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    McapRecord,
    Message,
    MessageIndex,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)

__all__ = ['MAGIC', 'McapFile']

MAGIC = b'\x89MCAP0\r\n'
"""The bytes an MCAP file starts and ends with."""

#: a Footer record up to its CRC: opcode, length, summary start, summary offset start
_FOOTER_HEAD = struct.Struct('<BQQQ')


def _taken(builder: RecordBuilder) -> bytes:
    """The bytes ``builder`` holds; it is empty again after."""
    data: bytes = builder.end()  # type: ignore[no-untyped-call]  # python mcap leaves it unannotated
    return data


class McapFile:
    """One MCAP file being written on ``stream``: header, chunks, summary and footer.

    Parameters
    ----------
    stream : binary file
        Where the bytes go; it must tell its position (a file).
    chunk_size : int
        Bytes of records past which :meth:`add_message` and :meth:`maybe_end_chunk` end the open chunk.
    profile, library : str
        The Header record's fields (``'ros2'``; who wrote the file).

    Attributes
    ----------
    chunk : mcap.data_stream.RecordBuilder
        The open chunk's records: :meth:`add_message` writes there, and so may a caller that also
        keeps :attr:`indices`, :attr:`statistics` and :meth:`took` up to date.
    indices : dict of int to MessageIndex
        The open chunk's message index per channel id (offsets into :attr:`chunk`).
    statistics : mcap.records.Statistics
        The file's counts so far.
    """

    def __init__(self, stream: BinaryIO, *, chunk_size: int, profile: str, library: str) -> None:
        self.stream = stream
        self.chunk_size = chunk_size
        self.chunk = RecordBuilder()
        self.indices: dict[int, MessageIndex] = {}
        self.chunk_start_ns = 0
        self.chunk_end_ns = 0
        self.chunk_messages = 0
        self.statistics = Statistics(
            attachment_count=0,
            channel_count=0,
            channel_message_counts=defaultdict(int),
            chunk_count=0,
            message_count=0,
            message_end_time=0,
            message_start_time=0,
            metadata_count=0,
            schema_count=0,
        )
        self.schemas: list[Schema] = []
        self.channels: list[Channel] = []
        self._chunk_indices: list[ChunkIndex] = []
        self._metadata_indices: list[MetadataIndex] = []
        stream.write(MAGIC)
        self._write(Header(profile=profile, library=library))

    def _write(self, record: McapRecord) -> int:
        """Write ``record`` to the file (outside any chunk); return its length in bytes."""
        builder = RecordBuilder()
        record.write(builder)
        data = _taken(builder)
        self.stream.write(data)
        return len(data)

    def register_schema(self, name: str, encoding: str, data: bytes) -> int:
        """Add a schema (into the open chunk, and the summary); return its id, from 1."""
        schema = Schema(id=len(self.schemas) + 1, name=name, encoding=encoding, data=data)
        self.schemas.append(schema)
        self.statistics.schema_count += 1
        schema.write(self.chunk)
        return schema.id

    def register_channel(self, topic: str, message_encoding: str, schema_id: int, metadata: Mapping[str, str]) -> int:
        """Add a channel (into the open chunk, and the summary); return its id, from 1."""
        channel = Channel(
            id=len(self.channels) + 1,
            topic=topic,
            message_encoding=message_encoding,
            schema_id=schema_id,
            metadata=dict(metadata),
        )
        self.channels.append(channel)
        self.statistics.channel_count += 1
        channel.write(self.chunk)
        return channel.id

    def add_metadata(self, name: str, data: Mapping[str, str]) -> None:
        """Write a Metadata record (outside the chunks) and index it."""
        offset = self.stream.tell()
        length = self._write(Metadata(name=name, metadata=dict(data)))
        self._metadata_indices.append(MetadataIndex(offset=offset, length=length, name=name))
        self.statistics.metadata_count += 1

    def add_message(self, channel_id: int, log_ns: int, data: bytes, publish_ns: int, sequence: int) -> None:
        """One message into the open chunk, which ends if that takes it over ``chunk_size``."""
        index = self.indices.get(channel_id)
        if index is None:
            index = self.indices[channel_id] = MessageIndex(channel_id=channel_id, records=[])
        index.records.append((log_ns, self.chunk.count))
        Message(channel_id=channel_id, sequence=sequence, log_time=log_ns, publish_time=publish_ns, data=data).write(
            self.chunk
        )
        self.statistics.channel_message_counts[channel_id] += 1
        self.took(1, log_ns, log_ns)
        self.maybe_end_chunk()

    def maybe_end_chunk(self) -> None:
        """End the open chunk if it holds more than ``chunk_size`` bytes of records."""
        if self.chunk.count > self.chunk_size:
            self.end_chunk()

    def took(self, count: int, first_ns: int, last_ns: int) -> None:
        """Count ``count`` messages, logged from ``first_ns`` to ``last_ns``, just written into :attr:`chunk`
        (per channel counts are the writer's to add to :attr:`statistics`)."""
        stats = self.statistics
        stats.message_start_time = first_ns if stats.message_count == 0 else min(stats.message_start_time, first_ns)
        stats.message_end_time = max(stats.message_end_time, last_ns)
        stats.message_count += count
        self.chunk_start_ns = first_ns if self.chunk_messages == 0 else min(self.chunk_start_ns, first_ns)
        self.chunk_end_ns = max(self.chunk_end_ns, last_ns)
        self.chunk_messages += count

    def end_chunk(self) -> None:
        """Compress the open chunk and write it, then its message indices (nothing if it holds no message:
        its schemas and channels stay for the next)."""
        if self.chunk_messages == 0:
            return
        data = _taken(self.chunk)
        packed = zstandard.compress(data)
        record = Chunk(
            compression='zstd',
            data=packed,
            message_start_time=self.chunk_start_ns,
            message_end_time=self.chunk_end_ns,
            uncompressed_crc=zlib.crc32(data),
            uncompressed_size=len(data),
        )
        start = self.stream.tell()
        length = self._write(record)
        offsets: dict[int, int] = {}
        at = start + length
        for channel_id, index in self.indices.items():
            offsets[channel_id] = at
            at += self._write(index)
        self._chunk_indices.append(
            ChunkIndex(
                message_start_time=self.chunk_start_ns,
                message_end_time=self.chunk_end_ns,
                chunk_start_offset=start,
                chunk_length=length,
                message_index_offsets=offsets,
                message_index_length=at - start - length,
                compression='zstd',
                compressed_size=len(packed),
                uncompressed_size=len(data),
            )
        )
        self.statistics.chunk_count += 1
        self.indices = {}
        self.chunk_messages = 0
        self.chunk_start_ns = self.chunk_end_ns = 0

    def flush(self) -> None:
        """End the open chunk and hand the file's bytes to the operating system."""
        self.end_chunk()
        self.stream.flush()

    def finish(self) -> None:
        """End the open chunk, write the data end, the summary (schemas, channels, statistics, chunk and
        metadata indices, their offsets) and the footer. The stream stays open."""
        self.end_chunk()
        self._write(DataEnd(data_section_crc=0))
        summary_start = self.stream.tell()
        summary = RecordBuilder()
        offsets: list[SummaryOffset] = []
        groups: list[tuple[Opcode, list[McapRecord]]] = [
            (Opcode.SCHEMA, list(self.schemas)),
            (Opcode.CHANNEL, list(self.channels)),
            (Opcode.STATISTICS, [self.statistics]),
            (Opcode.CHUNK_INDEX, list(self._chunk_indices)),
            (Opcode.ATTACHMENT_INDEX, []),
            (Opcode.METADATA_INDEX, list(self._metadata_indices)),
        ]
        for opcode, records in groups:
            group_start = summary.count
            for record in records:
                record.write(summary)
            offsets.append(
                SummaryOffset(
                    group_opcode=opcode,
                    group_start=summary_start + group_start,
                    group_length=summary.count - group_start,
                )
            )
        offset_start = summary_start + summary.count
        for offset in offsets:
            offset.write(summary)
        data = _taken(summary)
        crc = zlib.crc32(_FOOTER_HEAD.pack(Opcode.FOOTER, 20, summary_start, offset_start), zlib.crc32(data))
        self.stream.write(data)
        self._write(Footer(summary_start=summary_start, summary_offset_start=offset_start, summary_crc=crc))
        self.stream.write(MAGIC)
