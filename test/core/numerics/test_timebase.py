from __future__ import annotations

import math
from fractions import Fraction

import pytest
from hypothesis import given, settings
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


class TestLongRuns:
    """1e9 crank turns without drift (exact rational references)."""

    @settings(max_examples=60, deadline=None, derandomize=True)
    @given(
        num=st.integers(1, 10**6),
        den=st.integers(1, 10**4),
        turns=st.integers(0, 10**9),
        extra_ns=st.integers(0, 10**9),
        phase0=st.fractions(0, 1, max_denominator=10**6),
    )
    def test_shaft_clock_after_a_billion_turns_is_exact(
        self, num: int, den: int, turns: int, extra_ns: int, phase0: Fraction
    ) -> None:
        speed = Fraction(num, den)  # rev/s
        clock = ShaftClock(speed, phase0=phase0)
        t_ns = int(turns / speed * NS_PER_S) + extra_ns  # ~1e9 turns and beyond
        whole, frac = clock.turns(t_ns)
        exact = Fraction(t_ns, NS_PER_S) * speed + phase0 % 1
        assert whole == math.floor(exact)
        assert abs(Fraction(frac) - (exact - whole)) <= Fraction(1, 2**53)  # only the final float rounding
        # and the time of a turn at 1e9 turns is the nearest nanosecond
        t_back = clock.time_of_turn(turns, 0.25)
        assert abs(Fraction(t_back) - (turns + Fraction(0.25) - phase0 % 1) / speed * NS_PER_S) <= Fraction(1, 2)
