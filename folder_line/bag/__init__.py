"""rosbag2 bags in MCAP storage: the line's messages written in segments, read back, repaired.

One job per module, each importing only those before it:

- :mod:`~folder_line.bag.types`: the rosbags typestore of ROS 2 kilted, message
  definitions, CDR serialization of rclpy messages;
- :mod:`~folder_line.bag.metadata`: ``metadata.yaml`` (summaries, the YAML text, the
  ``custom_data`` keys) and the segment files' names;
- :mod:`~folder_line.bag.writer`: :class:`BagWriter`, the crash-safe segment writer;
- :mod:`~folder_line.bag.reader`: :func:`read_bag`, :class:`BagContents`, :func:`bag_info_lines`;
- :mod:`~folder_line.bag.repair`: :func:`repair`, which rebuilds ``metadata.yaml`` after a crash.

The names below are re-exported for users of the package; code inside folder_line imports
them from the module that defines them.
"""

from __future__ import annotations

from folder_line.bag.metadata import (
    KEY_COMPLETE,
    KEY_EFFECTS,
    KEY_PUBLISHED,
    KEY_REPAIR,
    KEY_SCENE,
    KEY_SCENE_NAME,
    KEY_SEGMENT_S,
    KEY_VERSION,
    METADATA_FILE,
    FileSummary,
    TopicSummary,
    segment_files,
)
from folder_line.bag.reader import BagContents, bag_info_lines, read_bag
from folder_line.bag.repair import RepairResult, repair, repair_bag
from folder_line.bag.types import msgtype_of, serialize
from folder_line.bag.writer import BagWriter
from folder_line.errors import BagError

__all__ = [
    'KEY_COMPLETE',
    'KEY_EFFECTS',
    'KEY_PUBLISHED',
    'KEY_REPAIR',
    'KEY_SCENE',
    'KEY_SCENE_NAME',
    'KEY_SEGMENT_S',
    'KEY_VERSION',
    'METADATA_FILE',
    'BagContents',
    'BagError',
    'BagWriter',
    'FileSummary',
    'RepairResult',
    'TopicSummary',
    'bag_info_lines',
    'msgtype_of',
    'read_bag',
    'repair',
    'repair_bag',
    'segment_files',
    'serialize',
]
