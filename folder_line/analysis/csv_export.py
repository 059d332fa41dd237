"""The messages of a bag as CSV: one file per topic, one row per message (``folder-line analyze --csv``).

:func:`flatten_message` turns a message (as rosbags decodes it) into columns;
:class:`CsvCollector` is handed every message while the bag is read
(:func:`folder_line.analysis.recording.read_recording`'s ``on_message``) and writes
``<topic>.csv`` files (:func:`csv_name`) atomically.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.typesys import Stores, get_typestore

from folder_line.files.atomic import check_output_file, write_csv_atomic

__all__ = ['CsvCollector', 'csv_name', 'flatten_message']


@functools.lru_cache(maxsize=64)
def _field_names(msgtype: str) -> tuple[str, ...]:
    """The fields of a message type (constants excluded), from the rosbags typestore."""
    store = get_typestore(Stores.ROS2_KILTED)
    return tuple(name for name, _ in store.fielddefs[msgtype][1])


def _is_message(value: Any) -> bool:
    return hasattr(value, '__msgtype__') and dataclasses.is_dataclass(value)


def _join(prefix: str, name: str) -> str:
    return f'{prefix}.{name}' if prefix else name


def _flatten(value: Any, prefix: str, out: dict[str, Any]) -> None:
    if _is_message(value):
        mt = value.__msgtype__
        if mt == 'sensor_msgs/msg/JointState':
            joints = [str(n) for n in value.name]
            for name in _field_names(mt):
                data = getattr(value, name)
                if name == 'name':
                    continue
                if name in ('position', 'velocity', 'effort') and joints and len(data) == len(joints):
                    for joint, x in zip(joints, np.asarray(data).tolist(), strict=True):
                        out[_join(_join(prefix, name), joint)] = x
                else:
                    _flatten(data, _join(prefix, name), out)
            return
        for name in _field_names(mt):
            _flatten(getattr(value, name), _join(prefix, name), out)
        return
    if isinstance(value, np.ndarray):
        for i, x in enumerate(value.reshape(-1).tolist()):
            out[f'{prefix}[{i}]'] = x
        return
    if isinstance(value, (list, tuple)):
        if value and all(_is_message(v) and v.__msgtype__ == 'diagnostic_msgs/msg/KeyValue' for v in value):
            for kv in value:
                out[_join(prefix, str(kv.key))] = kv.value
            return
        for i, v in enumerate(value):
            _flatten(v, f'{prefix}[{i}]', out)
        return
    out[prefix or 'data'] = value


def flatten_message(msg: Any) -> dict[str, Any]:
    """A bag message (rosbags) as ``{column: scalar}``.

    Nested fields are joined with ``.`` (``header.stamp.sec``), sequences indexed
    (``status[0].level``); joint states are named by joint (``position.knife_crank``;
    the ``name`` list itself is dropped) and ``diagnostic_msgs/KeyValue`` lists by key
    (``status[0].values.margin``).
    """
    out: dict[str, Any] = {}
    _flatten(msg, '', out)
    return out


def csv_name(topic: str) -> str:
    """File name of a topic's CSV: ``/line/crank_drive/joint_states`` -> ``line__crank_drive__joint_states.csv``."""
    return topic.strip('/').replace('/', '__') + '.csv'


class CsvCollector:
    """Rows of every topic, flattened (:func:`flatten_message`); written one CSV per topic.

    Call it with ``(topic, log time ns, message)`` for every message, then :meth:`write`.
    """

    def __init__(self) -> None:
        self.rows: dict[str, list[dict[str, Any]]] = {}

    def __call__(self, topic: str, t_ns: int, msg: Any) -> None:
        row = {'log_time_ns': int(t_ns)}
        row.update(flatten_message(msg))
        self.rows.setdefault(topic, []).append(row)

    @staticmethod
    def check(directory: Path, topics: Sequence[str], option: str) -> None:
        """Refuse (OutputError naming ``option``) if any topic's CSV cannot be written in ``directory``."""
        for topic in topics:
            check_output_file(directory / csv_name(topic), option)

    def write(self, directory: Path, topics: Sequence[str]) -> dict[str, Path]:
        """Write ``<directory>/<csv_name(topic)>`` for each of ``topics`` (a header only where none was
        recorded); topic -> the file written."""
        written: dict[str, Path] = {}
        for topic in topics:
            rows = self.rows.get(topic, [])
            names: dict[str, None] = {'log_time_ns': None}
            for row in rows:
                names.update(dict.fromkeys(row))
            columns = {name: [row.get(name, '') for row in rows] for name in names}
            written[topic] = write_csv_atomic(directory / csv_name(topic), columns)
        return written
