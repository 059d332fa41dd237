"""The fields of ROS messages that the package reads, as protocols.

A message is read by its fields (duck typing): rclpy's message, the one the rosbags typestore
decodes from a bag and a test's stand-in all fit. These protocols say which fields a reader needs,
with read-only members, so that a message whose fields are of a narrower type fits too. No message
package is imported (rclpy's message classes are untyped for mypy).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Protocol, TypeVar

__all__ = [
    'ClockLike',
    'DataLike',
    'DiagnosticArrayLike',
    'DiagnosticStatusLike',
    'HeaderLike',
    'JointStateLike',
    'KeyValueLike',
    'MarkerArrayLike',
    'StampLike',
    'StampedLike',
    'TimeReferenceLike',
]

_T_co = TypeVar('_T_co', covariant=True)


class StampLike(Protocol):
    """``builtin_interfaces/msg/Time``: ``sec`` s and ``nanosec`` ns."""

    @property
    def sec(self) -> int: ...
    @property
    def nanosec(self) -> int: ...


class HeaderLike(Protocol):
    """``std_msgs/msg/Header``: the stamp and the frame (the publishing node on the line)."""

    @property
    def stamp(self) -> StampLike: ...
    @property
    def frame_id(self) -> str: ...


class StampedLike(Protocol):
    """A message with a ``std_msgs/msg/Header`` (``visualization_msgs/msg/Marker``, ...)."""

    @property
    def header(self) -> HeaderLike: ...


class ClockLike(Protocol):
    """``rosgraph_msgs/msg/Clock``."""

    @property
    def clock(self) -> StampLike: ...


class TimeReferenceLike(Protocol):
    """``sensor_msgs/msg/TimeReference``: the line's events, commands and lockstep acknowledgements."""

    @property
    def header(self) -> HeaderLike: ...
    @property
    def time_ref(self) -> StampLike: ...
    @property
    def source(self) -> str: ...


class JointStateLike(Protocol):
    """``sensor_msgs/msg/JointState``: names and, per joint, position, velocity and effort."""

    @property
    def header(self) -> HeaderLike: ...
    @property
    def name(self) -> Sequence[str]: ...
    @property
    def position(self) -> Iterable[float]: ...
    @property
    def velocity(self) -> Iterable[float]: ...
    @property
    def effort(self) -> Iterable[float]: ...


class KeyValueLike(Protocol):
    """``diagnostic_msgs/msg/KeyValue``."""

    @property
    def key(self) -> str: ...
    @property
    def value(self) -> str: ...


class DiagnosticStatusLike(Protocol):
    """``diagnostic_msgs/msg/DiagnosticStatus``: ``level`` is one byte in rclpy's message, an int in rosbags'."""

    @property
    def level(self) -> int | bytes: ...
    @property
    def name(self) -> str: ...
    @property
    def message(self) -> str: ...
    @property
    def values(self) -> Sequence[KeyValueLike]: ...


class DiagnosticArrayLike(Protocol):
    """``diagnostic_msgs/msg/DiagnosticArray``."""

    @property
    def header(self) -> HeaderLike: ...
    @property
    def status(self) -> Sequence[DiagnosticStatusLike]: ...


class MarkerArrayLike(Protocol):
    """``visualization_msgs/msg/MarkerArray``: its markers, each with a header."""

    @property
    def markers(self) -> Iterable[StampedLike]: ...


class DataLike(Protocol[_T_co]):
    """A ``std_msgs`` message of one ``data`` field (``String``, ``UInt64``, ``Float64``)."""

    @property
    def data(self) -> _T_co: ...
