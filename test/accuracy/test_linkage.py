"""Accuracy study ``linkage``: the mpmath reference is checked, and the measured curves behave as theory says."""

from __future__ import annotations

import itertools
import math

import mpmath as mp
import numpy as np
import pytest

from folder_line.accuracy import linkage
from folder_line.accuracy.measure import Row
from folder_line.accuracy.reference import DPS, fourbar_mp, loop_residuals_mp, sixbar_mp, sixbar_reference
from folder_line.core.mechanisms.layup import LayupModel, LayupParams
from folder_line.core.mechanisms.layup_reach import swing_extremes

PARAMS = linkage.default_params()
EXTREMES = [e.phi for e in swing_extremes(PARAMS)]
# a spread of angles, the two swing extremes (ω3 = 0) and angles just beside them
ANGLES = [0.0, 0.7, 1.9, 3.0, -2.4, -0.9, 6.0] + EXTREMES + [x + 1e-3 for x in EXTREMES]


@pytest.mark.parametrize('phi', ANGLES)
def test_reference_closes_both_loops_on_the_assembly_branches(phi: float) -> None:
    sol = sixbar_mp(PARAMS, phi)
    res = loop_residuals_mp(PARAMS, sol)
    assert max(abs(r) for r in res) <= mp.mpf('1e-30')
    with mp.workdps(DPS):
        ax = mp.mpf(PARAMS.a) + mp.mpf(PARAMS.R_kr) * mp.cos(mp.mpf(phi))
        ay = mp.mpf(PARAMS.b) + mp.mpf(PARAMS.R_kr) * mp.sin(mp.mpf(phi))
        t3, t5 = sol.loop1.theta3, sol.theta5
        bx, by = PARAMS.O2B * mp.cos(t3), PARAMS.O2B * mp.sin(t3)
        cx, cy = PARAMS.l3 * mp.cos(t3), PARAMS.l3 * mp.sin(t3)
        ex, ey = PARAMS.l5 * mp.cos(t5), PARAMS.l5 * mp.sin(t5)  # E - O3
        # the assembly branch of the L six-bar (module docstring of core/mechanisms/layup.py):
        # (A - O2) × (B - O2) > 0 and (C - O3) × (E - O3) > 0, clearly (not a toggle)
        assert ax * by - ay * bx > mp.mpf('1e-3')
        assert (cx - PARAMS.O2O3) * ey - cy * ex > mp.mpf('1e-3')
        # the link lengths hold too (B on the rod circle, E on the coupler circle)
        assert abs(mp.hypot(bx - ax, by - ay) - PARAMS.l2) < mp.mpf('1e-30')
        assert abs(mp.hypot(ex + PARAMS.O2O3 - cx, ey - cy) - PARAMS.l4) < mp.mpf('1e-30')


@pytest.mark.parametrize('phi', ANGLES)
def test_reference_rates_match_an_mpmath_central_difference_of_its_positions(phi: float) -> None:
    w = PARAMS.omega
    with mp.workdps(DPS):
        h = mp.mpf('1e-15')
        x = mp.mpf(phi)
        plus, minus = sixbar_mp(PARAMS, x + h), sixbar_mp(PARAMS, x - h)
        mid = sixbar_mp(PARAMS, x)
        # truncation ~ h² θ'''/6 ~ 1e-31, round-off ~ 1e-50/h = 1e-35
        for got, p, m in (
            (mid.loop1.dtheta3, plus.loop1.theta3, minus.loop1.theta3),
            (mid.dtheta5, plus.theta5, minus.theta5),
            (mid.loop1.dtheta2, plus.loop1.theta2, minus.loop1.theta2),
            (mid.dtheta4, plus.theta4, minus.theta4),
        ):
            fd = mp.mpf(w) * (p - m) / (2 * h)
            assert abs(got - fd) <= mp.mpf('1e-25')


def test_reference_rates_vanish_at_the_swing_extremes() -> None:
    # the core's closed-form dead centres (crank and rod in line) are where ω3 = 0
    for phi in EXTREMES:
        sol = sixbar_mp(PARAMS, phi)
        assert abs(sol.loop1.dtheta3) < 1e-14
        assert abs(sol.dtheta5) < 1e-14
        assert abs(fourbar_mp(PARAMS, phi).dtheta3 - sol.loop1.dtheta3) == 0


def test_reference_agrees_with_the_core_closed_form() -> None:
    phi = np.concatenate([np.linspace(-math.pi, math.pi, 48, endpoint=False), ANGLES])
    ref = sixbar_reference(PARAMS, phi)
    model = LayupModel(PARAMS)
    st = model.arrays(phi)
    for name in ('theta3', 'theta5', 'omega3', 'omega5'):
        assert np.abs(getattr(st, name) - getattr(ref, name)).max() <= 1e-13, name
        scalar = np.array([getattr(model.point(float(x)), name) for x in phi])
        assert np.abs(scalar - getattr(ref, name)).max() <= 1e-13, name
    assert np.all((ref.theta3 > -math.pi) & (ref.theta3 <= math.pi))


def test_reference_is_cached_per_input() -> None:
    phi = np.linspace(0.1, 0.2, 5)
    a = sixbar_reference(PARAMS, phi)
    b = sixbar_reference(PARAMS, phi.copy())
    assert a is b
    assert np.array_equal(a.phi, phi)


@pytest.fixture(scope='module')
def rows() -> list[Row]:
    return linkage.run(quick=True)


def _curve(rows: list[Row], method: str) -> list[Row]:
    return [r for r in rows if r.method == method]


def test_rows_cover_every_method_with_the_documented_knobs(rows: list[Row]) -> None:
    assert {r.method for r in rows} == set(linkage.METHODS)
    for method in linkage.METHODS:
        knob, values = linkage.knob_settings(method, quick=True)
        curve = _curve(rows, method)
        assert [r.value for r in curve] == [float(v) for v in values]
        assert {r.knob for r in curve} == {knob}
        assert len(values) >= 3
        assert len(linkage.knob_settings(method, quick=False)[1]) >= 4
        for r in curve:
            assert r.study == 'linkage'
            assert math.isfinite(r.error) and r.error >= 0.0
            assert math.isfinite(r.cpu_s_per_sim_s) and r.cpu_s_per_sim_s > 0.0
            assert r.unit == ('rad/s' if 'velocity' in method else 'rad')
    # the knob ranges of the issue
    assert linkage.knob_settings('Newton loop closure')[1][0] == 1e-3
    assert linkage.knob_settings('Newton loop closure')[1][-1] == 1e-12
    h = linkage.knob_settings('finite difference velocity')[1]
    assert max(h) == pytest.approx(1e-1) and min(h) == pytest.approx(1e-9)


def test_closed_form_is_accurate_to_a_few_ulps(rows: list[Row]) -> None:
    for method in ('closed form', 'closed form, scalar', 'closed form velocity'):
        for r in _curve(rows, method):
            assert r.error <= 1e-12, (method, r.value, r.error)


def _jacobian_bound(params: LayupParams) -> float:
    """max over the reference angles of ||J⁻¹||∞ of the 4×4 loop-closure Jacobian (rad per m)."""
    ref = linkage.reference(params)
    p = params
    t3, t5 = ref.theta3, ref.theta5
    ax = p.a + p.R_kr * np.cos(ref.phi)
    ay = p.b + p.R_kr * np.sin(ref.phi)
    t2 = np.arctan2(p.O2B * np.sin(t3) - ay, p.O2B * np.cos(t3) - ax)
    t4 = np.arctan2(p.l5 * np.sin(t5) - p.l3 * np.sin(t3), p.O2O3 + p.l5 * np.cos(t5) - p.l3 * np.cos(t3))
    n = t3.size
    J = np.zeros((n, 4, 4))
    J[:, 0, 0], J[:, 1, 0] = -p.l2 * np.sin(t2), p.l2 * np.cos(t2)
    J[:, 0, 1], J[:, 1, 1] = p.O2B * np.sin(t3), -p.O2B * np.cos(t3)
    J[:, 2, 1], J[:, 3, 1] = -p.l3 * np.sin(t3), p.l3 * np.cos(t3)
    J[:, 2, 2], J[:, 3, 2] = -p.l4 * np.sin(t4), p.l4 * np.cos(t4)
    J[:, 2, 3], J[:, 3, 3] = p.l5 * np.sin(t5), -p.l5 * np.cos(t5)
    return float(np.abs(np.linalg.inv(J)).sum(axis=2).max())


def test_newton_error_is_bounded_by_tol_and_falls_with_it(rows: list[Row]) -> None:
    kappa = _jacobian_bound(PARAMS)
    assert 1.0 < kappa < 1e3
    curve = _curve(rows, 'Newton loop closure')
    for r in curve:
        # residual <= tol, first order: |Δθ| <= ||J⁻¹|| tol (with 50 % for the second order),
        # plus the rounding floor of the residual's evaluation
        assert r.error <= 1.5 * kappa * r.value + 1e-13, (r.value, r.error)
    errs = [r.error for r in curve]
    assert all(b <= a + 1e-15 for a, b in itertools.pairwise(errs)), errs
    assert errs[0] > 1e6 * errs[-1]  # the knob really trades accuracy
    assert errs[-1] <= 1e-12


def test_newton_at_tight_tol_matches_the_closed_form_step_by_step() -> None:
    phi = linkage.step_angles(PARAMS)[:300]
    t3, t5, iters = linkage.newton_turn(PARAMS, 1e-12, phi)
    st = LayupModel(PARAMS).arrays(phi, accelerations=False)
    assert np.abs(t3 - st.theta3).max() < 1e-12
    assert np.abs(t5 - st.theta5).max() < 1e-12
    assert 300 <= iters <= 300 * 4  # warm starts: one to a few iterations a step
    # at a loose tol most steps need no iteration at all
    assert linkage.newton_turn(PARAMS, 1e-3, phi)[2] < 100


def test_finite_differences_show_truncation_then_round_off(rows: list[Row]) -> None:
    curve = _curve(rows, 'finite difference velocity')
    h = np.array([r.value for r in curve])
    e = np.array([r.error for r in curve])
    big = h >= 1e-3
    assert big.sum() >= 3
    slope = np.polyfit(np.log(h[big]), np.log(e[big]), 1)[0]
    assert slope == pytest.approx(2.0, abs=0.3)
    best = int(np.argmin(e))
    assert 1e-7 < h[best] < 1e-3
    assert e[np.argmin(h)] > 100.0 * e[best]  # round-off ~ ε/h at the smallest step
    # the exact velocities of the closed form beat the best finite difference
    exact = max(r.error for r in _curve(rows, 'closed form velocity'))
    assert exact < e[best] / 100.0


def test_fd_velocity_direct_against_reference() -> None:
    ref = linkage.reference(PARAMS)
    model = LayupModel(PARAMS)
    # truncation estimate from the theory: error ∝ h², so halving h quarters it
    e1 = linkage.fd_error(model, ref, 2e-2)
    e2 = linkage.fd_error(model, ref, 1e-2)
    assert e1 / e2 == pytest.approx(4.0, rel=0.05)
