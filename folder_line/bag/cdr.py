"""CDR bytes of the line's fixed-layout messages, built directly (and many at a time) instead of by the typestore.

The batch bag (:mod:`folder_line.bag.batch`) writes millions of messages whose layout never
changes: ``rosgraph_msgs/Clock``, ``std_msgs/UInt64``, ``std_msgs/Float64``,
``std_msgs/String``, ``sensor_msgs/TimeReference`` and the ``sensor_msgs/JointState`` of one
node (fixed ``frame_id``, joint names and array lengths). Their little-endian CDR (the 4-byte
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

__all__ = ['JointStateLayout', 'clock_cdr', 'float64_cdr', 'string_cdr', 'time_reference_cdr', 'uint64_cdr']

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
        """The messages of ``len(stamps_ns)`` stamps, concatenated (each ``len(template)`` bytes).

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
        return out.tobytes()
