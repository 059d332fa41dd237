"""The lockstep's messages (:mod:`folder_line.ros.lockstep`): grants, the announcement and the
acknowledgements, as text on standard messages, each signed on a keyed line (:mod:`folder_line.ros.signing`).

Topics
------
``/line/participants`` (``std_msgs/String``, reliable, transient-local)
    Published once by ``line_clock`` before its first tick:
    ``'clock=lockstep end=<ns or none> participants=crank_drive,...,line_recorder'``
    (:func:`format_announcement`). Every participant waits for it, so the set of
    participants has one source: ``line_clock``'s ``participants`` parameter.
``/line/grant`` (``sensor_msgs/TimeReference``, reliable)
    ``header.stamp`` = the last tick granted, ``time_ref`` = the first tick of the
    current step, ``source`` = ``'step=<ns>'``, ``header.frame_id`` = ``line_clock``
    (:func:`grant_ticks`). Repeated while nothing new is granted: the clock is alive.
``/line/<node>/progress`` (``sensor_msgs/TimeReference``, best-effort)
    A participant's latest acknowledgement, published after all that tick's
    messages, every :data:`~folder_line.ros.lockstep.PROGRESS_EVERY` ticks, whenever it stops to wait, and every
    :data:`~folder_line.ros.lockstep.HEARTBEAT` s while it waits: ``header.stamp`` = the tick,
    ``header.frame_id`` = the participant, ``time_ref`` = its *promise* (nothing it
    publishes later matters before it: the tick itself, or for the supervisor the tick
    plus ``command_lead``), ``source`` = its cumulative published counts, per stream and
    per topic (:func:`folder_line.core.supervision.lockstep.format_counts`). Consumers
    that must not act on missing input count what they received from each producer and
    wait until the counts reach the acknowledged ones
    (:class:`folder_line.core.supervision.lockstep.TickLedger`). Acknowledgements are
    cumulative, so the clock and the nodes read them best-effort: a lost one is
    replaced by the next or by a repeat, never held back behind a repair.
``/line/<node>/tick_done`` (``sensor_msgs/TimeReference``, reliable)
    Only when the recorder takes part (it records every producer's messages at their
    own tick): the acknowledgements of every tick since the previous ``tick_done``, in
    one message, sent with each ``progress`` (``source``:
    :func:`folder_line.core.supervision.lockstep.format_ticks`; ``header.stamp`` and
    ``time_ref``: the last tick's).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import cast

from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Typestore
from sensor_msgs.msg import TimeReference

from folder_line.core.supervision.lockstep import parse_counts, parse_ticks
from folder_line.interfaces import KNOWN_PARTICIPANTS, NS_PER_S
from folder_line.ros.message_fields import TimeReferenceLike
from folder_line.ros.signing import open_text, sign_text
from folder_line.ros.time_msg import ns_to_time_msg, time_msg_to_ns

__all__ = [
    'CLOCK_MODES',
    'MAX_GRANT',
    'Announcement',
    'format_announcement',
    'format_grant',
    'grant_ticks',
    'parse_announcement',
    'participant_names',
    'read_ack',
    'read_ticks',
    'sign_ack',
]

#: most ticks one grant may add (a grant beyond it is refused as malformed)
MAX_GRANT = 1_000_000
CLOCK_MODES: tuple[str, ...] = ('lockstep', 'wall')


def format_grant(last: int, first: int, step: int) -> TimeReference:
    """The grant of every tick up to ``last`` (ns) on the grid ``first + k * step`` (ns)."""
    msg = TimeReference()
    msg.header.stamp = ns_to_time_msg(last)
    msg.header.frame_id = 'line_clock'
    msg.time_ref = ns_to_time_msg(first)
    msg.source = sign_text(f'step={step}', 'grant', msg.header.frame_id, msg.header.stamp, msg.time_ref)
    return msg


def grant_ticks(msg: TimeReference, granted: int | None) -> list[int]:
    """The ticks a grant adds after ``granted`` (ns; None: the first grant seen, which adds its last tick only).

    Raises ``ValueError`` with the reason for a message that is not a grant of ``line_clock``.
    """
    if msg.header.frame_id != 'line_clock':
        raise ValueError(f'grant from {msg.header.frame_id[:40]!r}: only line_clock grants time')
    try:
        source = open_text(msg.source, 'grant', msg.header.frame_id, msg.header.stamp, msg.time_ref)
    except ValueError as err:
        raise ValueError(f'grant: {err}') from None
    key, _, value = source.partition('=')
    if key != 'step' or not value.isdigit() or not 0 < int(value) <= 1000 * NS_PER_S:
        raise ValueError(f'grant source {source[:40]!r}: must be step=<ns>')
    last, first, step = time_msg_to_ns(msg.header.stamp), time_msg_to_ns(msg.time_ref), int(value)
    if first > last:
        raise ValueError(f'grant of {last} ns whose step starts later, at {first} ns')
    if granted is None:
        return [last]
    if last <= granted:
        return []
    start = granted + step if granted >= first else first
    if (last - start) // step >= MAX_GRANT:
        raise ValueError(f'grant of {(last - start) // step} ticks at once (at most {MAX_GRANT})')
    ticks = list(range(start, last, step))
    ticks.append(last)
    return ticks


@dataclass(frozen=True)
class Announcement:
    """What ``line_clock`` announces on :data:`PARTICIPANTS_TOPIC`."""

    clock: str
    end_ns: int | None
    participants: tuple[str, ...]


def format_announcement(a: Announcement) -> str:
    """``'clock=lockstep end=20000000000 participants=crank_drive,supervisor'``, signed on a keyed line
    (:func:`folder_line.ros.signing.sign_text`)."""
    end = 'none' if a.end_ns is None else str(a.end_ns)
    return sign_text(f'clock={a.clock} end={end} participants={",".join(a.participants)}', 'announcement')


def parse_announcement(text: str) -> Announcement:
    """Inverse of :func:`format_announcement`; ``ValueError`` with the reason on anything else."""
    if len(text) > 1000:
        raise ValueError(f'announcement of {len(text)} characters (at most 1000)')
    try:
        text = open_text(text, 'announcement')
    except ValueError as err:
        raise ValueError(f'announcement: {err}') from None
    fields = dict(item.partition('=')[::2] for item in text.split())
    if set(fields) != {'clock', 'end', 'participants'}:
        raise ValueError(f'announcement {text[:80]!r}: needs exactly clock=, end= and participants=')
    if fields['clock'] not in CLOCK_MODES:
        raise ValueError(f'clock={fields["clock"][:20]!r}: must be one of {", ".join(CLOCK_MODES)}')
    end = None if fields['end'] == 'none' else fields['end']
    if end is not None and not (end.isdigit() and len(end) <= 19):
        raise ValueError(f'end={end[:25]!r}: must be none or integer ns')
    try:
        names = participant_names(fields['participants'])
    except ValueError:
        raise ValueError(
            f'participants={fields["participants"][:80]!r}: must be distinct names among '
            f'{", ".join(KNOWN_PARTICIPANTS)}'
        ) from None
    return Announcement(fields['clock'], None if end is None else int(end), names)


def participant_names(text: str) -> tuple[str, ...]:
    """``'crank_drive, supervisor'`` -> ``('crank_drive', 'supervisor')``: distinct known participants, at
    least one; ``ValueError`` with the reason otherwise (``line_clock`` names its parameter in it)."""
    names = tuple(n.strip() for n in text.split(',') if n.strip())
    bad = [n for n in names if n not in KNOWN_PARTICIPANTS]
    if bad:
        raise ValueError(
            f'unknown node(s) {", ".join(b[:40] for b in bad[:5])}; known: {", ".join(KNOWN_PARTICIPANTS)}'
        )
    if len(set(names)) != len(names):
        raise ValueError('names a node twice')
    if not names:
        raise ValueError('names no node: the clock would have nobody to wait for')
    return names


@functools.cache
def _typestore() -> Typestore:
    return get_typestore(Stores.ROS2_KILTED)


#: the counts of an acknowledgement are parsed once, not once per consumer (the result is not mutated)
_cached_counts = functools.lru_cache(maxsize=256)(parse_counts)


def _decode(data: bytes) -> TimeReferenceLike:
    try:  # the typestore decodes the type it is asked for (its signature says object)
        return cast('TimeReferenceLike', _typestore().deserialize_cdr(data, 'sensor_msgs/msg/TimeReference'))
    except Exception as err:
        raise ValueError(f'not a sensor_msgs/TimeReference ({type(err).__name__}: {str(err)[:80]})') from None


def read_ack(data: bytes) -> tuple[str, int, dict[str, int], int]:
    """``(frame_id, stamp ns, counts, promise ns)`` of a ``progress`` message as published (CDR bytes).

    Raises ``ValueError`` with the reason for bytes that are not a ``sensor_msgs/TimeReference``
    or whose ``source`` is not counts (:func:`folder_line.core.supervision.lockstep.parse_counts`). The
    counts mapping may be shared between calls: read it, do not change it.
    """
    msg = _decode(data)
    source = _open_ack(msg, 'progress')
    return msg.header.frame_id, time_msg_to_ns(msg.header.stamp), _cached_counts(source), time_msg_to_ns(msg.time_ref)


def read_ticks(data: bytes) -> tuple[str, list[tuple[int, dict[str, int]]], int]:
    """``(frame_id, [(stamp ns, counts), ...], promise ns)`` of a ``tick_done`` message as published: the
    ticks it acknowledges, in order (:func:`folder_line.core.supervision.lockstep.parse_ticks`), and the
    promise of the last. ``ValueError`` with the reason, as :func:`read_ack`."""
    msg = _decode(data)
    source = _open_ack(msg, 'tick_done')
    stamp = time_msg_to_ns(msg.header.stamp)
    return msg.header.frame_id, parse_ticks(source, stamp), time_msg_to_ns(msg.time_ref)


def _open_ack(msg: TimeReferenceLike, kind: str) -> str:
    try:
        return open_text(msg.source, kind, msg.header.frame_id, msg.header.stamp, msg.time_ref)
    except ValueError as err:
        raise ValueError(f'{kind} of {msg.header.frame_id[:40]!r}: {err}') from None


def sign_ack(msg: TimeReference, kind: str) -> None:
    """Sign ``msg``, a ``progress`` or ``tick_done`` (``kind``) whose fields are all set, in place."""
    msg.source = sign_text(msg.source, kind, msg.header.frame_id, msg.header.stamp, msg.time_ref)
