from __future__ import annotations

import math
from fractions import Fraction

import pytest
from hypothesis import given
from hypothesis import strategies as st

from folder_line.core.numerics.timebase import ShaftClock
from folder_line.interfaces import NS_PER_S, seconds_to_ns


def test_knife_crank_period_is_exact() -> None:
    clock = ShaftClock(Fraction(50000, 3600))  # 50000 rev/h
    assert clock.period_ns() == 72_000_000
    assert clock.turns(72_000_000) == (1, 0.0)


def test_no_drift_after_a_billion_turns() -> None:
    clock = ShaftClock(Fraction(50000, 3600))
    t = 10**9 * 72_000_000 + 18_000_000  # 1e9 turns + a quarter turn (7.2e7 s of line time)
    whole, frac = clock.turns(t)
    assert whole == 10**9
    assert frac == 0.25
    assert math.isclose(clock.angle(t), math.pi / 2, rel_tol=0, abs_tol=1e-15)


def test_float_speed_is_taken_exactly() -> None:
    clock = ShaftClock(0.5)  # 30 rev/min
    assert clock.turns(4 * NS_PER_S * 10**7) == (2 * 10**7, 0.0)  # 4e7 s
    assert clock.turns(-1 * NS_PER_S)[0] == -1


@given(whole=st.integers(min_value=0, max_value=10**12), frac=st.floats(min_value=0.0, max_value=0.999))
def test_time_of_turn_inverts_turns(whole: int, frac: float) -> None:
    clock = ShaftClock(Fraction(50000, 3600), phase0=0.125)
    t = clock.time_of_turn(whole, frac)
    w, f = clock.turns(t)
    assert (w - whole) + (f - frac) == pytest.approx(0.0, abs=1.0 / 72_000_000)  # within 1 ns of shaft time


def test_phase0_and_rounding() -> None:
    clock = ShaftClock(1.0, phase0=0.75)
    assert clock.turns(500_000_000) == (1, 0.25)
    assert seconds_to_ns(0.072) == 72_000_000
    with pytest.raises(ValueError, match='rev_per_s'):
        ShaftClock(-1.0)
    with pytest.raises(ValueError, match='seconds='):
        seconds_to_ns(float('nan'))
