"""The messages of a bag as CSV: one file per topic (``folder-line analyze --csv``), streamed.

Every file begins with ``t``: the message's log time in the bag (its tick), s of line
time, as a float. Every other column is a field of the message (nested fields joined with
``.``), with three readings that make the tables usable as they are:

- a time (``builtin_interfaces/Time``: ``header.stamp``, ``time_ref``, ``clock``) is one
  column in seconds (float), not ``sec`` and ``nanosec``;
- ``/line/events``: the event's ``source`` is parsed
  (:func:`folder_line.interfaces.parse_event_source`) into ``kind, sheet, cycle, value``
  columns (a source that is not an event: ``kind`` empty, the text in ``source``);
- ``/diagnostics``: one row per status (``t, header.stamp, name, level, message,
  hardware_id``), its key/values as one column each (``values.<key>``, empty where a
  status lacks the key) -- not one very wide row per array;
- joint states: one column per joint and quantity (``position.knife_crank``).

:class:`CsvCollector` is handed every message while the bag is read
(:func:`folder_line.analysis.recording.read_recording`'s ``on_message``). It spools the
rows of each topic to a temporary file (JSON lines) as they come, keeping only the column
names in memory, and :meth:`CsvCollector.write` then streams each topic's rows into its
``<topic>.csv`` (:func:`csv_name`) atomically: memory stays bounded however long the bag.
"""

from __future__ import annotations

import csv
import dataclasses
import functools
import io
import json
import tempfile
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any, TypeAlias

import numpy as np
from rosbags.typesys import Stores, get_typestore

from folder_line.files.atomic import check_output_file, write_chunks_atomic
from folder_line.interfaces import DIAGNOSTICS_TOPIC, EVENTS_TOPIC, NS_PER_S, parse_event_source

if TYPE_CHECKING:  # the message classes of the typestore the bags are read with (folder_line.bag.types)
    from rosbags.typesys.stores.ros2_kilted import builtin_interfaces__msg__Time as Time

__all__ = ['CsvCollector', 'Row', 'csv_name', 'flatten_message', 'message_rows']

#: a row of a CSV: column -> a scalar of the message (a number, a string), or of its parsed event
Row: TypeAlias = dict[str, object]

_TIME = 'builtin_interfaces/msg/Time'
#: rows written per chunk of a CSV file
_CHUNK_ROWS = 4096


@functools.lru_cache(maxsize=64)
def _field_names(msgtype: str) -> tuple[str, ...]:
    """The fields of a message type (constants excluded), from the rosbags typestore."""
    store = get_typestore(Stores.ROS2_KILTED)
    return tuple(name for name, _ in store.fielddefs[msgtype][1])


def _is_message(value: object) -> bool:
    return hasattr(value, '__msgtype__') and dataclasses.is_dataclass(value)


def _join(prefix: str, name: str) -> str:
    return f'{prefix}.{name}' if prefix else name


def _seconds(stamp: Time) -> float:
    return (int(stamp.sec) * NS_PER_S + int(stamp.nanosec)) / NS_PER_S


def _flatten(value: Any, prefix: str, out: Row) -> None:
    """Add ``value``'s columns, named under ``prefix``, to ``out`` (see :func:`flatten_message`).

    ``value`` is a message or a field of one, of any type: read by its definition's names.
    """
    if _is_message(value):
        _flatten_message(value, prefix, out)
    elif isinstance(value, np.ndarray):
        for i, x in enumerate(value.reshape(-1).tolist()):
            out[f'{prefix}[{i}]'] = x
    elif isinstance(value, (list, tuple)):
        _flatten_sequence(value, prefix, out)
    else:
        out[prefix or 'data'] = value


def _flatten_message(value: Any, prefix: str, out: Row) -> None:
    """A message's columns: a time in seconds, a joint state's by joint, any other's field by field."""
    mt = value.__msgtype__
    if mt == _TIME:
        out[prefix or 'stamp'] = _seconds(value)
        return
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


def _flatten_sequence(value: list[Any] | tuple[Any, ...], prefix: str, out: Row) -> None:
    """A sequence's columns: a ``diagnostic_msgs/KeyValue`` list by key, any other item by item."""
    if value and all(_is_message(v) and v.__msgtype__ == 'diagnostic_msgs/msg/KeyValue' for v in value):
        for kv in value:
            out[_join(prefix, str(kv.key))] = kv.value
        return
    for i, v in enumerate(value):
        _flatten(v, f'{prefix}[{i}]', out)


def flatten_message(msg: object) -> Row:
    """A bag message (rosbags) as ``{column: scalar}``.

    Nested fields are joined with ``.``, a time is seconds (``header.stamp``), sequences
    indexed (``status[0].level``); joint states are named by joint (``position.knife_crank``;
    the ``name`` list itself is dropped) and ``diagnostic_msgs/KeyValue`` lists by key.
    """
    out: Row = {}
    _flatten(msg, '', out)
    return out


def message_rows(topic: str, t_ns: int, msg: Any) -> list[Row]:
    """The CSV rows of one message (of the topic's type): ``t`` (log time, s) and its columns (see the
    module's docstring).

    One row per message, but one per status on ``/diagnostics``.
    """
    t = t_ns / NS_PER_S
    if topic == DIAGNOSTICS_TOPIC and _is_message(msg) and hasattr(msg, 'status'):
        stamp = _seconds(msg.header.stamp)
        rows = []
        for st in msg.status:
            row: Row = {
                't': t,
                'header.stamp': stamp,
                'name': str(st.name),
                'level': int.from_bytes(st.level, 'little') if isinstance(st.level, bytes) else int(st.level),
                'message': str(st.message),
                'hardware_id': str(st.hardware_id),
            }
            row.update({f'values.{kv.key}': str(kv.value) for kv in st.values})
            rows.append(row)
        return rows
    row = {'t': t}
    flat = flatten_message(msg)
    if topic == EVENTS_TOPIC and 'source' in flat:
        source = flat.pop('source')
        try:
            kind, sheet, cycle, value = parse_event_source(str(source))
        except ValueError:
            flat.update({'kind': '', 'sheet': '', 'cycle': '', 'value': '', 'source': source})
        else:
            flat.update({'kind': kind, 'sheet': sheet, 'cycle': cycle, 'value': value})
    row.update(flat)
    return [row]


def csv_name(topic: str) -> str:
    """File name of a topic's CSV: ``/line/crank_drive/joint_states`` -> ``line__crank_drive__joint_states.csv``."""
    return topic.strip('/').replace('/', '__') + '.csv'


class CsvCollector:
    """Rows of every topic (:func:`message_rows`), spooled to temporary files; written one CSV per topic.

    Call it with ``(topic, log time ns, message)`` for every message, then :meth:`write`
    (or :meth:`close` to drop the spool).
    """

    def __init__(self) -> None:
        self._spool: dict[str, IO[str]] = {}
        self.columns: dict[str, dict[str, None]] = {}
        self.counts: dict[str, int] = {}

    def __call__(self, topic: str, t_ns: int, msg: object) -> None:
        fh = self._spool.get(topic)
        if fh is None:
            fh = self._spool[topic] = tempfile.TemporaryFile('w+', encoding='utf-8')  # noqa: SIM115 - closed in close()
            self.columns[topic] = {}
            self.counts[topic] = 0
        names = self.columns[topic]
        for row in message_rows(topic, t_ns, msg):
            for name in row:
                if name not in names:
                    names[name] = None
            fh.write(json.dumps(row, allow_nan=True))
            fh.write('\n')
            self.counts[topic] += 1

    @staticmethod
    def check(directory: Path, topics: Sequence[str], option: str) -> None:
        """Refuse (OutputError naming ``option``) if any topic's CSV cannot be written in ``directory``."""
        for topic in topics:
            check_output_file(directory / csv_name(topic), option)

    def _chunks(self, topic: str) -> Iterator[bytes]:
        names = list(self.columns.get(topic, {})) or ['t']
        buf = io.StringIO(newline='')
        writer = csv.writer(buf, lineterminator='\n')
        writer.writerow(names)
        fh = self._spool.get(topic)
        if fh is not None:
            fh.seek(0)
            for i, line in enumerate(fh, 1):
                row = json.loads(line)
                writer.writerow([_cell(row.get(name, '')) for name in names])
                if i % _CHUNK_ROWS == 0:
                    yield buf.getvalue().encode('utf-8')
                    buf.seek(0)
                    buf.truncate()
        yield buf.getvalue().encode('utf-8')

    def write(self, directory: Path, topics: Sequence[str]) -> dict[str, Path]:
        """Write ``<directory>/<csv_name(topic)>`` for each of ``topics`` (a header only where none was
        recorded); topic -> the file written. The spool is closed afterwards."""
        written: dict[str, Path] = {}
        try:
            for topic in topics:
                written[topic] = write_chunks_atomic(directory / csv_name(topic), self._chunks(topic))
        finally:
            self.close()
        return written

    def close(self) -> None:
        """Drop the spooled rows."""
        for fh in self._spool.values():
            fh.close()
        self._spool.clear()


def _cell(value: object) -> object:
    """A value as the CSV shows it: floats with ``repr`` precision (round-trip exact)."""
    return repr(value) if isinstance(value, float) else value
