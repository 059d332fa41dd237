from __future__ import annotations

from itertools import pairwise

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from folder_line.core.supervision.packml import ACTING, COMMANDS, STATES, PackML
from folder_line.errors import TransitionError


def test_a_normal_run() -> None:
    m = PackML()
    for cmd in ('reset',):
        m.command(cmd, 0.0)
    m.state_complete(0.1)
    assert m.state == 'IDLE'
    m.command('start', 0.2)
    m.state_complete(0.3)
    m.command('hold', 1.0)
    m.state_complete(1.5)
    assert m.state == 'HELD'
    m.command('unhold', 2.0)
    m.state_complete(2.5)
    m.command('stop', 3.0)
    m.state_complete(3.5)
    assert m.state == 'STOPPED'
    assert [tr.target for tr in m.history] == [
        'RESETTING',
        'IDLE',
        'STARTING',
        'EXECUTE',
        'HOLDING',
        'HELD',
        'UNHOLDING',
        'EXECUTE',
        'STOPPING',
        'STOPPED',
    ]


def test_illegal_commands_are_refused_with_a_reason() -> None:
    m = PackML('EXECUTE')
    with pytest.raises(TransitionError, match=r"'unhold' refused in state EXECUTE: legal only in HELD"):
        m.command('unhold', 1.0)
    with pytest.raises(TransitionError, match='unknown command'):
        m.command('warp', 1.0)
    with pytest.raises(TransitionError, match='not an acting state'):
        m.state_complete(1.0)
    assert m.state == 'EXECUTE' and m.history == []


def test_aborted_is_left_only_by_clear() -> None:
    m = PackML('EXECUTE')
    m.command('abort', 0.0)
    m.state_complete(0.1)
    for cmd in COMMANDS:
        if cmd != 'clear':
            assert not m.allowed(cmd), cmd
    m.command('clear', 1.0)
    assert m.state_complete(1.1).target == 'STOPPED'


@settings(max_examples=300)
@given(st.lists(st.sampled_from([*sorted(COMMANDS), 'state_complete']), max_size=40))
def test_random_sequences_follow_the_table(seq: list[str]) -> None:
    m = PackML()
    for i, cmd in enumerate(seq):
        before = m.state
        if cmd == 'state_complete':
            if before in ACTING:
                assert m.state_complete(float(i)).target == ACTING[before]
            else:
                with pytest.raises(TransitionError):
                    m.state_complete(float(i))
                assert m.state == before
            continue
        legal, target = COMMANDS[cmd]
        if before in legal:
            assert m.command(cmd, float(i)).target == target
        else:
            with pytest.raises(TransitionError):
                m.command(cmd, float(i))
            assert m.state == before
        assert m.state in STATES
    assert all(a.target == b.source for a, b in pairwise(m.history))
