"""A bag's ``metadata.yaml`` and file layout: summaries, the YAML text, the ``.mcap`` files.

A bag directory ``DIR`` is a rosbag2 bag, metadata version 9, storage ``mcap``::

    DIR/metadata.yaml    rosbag2 metadata: topics with types and counts, the files
                         (start, duration, count each), custom_data (see below)
    DIR/DIR_0.mcap       the messages (all of them, unless the bag is split)
    DIR/DIR_1.mcap       a split bag's next file, and so on

Each ``.mcap`` file carries the bag's custom data again as an MCAP metadata record
named ``folder_line`` (:data:`MCAP_METADATA_NAME`), so that
:func:`folder_line.bag.repair.repair` can restore it without ``metadata.yaml``.

``custom_data`` (rosbag2 allows strings only): ``folder_line.scene`` (the complete
scene as YAML), ``folder_line.scene_name``, ``folder_line.effects`` (JSON list),
``folder_line.version``, ``folder_line.max_bag_duration`` (s) and
``folder_line.max_bag_size`` (bytes; each 0 when the bag is not split so), any extra keys given to the
writer, ``folder_line.published`` (JSON ``{topic: count}``, publisher-side counts,
written at close when known), ``folder_line.repair`` (what
:func:`~folder_line.bag.repair.repair` did) and ``folder_line.complete`` (``false`` while
the writer has the bag open -- so a bag left by a crash or a failed write is marked
partial --, ``true`` once closed, ``repaired`` after :func:`~folder_line.bag.repair.repair`).
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from folder_line.bag.types import ROS_DISTRO
from folder_line.files.json_types import JsonObject
from folder_line.files.yamlio import METADATA_LIMIT, load_yaml_file

__all__ = [
    'KEY_COMPLETE',
    'KEY_EFFECTS',
    'KEY_MAX_BAG_DURATION',
    'KEY_MAX_BAG_SIZE',
    'KEY_PUBLISHED',
    'KEY_REPAIR',
    'KEY_SCENE',
    'KEY_SCENE_NAME',
    'KEY_VERSION',
    'MCAP_METADATA_NAME',
    'METADATA_FILE',
    'FileSummary',
    'MetadataBuilder',
    'TopicSummary',
    'files_text',
    'read_metadata',
    'segment_files',
    'segment_path',
]

ROSBAG2_VERSION = 9
STORAGE_ID = 'mcap'
METADATA_FILE = 'metadata.yaml'
#: name of the MCAP metadata record that carries the custom data in every ``.mcap`` file
MCAP_METADATA_NAME = 'folder_line'

KEY_SCENE = 'folder_line.scene'
KEY_SCENE_NAME = 'folder_line.scene_name'
KEY_EFFECTS = 'folder_line.effects'
KEY_VERSION = 'folder_line.version'
KEY_MAX_BAG_DURATION = 'folder_line.max_bag_duration'
KEY_MAX_BAG_SIZE = 'folder_line.max_bag_size'
KEY_PUBLISHED = 'folder_line.published'
KEY_REPAIR = 'folder_line.repair'
#: ``'false'`` while the writer has the bag open, ``'true'`` once it closed it, ``'repaired'`` after repair
KEY_COMPLETE = 'folder_line.complete'

_SPLIT = re.compile(r'_(\d+)\.mcap$')
#: a file name YAML writes as it is (a plain scalar that reads back as this string)
_PLAIN = re.compile(r'[A-Za-z_][A-Za-z0-9_.\-]{0,60}\.mcap\Z')


@dataclass(frozen=True)
class FileSummary:
    """One finished ``.mcap`` file of a bag.

    Attributes
    ----------
    path : str
        File name, relative to the bag directory.
    start_ns, end_ns : int
        Log times of its first and last message, ns of line time (0 and 0 if empty).
    count : int
        Messages in the file.
    """

    path: str
    start_ns: int
    end_ns: int
    count: int

    def entry(self) -> JsonObject:
        """The file's entry of ``files`` in ``metadata.yaml``."""
        return {
            'path': self.path,
            'starting_time': {'nanoseconds_since_epoch': self.start_ns},
            'duration': {'nanoseconds': self.end_ns - self.start_ns},
            'message_count': self.count,
        }


@dataclass(frozen=True)
class TopicSummary:
    """A topic of a bag: its message type, RIHS01 type hash and message count."""

    type: str
    count: int
    type_hash: str = ''


class _Dumper(yaml.SafeDumper):
    """Safe YAML with multi-line strings (the scene) as literal blocks where YAML allows it."""


def _str_representer(dumper: yaml.SafeDumper, data: str) -> yaml.Node:
    return dumper.represent_scalar('tag:yaml.org,2002:str', data, style='|' if '\n' in data else None)


_Dumper.add_representer(str, _str_representer)


def _dump(document: object, indent: int) -> str:
    text = yaml.dump(document, Dumper=_Dumper, sort_keys=False, default_flow_style=False, allow_unicode=True)
    pad = ' ' * indent
    return ''.join(pad + line if line.strip() else line for line in text.splitlines(keepends=True))


class MetadataBuilder:
    """Builds ``metadata.yaml``; each finished file's entry is rendered once, so that rewriting
    the metadata at every rollover stays cheap however many segments the bag has.

    Attributes
    ----------
    files : list of FileSummary
        The files added so far, in order.
    """

    def __init__(self) -> None:
        self.files: list[FileSummary] = []
        self._paths: list[str] = []
        self._entries: list[str] = []

    def add_file(self, summary: FileSummary) -> None:
        """List one more finished file (after the ones already added)."""
        self.files.append(summary)
        if _PLAIN.match(summary.path):  # what yaml writes, without its cost (a bag has thousands of files)
            self._paths.append(f'  - {summary.path}\n')
            self._entries.append(
                f'  - path: {summary.path}\n'
                f'    starting_time:\n      nanoseconds_since_epoch: {int(summary.start_ns)}\n'
                f'    duration:\n      nanoseconds: {int(summary.end_ns - summary.start_ns)}\n'
                f'    message_count: {int(summary.count)}\n'
            )
        else:
            self._paths.append(_dump([summary.path], 2))
            self._entries.append(_dump([summary.entry()], 2))

    def render(self, topics: Mapping[str, TopicSummary], custom: Mapping[str, str]) -> str:
        """The text of ``metadata.yaml`` for the files added, ``topics`` and ``custom`` (``custom_data``)."""
        counted = [f for f in self.files if f.count]
        start = min((f.start_ns for f in counted), default=0)
        end = max((f.end_ns for f in counted), default=0)
        head = {
            'version': ROSBAG2_VERSION,
            'storage_identifier': STORAGE_ID,
            'duration': {'nanoseconds': end - start},
            'starting_time': {'nanoseconds_since_epoch': start},
            'message_count': sum(f.count for f in self.files),
            'topics_with_message_count': [
                {
                    'topic_metadata': {
                        'name': name,
                        'type': t.type,
                        'serialization_format': 'cdr',
                        'offered_qos_profiles': [],
                        'type_description_hash': t.type_hash,
                    },
                    'message_count': t.count,
                }
                for name, t in topics.items()
            ],
            'compression_format': '',
            'compression_mode': '',
            'custom_data': dict(custom),
            'ros_distro': ROS_DISTRO,
        }
        parts = ['rosbag2_bagfile_information:\n', _dump(head, 2)]
        parts.append('  relative_file_paths:\n' if self._paths else '  relative_file_paths: []\n')
        parts.extend(self._paths)
        parts.append('  files:\n' if self._entries else '  files: []\n')
        parts.extend(self._entries)
        return ''.join(parts)


def read_metadata(directory: Path) -> Any:  # Any: the document as read, judged where it is used
    """``metadata.yaml`` of the bag ``directory``, parsed.

    Read by :func:`folder_line.files.yamlio.load_yaml_file` (size, aliases, tags and
    duplicate keys bounded).

    Raises
    ------
    folder_line.errors.ParameterError
        The file cannot be read or is not the YAML we accept; the message names the line and column.
    """
    return load_yaml_file(directory / METADATA_FILE, 'bag metadata', METADATA_LIMIT, max_nodes=1_000_000)


def segment_path(directory: Path, index: int) -> Path:
    """The ``index``-th ``.mcap`` file of the bag ``directory``: ``DIR/DIR_<index>.mcap``."""
    return directory / f'{directory.name}_{index}.mcap'


def files_text(n: int) -> str:
    """``'1 .mcap file'``, ``'3 .mcap files'``: how many files a bag has, for a line of output."""
    return f'{n} .mcap file' + ('' if n == 1 else 's')


def segment_files(directory: str | os.PathLike[str]) -> list[Path]:
    """The ``.mcap`` files of a bag directory in split order (``<name>_<i>.mcap`` by ``i``)."""

    def key(path: Path) -> tuple[int, str]:
        m = _SPLIT.search(path.name)
        return (int(m.group(1)) if m else -1, path.name)

    return sorted((p for p in Path(directory).glob('*.mcap') if p.is_file()), key=key)
