"""The text form of a line event in ``sensor_msgs/TimeReference.source`` -- no ROS needed.

The machine nodes publish each exact event on ``/line/events`` with ``time_ref`` =
the event time (nearest ns) and ``source`` = ``'<kind> sheet=<id> cycle=<k>
value=<repr>'``; the analysis of a bag (:mod:`folder_line.analysis.analysis`) reads them back.
Both use these two functions, so that a bag can be decoded without rclpy.
"""

from __future__ import annotations

import re

from folder_line.core.line.events import EVENT_KINDS

__all__ = ['SOURCE_PATTERN', 'event_source', 'parse_event_source']

#: the ``source`` of an event; ``value`` is Python's ``repr`` of a float (round-trip exact)
SOURCE_PATTERN = re.compile(r'^(?P<kind>\w+) sheet=(?P<sheet>-?\d+) cycle=(?P<cycle>-?\d+) value=(?P<value>\S+)$')


def event_source(kind: str, sheet: int, cycle: int, value: float) -> str:
    """``TimeReference.source`` of an event: ``'<kind> sheet=<id> cycle=<k> value=<repr>'``."""
    return f'{kind} sheet={int(sheet)} cycle={int(cycle)} value={float(value)!r}'


def parse_event_source(source: str) -> tuple[str, int, int, float]:
    """Inverse of :func:`event_source`: ``(kind, sheet, cycle, value)``.

    Raises
    ------
    ValueError
        ``source`` is not of that form, or names an unknown event kind.
    """
    m = SOURCE_PATTERN.match(source)
    if m is None or m['kind'] not in EVENT_KINDS:
        msg = f'not an event source: {source!r}'
        raise ValueError(msg)
    try:
        value = float(m['value'])
    except ValueError:
        msg = f'not an event source (value): {source!r}'
        raise ValueError(msg) from None
    return m['kind'], int(m['sheet']), int(m['cycle']), value
