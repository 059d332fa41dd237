"""Simulated time on the wire: integer nanoseconds <-> ``builtin_interfaces/msg/Time``.

Times are integer nanoseconds everywhere in the line (:data:`folder_line.interfaces.NS_PER_S`);
these two functions are the only conversions to and from the message.
"""

from __future__ import annotations

from builtin_interfaces.msg import Time as TimeMsg

from folder_line.interfaces import NS_PER_S, TIME_MSG_MAX_NS, stamp_ns

__all__ = ['ns_to_time_msg', 'time_msg_to_ns']


def ns_to_time_msg(ns: int) -> TimeMsg:
    """A ``builtin_interfaces/msg/Time`` for ``ns`` nanoseconds (``sec = ns // 1e9``, ``nanosec = ns % 1e9``).

    Raises
    ------
    ValueError
        ``ns`` is negative or beyond :data:`TIME_MSG_MAX_NS`.
    """
    if not 0 <= ns <= TIME_MSG_MAX_NS:
        msg = f'ns={ns!r}: must be in [0, {TIME_MSG_MAX_NS}] to fit builtin_interfaces/msg/Time'
        raise ValueError(msg)
    sec, nanosec = divmod(ns, NS_PER_S)
    return TimeMsg(sec=sec, nanosec=nanosec)


def time_msg_to_ns(stamp: TimeMsg) -> int:
    """Integer nanoseconds of a ``builtin_interfaces/msg/Time``."""
    return stamp_ns(stamp)
