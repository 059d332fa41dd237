"""The bag reader: open a bag with rosbags, summarise it, iterate its messages, describe it.

Messages are deserialized by the rosbags typestore (ROS 2 kilted); no rclpy is needed.
"""

from __future__ import annotations

import contextlib
import json
import os
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rosbags.rosbag2 import Reader

from folder_line import __version__
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

__all__ = ['BagContents', 'bag_info_lines', 'check_version', 'open_reader', 'read_bag']


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
        with open_reader(self.path) as reader:
            wanted = [c for c in reader.connections if topics is None or c.topic in topics]
            if not wanted:
                return
            for conn, t_ns, raw in reader.messages(connections=wanted, start=start_ns, stop=stop_ns):
                yield conn.topic, t_ns, store.deserialize_cdr(raw, conn.msgtype)


@contextlib.contextmanager
def open_reader(path: Path) -> Iterator[Reader]:
    """``with open_reader(path) as reader``: a rosbags ``Reader``, opened; rosbags errors become BagError.

    Raises
    ------
    BagError
        rosbags cannot open the bag; the message names the path and rosbags' reason.
    """
    reader = Reader(path)
    try:
        reader.open()
    except Exception as exc:  # rosbags raises ReaderError, FileNotFoundError, KeyError ...
        msg = f'{reader.path}: cannot open the bag: {exc}'
        raise BagError(msg) from exc
    try:
        yield reader
    finally:
        reader.close()


def _relative_paths(directory: Path) -> list[str]:
    data = read_metadata(directory)
    return list(data['rosbag2_bagfile_information'].get('relative_file_paths') or [])


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
    """Open a bag directory with rosbags and summarise it.

    Raises
    ------
    BagError
        Not a directory, no ``metadata.yaml`` (``folder-line bag repair DIR`` rebuilds
        it), rosbags cannot open the bag, or a later folder_line wrote it (:func:`check_version`).
    """
    directory = Path(path)
    if not directory.is_dir():
        msg = f'{directory}: not a bag directory'
        raise BagError(msg)
    meta = directory / METADATA_FILE
    if not os.path.lexists(meta):
        msg = f'{directory}: no {METADATA_FILE}; rebuild it with: folder-line bag repair {directory}'
        raise BagError(msg)
    if not meta.is_file():
        msg = f'{meta}: {describe_path(meta)}, not a regular file'
        raise BagError(msg)
    data = read_metadata(directory)  # bounded, strict YAML before rosbags parses it
    if not isinstance(data, dict) or not isinstance(data.get('rosbag2_bagfile_information'), dict):
        msg = (
            f'{meta}: line 1, column 1: not rosbag2 metadata (a mapping with rosbag2_bagfile_information); '
            f'rebuild it with: folder-line bag repair {directory}'
        )
        raise BagError(msg)
    with open_reader(directory) as reader:
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
    check_version(directory, custom)
    return BagContents(
        path=directory, topics=topics, custom=custom, files=files, message_count=count, start_ns=start, end_ns=end
    )


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
