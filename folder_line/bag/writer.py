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
(:class:`~folder_line.bag.tick_messages.TickMessages`: the records built with numpy, straight into the
open chunk), the same files byte for byte as :meth:`~BagWriter.write_many` tick by tick (``simulate --bag``).

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
from collections.abc import Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from folder_line import __version__
from folder_line.bag.metadata import (
    KEY_COMPLETE,
    KEY_EFFECTS,
    KEY_MAX_BAG_DURATION,
    KEY_MAX_BAG_SIZE,
    KEY_PUBLISHED,
    KEY_SCENE,
    KEY_SCENE_NAME,
    KEY_VERSION,
    METADATA_FILE,
    FileSummary,
    MetadataBuilder,
    TopicSummary,
    segment_path,
)
from folder_line.bag.segment import DEFAULT_CHUNK_SIZE, Segment
from folder_line.bag.tick_messages import TickMessages
from folder_line.bag.types import message_definition, msgtype_of, serialize
from folder_line.errors import BagError
from folder_line.files.atomic import write_text_atomic
from folder_line.interfaces import CLOCK_TOPIC, NS_PER_S, stamp_ns

__all__ = ['BagWriter']

#: a line time no bag reaches, ns: the split time of a bag not split by time
_NEVER = 2**63 - 1


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
        self._segment: Segment | None = self._open_segment(0)

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

    def _segment_at(self, log_ns: int) -> Segment:
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

    def _split_before(self, segment: Segment, log_ns: int) -> int:
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

    def _open_segment(self, index: int) -> Segment:
        segment = Segment(segment_path(self.path, index), self.chunk_size, self.custom, self.flush_ns)
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
