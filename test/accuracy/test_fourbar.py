"""Accuracy study ``fourbar``: the closed form vs ``solve_ivp`` on the layup's crank-rocker, and the
equal-error ratio."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from folder_line.accuracy import fourbar
from folder_line.accuracy.measure import Row
from folder_line.core.mechanisms.layup import LayupModel

PARAMS = fourbar.default_params()


def test_grid_and_span_follow_the_crank_speed() -> None:
    t = fourbar.grid(PARAMS)
    assert fourbar.span(PARAMS) == pytest.approx(2 * 2 * math.pi / PARAMS.omega)
    assert t[0] == 0.0 and t[-1] == pytest.approx(fourbar.span(PARAMS))
    assert np.allclose(np.diff(t), 1.0 / fourbar.OUTPUT_RATE)


def test_ode_right_hand_side_is_the_reference_rate() -> None:
    # the ODE a user would write, evaluated on the exact solution, gives the exact rate
    t = fourbar.grid(PARAMS)
    ref = fourbar.reference(PARAMS)
    f = fourbar.user_rhs(PARAMS)
    rate = np.array([f(float(tk), np.array([psi]))[0] for tk, psi in zip(t, ref.theta3, strict=True)])
    assert np.abs(rate - ref.omega3).max() <= 1e-13
    assert np.abs(ref.omega3).max() > 0.5  # the rocker really swings


def test_closed_form_matches_the_six_bar_and_the_reference() -> None:
    t = fourbar.grid(PARAMS)
    ref = fourbar.reference(PARAMS)
    psi = fourbar.closed_form_psi(PARAMS, t)
    six = LayupModel(PARAMS).arrays(PARAMS.omega * t, accelerations=False).theta3
    assert np.abs(psi - six).max() <= 1e-14
    assert np.abs(psi - ref.theta3).max() <= 1e-14
    # the reference covers both turns (the second at angles up to 4π, not reduced)
    assert (PARAMS.omega * t).max() > 3.9 * math.pi


@pytest.fixture(scope='module')
def rows() -> list[Row]:
    return fourbar.run(quick=True)


def _curve(rows: list[Row], method: str) -> list[Row]:
    return [r for r in rows if r.method == method]


ODES = [f'solve_ivp {m}' for m in fourbar.ODE_METHODS]


def test_rows_cover_every_method_with_the_documented_knobs(rows: list[Row]) -> None:
    assert {r.method for r in rows} == {fourbar.CLOSED_FORM, *ODES}
    n = fourbar.grid(PARAMS).size
    for method in (fourbar.CLOSED_FORM, *ODES):
        knob, values = fourbar.knob_settings(method, quick=True)
        curve = _curve(rows, method)
        assert [r.value for r in curve] == [float(min(v, n)) for v in values]
        assert {r.knob for r in curve} == {knob}
        assert len(values) >= 3 and len(fourbar.knob_settings(method)[1]) >= 4
        for r in curve:
            assert r.study == 'fourbar' and r.unit == 'rad'
            assert math.isfinite(r.error) and r.error >= 0.0
            assert math.isfinite(r.cpu_s_per_sim_s) and r.cpu_s_per_sim_s > 0.0
    rtols = fourbar.knob_settings(ODES[0])[1]
    assert max(rtols) == 1e-3 and min(rtols) == 1e-12


def test_closed_form_error_is_at_rounding_level(rows: list[Row]) -> None:
    for r in _curve(rows, fourbar.CLOSED_FORM):
        assert r.error <= 1e-12


@pytest.mark.parametrize('method', ODES)
def test_solve_ivp_error_falls_as_rtol_tightens(rows: list[Row], method: str) -> None:
    curve = sorted(_curve(rows, method), key=lambda r: -r.value)  # loosest first
    errs = [r.error for r in curve]
    # quick settings are 3 decades apart: each must gain at least one decade
    assert all(b < a / 10.0 for a, b in itertools.pairwise(errs)), errs
    # and the loose end is a real error, far above the closed form's
    assert errs[0] > 1e-5
    closed = max(r.error for r in _curve(rows, fourbar.CLOSED_FORM))
    assert errs[-1] > closed


@pytest.mark.parametrize('method', ODES)
def test_solve_ivp_costs_more_than_the_closed_form_at_equal_error(rows: list[Row], method: str) -> None:
    res = fourbar.ratio_at_equal_error(rows, fourbar.CLOSED_FORM, method)
    best_ode = min(r.error for r in _curve(rows, method))
    closed = max(r.error for r in _curve(rows, fourbar.CLOSED_FORM))
    assert res.reached == (best_ode <= closed)
    assert res.error == (closed if res.reached else best_ode)
    assert res.ratio == pytest.approx(res.cpu_b / res.cpu_a)
    assert res.ratio >= 1.0


def _row(method: str, error: float, cpu: float) -> Row:
    return Row('fourbar', method, 'k', 1.0, error, cpu, 'q', 'rad', 'r')


A = 'closed form (folder_line)'
B = 'solve_ivp X'
SYNTH_A = [_row(A, 2e-16, 1e-3), _row(A, 1e-16, 1e-5)]  # batch 1 (dear), whole grid (cheap)


def test_ratio_on_synthetic_rows_when_b_never_reaches_a() -> None:
    rows = [*SYNTH_A, _row(B, 0.01, 0.0001), _row(B, 1e-06, 0.001), _row(B, 1e-10, 0.01)]
    res = fourbar.ratio_at_equal_error(rows, A, B)
    assert not res.reached
    assert res.error == 1e-10  # b's best error
    assert res.cpu_b == 1e-2
    assert res.cpu_a == 1e-5  # a's cheapest point reaching 1e-10
    assert res.ratio == pytest.approx(1e3)


def test_ratio_on_synthetic_rows_interpolates_log_log() -> None:
    rows = [*SYNTH_A, _row(B, 1e-2, 1e-4), _row(B, 1e-18, 1e-2), _row(B, 1e-17, 5e-2)]  # the last is dominated
    res = fourbar.ratio_at_equal_error(rows, A, B)
    assert res.reached
    assert res.error == 2e-16  # a's level: the largest error of its settings
    # straight line between (1e-2, 1e-4) and (1e-18, 1e-2) in log-log
    log_cpu = np.interp(math.log(2e-16), [math.log(1e-18), math.log(1e-2)], [math.log(1e-2), math.log(1e-4)])
    assert res.cpu_b == pytest.approx(math.exp(log_cpu), rel=1e-12)
    assert res.cpu_a == 1e-5
    assert res.ratio == pytest.approx(math.exp(log_cpu) / 1e-5, rel=1e-12)
    # an explicit level on b's curve
    res = fourbar.ratio_at_equal_error(rows, A, B, error=1e-10)
    assert res.cpu_b == pytest.approx(1e-4 * 100.0 ** (8.0 / 16.0), rel=1e-12)  # halfway in log error


def test_ratio_ignores_other_studies_and_names_missing_methods() -> None:
    rows = [*SYNTH_A, _row(B, 1e-10, 0.01), Row('linkage', B, 'k', 1.0, 1e-20, 1e-09, 'q', 'rad', 'r')]
    assert fourbar.ratio_at_equal_error(rows, A, B).error == 1e-10
    with pytest.raises(KeyError):
        fourbar.ratio_at_equal_error(rows, A, 'solve_ivp Y')
    with pytest.raises(KeyError):
        fourbar.ratio_at_equal_error(rows, 'nothing', B)
