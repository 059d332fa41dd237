"""RK4 and DOPRI5 with dense output, breaks, terminal conditions and the vectorised inverse."""

from __future__ import annotations

import math
from itertools import pairwise

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from folder_line.core.numerics import dense
from folder_line.core.numerics.integrators import dopri5, rk4
from folder_line.core.numerics.stepper import Breaks, Terminal
from folder_line.errors import FolderLineError, IntegrationError


def decay(t: float, y: np.ndarray) -> np.ndarray:
    return -y


def oscillator(t: float, y: np.ndarray) -> np.ndarray:
    return np.array([y[1], -y[0]])


# ------------------------------------------------------------------ exactness


def test_rk4_is_exact_for_quartic_solutions_at_the_steps_and_cubic_in_between() -> None:
    # y' = 4 t^3 -> y = t^4: Simpson's rule (RK4 on a t-only RHS) is exact for cubics
    sol = rk4(lambda t, y: np.array([4 * t**3]), (0.0, 2.0), [0.0], 0.25)
    np.testing.assert_allclose(sol.y[:, 0], sol.t**4, rtol=0, atol=1e-14)
    # y = t^3 is a cubic: the Hermite dense output reproduces it everywhere
    sol3 = rk4(lambda t, y: np.array([3 * t**2]), (0.0, 2.0), [0.0], 0.25)
    t = np.linspace(0.0, 2.0, 777)
    np.testing.assert_allclose(sol3(t)[0], t**3, rtol=0, atol=1e-14)
    # ... but not a quartic in between (so the check above can fail)
    assert np.abs(sol.component(t, 0) - t**4).max() > 1e-6


def test_dopri5_is_exact_for_quintic_solutions_at_the_steps_and_quartic_in_between() -> None:
    sol = dopri5(lambda t, y: np.array([5 * t**4]), (0.0, 2.0), [0.0], rtol=1e-3, atol=1e-6, max_step=0.3)
    np.testing.assert_allclose(sol.y[:, 0], sol.t**5, rtol=0, atol=1e-13)
    sol4 = dopri5(lambda t, y: np.array([4 * t**3]), (0.0, 2.0), [0.0], rtol=1e-3, atol=1e-6, max_step=0.3)
    t = np.linspace(0.0, 2.0, 501)
    np.testing.assert_allclose(sol4.component(t, 0), t**4, rtol=0, atol=1e-13)
    assert np.abs(sol.component(t, 0) - t**5).max() > 1e-8


# ------------------------------------------------------------------ convergence


def _rk4_errors(hs: list[float]) -> np.ndarray:
    t = np.linspace(0.0, 5.0, 1001)
    out = []
    for h in hs:
        sol = rk4(oscillator, (0.0, 5.0), [1.0, 0.0], h)
        out.append((abs(sol.y[-1, 0] - math.cos(5.0)), np.abs(sol.component(t, 0) - np.cos(t)).max()))
    return np.array(out)


def test_rk4_error_is_fourth_order_at_the_steps_and_in_the_dense_output() -> None:
    hs = [0.2, 0.1, 0.05, 0.025]
    err = _rk4_errors(hs)
    orders = np.log2(err[:-1] / err[1:])
    assert np.all((orders > 3.8) & (orders < 4.3)), orders


def test_rk4_decay_matches_the_stability_function() -> None:
    # RK4 on y' = -y multiplies by R(-h) = 1 - h + h^2/2 - h^3/6 + h^4/24 each step
    h = 0.1
    sol = rk4(decay, (0.0, 1.0), [1.0], h)
    R = 1 - h + h**2 / 2 - h**3 / 6 + h**4 / 24
    np.testing.assert_allclose(sol.y[:, 0], R ** np.arange(sol.steps + 1), rtol=1e-14)


def test_dopri5_error_follows_rtol() -> None:
    errs = []
    for rtol in (1e-4, 1e-6, 1e-8, 1e-10):
        sol = dopri5(oscillator, (0.0, 10.0), [1.0, 0.0], rtol=rtol, atol=1e-14)
        t = np.linspace(0.0, 10.0, 2001)
        errs.append(np.abs(sol(t) - np.array([np.cos(t), -np.sin(t)])).max())
        assert errs[-1] < 50 * rtol
    assert all(a > 10 * b for a, b in pairwise(errs)), errs


@pytest.mark.parametrize('problem', ['decay', 'oscillator'])
@pytest.mark.parametrize('rtol', [1e-3, 1e-6, 1e-9])
def test_dopri5_takes_scipys_steps(problem: str, rtol: float) -> None:
    fun, y0 = (decay, [1.0]) if problem == 'decay' else (oscillator, [1.0, 0.0])
    sol = dopri5(fun, (0.0, 10.0), y0, rtol=rtol, atol=1e-12)
    ref = solve_ivp(fun, (0.0, 10.0), y0, method='RK45', rtol=rtol, atol=1e-12, dense_output=True)
    assert sol.steps == ref.t.size - 1
    assert sol.nfev == ref.nfev
    np.testing.assert_allclose(sol.t, ref.t, rtol=1e-15, atol=0)
    np.testing.assert_allclose(sol.y, ref.y.T, rtol=1e-14, atol=1e-15)
    t = np.linspace(0.0, 10.0, 997)
    np.testing.assert_allclose(sol(t), ref.sol(t), rtol=1e-13, atol=1e-15)


def test_dopri5_respects_max_step_and_first_step() -> None:
    sol = dopri5(decay, (0.0, 3.0), [1.0], rtol=1e-3, atol=1e-6, max_step=0.01, first_step=1e-4)
    assert np.diff(sol.t).max() <= 0.01 * (1 + 1e-12)
    assert sol.t[1] == pytest.approx(1e-4)


# ------------------------------------------------------------------ stiff, tiny and huge steps


def test_rk4_huge_steps_on_a_stiff_problem_raise_naming_the_step_and_time() -> None:
    with pytest.raises(IntegrationError) as info:
        rk4(lambda t, y: -1000.0 * y, (0.0, 1000.0), [1.0], 1.0)
    err = info.value
    assert err.method == 'rk4' and err.h == 1.0
    assert err.t == float(err.step)  # step k starts at t = k h
    assert f'step {err.step}' in str(err) and 'non-finite' in str(err)
    assert 10 < err.step < 200  # |R(-1000)| ~ 4e10: overflow after ~30 steps, not at once
    # one error class, defined with the others in folder_line.errors (the CLI catches FolderLineError)
    assert isinstance(err, FolderLineError) and isinstance(err, RuntimeError)
    assert IntegrationError.__module__ == 'folder_line.errors'


def test_rk4_huge_step_on_a_gentle_problem_is_fine() -> None:
    sol = rk4(decay, (0.0, 3.0), [1.0], 1.0)
    R = 1 - 1 + 1 / 2 - 1 / 6 + 1 / 24
    np.testing.assert_allclose(sol.y[:, 0], R ** np.arange(4), rtol=1e-14)


def test_tiny_steps() -> None:
    sol = rk4(decay, (0.0, 1e-6), [1.0], 1e-9)
    assert sol.steps == 1000
    assert sol.y[-1, 0] == pytest.approx(math.exp(-1e-6), rel=1e-15)
    d = dopri5(decay, (0.0, 1e-6), [1.0], rtol=1e-10, atol=1e-14, max_step=1e-9, first_step=1e-9)
    assert d.steps == pytest.approx(1000, abs=2)
    assert d.y[-1, 0] == pytest.approx(math.exp(-1e-6), rel=1e-15)


def test_dopri5_on_a_stiff_start_neither_blows_up_nor_stalls() -> None:
    # motor from standstill: omega' = (T0 (1 - omega/omega0) - b omega)/J, lambda = 1e4 1/s
    lam = 1e4

    def motor(t: float, y: np.ndarray) -> np.ndarray:
        return np.array([y[1], lam * (1.0 - y[1])])

    sol = dopri5(motor, (0.0, 1.0), [0.0, 0.0], rtol=1e-6, atol=1e-9)
    assert np.all(np.isfinite(sol.y))
    assert sol.y[-1, 1] == pytest.approx(1.0, abs=1e-6)
    # stability bounds the step (~3.3/lambda), so it takes ~lambda/3 steps, not millions
    assert 1000 < sol.steps < 10_000
    t = np.linspace(0.0, 1.0, 5001)
    np.testing.assert_allclose(sol.component(t, 1), -np.expm1(-lam * t), atol=1e-5)


def test_dopri5_non_finite_rhs_raises_clearly() -> None:
    def bad(t: float, y: np.ndarray) -> np.ndarray:
        return np.array([np.inf if t > 0.5 else -y[0]])

    with pytest.raises(IntegrationError, match='step size fell below'):
        dopri5(bad, (0.0, 1.0), [1.0])


def test_max_steps_guard() -> None:
    with pytest.raises(IntegrationError, match='max_steps'):
        rk4(decay, (0.0, 1.0), [1.0], 1e-3, max_steps=100)
    with pytest.raises(IntegrationError, match='max_steps'):
        dopri5(oscillator, (0.0, 100.0), [1.0, 0.0], rtol=1e-10, atol=1e-12, max_steps=100)


def test_bad_arguments() -> None:
    with pytest.raises(ValueError, match='t_span'):
        rk4(decay, (1.0, 1.0), [1.0], 0.1)
    with pytest.raises(ValueError, match='h must'):
        rk4(decay, (0.0, 1.0), [1.0], 0.0)
    with pytest.raises(ValueError, match='y0'):
        dopri5(decay, (0.0, 1.0), [np.nan])
    with pytest.raises(ValueError, match='rtol'):
        dopri5(decay, (0.0, 1.0), [1.0], rtol=1e-17)
    with pytest.raises(ValueError, match='atol'):
        dopri5(decay, (0.0, 1.0), [1.0], atol=0.0)


# ------------------------------------------------------------------ dense output and inverse


def _phase_problem() -> tuple[dense.DenseSolution, dense.DenseSolution]:
    # theta' = 1 + 0.5 sin t (monotone), theta = t - 0.5 cos t + 0.5
    def f(t: float, y: np.ndarray) -> np.ndarray:
        return np.array([1.0 + 0.5 * math.sin(t)])

    return rk4(f, (0.0, 20.0), [0.0], 0.05), dopri5(f, (0.0, 20.0), [0.0], rtol=1e-10, atol=1e-12)


def _theta_exact(t: np.ndarray) -> np.ndarray:
    return t - 0.5 * np.cos(t) + 0.5


def test_dense_output_shapes_and_derivative() -> None:
    sol = dopri5(oscillator, (0.0, 3.0), [1.0, 0.0], rtol=1e-10, atol=1e-12)
    t = np.linspace(0.0, 3.0, 12).reshape(3, 4)
    assert sol(t).shape == (2, 3, 4)
    assert sol(1.0).shape == (2,)
    assert sol.component(t, 1).shape == (3, 4)
    np.testing.assert_allclose(sol.derivative(t), np.array([-np.sin(t), -np.cos(t)]), atol=1e-8)
    np.testing.assert_allclose(sol.derivative(t, 0), -np.sin(t), atol=1e-8)
    with pytest.raises(ValueError):
        sol(np.nan)


def test_inverse_recovers_times_to_machine_precision() -> None:
    for sol in _phase_problem():
        targets = np.linspace(0.0, float(sol.y[-1, 0]), 100_003)
        t = sol.inverse(targets, 0)
        assert np.all(np.isfinite(t)) and np.all(np.diff(t) >= 0.0)
        # the dense output at the found times is the target, to rounding of the phase
        np.testing.assert_allclose(sol.component(t, 0), targets, rtol=0, atol=4e-15 * 21)


def test_inverse_against_brentq() -> None:
    sol = _phase_problem()[1]
    rng = np.random.default_rng(7)
    targets = np.sort(rng.uniform(0.0, 20.0, 50))
    # independent root finder on the same dense output: agreement to rounding
    on_dense = np.array(
        [brentq(lambda x, v=v: float(sol.component(x, 0)) - v, 0.0, 20.0, xtol=1e-15, rtol=8.9e-16) for v in targets]
    )
    np.testing.assert_allclose(sol.inverse(targets, 0), on_dense, rtol=0, atol=1e-14)
    # and on the exact phase: within the dense output's own error (~1e-8) over the slope (>= 0.5)
    exact = np.array(
        [brentq(lambda x, v=v: float(_theta_exact(np.array(x))) - v, 0.0, 25.0, xtol=1e-15) for v in targets]
    )
    grid = np.linspace(0.0, 20.0, 20001)
    dense_err = np.abs(sol.component(grid, 0) - _theta_exact(grid)).max()
    assert dense_err < 1e-7
    assert np.abs(sol.inverse(targets, 0) - exact).max() <= 1.01 * dense_err / 0.5 + 1e-14


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-5.0, 30.0, allow_nan=False), min_size=1, max_size=40))
def test_inverse_never_nan_and_clips(values: list[float]) -> None:
    sol = _phase_problem()[0]
    t = sol.inverse(np.array(values), 0)
    assert np.all(np.isfinite(t))
    assert np.all((t >= 0.0) & (t <= 20.0))
    top = float(sol.y[-1, 0])
    for v, tv in zip(values, t, strict=True):
        if v <= 0.0:
            assert tv == 0.0
        elif v > top:
            assert tv == 20.0
        else:
            assert abs(float(sol.component(tv, 0)) - v) <= 1e-13


def test_inverse_returns_the_start_of_a_plateau_and_rejects_a_falling_component() -> None:
    sol = rk4(lambda t, y: np.array([1.0]), (0.0, 1.0), [0.0], 0.1)
    joined = dense.concatenate([sol, dense.constant_solution(1.0, 3.0, sol.y[-1])])
    assert joined.inverse(np.array([1.0, 0.5]), 0).tolist() == pytest.approx([1.0, 0.5], abs=1e-15)
    np.testing.assert_array_equal(joined.component([2.0, 3.0], 0), [1.0, 1.0])
    falling = rk4(decay, (0.0, 1.0), [1.0], 0.1)
    with pytest.raises(ValueError, match='not non-decreasing'):
        falling.inverse([0.5], 0)


def test_concatenate_checks_the_joint() -> None:
    a = rk4(decay, (0.0, 1.0), [1.0], 0.1)
    b = rk4(decay, (1.5, 2.0), [1.0], 0.1)
    with pytest.raises(ValueError, match='do not join'):
        dense.concatenate([a, b])


# ------------------------------------------------------------------ breaks and terminal conditions


def _switching(t: float, y: np.ndarray, piece: tuple[float, float]) -> np.ndarray:
    # y0' = 1; y1' = cos(y0) on pieces below y0 = 1, then -2 sin(y0): a jump at y0 = 1
    return np.array([1.0, math.cos(y[0]) if piece[1] <= 1.0 else -2.0 * math.sin(y[0])])


def _switch_exact(t: np.ndarray) -> np.ndarray:
    return np.where(t < 1.0, np.sin(t), math.sin(1.0) + 2.0 * (np.cos(t) - math.cos(1.0)))


def _breaks_at_one(v: float) -> float:
    return 1.0 if v < 1.0 else math.inf


@pytest.mark.parametrize('method', ['rk4', 'dopri5'])
def test_breaks_keep_the_order_across_a_jump(method: str) -> None:
    brk = Breaks(0, _breaks_at_one)
    t = np.linspace(0.0, 3.0, 3001)
    if method == 'rk4':
        errs = []
        for h in (0.3, 0.15, 0.075):
            sol = rk4(_switching, (0.0, 3.0), [0.0, 0.0], h, breaks=brk)
            errs.append(abs(sol.y[-1, 1] - _switch_exact(np.array(3.0))))
        orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
        assert np.all(orders > 3.7), orders

        # the same grid without the break drops to first order: much worse at h = 0.075
        def plain(tt: float, y: np.ndarray) -> np.ndarray:
            return np.array([1.0, math.cos(y[0]) if y[0] < 1.0 else -2.0 * math.sin(y[0])])

        bad = rk4(plain, (0.0, 3.0), [0.0, 0.0], 0.07)
        assert abs(bad.y[-1, 1] - _switch_exact(np.array(3.0))) > 100 * errs[-1]
    else:
        sol = dopri5(_switching, (0.0, 3.0), [0.0, 0.0], rtol=1e-10, atol=1e-12, breaks=brk)
        np.testing.assert_allclose(sol.component(t, 1), _switch_exact(t), atol=1e-9)
    assert sol.break_t.tolist() == pytest.approx([1.0], abs=1e-14)
    assert sol.max_landing_error <= 1e-12
    assert 1.0 in sol.t.tolist() or np.min(np.abs(sol.t - 1.0)) < 1e-14


def test_breaks_on_break_callback_can_stop() -> None:
    seen: list[tuple[float, float]] = []

    def every_half(v: float) -> float:
        return (math.floor(v / 0.5) + 1) * 0.5

    def on_break(t: float, y: np.ndarray, b: float) -> bool:
        seen.append((t, b))
        return b >= 2.0

    sol = dopri5(lambda t, y, piece: np.array([2.0]), (0.0, 10.0), [0.0], breaks=Breaks(0, every_half, on_break))
    assert sol.status == 'stopped'
    assert [b for _, b in seen] == [0.5, 1.0, 1.5, 2.0]
    assert sol.t_end == pytest.approx(1.0, abs=1e-15)


@pytest.mark.parametrize('method', ['rk4', 'dopri5'])
def test_terminal_condition_from_the_dense_output(method: str) -> None:
    term = Terminal(0, 0.0)
    if method == 'rk4':
        sol = rk4(oscillator, (0.0, 10.0), [1.0, 0.0], 0.01, terminal=term)
        tol = 1e-9
    else:
        sol = dopri5(oscillator, (0.0, 10.0), [1.0, 0.0], rtol=1e-11, atol=1e-13, terminal=term)
        tol = 1e-9
    assert sol.status == 'terminal'
    assert sol.t_end == pytest.approx(math.pi / 2, abs=tol)
    assert sol.y[-1, 0] == 0.0
    assert sol.y[-1, 1] == pytest.approx(-1.0, abs=1e-8)


def test_terminal_does_not_fire_on_the_start_value() -> None:
    sol = dopri5(lambda t, y: np.array([1.0]), (0.0, 1.0), [0.0], terminal=Terminal(0, 0.0))
    assert sol.status == 'finished' and sol.t_end == 1.0


def test_determinism() -> None:
    a = dopri5(_switching, (0.0, 3.0), [0.0, 0.0], rtol=1e-8, atol=1e-10, breaks=Breaks(0, _breaks_at_one))
    b = dopri5(_switching, (0.0, 3.0), [0.0, 0.0], rtol=1e-8, atol=1e-10, breaks=Breaks(0, _breaks_at_one))
    assert a.t.tobytes() == b.t.tobytes() and a.coef.tobytes() == b.coef.tobytes()
