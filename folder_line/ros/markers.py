"""The scenery's markers as an rclpy ``visualization_msgs/MarkerArray`` (the fields: :mod:`folder_line.bag.markers`)."""

from __future__ import annotations

from geometry_msgs.msg import Point
from visualization_msgs.msg import Marker, MarkerArray

from folder_line.bag.markers import ACTION_DELETEALL, MarkerSpec
from folder_line.core.line.scenery import LINE_FRAME
from folder_line.ros.time_msg import ns_to_time_msg

__all__ = ['marker_array']


def _marker(spec: MarkerSpec | None, stamp_ns: int) -> Marker:
    m = Marker()
    m.header.stamp = ns_to_time_msg(stamp_ns)
    m.header.frame_id = LINE_FRAME
    m.pose.orientation.w = 1.0
    if spec is None:
        m.action = ACTION_DELETEALL
        return m
    m.ns, m.id, m.type, m.action = spec.ns, spec.id, spec.type, spec.action
    m.pose.position.x, m.pose.position.y, m.pose.position.z = spec.position
    m.scale.x, m.scale.y, m.scale.z = spec.scale
    m.color.r, m.color.g, m.color.b, m.color.a = spec.color
    m.points = [Point(x=x, y=y, z=z) for x, y, z in spec.points.tolist()]
    return m


def marker_array(specs: list[MarkerSpec], stamp_ns: int, *, delete_all: bool = False) -> MarkerArray:
    """The ``MarkerArray`` of ``specs`` stamped ``stamp_ns`` (a ``DELETEALL`` first if ``delete_all``)."""
    markers = [_marker(s, stamp_ns) for s in specs]
    if delete_all:
        markers.insert(0, _marker(None, stamp_ns))
    return MarkerArray(markers=markers)
