"""CDR bytes of the line's fixed-layout messages, built directly (and many at a time) instead of by the typestore.

The batch bag (:mod:`folder_line.bag.batch`) writes millions of messages whose layout never
changes: ``rosgraph_msgs/Clock``, ``std_msgs/UInt64``, ``std_msgs/Float64``,
``std_msgs/String``, ``sensor_msgs/TimeReference`` and the ``sensor_msgs/JointState`` of one
node (fixed ``frame_id``, joint names and array lengths), and the supervisor's
``diagnostic_msgs/DiagnosticArray`` (strings and a byte). The many of one tick grid are made a
column at a time (``clock_rows``, ``uint64_rows``, ``float64_rows``, :meth:`JointStateLayout.rows`,
:func:`time_references`). Their little-endian CDR (the 4-byte
encapsulation header ``00 01 00 00``, then the fields, each aligned to its size counted from
after that header) is assembled here with :mod:`struct` and numpy, byte for byte what
:func:`folder_line.bag.types.serialize` gives (``test/bag/test_cdr.py`` compares them).
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from folder_line.core.numerics.arrays import FloatArray
from folder_line.interfaces import NS_PER_S

__all__ = [
    'JointStateLayout',
    'clock_cdr',
    'clock_rows',
    'diagnostic_array_cdr',
    'float64_cdr',
    'float64_rows',
    'string_cdr',
    'time_reference_cdr',
    'time_references',
    'uint64_cdr',
    'uint64_rows',
]

#: little-endian CDR encapsulation header
_HEAD = b'\x00\x01\x00\x00'
_TIME = struct.Struct('<iI')


def _sec_nsec(ns: int) -> tuple[int, int]:
    sec, nsec = divmod(int(ns), NS_PER_S)
    return sec, nsec


def _string(body: bytearray, text: str) -> None:
    """Append a CDR string (aligned length with the terminating NUL, the bytes, NUL) to ``body``."""
    _align(body, 4)
    raw = text.encode()
    body += struct.pack('<I', len(raw) + 1) + raw + b'\x00'


def _align(body: bytearray, size: int) -> None:
    body += b'\x00' * ((-(len(body) - len(_HEAD))) % size)


def clock_cdr(ns: int) -> bytes:
    """``rosgraph_msgs/msg/Clock`` at ``ns`` (line time, ns)."""
    return _HEAD + _TIME.pack(*_sec_nsec(ns))


def diagnostic_array_cdr(
    stamp_ns: int, frame_id: str, statuses: Sequence[tuple[int, str, str, str, Sequence[tuple[str, str]]]]
) -> bytes:
    """``diagnostic_msgs/msg/DiagnosticArray``: ``header`` (``stamp_ns``, ``frame_id``), then each status
    ``(level, name, message, hardware_id, ((key, value), ...))``."""
    body = bytearray(_HEAD)
    body += _TIME.pack(*_sec_nsec(stamp_ns))
    _string(body, frame_id)
    _align(body, 4)
    body += struct.pack('<I', len(statuses))
    for level, name, message, hardware_id, values in statuses:
        body += struct.pack('<B', level)
        _string(body, name)
        _string(body, message)
        _string(body, hardware_id)
        _align(body, 4)
        body += struct.pack('<I', len(values))
        for key, value in values:
            _string(body, key)
            _string(body, value)
    return bytes(body)


def _rows(values: np.ndarray) -> np.ndarray:
    """``_HEAD`` then each of ``values`` (little endian): (n, 4 + itemsize) bytes."""
    v = np.ascontiguousarray(values)
    out = np.empty((len(v), len(_HEAD) + v.dtype.itemsize), dtype=np.uint8)
    out[:, : len(_HEAD)] = np.frombuffer(_HEAD, dtype=np.uint8)
    out[:, len(_HEAD) :] = v.view(np.uint8).reshape(len(v), v.dtype.itemsize)
    return out


def clock_rows(stamps_ns: np.ndarray) -> np.ndarray:
    """:func:`clock_cdr` of each of ``stamps_ns`` (ns, >= 0): (n, 12) bytes."""
    stamps = np.asarray(stamps_ns, dtype=np.int64).reshape(-1)
    time = np.empty(len(stamps), dtype=[('sec', '<i4'), ('nanosec', '<u4')])
    time['sec'] = stamps // NS_PER_S
    time['nanosec'] = stamps % NS_PER_S
    return _rows(time)


def uint64_rows(values: np.ndarray) -> np.ndarray:
    """:func:`uint64_cdr` of each of ``values``: (n, 12) bytes."""
    return _rows(np.asarray(values).reshape(-1).astype('<u8'))


def float64_rows(values: np.ndarray) -> np.ndarray:
    """:func:`float64_cdr` of each of ``values``: (n, 12) bytes."""
    return _rows(np.asarray(values, dtype='<f8').reshape(-1))


def uint64_cdr(value: int) -> bytes:
    """``std_msgs/msg/UInt64``."""
    return _HEAD + struct.pack('<Q', int(value))


def float64_cdr(value: float) -> bytes:
    """``std_msgs/msg/Float64``."""
    return _HEAD + struct.pack('<d', float(value))


def string_cdr(text: str) -> bytes:
    """``std_msgs/msg/String``."""
    body = bytearray(_HEAD)
    _string(body, text)
    return bytes(body)


def time_reference_cdr(stamp_ns: int, frame_id: str, time_ref_ns: int, source: str) -> bytes:
    """``sensor_msgs/msg/TimeReference``: ``header`` (``stamp_ns``, ``frame_id``), ``time_ref``, ``source``."""
    body = bytearray(_HEAD)
    body += _TIME.pack(*_sec_nsec(stamp_ns))
    _string(body, frame_id)
    _align(body, 4)
    body += _TIME.pack(*_sec_nsec(time_ref_ns))
    _string(body, source)
    return bytes(body)


def time_references(
    stamps_ns: np.ndarray, frame_id: str, time_refs_ns: np.ndarray, sources: Sequence[str]
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`time_reference_cdr` of many messages of one ``frame_id``, at once: their bytes one after the
    other (uint8) and the length of each.

    Parameters
    ----------
    stamps_ns, time_refs_ns : ndarray of int, shape (n,)
        ``header.stamp`` and ``time_ref`` of each, ns (>= 0).
    sources : sequence of str
        ``source`` of each (ASCII).
    """
    template = time_reference_cdr(0, frame_id, 0, '')
    size = len(template) - 1  # the fixed part: through the source's length
    n = len(sources)
    fixed = np.empty((n, size), dtype=np.uint8)
    fixed[:] = np.frombuffer(template[:size], dtype=np.uint8)
    for at, ns in ((4, stamps_ns), (size - 12, time_refs_ns)):
        ns = np.asarray(ns, dtype=np.int64).reshape(-1)
        time = np.empty(n, dtype=[('sec', '<i4'), ('nanosec', '<u4')])
        time['sec'] = ns // NS_PER_S
        time['nanosec'] = ns % NS_PER_S
        fixed[:, at : at + 8] = time.view(np.uint8).reshape(n, 8)
    text = ('\x00'.join(sources) + '\x00').encode('ascii') if n else b''
    strings = np.fromiter((len(s) + 1 for s in sources), dtype=np.int64, count=n)  # with the NUL
    fixed[:, size - 4 : size] = strings.astype('<u4').view(np.uint8).reshape(n, 4)
    lens = size + strings
    starts = np.zeros(n, dtype=np.int64)
    np.cumsum(lens[:-1], out=starts[1:])
    out = np.empty(int(lens.sum()), dtype=np.uint8)
    out[starts[:, None] + np.arange(size)] = fixed
    before = np.zeros(n, dtype=np.int64)
    np.cumsum(strings[:-1], out=before[1:])
    out[np.repeat(starts + size - before, strings) + np.arange(len(text))] = np.frombuffer(text, dtype=np.uint8)
    return out, lens


@dataclass(frozen=True)
class JointStateLayout:
    """The CDR layout of one node's ``sensor_msgs/msg/JointState``: everything but the stamp and the values fixed.

    Build it with :meth:`of`; :meth:`many` gives the messages of many stamps at once.

    Attributes
    ----------
    template : bytes
        A message with stamp 0 and every value 0.
    offsets : tuple of int
        Byte offsets of the ``position``, ``velocity`` and ``effort`` data (float64, little endian).
    lengths : tuple of int
        Values in each of those arrays.
    """

    template: bytes
    offsets: tuple[int, int, int]
    lengths: tuple[int, int, int]

    @classmethod
    def of(cls, frame_id: str, names: Sequence[str], lengths: tuple[int, int, int]) -> JointStateLayout:
        """The layout for ``frame_id``, joint ``names`` and ``(len(position), len(velocity), len(effort))``."""
        body = bytearray(_HEAD)
        body += _TIME.pack(0, 0)
        _string(body, frame_id)
        _align(body, 4)
        body += struct.pack('<I', len(names))
        for name in names:
            _string(body, name)
        offsets = []
        for n in lengths:
            _align(body, 4)
            body += struct.pack('<I', n)
            if n:
                _align(body, 8)
            offsets.append(len(body))
            body += b'\x00' * (8 * n)
        return cls(bytes(body), (offsets[0], offsets[1], offsets[2]), lengths)

    def many(
        self, stamps_ns: np.ndarray, position: FloatArray, velocity: FloatArray, effort: FloatArray | None
    ) -> bytes:
        """The messages of ``len(stamps_ns)`` stamps, concatenated (each ``len(template)`` bytes): :meth:`rows`."""
        return self.rows(stamps_ns, position, velocity, effort).tobytes()

    def rows(
        self, stamps_ns: np.ndarray, position: FloatArray, velocity: FloatArray, effort: FloatArray | None
    ) -> np.ndarray:
        """The messages of ``len(stamps_ns)`` stamps, one a row: (n, ``len(template)``) bytes.

        Parameters
        ----------
        stamps_ns : ndarray of int64, shape (n,)
            ``header.stamp`` of each message, ns.
        position, velocity : ndarray of float, shape (n, lengths[0]) and (n, lengths[1])
            The joints' values (rad or m, rad/s or m/s).
        effort : ndarray of float, shape (n, lengths[2]), or None
            N m or N; None when ``lengths[2]`` is 0.
        """
        n, size = len(stamps_ns), len(self.template)
        out = np.empty((n, size), dtype=np.uint8)
        out[:] = np.frombuffer(self.template, dtype=np.uint8)
        stamps = np.asarray(stamps_ns, dtype=np.int64)
        time = np.empty((n, 2), dtype='<u4')
        time[:, 0] = (stamps // NS_PER_S).astype(np.int64)
        time[:, 1] = stamps % NS_PER_S
        out[:, 4:12] = time.view(np.uint8).reshape(n, 8)
        for off, length, values in zip(self.offsets, self.lengths, (position, velocity, effort), strict=True):
            if length and values is not None:
                data = np.ascontiguousarray(np.asarray(values, dtype='<f8').reshape(n, length))
                out[:, off : off + 8 * length] = data.view(np.uint8).reshape(n, 8 * length)
        return out
