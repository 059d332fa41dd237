"""Brent's method and sign-change scanning: against scipy, closed forms and known polynomial roots."""

from __future__ import annotations

import math
from itertools import pairwise

import numpy as np
import pytest
import scipy.optimize
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose, assert_array_equal

from folder_line.core.numerics.roots import (
    RTOL,
    XTOL,
    brent,
    brentq,
    find_sign_changes,
    golden_section,
)
from folder_line.errors import (
    FolderLineError,
    NoConvergenceError,
    NonFiniteValueError,
    NotBracketedError,
    ParameterError,
)

from .._reference import EPS

CASES = [
    (math.cos, 0.0, 2.0, math.pi / 2),
    (lambda x: x**3 - 2.0, 0.0, 3.0, 2.0 ** (1.0 / 3.0)),
    (lambda x: math.exp(x) - 5.0, -1.0, 4.0, math.log(5.0)),
    (lambda x: math.atan(x - 0.3), -50.0, 1e3, 0.3),
    (lambda x: x - 1e-9, -1.0, 1.0, 1e-9),  # root near 0: xtol governs
    (lambda x: (x - 1.0) ** 5, 0.0, 2.5, 1.0),  # flat: many bisections
    (lambda x: x * math.exp(-x) - 0.1, 0.0, 1.0, None),  # Lambert W, checked against scipy only
]


@pytest.mark.parametrize(('f', 'a', 'b', 'root'), CASES)
def test_same_iterates_as_scipy(f, a, b, root) -> None:
    ours = brent(f, a, b)
    theirs, info = scipy.optimize.brentq(f, a, b, full_output=True)
    assert ours.root == theirs  # a line-by-line port: bit-identical
    assert ours.iterations == info.iterations
    assert ours.function_calls == info.function_calls
    if root is not None:
        assert abs(ours.root - root) <= XTOL + RTOL * abs(root) + 1e-15
    lo, hi = ours.bracket
    assert lo <= ours.root <= hi


@pytest.mark.parametrize(('f', 'a', 'b', 'root'), CASES[:4])
def test_reversed_bracket_and_tight_tolerance(f, a, b, root) -> None:
    r = brentq(f, b, a, xtol=1e-15)
    assert r == scipy.optimize.brentq(f, b, a, xtol=1e-15)
    assert abs(r - root) <= 1e-15 + 4 * RTOL * abs(root)


def test_exact_endpoints_returned_without_iterating() -> None:
    res = brent(lambda x: x - 1.0, 1.0, 5.0)
    assert res.root == 1.0 and res.iterations == 0 and res.function_calls == 2
    assert brentq(lambda x: x - 5.0, 1.0, 5.0) == 5.0
    assert brentq(lambda x: x * (x - 5.0), 0.0, 5.0) == 0.0  # both ends roots: a first, as scipy
    assert scipy.optimize.brentq(lambda x: x * (x - 5.0), 0.0, 5.0) == 0.0


def test_not_bracketed_is_a_clear_value_error() -> None:
    with pytest.raises(NotBracketedError, match='opposite signs') as info:
        brentq(lambda x: x * x + 1.0, -1.0, 1.0)
    assert isinstance(info.value, ValueError) and isinstance(info.value, FolderLineError)
    assert info.value.fa == 2.0 and info.value.fb == 2.0
    assert '-1.0' in str(info.value) and '2.0' in str(info.value)
    with pytest.raises(ValueError):  # scipy agrees that this is no bracket
        scipy.optimize.brentq(lambda x: x * x + 1.0, -1.0, 1.0)


def test_non_finite_values_raise() -> None:
    with pytest.raises(NonFiniteValueError):
        brentq(lambda x: math.nan, 0.0, 1.0)
    with pytest.raises(NonFiniteValueError):
        brentq(lambda x: x, -math.inf, 1.0)
    with pytest.raises(NonFiniteValueError):  # NaN met mid-iteration
        brentq(lambda x: math.nan if 0.4 < x < 0.6 else x - 0.5, 0.0, 1.0)


def test_iteration_limit() -> None:
    def f(x: float) -> float:
        return (x - 1.0) ** 5

    with pytest.raises(NoConvergenceError, match='maxiter=3') as info:
        brentq(f, 0.0, 2.5, maxiter=3)
    assert isinstance(info.value, RuntimeError)
    with pytest.raises(RuntimeError):
        scipy.optimize.brentq(f, 0.0, 2.5, maxiter=3)


@pytest.mark.parametrize(
    ('kw', 'key'),
    [
        ({'xtol': 0.0}, 'xtol'),
        ({'xtol': math.nan}, 'xtol'),
        ({'rtol': 1e-17}, 'rtol'),
        ({'maxiter': 0}, 'maxiter'),
        ({'maxiter': 2.5}, 'maxiter'),
        ({'maxiter': True}, 'maxiter'),
    ],
)
def test_bad_tolerances(kw, key) -> None:
    with pytest.raises(ParameterError) as info:
        brentq(math.sin, 3.0, 4.0, **kw)
    assert info.value.key == key


distinct_roots = (
    st.lists(st.floats(-10.0, 10.0, allow_nan=False), min_size=1, max_size=6)
    .map(lambda r: sorted(set(round(x, 3) for x in r)))
    .filter(lambda r: all(b - a >= 0.05 for a, b in pairwise(r)))
)


@settings(max_examples=200, deadline=None)
@given(roots=distinct_roots, scale=st.floats(1e-3, 1e3), k=st.integers(0, 5), shift=st.floats(0.05, 0.95))
def test_polynomials_with_known_roots(roots, scale, k, shift) -> None:
    k = k % len(roots)
    r = roots[k]
    lo = roots[k - 1] if k > 0 else r - 1.0
    hi = roots[k + 1] if k + 1 < len(roots) else r + 1.0
    a = lo + shift * (r - lo)  # strictly between the neighbour and the root
    b = r + (1.0 - shift) * (hi - r)

    def p(x: float) -> float:
        return scale * math.prod(x - q for q in roots)

    ours = brentq(p, a, b)
    assert ours == scipy.optimize.brentq(p, a, b)
    # the polynomial is evaluated with rounding; allow its root's conditioning
    assert abs(ours - r) <= 4e-12 + 1e-12 * abs(r)


# ----------------------------------------------------------------------------- sign changes


def test_sine_crossings_and_directions() -> None:
    grid = np.linspace(0.5, 10.0, 101)
    sc = find_sign_changes(math.sin, grid)
    assert_allclose(sc.x, [math.pi, 2 * math.pi, 3 * math.pi], rtol=0, atol=1e-14)
    assert_array_equal(sc.direction, [-1, 1, -1])
    assert not sc.on_sample.any()
    assert len(sc) == 3
    assert not sc.x.flags.writeable


def test_values_given_are_used_for_the_decision() -> None:
    grid = np.linspace(0.5, 10.0, 101)
    sc = find_sign_changes(math.sin, grid, values=np.sin(grid))
    assert_allclose(sc.x, [math.pi, 2 * math.pi, 3 * math.pi], atol=1e-14)
    assert sc.function_calls < 101  # only the refinements called f


def test_zero_on_a_sample_is_one_crossing_reported_exactly() -> None:
    grid = np.array([-1.0, -0.5, 0.0, 0.5, 1.0])
    sc = find_sign_changes(lambda x: x**3, grid)
    assert_array_equal(sc.x, [0.0])
    assert_array_equal(sc.direction, [1])
    assert sc.on_sample.tolist() == [True]


def test_zero_run_is_one_crossing_at_its_first_sample() -> None:
    grid = np.linspace(-2.0, 2.0, 9)
    f = lambda x: min(0.0, x + 1.0) if x < 0 else max(0.0, x - 1.0)  # noqa: E731 - 0 on [-1, 1]
    sc = find_sign_changes(f, grid)
    assert_array_equal(sc.x, [-1.0])
    assert_array_equal(sc.direction, [1])


@pytest.mark.parametrize('c', [0.3, 0.25])  # 0.25 is on the grid, 0.3 between samples
def test_grazing_touch_is_not_reported(c) -> None:
    grid = np.linspace(0.0, 1.0, 21)
    assert len(find_sign_changes(lambda x: (x - c) ** 2, grid)) == 0
    assert len(find_sign_changes(lambda x: -((x - c) ** 2), grid)) == 0


def test_touch_split_by_rounding_is_dropped_not_doubled() -> None:
    c = 0.25
    grid = np.linspace(0.0, 1.0, 21)  # contains c exactly; f(c) = -1e-30
    f = lambda x: (x - c) ** 2 - 1e-30  # noqa: E731 - roots c +- 1e-15: a touch at any tolerance we use
    assert len(find_sign_changes(f, grid)) == 0
    # resolvable roots are kept
    g = lambda x: (x - c) ** 2 - 1e-6  # noqa: E731
    sc = find_sign_changes(g, grid)
    assert_allclose(sc.x, [c - 1e-3, c + 1e-3], atol=1e-14)
    assert_array_equal(sc.direction, [-1, 1])


def test_ftol_turns_a_near_touch_into_a_touch() -> None:
    grid = np.linspace(0.0, 1.0, 21)
    f = lambda x: (x - 0.25) ** 2 - 1e-20  # noqa: E731
    assert len(find_sign_changes(f, grid, ftol=1e-18)) == 0


def test_zero_at_grid_ends_needs_left_sign() -> None:
    f = lambda x: x  # noqa: E731
    assert len(find_sign_changes(f, np.array([0.0, 1.0]))) == 0
    sc = find_sign_changes(f, np.array([0.0, 1.0]), left_sign=-1)
    assert_array_equal(sc.x, [0.0]) and sc.direction.tolist() == [1]
    assert len(find_sign_changes(f, np.array([-1.0, 0.0]))) == 0  # end of grid: undecidable
    assert len(find_sign_changes(f, np.array([0.0, 1.0]), left_sign=1)) == 0  # a touch


def test_stepwise_scan_reports_a_boundary_crossing_once() -> None:
    f = math.sin
    steps = [np.linspace(0.0, math.pi, 7), np.linspace(math.pi, 2 * math.pi, 7)]
    # make the shared boundary an exact zero of the sampled values
    vals = [np.sin(s) for s in steps]
    vals[0][-1] = 0.0
    vals[1][0] = 0.0
    found = []
    left = None
    for s, v in zip(steps, vals, strict=True):
        sc = find_sign_changes(f, s, values=v, left_sign=left)
        found.extend(sc.x.tolist())
        nz = v[v != 0.0]
        left = int(np.sign(nz[-1]))
    assert found == [math.pi]


@settings(max_examples=150, deadline=None)
@given(roots=distinct_roots, scale=st.floats(-1e3, 1e3).filter(lambda s: abs(s) > 1e-3))
def test_all_polynomial_roots_found(roots, scale) -> None:
    grid = np.linspace(-10.5, 10.5, 1051)  # spacing 0.02 < the 0.05 root separation

    def p(x: float) -> float:
        return scale * math.prod(x - q for q in roots)

    sc = find_sign_changes(p, grid)
    assert_allclose(sc.x, roots, rtol=0, atol=4e-12)
    assert np.all(sc.direction[1:] == -sc.direction[:-1])  # simple roots alternate
    assert np.all(np.diff(sc.x) > 0)


@pytest.mark.parametrize(
    ('grid', 'key'),
    [
        ([0.0], 'grid'),
        ([[0.0, 1.0]], 'grid'),
        ([0.0, 0.0, 1.0], 'grid'),
        ([0.0, math.nan], 'grid'),
    ],
)
def test_bad_grids(grid, key) -> None:
    with pytest.raises(ParameterError) as info:
        find_sign_changes(math.sin, grid)
    assert info.value.key == key


def test_bad_values_and_options() -> None:
    with pytest.raises(ParameterError):
        find_sign_changes(math.sin, [0.0, 1.0], values=[0.0])
    with pytest.raises(NonFiniteValueError):
        find_sign_changes(math.sin, [0.0, 1.0], values=[0.0, math.inf])
    with pytest.raises(ParameterError):
        find_sign_changes(math.sin, [0.0, 1.0], left_sign=2)
    with pytest.raises(ParameterError):
        find_sign_changes(math.sin, [0.0, 1.0], ftol=-1.0)


# ------------------------------------------------------------------------- grazing: a touch is found once or not at all
GRID = np.linspace(0.0, 1.0, 101)


class TestGrazing:
    """A touch of a threshold is reported once or not at all, never twice."""

    @settings(max_examples=150, deadline=None, derandomize=True)
    @given(
        i=st.integers(0, 100),
        where=st.sampled_from(['on', 'near', 'between']),
        frac=st.floats(-0.5, 0.5),
        c=st.sampled_from([0.0, -1e-15, -1e-300, 1e-30, 1e-26]),
        sign=st.sampled_from([1.0, -1.0]),
    )
    def test_sign_changes_of_a_touch(self, i: int, where: str, frac: float, c: float, sign: float) -> None:
        """f = sign (c - (t - t0)^2): a touch (c = 0), a near miss (c < 0), or two roots closer than
        the root tolerance (c = 1e-30: +-1e-15; 1e-26: +-1e-13) that rounding may split; t0 on a
        sample, within 1e-15 of one, or anywhere between; a touch at a grid end can leave one root
        inside the grid (then once), otherwise none."""
        step = GRID[1] - GRID[0]
        t0 = float(GRID[i]) + {'on': 0.0, 'near': 1e-15 * np.sign(frac), 'between': frac * step}[where]
        sc = find_sign_changes(lambda t: sign * (c - (t - t0) ** 2), GRID)
        inside_end = not (GRID[0] < t0 - 1e-12 and t0 + 1e-12 < GRID[-1])
        assert len(sc) == 0 or (len(sc) == 1 and inside_end)
        # a resolvable double crossing is kept (sanity of the same call): roots +-1e-3 around t0
        if 0.01 < t0 < 0.99:
            two = find_sign_changes(lambda t: sign * (1e-6 - (t - t0) ** 2), GRID)
            if len(two) == 2:  # both roots between samples (not split by a sample landing on one)
                assert np.allclose(two.x, [t0 - 1e-3, t0 + 1e-3], atol=1e-12)
                assert list(two.direction) == ([1, -1] if sign > 0 else [-1, 1])

    @settings(max_examples=100, deadline=None, derandomize=True)
    @given(i=st.integers(1, 99), rel=st.floats(-1e-8, 1e-8), scale=st.sampled_from([1.0, 1e3, 1e-3]))
    def test_a_noisy_touch_with_ftol_is_never_doubled(self, i: int, rel: float, scale: float) -> None:
        """(t - a)^2 evaluated expanded, t^2 - 2at + a^2, has rounding noise ~ eps a^2 around its
        touch, wider (sqrt(eps) a) than the root tolerance. With ftol at that noise level the touch
        is never reported (documented rule 1); without ftol a noise sign change is a real sign
        change of the float function and may come out as a pair (see rule 5 of roots.py)."""
        grid = GRID * scale
        a = float(grid[i]) * (1.0 + rel)

        def f(t: float) -> float:
            return -(t * t - 2.0 * a * t + a * a)

        noise = 4 * EPS * (a * a + 2 * abs(a) * scale + scale * scale)
        assert len(find_sign_changes(f, grid, ftol=noise)) == 0
        raw = find_sign_changes(f, grid)
        assert len(raw) % 2 == 0  # pairs only: both neighbours are below 0
        if len(raw):
            assert abs(raw.x[0] - a) < 1e-7 * scale and abs(raw.x[-1] - a) < 1e-7 * scale

    @settings(max_examples=40, deadline=None, derandomize=True)
    @given(k=st.integers(0, 5), split=st.integers(1, 99))
    def test_stepwise_scan_of_a_touch_on_a_step_boundary(self, k: int, split: int) -> None:
        """Scanning step by step with left_sign, a touch exactly on the shared boundary sample is
        reported in neither step."""
        t0 = float(GRID[split])

        def f(t: float) -> float:
            return -((t - t0) ** 2)

        first = find_sign_changes(f, GRID[: split + 1])
        left = int(np.sign(f(float(GRID[split - 1]))))
        second = find_sign_changes(f, GRID[split:], left_sign=left)
        assert len(first) + len(second) == 0


# --------------------------------------------------------------------------- golden section


def test_golden_section_narrows_to_the_minimum() -> None:
    calls: list[float] = []

    def f(x: float) -> float:
        calls.append(x)
        return (x - 0.3) ** 2

    last = golden_section(f, 0.0, 1.0, xtol=1e-10)
    assert last.lo <= 0.3 <= last.hi and last.hi - last.lo <= 1e-10
    assert abs(last.best[0] - 0.3) < 1e-10 and last.best[1] == f(last.best[0])
    assert len(calls) <= 3 + math.ceil(math.log(1e-10) / math.log((math.sqrt(5.0) - 1.0) / 2.0))  # one f per iteration


def test_golden_section_maxiter_runs_exactly_that_many() -> None:
    calls: list[float] = []
    golden_section(lambda x: calls.append(x) or abs(x), -1.0, 2.0, maxiter=7)
    assert len(calls) == 2 + 7
    with pytest.raises(ParameterError):
        golden_section(abs, -1.0, 1.0)
