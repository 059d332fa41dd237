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

from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from folder_line.bag.types import typestore
from folder_line.core.line.scenery import LINE_FRAME, Shape
from folder_line.interfaces import NS_PER_S

__all__ = [
    'ACTION_ADD',
    'ACTION_DELETE',
    'ACTION_DELETEALL',
    'MARKER_TYPES',
    'MARKERS_TYPE',
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
        stamp = round(i * NS_PER_S / rate)
        if stamp > until_ns:
            return
        if after_ns is None or stamp > after_ns:
            yield stamp
        i += 1


def markers_cdr(specs: list[MarkerSpec], stamp_ns: int, *, delete_all: bool = False) -> bytes:
    """CDR of the ``MarkerArray`` of ``specs`` stamped ``stamp_ns`` (a ``DELETEALL`` first if ``delete_all``)."""
    types = typestore().types
    header = types['std_msgs/msg/Header'](
        stamp=types['builtin_interfaces/msg/Time'](sec=stamp_ns // NS_PER_S, nanosec=stamp_ns % NS_PER_S),
        frame_id=LINE_FRAME,
    )
    markers = [_marker(types, header, s) for s in specs]
    if delete_all:
        markers.insert(0, _marker(types, header, None))
    msg = types[MARKERS_TYPE](markers=markers)
    return bytes(typestore().serialize_cdr(msg, MARKERS_TYPE, little_endian=True))


def _marker(types: Any, header: Any, s: MarkerSpec | None) -> Any:
    point, vec, rgba = (
        types['geometry_msgs/msg/Point'],
        types['geometry_msgs/msg/Vector3'],
        types['std_msgs/msg/ColorRGBA'],
    )
    pose = types['geometry_msgs/msg/Pose'](
        position=point(x=0.0, y=0.0, z=0.0) if s is None else point(x=s.position[0], y=s.position[1], z=s.position[2]),
        orientation=types['geometry_msgs/msg/Quaternion'](x=0.0, y=0.0, z=0.0, w=1.0),
    )
    return types['visualization_msgs/msg/Marker'](
        header=header,
        ns='' if s is None else s.ns,
        id=0 if s is None else s.id,
        type=0 if s is None else s.type,
        action=ACTION_DELETEALL if s is None else s.action,
        pose=pose,
        scale=vec(x=0.0, y=0.0, z=0.0) if s is None else vec(x=s.scale[0], y=s.scale[1], z=s.scale[2]),
        color=rgba(r=0.0, g=0.0, b=0.0, a=0.0)
        if s is None
        else rgba(r=s.color[0], g=s.color[1], b=s.color[2], a=s.color[3]),
        lifetime=types['builtin_interfaces/msg/Duration'](sec=0, nanosec=0),
        frame_locked=False,
        points=[] if s is None else [point(x=float(x), y=float(y), z=float(z)) for x, y, z in s.points],
        colors=[],
        texture_resource='',
        texture=types['sensor_msgs/msg/CompressedImage'](
            header=types['std_msgs/msg/Header'](
                stamp=types['builtin_interfaces/msg/Time'](sec=0, nanosec=0), frame_id=''
            ),
            format='',
            data=np.zeros(0, dtype=np.uint8),
        ),
        uv_coordinates=[],
        text='',
        mesh_resource='',
        mesh_file=types['visualization_msgs/msg/MeshFile'](filename='', data=np.zeros(0, dtype=np.uint8)),
        mesh_use_embedded_materials=False,
    )
