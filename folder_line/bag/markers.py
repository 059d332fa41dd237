"""``/line/markers``: the scenery (:mod:`folder_line.core.line.scenery`) as ``visualization_msgs/MarkerArray``.

One mapping from :class:`~folder_line.core.line.scenery.Shape` to marker fields, as plain
data (:func:`marker_specs`, no rclpy), used by the ``sheet_counter`` node to fill its rclpy
messages and here to write the same message into a batch bag (:func:`markers_cdr`):

* ``header.frame_id`` :data:`~folder_line.core.line.scenery.LINE_FRAME`, ``header.stamp`` the
  marker grid point; ``ns`` the shape's machine (``layup``, ``container``, ``folder``,
  ``delivery``, ``pile``), ``id`` its index among that machine's shapes (stable: the
  scenery's order);
* ``type`` ``LINE_STRIP`` (``strip``), ``LINE_LIST`` (``segments``), ``SPHERE_LIST``
  (``points``), ``CUBE`` (``box``: pose at the box centre, scale its size); the others carry
  their points in the frame itself (identity pose) and ``scale`` = the shape's width;
* ``action`` ``ADD``, or ``DELETE`` for a shape with nothing to show this time (no leaf in
  the air: RViz draws no empty list); the first array a node publishes starts with a
  ``DELETEALL`` (markers of an earlier run go); ``lifetime`` 0 (until replaced),
  ``frame_locked`` false.

The grid: marker arrays are stamped ``round(i · 1e9 / marker_rate)`` ns, i = 0, 1, ...
(:func:`marker_stamps`), each published at the first tick at or after its stamp, live and
in a batch bag alike.
"""

from __future__ import annotations

import functools
import struct
from collections.abc import Iterable, Iterator
from dataclasses import dataclass

import numpy as np

from folder_line.core.line.scenery import LINE_FRAME, Shape
from folder_line.interfaces import NS_PER_S

__all__ = [
    'ACTION_ADD',
    'ACTION_DELETE',
    'ACTION_DELETEALL',
    'MARKERS_TYPE',
    'MARKER_TYPES',
    'MarkerSpec',
    'marker_specs',
    'marker_stamps',
    'markers_cdr',
]

#: ``visualization_msgs/msg/Marker`` type of each shape kind
MARKER_TYPES: dict[str, int] = {'strip': 4, 'segments': 5, 'points': 7, 'box': 1}
ACTION_ADD = 0
ACTION_DELETE = 2
ACTION_DELETEALL = 3
#: the topic's type
MARKERS_TYPE = 'visualization_msgs/msg/MarkerArray'


@dataclass(frozen=True)
class MarkerSpec:
    """The fields of one marker that depend on the shape (the rest are the message's defaults).

    ``position`` is the pose's position (the orientation is the identity), ``scale`` x, y, z,
    ``color`` r, g, b, a, ``points`` (N, 3) in the frame.
    """

    ns: str
    id: int
    type: int
    action: int
    position: tuple[float, float, float]
    scale: tuple[float, float, float]
    color: tuple[float, float, float, float]
    points: np.ndarray


def _spec(shape: Shape, index: int) -> MarkerSpec:
    p = shape.points
    origin = (0.0, 0.0, 0.0)
    if not len(p):
        return MarkerSpec(
            shape.machine, index, MARKER_TYPES[shape.kind], ACTION_DELETE, origin, (1.0, 1.0, 1.0), shape.rgba, p
        )
    if shape.kind == 'box':
        lo, hi = p[0], p[1]
        centre = 0.5 * (lo + hi)
        size = np.maximum(hi - lo, 1e-6)
        return MarkerSpec(
            shape.machine,
            index,
            MARKER_TYPES['box'],
            ACTION_ADD,
            (float(centre[0]), float(centre[1]), float(centre[2])),
            (float(size[0]), float(size[1]), float(size[2])),
            shape.rgba,
            np.zeros((0, 3)),
        )
    w = shape.width
    return MarkerSpec(shape.machine, index, MARKER_TYPES[shape.kind], ACTION_ADD, origin, (w, w, w), shape.rgba, p)


def marker_specs(shapes: Iterable[Shape]) -> list[MarkerSpec]:
    """The markers of a scenery's shapes, in their order; ids count per namespace from 0."""
    seen: dict[str, int] = {}
    out = []
    for s in shapes:
        i = seen.get(s.machine, 0)
        seen[s.machine] = i + 1
        out.append(_spec(s, i))
    return out


def marker_stamps(after_ns: int | None, until_ns: int, rate: float) -> Iterator[int]:
    """The grid points ``round(i · 1e9 / rate)`` in ``(after_ns, until_ns]`` (all up to ``until_ns`` if
    ``after_ns`` is None), ns; none if ``rate`` <= 0."""
    if rate <= 0.0:
        return
    i = 0 if after_ns is None else max(0, int(after_ns * rate // NS_PER_S) - 1)
    while True:
        x = i * NS_PER_S / rate
        if not x <= until_ns + 1:  # past the end (an infinite one too: a rate so low its next point overflows)
            return
        stamp = round(x)
        if stamp > until_ns:
            return
        if after_ns is None or stamp > after_ns:
            yield stamp
        i += 1


def markers_cdr(specs: list[MarkerSpec], stamp_ns: int, *, delete_all: bool = False) -> bytes:
    """CDR of the ``MarkerArray`` of ``specs`` stamped ``stamp_ns`` (a ``DELETEALL`` first if ``delete_all``).

    Little-endian CDR as the rosbags typestore serializes it (``test/bag/test_markers_cdr.py``
    compares them), written field by field with :mod:`struct`: a marker's layout depends only
    on its namespace and where it starts (the alignment), so each is one packing of its
    numbers, its points' bytes and the constant tail of empty fields.
    """
    sec, nanosec = divmod(int(stamp_ns), NS_PER_S)
    body = bytearray(_ENCAPSULATION)
    body += struct.pack('<I', len(specs) + bool(delete_all))
    if delete_all:
        _append_marker(body, sec, nanosec, '', 0, 0, ACTION_DELETEALL, _ORIGIN, _ORIGIN, (0.0, 0.0, 0.0, 0.0), None)
    for m in specs:
        _append_marker(body, sec, nanosec, m.ns, m.id, m.type, m.action, m.position, m.scale, m.color, m.points)
    return bytes(body)


#: little-endian CDR encapsulation header
_ENCAPSULATION = b'\x00\x01\x00\x00'
_ORIGIN = (0.0, 0.0, 0.0)
_FRAME = LINE_FRAME.encode()


def _layout(codes: list[str], start: int) -> tuple[struct.Struct, int]:
    """The :class:`struct.Struct` of CDR fields ``codes`` (struct codes; ``<n>s`` for raw bytes) written
    from an offset ``start`` (mod 8) of the message body, each aligned to its size; and where it ends (mod 8)."""
    fmt = '<'
    pos = start
    for code in codes:
        size = int(code[:-1]) if code.endswith('s') else struct.calcsize('<' + code)
        align = 1 if code.endswith('s') else size
        pad = -pos % align
        fmt += f'{pad}x{code}' if pad else code
        pos += pad + size
    return struct.Struct(fmt), pos % 8


@functools.cache
def _head(ns: bytes, start: int) -> tuple[struct.Struct, int]:
    """A marker's fields up to its points' count (namespace ``ns``, starting at ``start`` mod 8)."""
    codes = ['i', 'I', 'I', f'{len(_FRAME) + 1}s', 'I', f'{len(ns) + 1}s', 'i', 'i', 'i']
    codes += ['d'] * 10 + ['f'] * 4 + ['i', 'I', '?', 'I']  # pose, scale; color; lifetime, frame_locked, points
    return _layout(codes, start)


@functools.cache
def _tail(start: int) -> bytes:
    """A marker's fields after its points (all empty), starting at ``start`` mod 8."""
    codes = ['I', 'I', '1s', 'i', 'I', 'I', '1s', 'I', '1s', 'I', 'I', 'I', '1s', 'I', '1s', 'I', '1s', 'I', '?']
    layout, _ = _layout(codes, start)
    return layout.pack(0, 1, b'', 0, 0, 1, b'', 1, b'', 0, 0, 1, b'', 1, b'', 1, b'', 0, False)


def _append_marker(
    body: bytearray,
    sec: int,
    nanosec: int,
    ns: str,
    id_: int,
    type_: int,
    action: int,
    position: tuple[float, float, float],
    scale: tuple[float, float, float],
    color: tuple[float, float, float, float],
    points: np.ndarray | None,
) -> None:
    """One ``visualization_msgs/Marker`` (frame :data:`LINE_FRAME`, identity orientation) appended to ``body``."""
    raw = ns.encode()
    head, end = _head(raw, (len(body) - 4) % 8)
    n = 0 if points is None else len(points)
    body += head.pack(
        sec,
        nanosec,
        len(_FRAME) + 1,
        _FRAME,
        len(raw) + 1,
        raw,
        id_,
        type_,
        action,
        *position,
        0.0,
        0.0,
        0.0,
        1.0,
        *scale,
        *color,
        0,
        0,
        False,
        n,
    )
    if n:
        body += bytes(-end % 8)
        body += np.ascontiguousarray(points, dtype='<f8').tobytes()
        end = 0
    body += _tail(end)
