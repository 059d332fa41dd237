"""Bag repair: rebuild ``metadata.yaml`` from the ``.mcap`` files, salvaging what can be read, naming what cannot.

A SIGKILL of the writer leaves the finished segments whole and listed, and the open
segment without summary or footer (:mod:`folder_line.bag.writer`). :func:`repair` reads
every file chunk by chunk, each chunk checked against its CRC: an unfinished file is read up
to its last complete chunk, a chunk whose checksum fails is dropped, and such a file is
rewritten as a finished file of what is whole (the original kept beside it). Every file is
listed again in a new ``metadata.yaml``. What is lost in the middle of the bag -- a dropped
chunk, the tail of an unfinished file before the last, a segment file that is missing -- is
recorded as a gap of line time (:mod:`folder_line.bag.gaps`), and the bag is then
``repaired``, never ``complete``.
"""

from __future__ import annotations

import os
import re
import shutil
import struct
from dataclasses import dataclass, field
from pathlib import Path

from mcap.exceptions import McapError
from mcap.records import Channel, Chunk, Footer, McapRecord, Message, Metadata, Schema
from mcap.stream_reader import StreamReader, breakup_chunk

from folder_line.bag.gaps import KEY_GAPS, Gap, describe_gaps, format_gaps, merge_gaps, read_gaps
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
from folder_line.bag.segment import start_mcap
from folder_line.errors import BagError, FolderLineError
from folder_line.files.atomic import write_text_atomic

__all__ = ['DAMAGED_SUFFIX', 'TRUNCATED_SUFFIX', 'RepairResult', 'repair', 'repair_bag', 'repairable']

#: added to the name of an unfinished file that repair replaced or set aside
TRUNCATED_SUFFIX = '.truncated'
#: added to the name of a finished file with chunks whose checksum fails, which repair replaced
DAMAGED_SUFFIX = '.damaged'

_SEGMENT = re.compile(r'(.+)_(\d+)\.mcap')

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
    bad_chunks : dict of str to int
        File -> chunks dropped because their checksum fails (a finished file so damaged is
        rewritten too, the original kept as ``<file>.damaged``).
    missing : list of str
        Segment files missing between those present (by their ``_<i>`` numbers, or listed in
        the old ``metadata.yaml``).
    gaps : list of Gap
        Line time whose messages were lost, merged (:mod:`folder_line.bag.gaps`).
    unreadable : str
        The old ``metadata.yaml``'s gaps, when they could not be read (then not kept), else ''.
    """

    metadata: Path
    files: list[FileSummary] = field(default_factory=list)
    salvaged: dict[str, int] = field(default_factory=dict)
    dropped: dict[str, int] = field(default_factory=dict)
    removed: list[str] = field(default_factory=list)
    bad_chunks: dict[str, int] = field(default_factory=dict)
    missing: list[str] = field(default_factory=list)
    gaps: list[Gap] = field(default_factory=list)
    unreadable: str = ''

    def describe(self) -> str:
        """One line: what was listed, salvaged and dropped, and the gaps left."""
        parts = [f'{len(self.files)} files, {sum(f.count for f in self.files)} messages']
        for name, n in self.salvaged.items():
            if name in self.dropped:
                parts.append(f'{name} unfinished: salvaged {n} messages, dropped {self.dropped[name]} bytes')
        for name in self.removed:
            parts.append(f'{name} unfinished: nothing to salvage, dropped {self.dropped.get(name, 0)} bytes')
        for name, n in self.bad_chunks.items():
            parts.append(f'{name}: dropped {n} chunk{"s" if n > 1 else ""} whose checksum fails')
        if self.missing:
            parts.append('missing ' + ', '.join(self.missing))
        if self.gaps:
            parts.append(describe_gaps(self.gaps))
        if self.unreadable:
            parts.append(f'the old gaps could not be read, and were not kept: {self.unreadable}')
        if len(parts) == 1:
            parts.append('nothing dropped')
        return '; '.join(parts)


@dataclass
class _Scan:
    """Schemas, channels, counts and times of one ``.mcap`` file."""

    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    counts: dict[int, int] = field(default_factory=dict)
    start_ns: int = 0
    end_ns: int = 0
    custom: dict[str, str] | None = None

    @property
    def count(self) -> int:
        return sum(self.counts.values())

    def note_metadata(self, record: Metadata) -> None:
        """Keep the bag's custom data if ``record`` (an MCAP metadata record) is folder_line's."""
        if record.name == MCAP_METADATA_NAME:
            self.custom = dict(record.metadata)


@dataclass
class _Read:
    """One ``.mcap`` file read record by record, each chunk checked against its CRC."""

    scan: _Scan
    messages: list[Message]
    metadata: list[Metadata]
    good: int  # bytes read before the first record that could not be read
    finished: bool  # its footer was read
    lost: list[Gap]  # the log-time spans of the chunks whose checksum fails

    @property
    def damaged(self) -> bool:
        return not self.finished or bool(self.lost)


@dataclass
class _Tally:
    """What :func:`_read` takes of a file's records, one at a time (:meth:`take`)."""

    keep: bool
    scan: _Scan = field(default_factory=lambda: _Scan())
    messages: list[Message] = field(default_factory=list)
    metadata: list[Metadata] = field(default_factory=list)
    counts: dict[int, int] = field(default_factory=dict)
    spans: dict[int, tuple[int, int]] = field(default_factory=dict)  # channel id -> first and last log time

    def take(self, record: McapRecord) -> None:
        """Note a schema, channel or metadata record; count a message (kept if :attr:`keep`)."""
        if isinstance(record, Schema):
            self.scan.schemas[record.id] = record
        elif isinstance(record, Channel):
            self.scan.channels[record.id] = record
        elif isinstance(record, Message):
            cid, t = record.channel_id, record.log_time
            self.counts[cid] = self.counts.get(cid, 0) + 1
            first, last = self.spans.get(cid, (t, t))
            self.spans[cid] = (min(first, t), max(last, t))
            if self.keep:
                self.messages.append(record)
        elif isinstance(record, Metadata):
            self.metadata.append(record)
            self.scan.note_metadata(record)

    def result(self, good: int, finished: bool, lost: list[Gap]) -> _Read:
        """The file's :class:`_Read`: only what belongs to a channel it declares."""
        scan = self.scan
        messages = [m for m in self.messages if m.channel_id in scan.channels]
        scan.counts = {cid: n for cid, n in self.counts.items() if cid in scan.channels}
        known = [span for cid, span in self.spans.items() if cid in scan.channels]
        if known:
            scan.start_ns = min(first for first, _ in known)
            scan.end_ns = max(last for _, last in known)
        return _Read(scan, messages, self.metadata, good, finished, lost)


def _chunk_records(chunk: Chunk, lost: list[Gap]) -> list[McapRecord]:
    """The records of ``chunk``; none if its CRC fails, and then its log-time span is added to ``lost``."""
    try:
        return breakup_chunk(chunk, validate_crc=True)
    except _READ_ERRORS:
        lost.append(Gap(chunk.message_start_time, max(chunk.message_end_time, chunk.message_start_time)))
        return []


def _read(path: Path, keep: bool = False) -> _Read:
    """Every readable record of ``path`` up to its first unreadable one; a chunk whose CRC fails is
    skipped (its span noted), the records after it are read on. The messages are kept only if ``keep``
    (to rewrite a damaged file): an intact file is only counted, chunk by chunk."""
    tally = _Tally(keep)
    lost: list[Gap] = []
    good = 0
    finished = footer = False
    with path.open('rb') as fh:
        try:
            for record in StreamReader(fh, emit_chunks=True).records:
                if isinstance(record, Chunk):
                    for r in _chunk_records(record, lost):
                        tally.take(r)
                else:
                    tally.take(record)
                    footer = footer or isinstance(record, Footer)
                good = fh.tell()
            finished = footer  # and the magic after it read: the stream ended where it should
        except _READ_ERRORS:
            pass
    return tally.result(good, finished, lost)


def _rewrite(
    path: Path, scan: _Scan, messages: list[Message], metadata: list[Metadata], suffix: str = TRUNCATED_SUFFIX
) -> None:
    """Write the salvaged records as a finished file in place of ``path``; keep the original
    as ``<path><suffix>`` (hard link first, so that a crash in between loses nothing)."""
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
        writer.finish()
    keep = path.with_name(path.name + suffix)
    keep.unlink(missing_ok=True)
    try:
        os.link(path, keep)
    except OSError:
        shutil.copy2(path, keep)
    os.replace(tmp, path)
    # the channel ids of the rewritten file follow the order of scan.channels
    scan.channels = {channel_ids[cid]: c for cid, c in scan.channels.items()}
    scan.counts = {channel_ids[cid]: n for cid, n in scan.counts.items()}


def _old_metadata(bag: Path) -> tuple[dict[str, str] | None, dict[str, Gap]]:
    """``custom_data`` of the bag's old ``metadata.yaml`` (None if it cannot be read), and the log-time span
    of each file it lists (by name)."""
    try:
        info = read_metadata(bag)['rosbag2_bagfile_information']
        custom = info.get('custom_data')
    except (FolderLineError, KeyError, TypeError, AttributeError):
        return None, {}
    spans: dict[str, Gap] = {}
    try:
        for entry in info.get('files') or ():
            start = int(entry['starting_time']['nanoseconds_since_epoch'])
            spans[str(entry['path'])] = Gap(start, start + int(entry['duration']['nanoseconds']))
    except (KeyError, TypeError, ValueError, AttributeError):
        spans = {}
    return ({str(k): str(v) for k, v in custom.items()} if isinstance(custom, dict) else None), spans


def _missing(paths: list[Path], listed: dict[str, Gap]) -> list[str]:
    """Segment files absent between the first and the last present (``<name>_<i>.mcap``), and those the old
    metadata lists that are absent, in order."""
    present = {p.name for p in paths}
    out = [name for name in listed if name not in present]
    numbered = [(m.group(1), int(m.group(2))) for p in paths if (m := _SEGMENT.fullmatch(p.name))]
    for stem in {s for s, _ in numbered}:
        idx = sorted(i for s, i in numbered if s == stem)
        out += [f'{stem}_{i}.mcap' for i in range(0, idx[-1]) if i not in idx and f'{stem}_{i}.mcap' not in out]
    return sorted(set(out), key=_segment_key)


def _gaps(
    reads: list[tuple[Path, _Read]], missing: list[str], listed: dict[str, Gap], recorded: list[Gap]
) -> list[Gap]:
    """The line time lost: dropped chunks, the unread tail of an unfinished file before the last one with
    messages, and each missing file (its span from the old metadata, else the gap an earlier repair recorded
    between its neighbours, else all the time between them); and the gaps ``recorded`` already."""
    gaps = [g for _, r in reads for g in r.lost]
    spans = [(p.name, r.scan.start_ns, r.scan.end_ns) for p, r in reads if r.scan.count]
    order = {n: i for i, n in enumerate(sorted([*(p.name for p, _ in reads), *missing], key=_segment_key))}
    for path, r in reads:
        after = [s for n, s, _ in spans if order[n] > order[path.name]]
        if not r.finished and after:  # its tail is lost up to the next file's first message
            gaps.append(Gap(r.scan.end_ns + 1 if r.scan.count else 0, min(after) - 1))
    for name in missing:
        before = [e for n, _, e in spans if order[n] < order[name]]
        after = [s for n, s, _ in spans if order[n] > order[name]]
        if name in listed:
            gaps.append(listed[name])
        elif after:
            between = Gap(max(before) + 1 if before else 0, min(after) - 1)
            known = [g for g in recorded if between.first_ns <= g.first_ns and g.last_ns <= between.last_ns]
            gaps += known or [between]
    return merge_gaps(g for g in [*gaps, *recorded] if g.last_ns >= g.first_ns)


def _segment_key(name: str) -> tuple[int, str]:
    m = _SEGMENT.fullmatch(name)
    return (int(m.group(2)) if m else -1, name)


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


def _salvage(reads: list[tuple[Path, _Read]], result: RepairResult) -> list[tuple[Path, _Scan]]:
    """Rewrite each damaged file from what is whole (one with nothing whole is set aside), noting it in
    ``result``; the scans of the files the bag keeps, in order."""
    scans: list[tuple[Path, _Scan]] = []
    for path, r in reads:
        if r.damaged:
            if not r.finished:
                result.dropped[path.name] = path.stat().st_size - r.good
            if r.lost:
                result.bad_chunks[path.name] = len(r.lost)
            if not r.messages:
                os.replace(path, path.with_name(path.name + TRUNCATED_SUFFIX))
                result.removed.append(path.name)
                continue
            _rewrite(path, r.scan, r.messages, r.metadata, TRUNCATED_SUFFIX if not r.finished else DAMAGED_SUFFIX)
            result.salvaged[path.name] = len(r.messages)
        scans.append((path, r.scan))
    return scans


def _summaries(scans: list[tuple[Path, _Scan]]) -> tuple[dict[str, TopicSummary], MetadataBuilder]:
    """The topics of the files ``scans`` (their types and counts) and the files, for ``metadata.yaml``."""
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
    return topics, meta


def repair(directory: str | os.PathLike[str]) -> RepairResult:
    """Rebuild a bag's ``metadata.yaml`` from the ``.mcap`` files present; record what is lost.

    Every file is read chunk by chunk, each chunk checked against its CRC (:func:`_read`). A
    whole finished file is listed as it is. An unfinished file (no footer, as a SIGKILL leaves
    the open segment) is read up to its first incomplete record, and a chunk whose checksum
    fails is dropped: such a file is rewritten as a finished file of what is whole (the
    original kept as ``<file>.truncated``, or ``<file>.damaged`` for a finished one); one with
    nothing whole is renamed to ``<file>.truncated`` and not listed. ``custom_data`` comes from
    the old ``metadata.yaml`` if it is readable, else from the files' MCAP metadata records;
    ``folder_line.repair`` records what was done, ``folder_line.gaps`` the line time lost
    (:mod:`folder_line.bag.gaps`), and ``folder_line.complete`` is ``repaired`` unless the bag
    was closed by its writer and nothing is lost. The result is checked by opening the bag with
    rosbags.

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
    reads = [(path, _read(path)) for path in paths]
    reads = [(path, _read(path, keep=True) if r.damaged else r) for path, r in reads]  # to rewrite it
    if not any(r.scan.count or not r.damaged for _, r in reads):  # a whole file, even empty, is a bag
        msg = f'{bag}: none of the {len(paths)} .mcap files holds a readable message (nothing was changed)'
        raise BagError(msg)
    custom, listed = _old_metadata(bag)
    result.missing = _missing(paths, listed)
    try:
        recorded = read_gaps(custom or {})
    except BagError as err:  # named in folder_line.repair, not kept
        recorded, result.unreadable = [], str(err)
    result.gaps = _gaps(reads, result.missing, listed, recorded)
    scans = _salvage(reads, result)
    if custom is None:
        custom = next((dict(s.custom) for _, s in scans if s.custom is not None), {})
    topics, meta = _summaries(scans)
    result.files = list(meta.files)
    lossless = not (result.gaps or result.missing or result.bad_chunks)
    if not (custom.get(KEY_COMPLETE) == 'true' and lossless):
        custom[KEY_COMPLETE] = 'repaired'
    if result.gaps:  # a second repair keeps the first's
        custom[KEY_GAPS] = format_gaps(result.gaps)
    custom[KEY_REPAIR] = result.describe()
    write_text_atomic(result.metadata, meta.render(topics, custom))
    open_each(bag)
    return result


def repair_bag(directory: str | os.PathLike[str]) -> Path:
    """:func:`repair` and return the path of the rebuilt ``metadata.yaml``."""
    return repair(directory).metadata
