"""The lockstep ledger (pure): a tick is complete only when its acknowledgement and every counted message are in."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from folder_line.core.supervision.lockstep import (
    MAX_TICKS,
    STREAMS,
    TickLedger,
    format_counts,
    format_ticks,
    parse_counts,
    parse_ticks,
)


def counts(messages: int = 0, events: int = 0, commands: int = 0) -> dict[str, int]:
    return {'messages': messages, 'events': events, 'commands': commands}


def test_counts_round_trip_and_refusals() -> None:
    c = counts(12, 3, 1)
    assert format_counts(c) == 'messages=12 events=3 commands=1'
    assert parse_counts(format_counts(c)) == c
    for bad, why in [
        ('', 'lack'),
        ('messages=1 events=2', 'lack commands'),
        ('messages=1 events=2 commands=x', 'integer'),
        ('messages=1 events=2 commands=-1', 'integer'),
        ('messages=1 messages=2 events=0 commands=0', 'unexpected'),
        ('jump=1 messages=1 events=2 commands=0', 'unexpected'),
        ('x' * 2001, 'at most 2000'),
        ('messages=1 events=2 commands=0 /a=1 /a=2', 'unexpected'),
        ('messages=1 events=2 commands=0 /a b=1', 'unexpected'),
        ('messages=1 events=2 commands=0 ' + ' '.join(f'/t{i}=1' for i in range(17)), 'unexpected'),
        ('messages=99999999999999999999 events=0 commands=0', 'integer'),
    ]:
        with pytest.raises(ValueError, match=why):
            parse_counts(bad)


def test_per_topic_counts_round_trip_and_are_counted() -> None:
    c = {**counts(4, 1), '/line/supervisor/state': 3}
    text = format_counts(c)
    assert text == 'messages=4 events=1 commands=0 /line/supervisor/state=3'
    assert parse_counts(text) == c
    ledger = TickLedger(['supervisor'], ['/line/supervisor/state'])
    assert ledger.ack('supervisor', 10, c) is None
    for _ in range(2):
        ledger.received('supervisor', '/line/supervisor/state')
    assert not ledger.complete_through(10)
    ledger.received('supervisor', '/line/supervisor/state')
    assert ledger.complete_through(10)


def test_a_promise_lets_a_consumer_run_ahead_of_the_complete_tick() -> None:
    ledger = TickLedger(['supervisor'], ['commands'])
    assert ledger.ack('supervisor', 10, counts(commands=1), promise_ns=50) is None
    assert not ledger.ready(15, 40)  # the command it counted is not in: nothing is promised yet
    ledger.received('supervisor', 'commands')
    assert ledger.promised('supervisor') == 50
    assert ledger.ready(15, 50) and ledger.ready(10) and not ledger.ready(15, 51) and not ledger.ready(11)
    assert ledger.waiting_for(15, 51) == ['supervisor'] and ledger.waiting_for(15, 50) == []
    assert 'before its tick' in (ledger.ack('supervisor', 20, counts(commands=1), promise_ns=19) or '')
    assert ledger.ack('supervisor', 20, counts(commands=1)) is None  # no promise: the tick itself
    assert ledger.promised('supervisor') == 20 and not ledger.ready(21, 30)


def test_a_tick_is_complete_only_when_its_messages_are_in() -> None:
    ledger = TickLedger(['crank_drive', 'supervisor'], ['events'])
    assert ledger.ack('crank_drive', 5, counts(events=2)) is None
    assert ledger.complete('crank_drive') is None and not ledger.complete_through(5)
    assert ledger.waiting_for(5) == ['crank_drive', 'supervisor']
    assert ledger.missing('crank_drive') == {'events': 2}
    ledger.received('crank_drive', 'events')
    assert ledger.complete('crank_drive') is None  # one of two events in
    ledger.received('crank_drive', 'events')
    assert ledger.complete('crank_drive') == 5
    assert ledger.ack('supervisor', 5, counts()) is None
    assert ledger.complete_through(5) and not ledger.complete_through(6)


def test_messages_may_arrive_before_their_acknowledgement() -> None:
    ledger = TickLedger(['feed_transporter'], ['events'])
    ledger.received('feed_transporter', 'events', 3)  # the events topic was faster than the ack topic
    assert ledger.ack('feed_transporter', 10, counts(events=1)) is None
    assert ledger.ack('feed_transporter', 20, counts(events=3)) is None
    assert ledger.complete('feed_transporter') == 20
    assert ledger.ack('feed_transporter', 30, counts(events=4)) is None
    assert ledger.complete('feed_transporter') == 20


def test_refusals_unknown_lost_backwards() -> None:
    ledger = TickLedger(['a'], ['messages'])
    assert 'not a participant' in ledger.ack('b', 1, counts())  # type: ignore[operator]
    assert ledger.ack('a', 10, counts(messages=5)) is None
    assert ledger.ack('a', 10, counts(messages=5)) is None  # a repeat of the latest: taken, no change
    assert 'older' in ledger.ack('a', 9, counts(messages=5))  # type: ignore[operator]
    assert 'backwards' in ledger.ack('a', 11, counts(messages=4))  # type: ignore[operator]
    assert ledger.lose('a') and not ledger.lose('a')
    assert 'lost' in ledger.ack('a', 12, counts(messages=9))  # type: ignore[operator]
    assert ledger.complete_through(10**18) and ledger.waiting_for(10**18) == []  # a lost producer is not waited for
    assert not ledger.received('b', 'messages') and not ledger.received('a', 'events')
    with pytest.raises(ValueError, match='streams'):
        TickLedger(['a'], ['bytes'])


@settings(max_examples=200, deadline=None)
@given(data=st.data(), n_ticks=st.integers(1, 12))
def test_any_interleaving_completes_exactly_the_ticks_whose_messages_are_in(data: st.DataObject, n_ticks: int) -> None:
    """Acks and messages interleaved in any order (each topic in order): complete = the latest ack covered."""
    per_tick = data.draw(st.lists(st.integers(0, 3), min_size=n_ticks, max_size=n_ticks))
    total = [sum(per_tick[: k + 1]) for k in range(n_ticks)]
    acks = [('ack', k) for k in range(n_ticks)]
    msgs = [('msg', i) for i in range(total[-1])]
    order: list[tuple[str, int]] = []
    while acks or msgs:  # a random merge of the two ordered streams
        pick = data.draw(st.booleans()) if acks and msgs else bool(acks)
        order.append(acks.pop(0) if pick else msgs.pop(0))
    ledger = TickLedger(['n'], ['events'])
    received = acked = 0
    for what, k in order:
        if what == 'ack':
            assert ledger.ack('n', (k + 1) * 1000, counts(events=total[k])) is None
            acked = k + 1
        else:
            ledger.received('n', 'events')
            received += 1
        covered = [k for k in range(acked) if total[k] <= received]
        assert ledger.complete('n') == (None if not covered else (covered[-1] + 1) * 1000)
    assert ledger.complete('n') == n_ticks * 1000


def test_streams_are_the_acknowledged_ones() -> None:
    assert STREAMS == ('messages', 'events', 'commands')


@settings(max_examples=200, deadline=None)
@given(
    st.lists(
        st.tuples(st.integers(1, 10**9), st.integers(0, 3), st.integers(0, 2), st.integers(0, 2), st.integers(0, 1)),
        min_size=1,
        max_size=MAX_TICKS,
    )
)
def test_ticks_round_trip(steps: list[tuple[int, int, int, int, int]]) -> None:
    """Several ticks' acknowledgements in one text come back as they were, in order: stamps and every count
    (a topic first counted at a later tick reads as 0 before it)."""
    ticks: list[tuple[int, dict[str, int]]] = []
    stamp, c = 0, {**counts(), '/line/a': 0}
    for gap, m, e, a, b in steps:
        stamp += gap
        c = dict(c)
        c['messages'] += m + e + a + b
        c['events'] += e
        c['/line/a'] += a
        if b or '/line/b' in c:
            c['/line/b'] = c.get('/line/b', 0) + b
        ticks.append((stamp, c))
    back = parse_ticks(format_ticks(ticks), stamp)
    assert [s for s, _ in back] == [s for s, _ in ticks]
    for (_, got), (_, want) in zip(back, ticks, strict=True):
        assert {k: n for k, n in got.items() if n or k in want} == want


def test_ticks_refusals() -> None:
    """A tick text that is not one of format_ticks is refused with the reason; nothing of it is taken."""
    head = 'messages=4 events=1 commands=0 /a=3'
    assert parse_ticks(head, 20) == [(20, {**counts(4, 1), '/a': 3})]
    for bad, why in [
        (head + ' | 0 messages=1', 'positive'),
        (head + ' | x messages=1', 'positive'),
        (head + ' | 21 messages=1', 'up to the tick'),
        (head + ' | 5 messages=5', 'unexpected item'),  # a count below zero
        (head + ' | 5 /b=1', 'unexpected item'),  # a key the later tick does not have
        (head + ' | 5 messages=-1', 'unexpected item'),
        (head + ' | 1' * MAX_TICKS, f'at most {MAX_TICKS}'),
        ('messages=4 events=1', 'lack'),
    ]:
        with pytest.raises(ValueError, match=why):
            parse_ticks(bad, 20)
    with pytest.raises(ValueError, match='does not follow'):
        format_ticks([(5, counts()), (5, counts())])
