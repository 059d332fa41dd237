"""Bag repair: rebuild ``metadata.yaml`` from the ``.mcap`` files, salvaging an unfinished one.

A SIGKILL of the writer leaves the finished segments whole and listed, and the open
segment without summary or footer (:mod:`folder_line.bag.writer`). :func:`repair` reads
that file up to its last complete chunk, rewrites it as a finished file and lists
every file again in a new ``metadata.yaml``.
"""

from __future__ import annotations

import os
import shutil
import struct
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.records import Channel, Message, Metadata, Schema
from mcap.stream_reader import StreamReader

from folder_line.bag.metadata import (
    KEY_COMPLETE,
    KEY_REPAIR,
    MCAP_METADATA_NAME,
    METADATA_FILE,
    FileSummary,
    MetadataBuilder,
    TopicSummary,
    read_metadata,
    segment_files,
)
from folder_line.bag.reader import open_each
from folder_line.bag.writer import start_mcap
from folder_line.errors import BagError, FolderLineError
from folder_line.files.atomic import write_text_atomic

__all__ = ['TRUNCATED_SUFFIX', 'RepairResult', 'repair', 'repair_bag', 'repairable']

#: added to the name of an unfinished file that repair replaced or set aside
TRUNCATED_SUFFIX = '.truncated'

# what the mcap reader raises on a file that ends early or has garbage at its end
_READ_ERRORS: tuple[type[BaseException], ...] = (
    McapError,
    EOFError,
    ValueError,
    struct.error,
    IndexError,
    KeyError,
    OSError,
)


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

    def note_metadata(self, record: Any) -> None:
        """Keep the bag's custom data if ``record`` (an MCAP metadata record) is folder_line's."""
        if record.name == MCAP_METADATA_NAME:
            self.custom = dict(record.metadata)


def _scan_finished(path: Path) -> _Scan | None:
    """The summary of a finished file (footer and statistics), or None if it has none."""
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
                scan.note_metadata(record)
            return scan
    except _READ_ERRORS:
        return None


def _salvage(path: Path) -> tuple[_Scan, list[Any], list[Any], int]:
    """Read an unfinished file record by record up to its first incomplete record.

    Returns the scan, the complete messages, the metadata records and the number of
    bytes read successfully.
    """
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
                    scan.note_metadata(record)
                good = fh.tell()
        except _READ_ERRORS:
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
    tmp = path.with_name(f'.{path.name}.salvage.tmp')
    with tmp.open('wb') as fh:
        writer = start_mcap(fh, role='repair')
        for record in metadata:
            writer.add_metadata(record.name, dict(record.metadata))
        schema_ids = {sid: writer.register_schema(s.name, s.encoding, s.data) for sid, s in scan.schemas.items()}
        channel_ids = {
            cid: writer.register_channel(c.topic, c.message_encoding, schema_ids.get(c.schema_id, 0), dict(c.metadata))
            for cid, c in scan.channels.items()
        }
        for m in messages:
            writer.add_message(channel_ids[m.channel_id], m.log_time, m.data, m.publish_time, m.sequence)
        writer.finish()  # type: ignore[no-untyped-call]  # mcap leaves Writer.finish unannotated (-> None)
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


def _old_custom(bag: Path) -> dict[str, str] | None:
    """``custom_data`` of the bag's old ``metadata.yaml``, or None if it cannot be read."""
    try:
        data = read_metadata(bag)
        custom = data['rosbag2_bagfile_information'].get('custom_data')
    except (FolderLineError, KeyError, TypeError, AttributeError):
        return None
    return {str(k): str(v) for k, v in custom.items()} if isinstance(custom, dict) else None


def repairable(directory: str | os.PathLike[str]) -> list[Path]:
    """The ``.mcap`` files :func:`repair` would read in ``directory``; ``BagError`` (nothing touched) if it is
    not a directory or holds none: not a bag."""
    bag = Path(directory)
    if not bag.is_dir():
        msg = f'{bag}: not a directory'
        raise BagError(msg)
    paths = segment_files(bag)
    if not paths:
        msg = f'{bag}: no .mcap files: not a rosbag2 bag in MCAP storage'
        raise BagError(msg)
    return paths


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
    bag = Path(directory)
    paths = repairable(bag)
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
    meta = MetadataBuilder()
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
    open_each(bag)
    return result


def repair_bag(directory: str | os.PathLike[str]) -> Path:
    """:func:`repair` and return the path of the rebuilt ``metadata.yaml``."""
    return repair(directory).metadata
