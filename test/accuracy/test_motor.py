"""Accuracy study ``motor``: the references are checked, the methods converge as they should, rows are sane."""

from __future__ import annotations

import itertools
import math

import mpmath
import numpy as np
import pytest

from folder_line.accuracy import motor as M
from folder_line.accuracy.measure import Row
from folder_line.core.effects import chain_friction as cf
from folder_line.core.effects import motor_dynamics as md
from folder_line.errors import ParameterError


@pytest.fixture(scope='module')
def chain_ref() -> M.ChainReference:
    return M.chain_reference(M.make_scene(True))


def _slope(hs: tuple[float, ...], errs: list[float]) -> float:
    return float(np.polyfit(np.log(hs), np.log(errs), 1)[0])


# ------------------------------------------------------------------ references


def test_closed_form_against_mpmath_at_40_digits() -> None:
    p = M.motor_params(M.make_scene(False))
    with mpmath.workdps(40):
        J, T0, w0, b, wn = (mpmath.mpf(v) for v in (p.J, p.T_0, p.omega_0, p.b, p.omega_nom))
        # the ODE itself, by mpmath's Taylor-series integrator from standstill
        sol = mpmath.odefun(
            lambda t, y: [y[1] / wn, (T0 * (1 - y[1] / w0) - b * y[1]) / J], 0, [mpmath.mpf(0), mpmath.mpf(0)]
        )
        c = T0 / w0 + b
        tau, w_ss = J / c, T0 / c

        def exact(t: mpmath.mpf) -> tuple[mpmath.mpf, mpmath.mpf]:
            e = mpmath.exp(-t / tau)
            return w_ss / wn * (t - tau * (1 - e)), w_ss * (1 - e)

        for ts in ('0.01', '0.3', '1', '2'):
            t = mpmath.mpf(ts)
            th_ode, w_ode = sol(t)
            th, w = exact(t)
            assert abs(th_ode - th) < mpmath.mpf('1e-30') and abs(w_ode - w) < mpmath.mpf('1e-28')
        # the float evaluation (expm1) of the same formula, over the whole span
        t_grid = np.linspace(0.0, M.DURATION, 201)
        th_f, w_f = M.closed_form(p, t_grid)
        th_mp = np.array([float(exact(mpmath.mpf(float(x)))[0]) for x in t_grid])
        w_mp = np.array([float(exact(mpmath.mpf(float(x)))[1]) for x in t_grid])
    np.testing.assert_allclose(th_f, th_mp, rtol=0, atol=8 * np.finfo(float).eps)
    np.testing.assert_allclose(w_f, w_mp, rtol=0, atol=8 * np.finfo(float).eps * p.omega_free)
    # the span covers the start-up: from standstill to within 1 % of the free speed
    assert w_f[0] == 0.0 and 0.99 * p.omega_free < w_f[-1] < p.omega_free
    assert 5 * p.tau < M.DURATION


def test_chain_reference_is_checked(chain_ref: M.ChainReference) -> None:
    sc = M.make_scene(True)
    t = np.linspace(0.0, M.DURATION, 4001)
    ref = chain_ref(t)
    # an independent integrator (the core's DOPRI5, its own break landing) at rtol 1e-13
    core = M.run_core(M.make_scene(True, method='dopri5', h=M.DURATION, rtol=1e-13, atol=1e-16))
    assert np.abs(core.theta(t) - ref[0]).max() < 5e-11
    assert np.abs(core.omega(t) - ref[1]).max() < 1e-8
    # the reference against itself at a looser tolerance
    loose = M.chain_reference(sc, rtol=1e-12, atol=1e-14)(t)
    assert np.abs(loose[0] - ref[0]).max() < 5e-11
    # it did restart at every break, and the load is felt: slower than the free start-up
    load = cf.master_load(sc)
    n_breaks = sum(1 for _ in _breaks_below(load, float(ref[0, -1])))
    assert len(chain_ref.sols) == n_breaks + 1
    free = M.closed_form(M.motor_params(M.make_scene(False)), t)[0]
    assert free[-1] - ref[0, -1] > 1e-3


def _breaks_below(load: cf.MasterLoad, theta_end: float) -> list[float]:
    out, b = [], load.next_break(0.0)
    while b < theta_end:
        out.append(b)
        b = load.next_break(b)
    return out


def test_user_rhs_is_the_documented_ode() -> None:
    sc = M.make_scene(True)
    p = M.motor_params(sc)
    f = M.user_rhs(sc)
    f_free = M.user_rhs(M.make_scene(False))
    rng = np.random.default_rng(3)
    for theta, w in zip(rng.uniform(0.0, 2.0, 300), rng.uniform(0.0, 150.0, 300), strict=True):
        load = float(cf.master_load_torque(sc, theta))  # the public vectorised load, membership by Θ
        y = np.array([theta, w])
        expect = (p.T_0 * (1 - w / p.omega_0) - p.b * w - load) / p.J
        assert f(0.0, y) == pytest.approx([w / p.omega_nom, expect], rel=1e-12, abs=1e-12)
        assert f_free(0.0, y)[1] == pytest.approx(expect + load / p.J, rel=1e-12, abs=1e-12)


# ------------------------------------------------------------------ convergence


def test_rk4_is_fourth_order(chain_ref: M.ChainReference) -> None:
    hs = (0.1, 0.05, 0.025)
    errs = [M.error_of(False, M.RK4, h) for h in hs]
    assert abs(_slope(hs, errs) - 4.0) < 0.5, errs
    assert errs[-1] > 1e-12  # above rounding: the asymptotic range
    hs_c = (4e-3, 2e-3, 1e-3)  # with the load: the breaks keep the order
    errs_c = [M.error_of(True, M.RK4, h, chain_ref.theta) for h in hs_c]
    assert abs(_slope(hs_c, errs_c) - 4.0) < 0.5, errs_c
    assert errs_c[-1] > 1e-10  # well above the reference's checked accuracy
    # beyond RK4's stability limit the core refuses
    p = M.motor_params(M.make_scene(False))
    with pytest.raises(ParameterError, match='unstable'):
        M.run_core(M.make_scene(False, method='rk4', h=1.01 * md.RK4_STABILITY * p.tau))


@pytest.mark.parametrize('method', [M.DOPRI5, M.RK45, M.DOP853])
def test_adaptive_errors_fall_with_rtol_without_load(method: str) -> None:
    rtols = tuple(10.0**-k for k in range(3, 11))
    errs = [M.error_of(False, method, r) for r in rtols]
    assert all(e2 <= 1.5 * e1 for e1, e2 in itertools.pairwise(errs)), errs
    assert errs[-1] <= 1e-5 * errs[0], errs
    # the global phase error stays below rtol (Θ <= 1.7 nominal s here)
    assert all(e <= r for e, r in zip(errs, rtols, strict=True)), errs


@pytest.mark.parametrize('method', [M.DOPRI5, M.RK45, M.DOP853])
def test_adaptive_errors_fall_with_rtol_with_load(method: str, chain_ref: M.ChainReference) -> None:
    rtols = (1e-4, 1e-6, 1e-8, 1e-10)
    errs = [M.error_of(True, method, r, chain_ref.theta) for r in rtols]
    assert all(e2 <= 1.5 * e1 for e1, e2 in itertools.pairwise(errs)), errs
    assert errs[-1] <= 1e-4 * errs[0], errs
    assert errs[-1] < 1e-7


@pytest.mark.parametrize('rtol', [1e-3, 1e-6, 1e-9, 1e-12])
def test_core_dopri5_error_is_that_of_scipy_rk45(rtol: float) -> None:
    ours = M.error_of(False, M.DOPRI5, rtol)
    scipys = M.error_of(False, M.RK45, rtol)
    assert scipys / 3 <= ours <= 3 * scipys, (ours, scipys)


# ------------------------------------------------------------------ rows


def test_quick_rows() -> None:
    rows = M.run(quick=True)
    assert all(isinstance(r, Row) and r.study == 'motor' for r in rows)
    assert all(math.isfinite(r.error) and math.isfinite(r.cpu_s_per_sim_s) and r.cpu_s_per_sim_s > 0 for r in rows)
    assert all(r.unit == 'nominal s' and r.quantity == f'master phase Θ, {r.method.split("[")[1][:-1]}' for r in rows)
    curves: dict[str, list[Row]] = {}
    for r in rows:
        curves.setdefault(r.method, []).append(r)
    assert len(curves) == len(M.METHODS) * len(M.CASES) == 8
    for name, curve in curves.items():
        assert len(curve) >= 2 and len({r.value for r in curve}) == len(curve)
        assert {r.knob for r in curve} == ({'h'} if name.startswith(M.RK4) else {'rtol'})
        # tightening the knob buys accuracy and costs CPU
        assert curve[-1].error < 1e-2 * curve[0].error, name
        assert curve[-1].cpu_s_per_sim_s > curve[0].cpu_s_per_sim_s, name
    # full mode has >= 4 settings per curve, in the ranges
    for chain in M.CASES.values():
        for method in M.METHODS:
            full = M.knob_settings(chain, method)
            assert len(full) >= 4
            if method != M.RK4:
                assert max(full) == pytest.approx(1e-3) and min(full) == pytest.approx(1e-12)
    assert min(M.knob_settings(False, M.RK4)) == pytest.approx(1e-5)
