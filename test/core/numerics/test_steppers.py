"""RK4Stepper and Dopri5Stepper: resumable runs whose steps do not depend on where they are advanced to."""

from __future__ import annotations

import copy
import functools
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from folder_line.core.numerics.dense import DenseSolution
from folder_line.core.numerics.dopri5_stepper import Dopri5Stepper
from folder_line.core.numerics.integrators import dopri5, rk4
from folder_line.core.numerics.rk4_stepper import RK4Stepper
from folder_line.core.numerics.stepper import Breaks, Terminal
from folder_line.errors import IntegrationError

Stepper = RK4Stepper | Dopri5Stepper


# ------------------------------------------------------------------ problems


def oscillator(t: float, y: np.ndarray) -> np.ndarray:
    return np.array([y[1], -y[0]])


def decay(t: float, y: np.ndarray) -> np.ndarray:
    return -y


def grid(step: float) -> Callable[[float], float]:
    def next_after(v: float) -> float:  # the smallest k step above v
        k = math.floor(v / step) + 1
        while k * step <= v:
            k += 1
        return k * step

    return next_after


def loaded_motor(t: float, y: np.ndarray, piece: tuple[float, float]) -> np.ndarray:
    # phase, speed, work: the load switches with the piece of the phase (breaks every 0.3)
    load = 0.2 * (round(piece[0] / 0.3) % 3)
    return np.array([y[1], 5.0 * (1.0 - y[1]) - load - 0.3 * math.sin(y[0]), y[1] * (1.0 + load)])


def rough(t: float, y: np.ndarray, piece: tuple[float, float]) -> np.ndarray:
    # fast forcing and loose tolerances: rejected steps, and break landings whose shorter redo fails
    w = 110.36914384693884
    return np.array(
        [
            1.0 + 0.9 * math.sin(w * t),
            0.235039654891035 * math.sin(w * y[0] * (1 + piece[0])) * y[1] + math.cos(3 * w * t),
        ]
    )


def stop_at_1_2(t: float, y: np.ndarray, b: float) -> bool:
    return b >= 1.2 - 1e-12  # stateless, so a deep copy behaves like the original


@dataclass(frozen=True)
class Problem:
    method: str
    fun: Callable[..., np.ndarray]
    t1: float
    y0: tuple[float, ...]
    options: dict[str, Any] = field(default_factory=dict)

    def stepper(self, t_bound: float | None = None, **extra: Any) -> Stepper:
        tb = self.t1 if t_bound is None else t_bound
        cls = RK4Stepper if self.method == 'rk4' else Dopri5Stepper
        return cls(self.fun, 0.0, self.y0, t_bound=tb, **{**self.options, **extra})

    def wrapper(self) -> DenseSolution:
        if self.method == 'rk4':
            opts = dict(self.options)
            h = opts.pop('h')
            return rk4(self.fun, (0.0, self.t1), self.y0, h, **opts)
        return dopri5(self.fun, (0.0, self.t1), self.y0, **self.options)


PROBLEMS = {
    'rk4': Problem('rk4', oscillator, 5.03, (1.0, 0.0), {'h': 0.07}),
    'dopri5': Problem('dopri5', oscillator, 10.0, (1.0, 0.0), {'rtol': 1e-8, 'atol': 1e-10}),
    'rk4-breaks': Problem('rk4', loaded_motor, 4.0, (0.0, 0.0, 0.0), {'h': 0.05, 'breaks': Breaks(0, grid(0.3))}),
    'dopri5-breaks': Problem(
        'dopri5',
        loaded_motor,
        4.0,
        (0.0, 0.0, 0.0),
        {'rtol': 1e-7, 'atol': [1e-9, 1e-9, 1e-6], 'max_step': 0.2, 'breaks': Breaks(0, grid(0.3))},
    ),
    'dopri5-rough': Problem(
        'dopri5',
        rough,
        3.0,
        (0.0, 1.0),
        {'rtol': 0.004115569496215322, 'atol': 4.115569496215322e-05, 'breaks': Breaks(0, grid(0.3792214232506552))},
    ),
    'rk4-on-break': Problem(
        'rk4', loaded_motor, 10.0, (0.0, 0.0, 0.0), {'h': 0.05, 'breaks': Breaks(0, grid(0.3), stop_at_1_2)}
    ),
    'dopri5-on-break': Problem(
        'dopri5', loaded_motor, 10.0, (0.0, 0.0, 0.0), {'first_step': 0.01, 'breaks': Breaks(0, grid(0.3), stop_at_1_2)}
    ),
    'rk4-terminal': Problem('rk4', oscillator, 10.0, (1.0, 0.0), {'h': 0.01, 'terminal': Terminal(0, 0.0)}),
    'dopri5-terminal': Problem(
        'dopri5', oscillator, 10.0, (1.0, 0.0), {'rtol': 1e-9, 'atol': 1e-12, 'terminal': Terminal(0, 0.0)}
    ),
}


@functools.cache
def reference(name: str) -> DenseSolution:
    """The one-call run of a problem (rk4 or dopri5)."""
    return PROBLEMS[name].wrapper()


def fingerprint(sol: DenseSolution) -> tuple[object, ...]:
    return (
        sol.method,
        sol.t.tobytes(),
        sol.y.tobytes(),
        sol.h.tobytes(),
        sol.coef.tobytes(),
        sol.break_t.tobytes(),
        sol.break_value.tobytes(),
        sol.nfev,
        sol.steps,
        sol.rejected,
        sol.status,
        sol.max_landing_error,
    )


def assert_same(a: DenseSolution, b: DenseSolution) -> None:
    """Bit for bit the same steps, dense output and counters."""
    assert a.steps == b.steps, (a.steps, b.steps)
    np.testing.assert_array_equal(a.t, b.t)  # readable failures first
    np.testing.assert_array_equal(a.y, b.y)
    assert fingerprint(a) == fingerprint(b)


def test_the_problems_exercise_what_they_claim() -> None:
    assert reference('rk4').status == 'finished' and reference('rk4').t_end == 5.03
    assert reference('dopri5').rejected > 0
    for name in ('rk4-breaks', 'dopri5-breaks', 'dopri5-rough'):
        assert reference(name).status == 'finished' and reference(name).break_t.size >= 7
    assert reference('dopri5-rough').rejected > 5
    for name in ('rk4-on-break', 'dopri5-on-break'):
        sol = reference(name)
        assert sol.status == 'stopped' and sol.break_value.tolist() == pytest.approx([0.3, 0.6, 0.9, 1.2])
        assert sol.t_end < 5.0
    for name in ('rk4-terminal', 'dopri5-terminal'):
        assert reference(name).status == 'terminal'
        assert reference(name).t_end == pytest.approx(math.pi / 2, abs=1e-9)


# ------------------------------------------------------------------ chunked advance == one advance == wrapper


@pytest.mark.parametrize('name', PROBLEMS)
def test_one_advance_is_the_wrapper(name: str) -> None:
    p = PROBLEMS[name]
    s = p.stepper()
    assert s.status == 'running' and s.t == 0.0
    s.advance(p.t1)
    assert_same(s.solution(), reference(name))
    assert s.status == reference(name).status
    assert s.t == reference(name).t_end
    np.testing.assert_array_equal(s.y, reference(name).y[-1])


def _chunk_ends(t: np.ndarray) -> st.SearchStrategy[list[float]]:
    """Chunk ends anywhere (before t0 and past the end too), exactly on a step end, one ulp
    either side of one, each possibly repeated, in any order or increasing."""
    ends = [float(v) for v in t]
    on_step = st.sampled_from(ends)
    near_step = st.tuples(on_step, st.sampled_from([-math.inf, math.inf])).map(
        lambda p: float(np.nextafter(p[0], p[1]))
    )
    anywhere = st.floats(ends[0] - 0.1, ends[-1] + 0.1, allow_nan=False)
    one = st.one_of(anywhere, on_step, near_step)
    repeated = st.lists(st.tuples(one, st.integers(1, 3)), min_size=1, max_size=20).map(
        lambda ps: [v for v, k in ps for _ in range(k)]
    )
    return st.tuples(repeated, st.booleans()).map(lambda r: sorted(r[0]) if r[1] else r[0])


def _advance_in_chunks(s: Stepper, ends: list[float]) -> None:
    for u in ends:
        before, status_before = s.t, s.status
        s.advance(u)
        if not before < u or status_before != 'running':
            assert s.t == before  # already covered, or no longer running: nothing happens
        elif s.status == 'running':
            sol = s.solution()
            # the last step straddles u (or ends on it); the one before it ends before u
            assert sol.t[-1] == s.t and sol.t[-2] < u <= s.t


@pytest.mark.parametrize('name', PROBLEMS)
@settings(max_examples=25, deadline=None)
@given(data=st.data())
def test_advancing_in_chunks_takes_the_steps_of_one_advance(name: str, data: st.DataObject) -> None:
    p = PROBLEMS[name]
    ref = reference(name)
    ends = data.draw(_chunk_ends(ref.t), label='chunk ends')
    s = p.stepper()
    _advance_in_chunks(s, ends)
    s.advance(p.t1)
    assert_same(s.solution(), ref)


@pytest.mark.parametrize('name', PROBLEMS)
def test_chunks_on_every_step_end_in_the_middle_of_every_step_and_repeated(name: str) -> None:
    p = PROBLEMS[name]
    ref = reference(name)
    on_ends = p.stepper()
    for v in ref.t:
        on_ends.advance(float(v))
        on_ends.advance(float(v))
    assert_same(on_ends.solution(), ref)
    mid = p.stepper()
    for a, b in zip(ref.t[:-1], ref.t[1:], strict=True):
        m = float(0.5 * (a + b))
        mid.advance(m)
        assert mid.t == b  # the step that straddles m, not one cut at m
        mid.advance(m)
        mid.advance(float(a))
    assert_same(mid.solution(), ref)


def test_a_finished_stepper_does_nothing() -> None:
    p = PROBLEMS['rk4']
    s = p.stepper()
    s.advance(100.0)  # past t_bound: stops there
    assert s.status == 'finished' and s.t == p.t1
    before = fingerprint(s.solution())
    s.advance(200.0)
    assert fingerprint(s.solution()) == before and s.t == p.t1


# ------------------------------------------------------------------ streams (t_bound = inf)


@pytest.mark.parametrize('name', ['rk4', 'dopri5', 'rk4-breaks', 'dopri5-breaks', 'dopri5-rough'])
@settings(max_examples=15, deadline=None)
@given(windows=st.lists(st.floats(1e-3, 0.7), min_size=1, max_size=25))
def test_a_stream_takes_the_steps_of_an_unbroken_run(name: str, windows: list[float]) -> None:
    p = PROBLEMS[name]
    chunked = p.stepper(t_bound=math.inf)
    until = 0.0
    for w in windows:
        until += w
        chunked.advance(until)
        assert chunked.status == 'running' and chunked.t >= until
    unbroken = p.stepper(t_bound=math.inf)
    unbroken.advance(until)
    a, b = chunked.solution(), unbroken.solution()
    np.testing.assert_array_equal(a.t, b.t)  # no step shortened at a chunk end
    assert_same(a, b)
    assert a.status == 'running'


def test_an_rk4_stream_stays_on_its_grid() -> None:
    h = 0.07
    s = RK4Stepper(oscillator, 0.0, [1.0, 0.0], h=h)
    for until in np.arange(1, 200) * 0.123:
        s.advance(float(until))
    t = s.solution().t
    assert t.tobytes() == (np.arange(t.size) * h).tobytes()
    # and the steps before the clipped last one are those of a finite run
    ref = rk4(oscillator, (0.0, 10.0), [1.0, 0.0], h)
    np.testing.assert_array_equal(s.solution().coef[:, : ref.steps - 1], ref.coef[:, : ref.steps - 1])


def test_a_stream_is_not_cut_by_max_steps_over_many_calls() -> None:
    s = RK4Stepper(decay, 0.0, [1.0], h=0.01, max_steps=50)
    for k in range(1, 11):
        s.advance(0.2 * k)  # 20 steps per call
    assert s.solution().steps >= 200
    with pytest.raises(IntegrationError, match='max_steps=50') as info:
        s.advance(s.t + 1.0)  # 100 steps in one call, and nothing can end it early: refused before a step
    assert info.value.step == s.solution().steps
    d = Dopri5Stepper(decay, 0.0, [1.0], max_step=0.01, max_steps=50)
    with pytest.raises(IntegrationError, match='max_steps=50'):
        d.advance(math.inf)
    assert d.t == 0.0


@pytest.mark.parametrize('name', ['rk4-breaks', 'dopri5-rough', 'dopri5'])
def test_after_max_steps_a_stream_goes_on_with_the_steps_of_an_unbroken_run(name: str) -> None:
    # max_steps=1 with a terminal condition that never fires: every call stops after one step or
    # attempt (dopri5: also right after a rejection or a failed landing redo), and the run resumes
    p = PROBLEMS[name]
    never = Terminal(1, 1e9)
    s = p.stepper(terminal=never, max_steps=1)
    errors = 0
    while s.t < p.t1:
        try:
            s.advance(p.t1)
        except IntegrationError as e:
            assert 'max_steps=1' in str(e)
            errors += 1
    unbroken = p.stepper(terminal=never)
    unbroken.advance(p.t1)
    assert_same(s.solution(), unbroken.solution())
    assert errors >= unbroken.solution().steps - 1


# ------------------------------------------------------------------ prune


@pytest.mark.parametrize('name', ['rk4-breaks', 'dopri5-breaks', 'dopri5'])
def test_prune_keeps_the_values_on_the_kept_range_and_bounds_the_steps(name: str) -> None:
    p = PROBLEMS[name]
    window, n_windows = 0.5, 60
    full = p.stepper(t_bound=math.inf)
    full.advance(window * n_windows)
    F = full.solution()
    j = 0  # the phase of the loaded motor: non-decreasing, so it has an inverse
    s = p.stepper(t_bound=math.inf)
    twin = p.stepper(t_bound=math.inf)  # advanced alike, never pruned
    kept_max = 0
    for k in range(1, n_windows + 1):
        t_keep = window * (k - 1)
        s.advance(window * k)
        twin.advance(window * k)
        s.prune(t_keep)
        sol, whole = s.solution(), twin.solution()
        kept_max = max(kept_max, sol.steps)
        # exactly the steps of the unbroken run that end at or after t_keep (at least one)
        i_end = int(np.searchsorted(F.t, s.t))
        assert F.t[i_end] == s.t == whole.t_end
        d = min(int(np.searchsorted(F.t[1:], t_keep, side='left')), i_end - 1)
        assert sol.t[0] <= t_keep and (d == 0 or F.t[d] < t_keep)
        assert sol.t.tobytes() == F.t[d : i_end + 1].tobytes()
        assert sol.coef.tobytes() == F.coef[:, d:i_end].tobytes()
        # the dense output on the kept range, bit for bit (the end included)
        tt = np.linspace(t_keep, s.t, 97)
        assert sol(tt).tobytes() == whole(tt).tobytes()
        assert sol.component(tt, 1).tobytes() == whole.component(tt, 1).tobytes()
        assert sol.derivative(tt).tobytes() == whole.derivative(tt).tobytes()
        if p.fun is loaded_motor:
            targets = np.linspace(sol.y[0, j], sol.y[-1, j], 101)[1:]
            assert sol.inverse(targets, j).tobytes() == whole.inverse(targets, j).tobytes()
            kept_breaks = whole.break_t[whole.break_t >= sol.t[0]]
            assert sol.break_t.tobytes() == kept_breaks.tobytes()
        assert (sol.nfev, sol.rejected) == (whole.nfev, whole.rejected)
    assert (sol.nfev, sol.rejected) == (F.nfev, F.rejected)
    assert kept_max * 20 < F.steps  # bounded by about two windows of steps, not the whole run
    if p.fun is loaded_motor:
        assert 0 < sol.break_t.size * 10 < whole.break_t.size  # the breaks before the kept steps are dropped too


def test_prune_keeps_the_last_step_and_ignores_what_is_already_gone() -> None:
    s = RK4Stepper(decay, 0.0, [1.0], h=0.1)
    s.advance(1.0)
    s.prune(50.0)
    sol = s.solution()
    assert sol.steps == 1 and sol.t[-1] == s.t
    s.prune(0.0)
    assert s.solution().steps == 1
    s.advance(2.0)
    assert s.solution().steps == 11
    with pytest.raises(ValueError, match='prune'):
        s.prune(math.nan)


def test_prune_keeps_a_step_that_ends_on_t_keep() -> None:
    s = RK4Stepper(decay, 0.0, [1.0], h=0.125)  # a grid of exact binary fractions
    s.advance(2.0)
    s.prune(1.0)
    assert s.solution().t[0] == 0.875  # the step [0.875, 1.0] ends on t_keep, not before it
    s.prune(float(np.nextafter(1.0, 2.0)))
    assert s.solution().t[0] == 1.0
    assert s.solution().steps == 8


# ------------------------------------------------------------------ deepcopy


@pytest.mark.parametrize('name', PROBLEMS)
def test_a_deep_copy_is_an_independent_stepper(name: str) -> None:
    p = PROBLEMS[name]
    ref = reference(name)
    u1 = float(0.5 * (ref.t[ref.steps // 3] + ref.t[ref.steps // 3 + 1]))
    s = p.stepper()
    s.advance(u1)
    before, t_before, y_before = fingerprint(s.solution()), s.t, s.y
    c = copy.deepcopy(s)
    assert fingerprint(c.solution()) == before
    c.advance(p.t1)
    c.prune(u1)
    # running and pruning the copy leaves the original where it was
    assert fingerprint(s.solution()) == before and s.t == t_before and s.status == 'running'
    assert s.y.tobytes() == y_before.tobytes()
    # the original takes the same steps in other chunks ...
    s.advance(float(ref.t[2 * ref.steps // 3]))
    s.advance(p.t1)
    assert_same(s.solution(), ref)
    # ... and that did not touch the copy
    kept = c.solution()
    assert kept.t.tobytes() == ref.t[-kept.t.size :].tobytes()
    assert kept.nfev == ref.nfev and c.status == ref.status


def test_y_is_a_copy() -> None:
    s = Dopri5Stepper(oscillator, 0.0, [1.0, 0.0])
    s.advance(1.0)
    y = s.y
    y[:] = 99.0
    assert s.y[0] != 99.0
    s2 = copy.deepcopy(s)
    s.advance(2.0)
    s2.advance(2.0)
    assert s.y.tobytes() == s2.y.tobytes()


# ------------------------------------------------------------------ errors and validation


def test_a_non_finite_rhs_in_a_stream_raises_naming_the_step_and_time() -> None:
    def stiff(t: float, y: np.ndarray) -> np.ndarray:
        return -1000.0 * y

    with pytest.raises(IntegrationError) as whole:
        rk4(stiff, (0.0, 1000.0), [1.0], 1.0)
    s = RK4Stepper(stiff, 0.0, [1.0], h=1.0)
    s.advance(5.5)
    s.advance(12.0)
    with pytest.raises(IntegrationError) as info:
        s.advance(1000.0)
    err = info.value
    assert (err.method, err.step, err.t, err.h) == (whole.value.method, whole.value.step, whole.value.t, 1.0)
    assert 10 < err.step < 200 and err.t == float(err.step)
    assert f'step {err.step}' in str(err) and 'non-finite' in str(err)
    assert s.t == err.t and np.all(np.isfinite(s.y))  # the stepper keeps its last good step

    def bad(t: float, y: np.ndarray) -> np.ndarray:
        return np.array([np.inf if t > 0.5 else -y[0]])

    d = Dopri5Stepper(bad, 0.0, [1.0])
    d.advance(0.2)
    with pytest.raises(IntegrationError, match='step size fell below') as info:
        d.advance(1.0)
    assert info.value.method == 'dopri5' and info.value.t == pytest.approx(0.5, abs=1e-12)
    assert f'step {info.value.step} starting at t=' in str(info.value)
    with pytest.raises(IntegrationError, match='initial state'):
        RK4Stepper(lambda t, y: np.array([np.nan]), 0.0, [1.0], h=0.1)
    with pytest.raises(IntegrationError, match='initial state'):
        Dopri5Stepper(lambda t, y: np.array([np.nan]), 0.0, [1.0])


@pytest.mark.parametrize('cls', [RK4Stepper, Dopri5Stepper])
def test_bad_arguments(cls: type[RK4Stepper] | type[Dopri5Stepper]) -> None:
    kw: dict[str, Any] = {'h': 0.1} if cls is RK4Stepper else {}
    for t0, t_bound in [(0.0, 0.0), (1.0, 0.5), (0.0, -math.inf), (0.0, math.nan), (math.inf, math.inf)]:
        with pytest.raises(ValueError, match='t_bound'):
            cls(decay, t0, [1.0], t_bound=t_bound, **kw)
    with pytest.raises(ValueError, match='y0'):
        cls(decay, 0.0, [], **kw)
    with pytest.raises(ValueError, match='breaks'):
        cls(decay, 0.0, [1.0], breaks=Breaks(3, grid(1.0)), **kw)
    s = cls(decay, 0.0, [1.0], **kw)  # t_bound = inf
    with pytest.raises(ValueError, match='no step'):
        s.solution()
    with pytest.raises(ValueError, match='until'):
        s.advance(math.nan)
    s.advance(-1.0)
    assert s.t == 0.0 and s.status == 'running'
