"""The bag reader: open a bag with rosbags, summarise it, iterate its messages, describe it.

Messages are deserialized by the rosbags typestore (ROS 2 kilted); no rclpy is needed.
"""

from __future__ import annotations

import contextlib
import json
import os
import shlex
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path, PurePath
from typing import Any

from rosbags.rosbag2 import Reader, ReaderError

from folder_line import __version__
from folder_line.bag.gaps import Gap, describe_gaps, read_gaps
from folder_line.bag.metadata import (
    KEY_COMPLETE,
    KEY_EFFECTS,
    KEY_PUBLISHED,
    KEY_SCENE,
    KEY_SCENE_NAME,
    KEY_VERSION,
    METADATA_FILE,
    TopicSummary,
    read_metadata,
)
from folder_line.bag.types import typestore
from folder_line.errors import BagError
from folder_line.files.atomic import describe_path
from folder_line.interfaces import NS_PER_S

__all__ = ['MCAP_MAGIC', 'BagContents', 'bag_info_lines', 'check_version', 'open_each', 'open_reader', 'read_bag']


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
        The storage files (``.mcap``), in order.
    message_count : int
        Messages in the bag.
    start_ns, end_ns : int
        Log times of the first and the last message, ns of line time (0, 0 if empty).
    spans : tuple of (int, int) or None
        Per file, the log times of its first and last message from ``metadata.yaml``
        (None where the metadata does not say): files outside a window are not opened.
    compressed : bool
        The bag is zstd-compressed (``compression_mode`` file or message): it is read
        through rosbags' directory reader, which opens every file at once.
    """

    path: Path
    topics: dict[str, TopicSummary]
    custom: dict[str, str]
    files: tuple[str, ...]
    message_count: int
    start_ns: int
    end_ns: int
    spans: tuple[tuple[int, int] | None, ...] = ()
    compressed: bool = False

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
    def gaps(self) -> list[Gap]:
        """Line time whose messages are lost, as a repair recorded it (:mod:`folder_line.bag.gaps`)."""
        return read_gaps(self.custom)

    @property
    def published(self) -> dict[str, int] | None:
        """Publisher-side counts per topic, or None if the writer did not know them."""
        text = self.custom.get(KEY_PUBLISHED)
        return None if text is None else {str(k): int(v) for k, v in json.loads(text).items()}

    def messages(
        self, topics: Sequence[str] | None = None, start_ns: int | None = None, stop_ns: int | None = None
    ) -> Iterator[tuple[str, int, Any]]:
        """``(topic, log time ns, message)`` in file order and, within a file, log-time order.

        Messages are deserialized by the rosbags typestore (ROS 2 kilted): dataclasses
        with the fields of the ROS message, float arrays as numpy arrays; no rclpy needed.
        One message at a time: memory does not grow with the bag. ``start_ns`` and
        ``stop_ns`` (log times, ns; ``stop_ns`` excluded) bound the messages read.
        """
        store = typestore()
        for topic, msgtype, t_ns, raw in self.raw_messages(topics, start_ns, stop_ns):
            yield topic, t_ns, store.deserialize_cdr(raw, msgtype)

    def raw_messages(
        self, topics: Sequence[str] | None = None, start_ns: int | None = None, stop_ns: int | None = None
    ) -> Iterator[tuple[str, str, int, bytes]]:
        """``(topic, type, log time ns, CDR bytes)``, as :meth:`messages` without deserializing.

        The files are opened one at a time, and a file the metadata places outside
        ``[start_ns, stop_ns)`` is not opened: an hour's bag is 3600 files, more than the
        usual limit of 1024 open files, and each open file holds its index in memory.

        Raises
        ------
        BagError
            A file cannot be opened (named, with rosbags' reason).
        """
        if self.compressed:
            yield from _raw_of(self.path, topics, start_ns, stop_ns)
            return
        for name, span in zip(self.files, self.spans or (None,) * len(self.files), strict=True):
            if span is not None and (
                (stop_ns is not None and span[0] >= stop_ns) or (start_ns is not None and span[1] < start_ns)
            ):
                continue
            yield from _raw_of(self.path / name, topics, start_ns, stop_ns)


def _raw_of(
    path: Path, topics: Sequence[str] | None, start_ns: int | None, stop_ns: int | None
) -> Iterator[tuple[str, str, int, bytes]]:
    """The raw messages of one storage file (or of a compressed bag directory)."""
    with open_reader(path) as reader:
        wanted = [c for c in reader.connections if topics is None or c.topic in topics]
        if not wanted:
            return
        messages = reader.messages(connections=wanted, start=start_ns, stop=stop_ns)
        while True:
            try:
                conn, t_ns, raw = next(messages)
            except StopIteration:
                return
            except ReaderError as exc:  # a chunk whose checksum fails, a record cut short
                bag = path if path.is_dir() else path.parent
                msg = (
                    f'{path}: cannot read on: {exc} '.replace('\n', ' ')
                    + f'(the file is damaged; folder-line bag repair {shlex.quote(str(bag))} drops what cannot be '
                    'read and records the line time lost)'
                )
                raise BagError(msg) from exc
            yield conn.topic, conn.msgtype, t_ns, raw


@contextlib.contextmanager
def open_reader(path: Path) -> Iterator[Reader]:
    """``with open_reader(path) as reader``: a rosbags ``Reader`` of one storage file (or of a bag
    directory: every file opened at once), opened; rosbags errors become BagError.

    Raises
    ------
    BagError
        rosbags cannot open the bag; the message names the path and rosbags' reason.
    """
    reader = Reader(path)
    try:
        reader.open()
    except Exception as exc:  # rosbags raises ReaderError, FileNotFoundError, KeyError ...
        msg = f'{reader.path}: cannot open the bag: {exc}'.replace('\n', ' ')
        raise BagError(msg) from exc
    try:
        yield reader
    finally:
        reader.close()


def _release(version: str) -> tuple[int, int] | None:
    """``(major, minor)`` of a version ``'0.1.0'``; None if it is not one."""
    parts = version.strip().split('.')
    if len(parts) < 2 or not all(p.isdigit() for p in parts[:2]):
        return None
    return int(parts[0]), int(parts[1])


def check_version(directory: Path, custom: dict[str, str]) -> None:
    """Refuse a bag written by a folder_line this one cannot read: a later release (major, minor), or a
    version that is not one. A bag without the key (another recorder's) is read as it is.

    Raises
    ------
    BagError
        The message names the bag, the version it records and the versions read.
    """
    version = custom.get(KEY_VERSION)
    if version is None:
        return
    ours = _release(__version__)
    theirs = _release(version)
    if theirs is None or ours is None or theirs > ours:
        msg = (
            f'{directory}: written by folder_line {version!r} ({KEY_VERSION}); this folder_line {__version__} '
            f'reads bags of versions up to {__version__}'
        )
        raise BagError(msg)


def read_bag(path: str | os.PathLike[str]) -> BagContents:
    """Summarise a bag directory from its ``metadata.yaml``, and check its files.

    No file is kept open: :meth:`BagContents.messages` opens one file at a time. Each
    storage file must exist, and an MCAP file must start and end with the MCAP magic (a
    file cut short by a killed writer does not end with it).

    Raises
    ------
    BagError
        Not a directory, no ``metadata.yaml`` (``folder-line bag repair <directory>`` rebuilds
        it), metadata rosbags would not read, a missing or cut file, or a later
        folder_line wrote it (:func:`check_version`).
    """
    directory = Path(path)
    if not directory.is_dir():
        msg = f'{directory}: not a bag directory'
        raise BagError(msg)
    meta = directory / METADATA_FILE
    if not os.path.lexists(meta):
        if not any(directory.glob('*.mcap')):  # nothing a repair could rebuild the metadata from
            msg = f'{directory}: not a bag: no {METADATA_FILE} and no .mcap files'
            raise BagError(msg)
        msg = f'{directory}: no {METADATA_FILE}; rebuild it with: folder-line bag repair {shlex.quote(str(directory))}'
        raise BagError(msg)
    if not meta.is_file():
        msg = f'{meta}: {describe_path(meta)}, not a regular file'
        raise BagError(msg)
    data = read_metadata(directory)  # bounded, strict YAML before rosbags parses it
    if not isinstance(data, dict) or not isinstance(data.get('rosbag2_bagfile_information'), dict):
        msg = (
            f'{meta}: line 1, column 1: not rosbag2 metadata (a mapping with rosbag2_bagfile_information); '
            f'rebuild it with: folder-line bag repair {shlex.quote(str(directory))}'
        )
        raise BagError(msg)
    contents = _summarise(directory, data['rosbag2_bagfile_information'])
    check_version(directory, contents.custom)
    for name in contents.files:
        _check_file(directory, name)
    return contents


def open_each(directory: Path) -> None:
    """Open every storage file of the bag ``directory`` with rosbags, one at a time (what
    :func:`read_bag` does not do, for speed): a check that every file's summary and index read.

    Raises
    ------
    BagError
        Metadata rosbags would not read, or a file rosbags cannot open, named with rosbags' reason.
    """
    contents = _summarise(directory, read_metadata(directory)['rosbag2_bagfile_information'])
    if contents.compressed:
        with open_reader(contents.path):
            return
    for name in contents.files:
        with open_reader(contents.path / name):
            pass


#: the magic an MCAP file starts and ends with (a file cut short lacks the second)
MCAP_MAGIC = b'\x89MCAP0\r\n'


def _topics(entries: list[Any], refuse: Callable[[str], BagError]) -> dict[str, TopicSummary]:
    """The topics of ``metadata.yaml``'s ``topics_with_message_count`` (a topic listed twice: counts added);
    ``refuse(why)`` for a serialization other than CDR."""
    topics: dict[str, TopicSummary] = {}
    for entry in entries:
        tm = entry['topic_metadata']
        if str(tm.get('serialization_format', 'cdr')) != 'cdr':
            raise refuse(f'topic {tm["name"]}: serialization {tm["serialization_format"]!r}, not cdr')
        old = topics.get(str(tm['name']))
        topics[str(tm['name'])] = TopicSummary(
            old.type if old else str(tm['type']),
            (old.count if old else 0) + int(entry['message_count']),
            old.type_hash if old else str(tm.get('type_description_hash', '') or ''),
        )
    return topics


def _summarise(directory: Path, info: dict[str, Any]) -> BagContents:
    """:class:`BagContents` from the ``rosbag2_bagfile_information`` of ``metadata.yaml``.

    The checks are rosbags' own (``DirectoryReader.open``), made here so that no file is
    opened: a version up to 9, MCAP or SQLite storage, CDR serialization.

    Raises
    ------
    BagError
        A key is missing or malformed, or the bag is of a kind rosbags does not read.
    """
    meta = directory / METADATA_FILE

    def refuse(why: str) -> BagError:
        return BagError(f'{meta}: {why}; rebuild it with: folder-line bag repair {shlex.quote(str(directory))}')

    try:
        version = int(info['version'])
        storage = str(info['storage_identifier'])
        mode = str(info.get('compression_mode') or '').lower()
        names = tuple(PurePath(str(x)).name for x in info['relative_file_paths'] or [])
        topics = _topics(info['topics_with_message_count'] or [], refuse)
        count = int(info['message_count'])
        start = int(info['starting_time']['nanoseconds_since_epoch'])
        duration = int(info['duration']['nanoseconds'])
        custom = {str(k): str(v) for k, v in (info.get('custom_data') or {}).items()}
        spans: dict[str, tuple[int, int]] = {}
        for entry in info.get('files') or []:
            first = int(entry['starting_time']['nanoseconds_since_epoch'])
            spans[PurePath(str(entry['path'])).name] = (first, first + int(entry['duration']['nanoseconds']))
    except BagError:
        raise
    except KeyError as exc:
        raise refuse(f'the key {exc} is missing') from None
    except (TypeError, ValueError, AttributeError) as exc:
        raise refuse(f'malformed: {exc}') from None
    if version > 9:
        raise refuse(f'rosbag2 metadata version {version}; versions up to 9 are read')
    if storage not in ('mcap', 'sqlite3'):
        raise refuse(f'storage {storage!r}; mcap and sqlite3 are read')
    compressed = mode not in ('', 'none')
    if compressed and str(info.get('compression_format') or '') != 'zstd':
        raise refuse(f'compression {info.get("compression_format")!r}; zstd is read')
    return BagContents(
        path=directory,
        topics=topics,
        custom=custom,
        files=names,
        message_count=count,
        start_ns=start if count else 0,
        end_ns=start + duration if count else 0,
        spans=tuple(spans.get(name) for name in names),
        compressed=compressed,
    )


def _check_file(directory: Path, name: str) -> None:
    """Refuse a storage file that is missing, not a regular file, or an MCAP file cut short.

    Raises
    ------
    BagError
        Naming the file; for a cut file, how to salvage the bag.
    """
    path = directory / name
    if not path.is_file():
        what = 'missing' if not os.path.lexists(path) else f'{describe_path(path)}, not a regular file'
        msg = f'{path}: cannot open the bag: the file is {what}'
        raise BagError(msg)
    if path.suffix != '.mcap':
        return
    size = path.stat().st_size
    with path.open('rb') as fh:
        head = fh.read(len(MCAP_MAGIC))
        fh.seek(max(size - len(MCAP_MAGIC), 0))
        tail = fh.read(len(MCAP_MAGIC))
    if head != MCAP_MAGIC:
        msg = f'{path}: cannot open the bag: not an MCAP file'
        raise BagError(msg)
    if size < 2 * len(MCAP_MAGIC) or tail != MCAP_MAGIC:
        msg = (
            f'{path}: cannot open the bag: the file is cut short (no closing MCAP magic); '
            f'salvage what it holds with: folder-line bag repair {shlex.quote(str(directory))}'
        )
        raise BagError(msg)


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
        f'are whole, the rest is salvaged by: folder-line bag repair {shlex.quote(str(contents.path))}',
        'repaired': 'repaired after its writer stopped (see folder_line.repair)',
    }.get(state or '', 'not recorded (written before folder_line.complete existed)')
    gaps = contents.gaps
    if gaps:
        state_text = (
            f'repaired with {describe_gaps(gaps)} of line time: messages were lost there (see folder_line.repair)'
        )
    lines = [
        f'bag        {contents.path}',
        f'state      {state_text}',
        f'files      {len(contents.files)} ({names})',
        f'line time  {span}',
        *(
            f'gap        {g.first_ns / NS_PER_S:.3f} .. {g.last_ns / NS_PER_S:.3f} s ({g.seconds:.3f} s): '
            'analyze judges no cycle across it'
            for g in gaps[:10]
        ),
        f'messages   {contents.message_count}',
        'topics:',
    ]
    published = contents.published
    span_s = contents.duration_ns / NS_PER_S
    lines.append(f'  {"topic":<40} {"type":<36} {"messages":>9} {"rate, 1/s":>10}')
    for name, t in contents.topics.items():
        extra = '' if published is None else f'  (published {published.get(name, "?")})'
        rate = f'{t.count / span_s:10.4g}' if span_s > 0 else f'{"-":>10}'
        lines.append(f'  {name:<40} {t.type:<36} {t.count:>9} {rate}{extra}')
    lines.append("  (rate: messages per second of line time over the bag's span)")
    lines.append('custom data:')
    for key, value in contents.custom.items():
        rows = value.splitlines() or ['']
        more = f'  ... ({len(rows)} lines)' if len(rows) > 1 else ''
        lines.append(f'  {key}: {rows[0][:100]}{more}')
    return lines
