"""Lockstep bookkeeping: who has finished which tick, and has everything they sent arrived.

The live line runs in lockstep (as Gazebo's lockstep and CARLA's synchronous mode
do): the clock publishes tick ``k + 1`` only when every participant has finished
tick ``k``. A participant finishes a tick by publishing an acknowledgement after
all of that tick's messages; the acknowledgement carries the participant's
cumulative counts of what it has published, per *stream* (``messages``: every
message of the line's topics; ``events``: the line events; ``commands``: drive
commands). Messages on different topics are not ordered with respect to each
other, so an acknowledgement alone does not mean its messages are in: a consumer
counts what it has received from each producer, and a tick of that producer is
*complete* for it once its acknowledgement is in and the received counts reach
the acknowledged ones. :class:`TickLedger` keeps that book; it is pure (no ROS,
no clock) so that it can be tested exhaustively.

An acknowledgement may also carry a *promise*: a time up to which nothing the
producer publishes later can matter (the supervisor's commands take effect
``command_lead`` after their decision, so its promise runs that far ahead of its
tick). A consumer may run ahead to what the promises of its producers allow
(:meth:`TickLedger.ready`): the lookahead of conservative distributed simulation.

Counts travel as text, ``'messages=12 events=3 commands=0'``, optionally followed by
per-topic counts, ``'/line/supervisor/state=7'`` (:func:`format_counts`, :func:`parse_counts`).
The acknowledgements of several ticks travel as one text (:func:`format_ticks`,
:func:`parse_ticks`): the counts of the latest, then, tick by tick backwards, how much earlier
each previous tick was and what it had not yet published, ``'... | 5000000 messages=2 /line/events=1'``.
"""

from __future__ import annotations

import re
from collections import deque
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field

__all__ = [
    'MAX_TICKS',
    'MAX_TOPICS',
    'STREAMS',
    'TickLedger',
    'format_counts',
    'format_ticks',
    'is_topic_stream',
    'parse_counts',
    'parse_ticks',
]

#: the counted streams, in the order :func:`format_counts` writes them
STREAMS: tuple[str, ...] = ('messages', 'events', 'commands')

_MAX_COUNT = 2**63 - 1
#: at most this many per-topic counts in one acknowledgement
MAX_TOPICS = 16
#: at most this many ticks in one text of :func:`format_ticks`
MAX_TICKS = 64
_TOPIC = re.compile(r'/[A-Za-z0-9_/]{1,120}')
_TICK_SEP = ' | '


def is_topic_stream(key: str) -> bool:
    """Whether ``key`` names a per-topic count (a topic name, ``'/line/events'``) rather than a stream."""
    return _TOPIC.fullmatch(key) is not None


def format_counts(counts: Mapping[str, int]) -> str:
    """``{'messages': 12, 'events': 3}`` -> ``'messages=12 events=3 commands=0'`` (every stream, in order),
    then the per-topic counts of ``counts`` (keys that are topic names) in the order given."""
    streams = ' '.join(f'{s}={int(counts.get(s, 0))}' for s in STREAMS)
    topics = ''.join(f' {k}={int(n)}' for k, n in counts.items() if k[:1] == '/')
    return streams + topics


def parse_counts(text: str) -> dict[str, int]:
    """The counts of :func:`format_counts`; raises ``ValueError`` with the reason on anything else.

    Every stream of :data:`STREAMS` must appear exactly once with a count in ``[0, 2**63)``;
    besides them, at most :data:`MAX_TOPICS` distinct topic names may.
    """
    if len(text) > 2000:
        raise ValueError(f'counts text of {len(text)} characters (at most 2000)')
    out: dict[str, int] = {}
    topics = 0
    for item in text.split():
        key, sep, value = item.partition('=')
        topic = is_topic_stream(key)
        topics += topic
        if not sep or (key not in STREAMS and not topic) or key in out or topics > MAX_TOPICS:
            raise ValueError(f'unexpected item {item[:40]!r} in counts {text[:80]!r}')
        if not value.isdigit() or len(value) > 19 or int(value) > _MAX_COUNT:
            raise ValueError(f'count {item[:40]!r} is not an integer in [0, 2**63)')
        out[key] = int(value)
    missing = [s for s in STREAMS if s not in out]
    if missing:
        raise ValueError(f'counts {text[:80]!r} lack {", ".join(missing)}')
    return out


def format_ticks(ticks: Sequence[tuple[int, Mapping[str, int]]]) -> str:
    """The acknowledgements ``[(stamp ns, counts), ...]`` of consecutive ticks (stamps increasing) as one
    text: :func:`format_counts` of the last, then per earlier tick, latest first, ``' | <ns before the
    next> key=<what it had not yet published> ...'`` (the keys that differ only)."""
    if not ticks:
        raise ValueError('no tick to format')
    parts = [format_counts(ticks[-1][1])]
    for (stamp, counts), (later, later_counts) in zip(ticks[-2::-1], ticks[:0:-1], strict=True):
        if later <= stamp:
            raise ValueError(f'tick {later} ns does not follow {stamp} ns')
        less = ''.join(f' {k}={n - counts.get(k, 0)}' for k, n in later_counts.items() if n != counts.get(k, 0))
        parts.append(f'{later - stamp}{less}')
    return _TICK_SEP.join(parts)


def parse_ticks(text: str, stamp_ns: int) -> list[tuple[int, dict[str, int]]]:
    """The acknowledgements of :func:`format_ticks` whose last tick is ``stamp_ns``, in tick order;
    raises ``ValueError`` with the reason on anything else (counts that would go negative, a tick
    not before the next, more than :data:`MAX_TICKS` ticks)."""
    if len(text) > 2000 * MAX_TICKS:
        raise ValueError(f'ticks text of {len(text)} characters (at most {2000 * MAX_TICKS})')
    head, *earlier = text.split(_TICK_SEP)
    if len(earlier) >= MAX_TICKS:
        raise ValueError(f'{len(earlier) + 1} ticks in one acknowledgement (at most {MAX_TICKS})')
    counts = parse_counts(head)
    out = [(stamp_ns, counts)]
    for part in earlier:
        gap, *items = part.split()
        if not gap.isdigit() or not 0 < int(gap) <= stamp_ns or len(gap) > 19:
            raise ValueError(f'tick gap {gap[:25]!r} is not a positive integer up to the tick, in ns')
        stamp_ns -= int(gap)
        counts = dict(counts)
        for item in items:
            key, _, value = item.partition('=')
            if key not in counts or not value.isdigit() or len(value) > 19 or int(value) > counts[key]:
                raise ValueError(f'unexpected item {item[:40]!r} in the tick before {stamp_ns + int(gap)} ns')
            counts[key] -= int(value)
        out.append((stamp_ns, counts))
    out.reverse()
    return out


@dataclass
class _Producer:
    acks: deque[tuple[int, dict[str, int], int]] = field(default_factory=deque)  # (stamp, counts, promise)
    last_ack: int | None = None  # latest acknowledged stamp, ns
    last_counts: dict[str, int] = field(default_factory=dict)
    complete: int | None = None  # latest stamp whose messages are all in, ns
    promised: int | None = None  # the promise of that complete acknowledgement, ns
    received: dict[str, int] = field(default_factory=dict)
    lost: bool = False


class TickLedger:
    """What one consumer knows of its producers' ticks (see the module docstring).

    Parameters
    ----------
    producers : iterable of str
        The participants whose ticks this consumer waits for.
    streams : iterable of str
        The streams this consumer counts (of :data:`STREAMS`, or topic names); an
        acknowledged stream it does not count is not waited for.
    """

    def __init__(self, producers: Iterable[str], streams: Iterable[str] = ()) -> None:
        self._streams = tuple(streams)
        unknown = sorted(s for s in set(self._streams) - set(STREAMS) if not is_topic_stream(s))
        if unknown:
            raise ValueError(f'streams {unknown}: not among {STREAMS}')
        self._p: dict[str, _Producer] = {p: _Producer(received=dict.fromkeys(self._streams, 0)) for p in producers}

    @property
    def producers(self) -> tuple[str, ...]:
        """Every producer, lost ones included."""
        return tuple(self._p)

    @property
    def live(self) -> tuple[str, ...]:
        """The producers not declared lost."""
        return tuple(p for p, st in self._p.items() if not st.lost)

    def knows(self, producer: str) -> bool:
        """Whether ``producer`` is one of this ledger's producers."""
        return producer in self._p

    def ack(self, producer: str, stamp_ns: int, counts: Mapping[str, int], promise_ns: int | None = None) -> str | None:
        """Take ``producer``'s acknowledgement of the tick at ``stamp_ns``, promising ``promise_ns``
        (default: the tick itself; never less).

        Returns None if taken (a repeated acknowledgement of the latest tick, as at
        start-up, is taken and changes nothing), else the reason it is refused: an
        unknown or lost producer, a stamp older than the latest acknowledged one,
        counts that go backwards, or a promise before the tick.
        """
        promise = stamp_ns if promise_ns is None else promise_ns
        if promise < stamp_ns:
            return f'promise {promise} ns is before its tick {stamp_ns} ns'

        st = self._p.get(producer)
        if st is None:
            return f'{producer!r} is not a participant here'
        if st.lost:
            return f'{producer!r} was declared lost'
        if st.last_ack is not None:
            if stamp_ns < st.last_ack:
                return f'tick {stamp_ns} ns is older than the acknowledged {st.last_ack} ns'
            if stamp_ns == st.last_ack:
                return None
            if any(int(counts.get(s, 0)) < st.last_counts.get(s, 0) for s in self._streams):
                return f'counts {dict(counts)} go backwards from {st.last_counts}'
        st.last_ack = stamp_ns
        st.last_counts = {s: int(counts.get(s, 0)) for s in self._streams}
        st.acks.append((stamp_ns, st.last_counts, promise))
        self._settle(st)
        return None

    def received(self, producer: str, stream: str, n: int = 1) -> bool:
        """Count ``n`` messages of ``stream`` received from ``producer``; False if it is not counted here."""
        st = self._p.get(producer)
        if st is None or stream not in st.received:
            return False
        st.received[stream] += n
        if st.acks:
            self._settle(st)
        return True

    def _settle(self, st: _Producer) -> None:
        while st.acks and all(st.received[s] >= n for s, n in st.acks[0][1].items()):
            st.complete, _, st.promised = st.acks.popleft()

    def complete(self, producer: str) -> int | None:
        """Latest tick (ns) of ``producer`` whose messages are all in (None: none yet)."""
        return self._p[producer].complete

    def last_ack(self, producer: str) -> int | None:
        """Latest tick (ns) ``producer`` acknowledged."""
        return self._p[producer].last_ack

    def promised(self, producer: str) -> int | None:
        """The promise (ns) of ``producer``'s latest complete tick (None: none yet)."""
        return self._p[producer].promised

    def complete_through(self, stamp_ns: int) -> bool:
        """Whether every live producer's ticks up to ``stamp_ns`` are complete."""
        return self.ready(stamp_ns)

    @staticmethod
    def _ready(st: _Producer, stamp_ns: int, promise_ns: int | None) -> bool:
        if st.lost:
            return True
        if st.complete is None or st.promised is None:
            return False
        return st.complete >= stamp_ns or (promise_ns is not None and st.promised >= promise_ns)

    def ready(self, stamp_ns: int, promise_ns: int | None = None) -> bool:
        """Whether every live producer's ticks up to ``stamp_ns`` are complete, or (``promise_ns`` given) a
        complete tick of it promises at least ``promise_ns``."""
        return all(self._ready(st, stamp_ns, promise_ns) for st in self._p.values())

    def waiting_for(self, stamp_ns: int, promise_ns: int | None = None) -> list[str]:
        """The live producers that :meth:`ready` still waits for, in order."""
        return [p for p, st in self._p.items() if not self._ready(st, stamp_ns, promise_ns)]

    def missing(self, producer: str) -> dict[str, int]:
        """Per stream, how many acknowledged messages of ``producer`` have not arrived (positive only)."""
        st = self._p[producer]
        if not st.acks:
            return {}
        want = st.acks[-1][1]
        return {s: n - st.received[s] for s, n in want.items() if n > st.received[s]}

    def lose(self, producer: str) -> bool:
        """Declare ``producer`` lost: it is no longer waited for. False if it already was."""
        st = self._p[producer]
        if st.lost:
            return False
        st.lost = True
        st.acks.clear()
        return True

    def is_lost(self, producer: str) -> bool:
        """Whether ``producer`` was declared lost."""
        return self._p[producer].lost
