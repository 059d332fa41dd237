"""D: delivery transporter efficiency (paper 002): the paper's Fig. 2, closed forms, hard regions."""

from __future__ import annotations

import dataclasses
import math
import warnings
from typing import Any

import mpmath as mp
import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from folder_line.config.params import load_params
from folder_line.core.mechanisms import delivery as dl
from folder_line.core.mechanisms import delivery_laws as dlaws
from folder_line.core.mechanisms.delivery import (
    DeliveryParams,
    evaluate,
    evaluate_point,
    evaluate_stroke,
    evaluate_stroke_point,
    stroke_minimum,
)
from folder_line.core.mechanisms.delivery_laws import ProfileLaw, register_law
from folder_line.core.mechanisms.delivery_results import (
    SAMPLE_FIELDS,
    STATE_CARRIAGE_REVERSED,
    STATE_KV_ZERO,
    STATE_NAMES,
    STATE_OK,
    STATE_SELF_LOCKING,
    DeliverySamples,
    state_names,
)
from folder_line.errors import ParameterError

REF: dict[str, Any] = dict(
    Lambda=0.4,
    alpha_m_deg=60.0,
    law='sinusoidal',
    f_Ap=0.1,
    f_Bp=0.1,
    f_A=0.15,
    f_B=0.15,
    f_O=0.15,
    r_A=0.1,
    r_B=0.1,
    r_O=0.1,
)
FRICTION = ('f_Ap', 'f_Bp', 'f_A', 'f_B', 'f_O', 'r_A', 'r_B', 'r_O')
FLOAT_FIELDS = (
    'eta_O',
    'eta_A',
    'eta_B',
    'eta',
    'K_v',
    'k_BA',
    'alpha',
    'beta',
    'psi',
    'dpsi',
    'p_AB',
    'p_ch',
    'm_1',
    'p_AB_ideal',
    'p_ch_ideal',
    'm_1_ideal',
)


def ref(**changes: Any) -> DeliveryParams:
    return DeliveryParams(**{**REF, **changes})


def frictionless(**changes: Any) -> DeliveryParams:
    return ref(**{**{k: 0.0 for k in FRICTION}, **changes})


# -------------------------------------------------------------------- hand formulas (no module calls)


def hand(
    xi: float,
    Lambda: float = 0.4,
    alpha_m_deg: float = 60.0,
    sign: float = 1.0,
    f_Ap: float = 0.1,
    f_Bp: float = 0.1,
    f_A: float = 0.15,
    f_B: float = 0.15,
    f_O: float = 0.15,
    r_A: float = 0.1,
    r_B: float = 0.1,
    r_O: float = 0.1,
    signed: bool = False,
) -> dict[str, float]:
    """The delivery paper's eqs. (1)-(9) (module docstring of core/mechanisms/delivery.py), cycloidal law,
    written out with math only.

    ``signed=True`` keeps the paper's signs; otherwise every friction term is a magnitude.
    """
    psi = xi - math.sin(2 * math.pi * xi) / (2 * math.pi)
    dpsi = 1 - math.cos(2 * math.pi * xi)
    a = math.asin(psi * math.sin(math.radians(alpha_m_deg)))
    b = sign * math.atan(dpsi * Lambda)
    m = (lambda x: x) if signed else abs
    K_v = math.cos(a - b) / math.cos(a)
    eta_B = 1 - f_Bp * math.tan(a) - f_B * r_B * m(math.sin(b)) / (K_v * math.cos(a) ** 2)
    eta_A = 1 / (1 + f_Ap * m(math.tan(a - b)) + f_A * r_A * m(math.sin(b)) / (math.cos(a) * math.cos(a - b)))
    eta_O = 1 / (1 + f_O * r_O)
    P_AB = 1 / (math.cos(a) - f_Bp * math.sin(a) - f_B * r_B * m(math.sin(b)) / (K_v * math.cos(a)))
    P_ch = P_AB * (math.cos(a - b) + f_Ap * m(math.sin(a - b)) + f_A * r_A * m(math.sin(b)) / math.cos(a))
    return dict(
        alpha=a,
        beta=b,
        K_v=K_v,
        k_BA=math.sin(b) / math.cos(a),
        eta_A=eta_A,
        eta_B=eta_B,
        eta_O=eta_O,
        eta=eta_O * eta_A * eta_B,
        p_AB=P_AB,
        p_ch=P_ch,
        m_1=P_ch * (1 + f_O * r_O),
        p_AB_ideal=1 / math.cos(a),
        p_ch_ideal=math.cos(a - b) / math.cos(a),
    )


# -------------------------------------------------------------------- the paper's published result


def test_reference_case_comes_from_the_config_file() -> None:
    assert load_params('delivery') == ref()


def test_paper_fig2_lowest_at_the_section_boundary() -> None:
    p = load_params('delivery')
    s = evaluate(p, [0.0, 1.0])
    assert list(s.state) == [STATE_OK, STATE_OK]
    assert s.eta[1] == pytest.approx(0.69, abs=0.005)
    # the lowest over a dense grid of the section and of the paper's (mirrored) stroke
    xi = np.linspace(0.0, 1.0, 100_001)
    assert np.argmin(evaluate(p, xi).eta) == xi.size - 1
    u = np.linspace(0.0, 2.0, 200_001)
    stroke = evaluate_stroke(p, u, return_section='paper_mirror')
    assert u[np.argmin(stroke.eta)] == 1.0
    assert stroke.eta.min() == s.eta[1]
    assert stroke_minimum(p, 'eta', return_section='paper_mirror') == pytest.approx((1.0, s.eta[1]), abs=1e-9)


def test_paper_fig2_highest_at_constant_speed() -> None:
    s = evaluate(load_params('delivery'), 0.0)
    assert float(s.alpha) == 0.0 and float(s.beta) == 0.0 and float(s.K_v) == 1.0
    assert 0.98 <= float(s.eta) < 0.99  # paper: 0.98 (= eta_O = 1/1.015 = 0.9852)
    u = np.linspace(0.0, 2.0, 20_001)
    for mode in dl.RETURN_SECTIONS:
        assert evaluate_stroke(load_params('delivery'), u, return_section=mode).eta.max() == float(s.eta)


def test_geometric_stroke_findings_reported_to_the_lead() -> None:
    """Where the velocity plan puts the slowest carriage and the lowest eta (see the module doc)."""
    p = load_params('delivery')
    u_kv, kv = stroke_minimum(p, 'K_v')
    assert u_kv == pytest.approx(1.35388, abs=1e-4) and kv == pytest.approx(0.354306, abs=1e-5)
    h = hand(2.0 - u_kv, sign=-1.0)  # the return section descends: beta < 0
    assert kv == pytest.approx(h['K_v'], rel=1e-12)
    u_eta, eta = stroke_minimum(p, 'eta')
    assert u_eta == pytest.approx(1.2982, abs=1e-3) and eta == pytest.approx(0.5915, abs=1e-4)
    assert eta < 0.69  # lower than the paper's boundary value: the paper's claim needs the mirror
    # at the boundary itself the carriage moves at chain speed
    assert float(evaluate_stroke(p, 1.0).K_v) == 1.0
    # first section: a shallow dip below 1 where beta > 2 alpha, then faster than the chain
    s = evaluate(p, np.linspace(0.0, 1.0, 10_001))
    assert s.K_v.min() == pytest.approx(0.94505, abs=1e-5) and s.K_v.max() == pytest.approx(1.40581, abs=1e-5)
    dip = s.K_v < 1.0 - 1e-12
    assert np.all(s.beta[dip] > 2 * s.alpha[dip])


# -------------------------------------------------------------------- closed forms


@pytest.mark.parametrize('xi', [0.0, 0.5, 1.0])
def test_closed_form_reference_case(xi: float) -> None:
    got = evaluate(ref(), xi)
    pt = evaluate_point(ref(), xi)
    want = hand(xi)
    for key, value in want.items():
        assert float(getattr(got, key)) == pytest.approx(value, rel=1e-12, abs=1e-15), key
        assert getattr(pt, key) == pytest.approx(value, rel=1e-12, abs=1e-15), key
    assert float(got.m_1_ideal) == pytest.approx(want['p_ch_ideal'], rel=1e-12)


def test_closed_form_numbers() -> None:
    """The values quoted in the report, written out."""
    s = evaluate(ref(), [0.0, 0.5, 1.0])
    np.testing.assert_allclose(np.degrees(s.alpha), [0.0, 25.6589, 60.0], atol=1e-4)
    np.testing.assert_allclose(np.degrees(s.beta), [0.0, 38.6598, 0.0], atol=1e-4)
    np.testing.assert_allclose(s.K_v, [1.0, 1.08096, 1.0], atol=1e-5)
    np.testing.assert_allclose(s.eta, [0.98522, 0.89710, 0.69432], atol=1e-5)
    # xi = 1: alpha = 60 deg, beta = 0 -> eta = (1 - 0.1 tan 60) / (1 + 0.1 tan 60) / 1.015
    t = math.tan(math.radians(60.0))
    assert s.eta[2] == pytest.approx((1 - 0.1 * t) / (1 + 0.1 * t) / 1.015, rel=1e-13)


@settings(max_examples=200, deadline=None)
@given(
    Lambda=st.floats(1e-3, 1e3),
    alpha_m_deg=st.floats(0.1, 89.0),
    law=st.sampled_from(['sinusoidal', 'harmonic']),
    xi=st.lists(st.floats(0.0, 1.0), min_size=1, max_size=20),
)
def test_frictionless_is_ideal(Lambda: float, alpha_m_deg: float, law: str, xi: list[float]) -> None:
    p = frictionless(Lambda=Lambda, alpha_m_deg=alpha_m_deg, law=law)
    s = evaluate(p, xi)
    assert np.all(s.state == STATE_OK)  # beta >= 0 -> K_v >= cos(beta) > 0; alpha_m <= 89
    assert np.all(s.eta == 1.0) and np.all(s.eta_A == 1.0) and np.all(s.eta_B == 1.0) and np.all(s.eta_O == 1.0)
    f = s.forces(P_k=250.0, r=0.08)
    np.testing.assert_allclose(f.P_AB, f.P_AB_ideal, rtol=1e-15)
    np.testing.assert_allclose(f.P_ch, f.P_ch_ideal, rtol=1e-15)
    np.testing.assert_allclose(f.M_1, f.M_1_ideal, rtol=1e-15)
    np.testing.assert_allclose(f.P_AB_ideal, 250.0 / np.cos(s.alpha), rtol=1e-12)
    np.testing.assert_allclose(f.P_ch_ideal, f.P_AB_ideal * np.cos(s.alpha - s.beta), rtol=1e-12)
    np.testing.assert_allclose(f.M_1_ideal, f.P_ch_ideal * 0.08, rtol=1e-15)


@given(f_O=st.floats(0.0, 1e6), r_O=st.floats(0.0, 1e6))
def test_eta_O_exact(f_O: float, r_O: float) -> None:
    p = ref(f_O=f_O, r_O=r_O)
    assert p.eta_O == 1.0 / (1.0 + f_O * r_O)
    assert np.all(evaluate(p, [0.0, 0.3, 1.0]).eta_O == 1.0 / (1.0 + f_O * r_O))
    assert evaluate_point(p, 0.7).eta_O == 1.0 / (1.0 + f_O * r_O)


@pytest.mark.parametrize('name', ['sinusoidal', 'harmonic'])
def test_laws_against_numerical_derivative(name: str) -> None:
    law = dlaws.LAWS[name]
    xi = np.linspace(0.0, 1.0, 201)
    h = 1e-6
    numeric = (law.psi(xi + h) - law.psi(xi - h)) / (2 * h)
    np.testing.assert_allclose(law.dpsi(xi), numeric, atol=1e-8)
    assert law.psi(0.0) == 0.0 and law.psi(1.0) == pytest.approx(1.0, abs=1e-15)
    assert law.dpsi(0.0) == 0.0 and law.dpsi(1.0) == pytest.approx(0.0, abs=1e-15)
    assert np.all(np.diff(law.psi(xi)) > 0)


def test_harmonic_closed_form() -> None:
    law = dlaws.LAWS['harmonic']
    xi = np.array([0.0, 0.25, 0.5, 1.0])
    np.testing.assert_allclose(law.psi(xi), [0.0, (1 - math.sqrt(0.5)) / 2, 0.5, 1.0], atol=1e-15)
    np.testing.assert_allclose(law.dpsi(xi), [0.0, math.pi / 2 * math.sqrt(0.5), math.pi / 2, 0.0], atol=1e-15)
    s = evaluate(ref(law='harmonic'), 0.5)
    assert float(s.alpha) == pytest.approx(math.asin(0.5 * math.sin(math.radians(60))), rel=1e-14)
    assert float(s.beta) == pytest.approx(math.atan(0.4 * math.pi / 2), rel=1e-14)


# -------------------------------------------------------------------- friction signs


def test_signed_paper_formula_would_gain_energy_ours_does_not() -> None:
    signed = hand(0.3, signed=True)
    assert signed['eta_A'] > 1.0  # 1.030: friction in pair A "helping" -- not a loss
    assert signed['eta_A'] == pytest.approx(1.0303, abs=1e-4)
    s = evaluate(ref(), np.linspace(0.0, 1.0, 10_001))
    assert np.all(s.eta_A <= 1.0) and np.all(s.eta_B <= 1.0) and np.all(s.eta <= s.eta_O)
    assert float(evaluate(ref(), 0.3).eta_A) == pytest.approx(hand(0.3)['eta_A'], rel=1e-12)
    # where alpha >= beta >= 0 the two agree: the paper's formula verbatim
    for xi in (0.65, 0.8, 0.95):
        assert hand(xi, signed=True)['eta'] == pytest.approx(hand(xi)['eta'], rel=1e-15)
        assert float(evaluate(ref(), xi).eta) == pytest.approx(hand(xi, signed=True)['eta'], rel=1e-12)


friction_value = st.one_of(st.just(0.0), st.floats(0.0, 0.5), st.floats(0.0, 10.0))


@settings(max_examples=200, deadline=None)
@given(
    Lambda=st.floats(1e-3, 1e3),
    alpha_m_deg=st.floats(1.0, 89.0),
    base=st.fixed_dictionaries({k: friction_value for k in FRICTION}),
    which=st.sampled_from(FRICTION),
    extra=st.floats(1e-6, 1.0),
    mode=st.sampled_from(dl.RETURN_SECTIONS),
)
def test_more_friction_never_raises_eta(
    Lambda: float, alpha_m_deg: float, base: dict[str, float], which: str, extra: float, mode: str
) -> None:
    u = np.linspace(0.0, 2.0, 401)
    p0 = ref(Lambda=Lambda, alpha_m_deg=alpha_m_deg, **base)
    p1 = dataclasses.replace(p0, **{which: base[which] + extra})
    e0 = evaluate_stroke(p0, u, return_section=mode).eta
    e1 = evaluate_stroke(p1, u, return_section=mode).eta
    assert np.all(e1 <= e0)


@pytest.mark.parametrize('which', FRICTION)
def test_each_friction_coefficient_strictly_lowers_eta_mid_section(which: str) -> None:
    e0 = float(evaluate(ref(), 0.5).eta)
    e1 = float(evaluate(ref(**{which: REF[which] * 1.5}), 0.5).eta)
    assert e1 < e0


# -------------------------------------------------------------------- power balance and kinematics


params_moderate = st.builds(
    DeliveryParams,
    Lambda=st.floats(1e-3, 1e3),
    alpha_m_deg=st.floats(0.5, 89.5),
    law=st.sampled_from(['sinusoidal', 'harmonic']),
    **{k: st.floats(0.0, 1.0) for k in FRICTION},
)


@settings(max_examples=200, deadline=None)
@given(
    p=params_moderate,
    mode=st.sampled_from(dl.RETURN_SECTIONS),
    P_k=st.floats(1e-3, 1e4),
    r=st.floats(1e-3, 1.0),
    v_A=st.floats(0.01, 10.0),
)
def test_power_balance_eta_is_useful_over_input_power(
    p: DeliveryParams, mode: str, P_k: float, r: float, v_A: float
) -> None:
    s = evaluate_stroke(p, np.linspace(0.0, 2.0, 201), return_section=mode)
    f = s.forces(P_k, r)
    ok = s.ok
    useful = P_k * s.carriage_speed(v_A)[ok]
    drive = f.M_1[ok] * (v_A / r)  # omega_sprocket = v_A / r
    np.testing.assert_allclose(useful / drive, s.eta[ok], rtol=1e-9)
    np.testing.assert_allclose(f.M_1_ideal[ok] / f.M_1[ok], s.eta[ok], rtol=1e-9)
    np.testing.assert_allclose(f.M_1_ideal[ok] * (v_A / r), useful, rtol=1e-12)


def test_velocity_plan_by_finite_differences() -> None:
    """K_v and v_BA follow from x_B = x_A - l cos(alpha) along the closed profile (geometric mode)."""
    p = ref(Lambda=0.4, alpha_m_deg=60.0)
    x_max = 0.5
    rod_len = p.rod_length(x_max)
    y_max = p.Lambda * x_max
    assert rod_len * math.sin(p.alpha_m) == pytest.approx(y_max)
    law = dlaws.LAWS[p.law]

    def geometry(u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        xi = np.where(u <= 1.0, u, 2.0 - u)
        y_A = y_max * law.psi(xi)
        alpha = np.arcsin(y_A / rod_len)
        return u * x_max, y_A, alpha

    u = np.concatenate([np.linspace(0.001, 0.999, 300), np.linspace(1.001, 1.999, 300)])
    h = 1e-6
    xa_p, ya_p, al_p = geometry(u + h)
    xa_m, ya_m, al_m = geometry(u - h)
    ds = np.hypot(xa_p - xa_m, ya_p - ya_m)  # chain path
    dx_B = (xa_p - rod_len * np.cos(al_p)) - (xa_m - rod_len * np.cos(al_m))
    s = evaluate_stroke(p, u)
    np.testing.assert_allclose(s.K_v, dx_B / ds, atol=1e-7)
    np.testing.assert_allclose(s.rod_angular_speed(v_A=1.0, l=rod_len), (al_p - al_m) / ds, atol=1e-6)
    # the mirrored return is not what the geometry gives
    mirror = evaluate_stroke(p, u, return_section='paper_mirror')
    assert np.max(np.abs(mirror.K_v - dx_B / ds)) > 0.5
    # over the closed stroke the carriage travels exactly as far as the chain's horizontal run
    uu = np.linspace(0.0, 2.0, 200_001)
    full = evaluate_stroke(p, uu)
    _, y, _ = geometry(uu)
    ds_du = np.hypot(x_max, y_max * np.gradient(law.psi(np.where(uu <= 1, uu, 2 - uu)), uu))
    integrand = full.K_v * ds_du
    travel = float(np.sum((integrand[1:] + integrand[:-1]) / 2 * np.diff(uu)))
    assert travel == pytest.approx(2.0 * x_max, rel=1e-6)
    assert y[0] == 0.0


def test_speeds_and_forces_scale() -> None:
    s = evaluate(ref(), [0.25, 0.5])
    np.testing.assert_allclose(s.carriage_speed(2.0), 2.0 * s.K_v)
    np.testing.assert_allclose(s.rod_relative_speed(2.0), 2.0 * np.sin(s.beta) / np.cos(s.alpha))
    f1, f2 = s.forces(100.0, 0.1), s.forces(200.0, 0.2)
    np.testing.assert_allclose(f2.P_AB, 2 * f1.P_AB)
    np.testing.assert_allclose(f2.M_1, 4 * f1.M_1)
    pf = evaluate_point(ref(), 0.5).forces(100.0, 0.1)
    assert float(pf.M_1) == pytest.approx(f1.M_1[1], rel=1e-12)
    with pytest.raises(ParameterError, match='P_k'):
        s.forces(-1.0, 0.1)
    with pytest.raises(ParameterError, match='r='):
        s.forces(1.0, 0.0)
    with pytest.raises(ParameterError, match='overflow'):
        s.forces(1e300, 1e300)
    with pytest.raises(ParameterError, match='l='):
        s.rod_angular_speed(1.0, 0.0)


# -------------------------------------------------------------------- hard regions and states


def _finite_everywhere(s: DeliverySamples) -> None:
    for name in FLOAT_FIELDS:
        assert np.all(np.isfinite(getattr(s, name))), name
    assert np.all((s.eta >= 0.0) & (s.eta <= 1.0))
    assert np.all((s.eta_A >= 0.0) & (s.eta_A <= 1.0)) and np.all(s.eta_B <= 1.0)
    assert set(np.unique(s.state)) <= {STATE_OK, STATE_SELF_LOCKING, STATE_KV_ZERO, STATE_CARRIAGE_REVERSED}
    bad = ~s.ok
    for name in ('eta', 'eta_A', 'eta_B', 'p_AB', 'p_ch', 'm_1', 'p_AB_ideal', 'p_ch_ideal', 'm_1_ideal'):
        assert np.all(getattr(s, name)[bad] == 0.0), name
    assert np.all(s.eta[s.ok] > dl.ETA_TOL)


def test_alpha_m_just_below_90_self_locks_near_the_end_of_the_section() -> None:
    xi = np.linspace(0.0, 1.0, 10_001)
    s = evaluate_stroke(ref(alpha_m_deg=89.999999), np.concatenate([xi, 2.0 - xi]))
    _finite_everywhere(s)
    assert s.state[xi.size - 1] == STATE_SELF_LOCKING and s.state[0] == STATE_OK
    # without friction the same geometry still drives (rod force 1/cos(alpha) ~ 5e7 P_k)
    f0 = evaluate(frictionless(alpha_m_deg=89.999999), 1.0)
    assert int(f0.state) == STATE_OK and float(f0.p_AB) > 1e7 and float(f0.eta) == 1.0


def test_cos_alpha_zero_is_self_locking_even_without_friction() -> None:
    p = frictionless(alpha_m_deg=math.nextafter(90.0, 0.0))
    assert math.sin(p.alpha_m) == 1.0  # float: the rod is exactly across the guide at psi = 1
    s = evaluate(p, [0.5, 1.0])
    assert list(s.state) == [STATE_OK, STATE_SELF_LOCKING]
    assert s.K_v[1] == 0.0 and s.k_BA[1] == 0.0 and s.eta[1] == 0.0
    pt = evaluate_point(p, 1.0)
    assert pt.state_name == 'self_locking' and pt.K_v == 0.0


def test_huge_lambda_beta_to_90() -> None:
    xi = np.linspace(0.0, 1.0, 100_001)
    s = evaluate(ref(Lambda=1e6), xi)
    _finite_everywhere(s)
    assert np.degrees(s.beta).max() > 89.9999
    assert s.K_v[1:].min() < 1e-3
    # beta ~ 90 deg: K_v -> tan(alpha), small early in the section where alpha is small, and
    # the 1/K_v term of eta_B eats the drive power there (a band xi ~ 0.002 .. 0.14)
    locked = np.flatnonzero(s.state == STATE_SELF_LOCKING)
    assert locked.size > 0 and np.all(np.diff(locked) == 1)
    assert 0.0 < xi[locked[0]] < 0.01 and 0.1 < xi[locked[-1]] < 0.2
    mid = xi.size // 2
    assert s.state[mid] == STATE_OK and s.K_v[mid] == pytest.approx(math.tan(s.alpha[mid]), rel=1e-5)
    s0 = evaluate(frictionless(Lambda=1e6), xi)
    _finite_everywhere(s0)
    assert np.all(s0.ok) and np.all(s0.eta == 1.0)


def test_kv_zero_state() -> None:
    xi = np.linspace(0.0, 1e-3, 10_001)
    s = evaluate(frictionless(Lambda=1e300), xi)
    _finite_everywhere(s)
    assert s.state[0] == STATE_OK  # xi = 0: psi' = 0, beta = 0, K_v = 1
    kz = s.state == STATE_KV_ZERO
    assert kz.any() and np.all(np.abs(s.K_v[kz]) < dl.KV_TOL)
    assert 'kv_zero' in set(s.state_names())


def test_carriage_reversed_on_the_geometric_return() -> None:
    u = np.linspace(1.0, 2.0, 10_001)
    s = evaluate_stroke(frictionless(Lambda=50.0, alpha_m_deg=80.0), u)
    _finite_everywhere(s)
    rev = s.state == STATE_CARRIAGE_REVERSED
    assert rev.any() and np.all(s.K_v[rev] <= -dl.KV_TOL)
    assert np.all(np.abs(s.alpha[rev]) + np.abs(s.beta[rev]) > math.pi / 2)
    pt = evaluate_stroke_point(frictionless(Lambda=50.0, alpha_m_deg=80.0), float(u[np.argmax(rev)]))
    assert pt.state_name == 'carriage_reversed'


def test_large_friction_negative_eta_is_self_locking() -> None:
    s = evaluate(ref(f_Bp=2.0), np.linspace(0.0, 1.0, 1001))
    _finite_everywhere(s)
    locked = s.state == STATE_SELF_LOCKING
    assert locked[-1] and not locked[0]
    # the raw eta_B = 1 - 2 tan(alpha) - ... would be negative there; reported 0.0
    assert 1 - 2.0 * math.tan(math.radians(60.0)) < 0
    f = s.forces(100.0, 0.1)
    assert np.all(f.P_AB[locked] == 0.0) and np.all(f.M_1[locked] == 0.0)
    # the boundary of the lock: eta_B crosses 0 where the P_AB denominator does
    first = int(np.argmax(locked))
    h = hand(float(s.xi[first]), f_Bp=2.0)
    assert h['eta_B'] <= 0.0 and 1 / h['p_AB'] <= 0.0
    assert hand(float(s.xi[first - 1]), f_Bp=2.0)['eta_B'] > 0.0


def test_overflowing_friction_products() -> None:
    p = ref(f_A=1e300, r_A=1e300, f_B=1e300, r_B=1e300, f_Ap=1e308, f_Bp=1e308, f_O=1e-300, r_O=1e-300)
    s = evaluate_stroke(p, np.linspace(0.0, 2.0, 2001))
    _finite_everywhere(s)
    assert s.state[0] == STATE_OK and s.eta[0] == 1.0  # xi = 0: no friction term is active
    assert np.all(s.state[1:-1] == STATE_SELF_LOCKING)
    s2 = evaluate(ref(f_O=1e300, r_O=1e300), [0.0, 0.5])
    _finite_everywhere(s2)
    assert np.all(s2.state == STATE_SELF_LOCKING) and np.all(s2.eta_O == 0.0)


wide = st.one_of(st.just(0.0), st.floats(0.0, 2.0), st.floats(0.0, 1.7976931348623157e308))
params_any = st.builds(
    DeliveryParams,
    Lambda=st.one_of(st.floats(0.0, 1.7976931348623157e308, exclude_min=True), st.sampled_from([5e-324, 1e6, 1e300])),
    alpha_m_deg=st.one_of(
        st.floats(0.0, 90.0, exclude_min=True, exclude_max=True),
        st.sampled_from([89.999999, math.nextafter(90.0, 0.0), 5e-324]),
    ),
    law=st.sampled_from(['sinusoidal', 'harmonic']),
    **{k: wide for k in FRICTION},
)
positions = st.lists(
    st.one_of(st.floats(0.0, 2.0), st.sampled_from([0.0, 1.0, 2.0, 1e-300, 1.0 - 1e-16, 1.0 + 2e-16, 2.0 - 1e-16])),
    min_size=1,
    max_size=30,
)


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(p=params_any, u=positions, mode=st.sampled_from(dl.RETURN_SECTIONS))
def test_never_nan_or_inf_and_no_numpy_warnings(p: DeliveryParams, u: list[float], mode: str) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        s = evaluate_stroke(p, u, return_section=mode)
        _finite_everywhere(s)
        sec = evaluate(p, np.minimum(u, 1.0))
        _finite_everywhere(sec)
        f = s.forces(1.0, 1.0)
        for name in ('P_AB', 'P_ch', 'M_1', 'P_AB_ideal', 'P_ch_ideal', 'M_1_ideal'):
            assert np.all(np.isfinite(getattr(f, name)))
        for x in u:
            pt = evaluate_stroke_point(p, x, return_section=mode)
            assert all(math.isfinite(getattr(pt, k)) for k in FLOAT_FIELDS)
            assert 0.0 <= pt.eta <= 1.0


@settings(max_examples=300, deadline=None)
@given(p=params_any, u=st.floats(0.0, 2.0), mode=st.sampled_from(dl.RETURN_SECTIONS))
def test_scalar_path_matches_vector_path(p: DeliveryParams, u: float, mode: str) -> None:
    v = evaluate_stroke(p, [u], return_section=mode)
    pt = evaluate_stroke_point(p, u, return_section=mode)
    # a state decided on a hair's breadth may differ by the last bit of sin/cos; skip those
    kv = float(v.K_v[0])
    assume(abs(abs(kv) - dl.KV_TOL) > 1e-12 * max(1.0, abs(kv)))
    assume(abs(float(np.cos(v.alpha[0])) - dl.COS_ALPHA_TOL) > 1e-15)
    assert pt.state == int(v.state[0])
    assert pt.section == int(v.section[0])
    for k in (*FLOAT_FIELDS, 'u', 'xi'):
        assert getattr(pt, k) == pytest.approx(float(getattr(v, k)[0]), rel=1e-9, abs=1e-300), k


# -------------------------------------------------------------------- domain, validation, registry


def test_positions_outside_the_section_are_errors_rounding_is_clipped() -> None:
    for bad in (-0.1, 1.1, float('nan'), float('inf')):
        with pytest.raises(ParameterError, match='xi='):
            evaluate(ref(), [0.5, bad])
        with pytest.raises(ParameterError, match='xi='):
            evaluate_point(ref(), bad)
    with pytest.raises(ParameterError, match=r'u=2\.5'):
        evaluate_stroke(ref(), 2.5)
    with pytest.raises(ParameterError, match='u='):
        evaluate_stroke_point(ref(), -1.0)
    with pytest.raises(ParameterError, match='xi='):
        evaluate(ref(), 'abc')
    s = evaluate(ref(), [1.0 + 1e-12, -1e-12])
    assert list(s.xi) == [1.0, 0.0]
    assert evaluate_point(ref(), 1.0 + 1e-12).xi == 1.0
    with pytest.raises(ParameterError, match='return_section'):
        evaluate_stroke(ref(), 0.5, return_section='mirror')  # type: ignore[arg-type]


def test_shapes_sections_and_names() -> None:
    u = np.linspace(0.0, 2.0, 12).reshape(3, 4)
    s = evaluate_stroke(ref(), u)
    for name in SAMPLE_FIELDS:
        assert getattr(s, name).shape == (3, 4), name
    assert s.state.dtype == np.int8 and s.section.dtype == np.int8
    np.testing.assert_array_equal(s.section, (u > 1.0).astype(np.int8))
    np.testing.assert_array_equal(s.xi, np.where(u <= 1.0, u, 2.0 - u))
    assert np.all(s.beta[u > 1.0] <= 0.0) and np.all(s.beta[u <= 1.0] >= 0.0)
    cols = s.columns()
    assert set(cols) == set(SAMPLE_FIELDS) | {'state_name', 'section_name'}
    assert all(c.shape == (12,) for c in cols.values())
    assert set(cols['section_name']) == {'deceleration', 'acceleration'}
    assert (
        list(state_names([0, 1, 2, 3])) == list(STATE_NAMES) == ['ok', 'self_locking', 'kv_zero', 'carriage_reversed']
    )
    assert float(evaluate(ref(), 0.5).eta) == evaluate(ref(), [0.5]).eta[0]  # 0-d input -> 0-d arrays
    assert evaluate(ref(), 0.5).eta.shape == ()
    pt = evaluate_stroke_point(ref(), 1.5)
    assert pt.section_name == 'acceleration' and pt.xi == 0.5 and pt.beta < 0
    assert evaluate_stroke_point(ref(), 1.5, return_section='paper_mirror').beta > 0


def test_params_have_no_defaults_and_match_the_yaml_keys() -> None:
    fields = dataclasses.fields(DeliveryParams)
    assert [f.name for f in fields] == list(REF)
    assert all(f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING for f in fields)
    p = ref(Lambda=1, alpha_m_deg=45, f_A=0)
    assert isinstance(p.Lambda, float) and isinstance(p.alpha_m_deg, float) and isinstance(p.f_A, float)
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.Lambda = 2.0  # type: ignore[misc]


@pytest.mark.parametrize(
    ('key', 'value', 'message'),
    [
        ('Lambda', 0.0, '> 0'),
        ('Lambda', -0.4, '> 0'),
        ('Lambda', float('nan'), 'finite'),
        ('Lambda', float('inf'), 'finite'),
        ('Lambda', True, 'number'),
        ('Lambda', '0.4', 'number'),
        ('alpha_m_deg', 0.0, r'\(0, 90\)'),
        ('alpha_m_deg', -10.0, r'\(0, 90\)'),
        ('alpha_m_deg', 90.0, 'self-locks by construction'),
        ('alpha_m_deg', 120.0, '< 90'),
        ('alpha_m_deg', float('inf'), 'finite'),
        ('law', 'cosine', 'sinusoidal, harmonic'),
        ('law', 3, 'one of'),
        ('f_Ap', -0.1, '>= 0'),
        ('f_Bp', float('inf'), 'finite'),
        ('f_A', float('nan'), 'finite'),
        ('f_B', -1e-300, '>= 0'),
        ('f_O', None, 'number'),
        ('r_A', -1.0, '>= 0'),
        ('r_B', float('-inf'), 'finite'),
        ('r_O', -0.1, '>= 0'),
    ],
)
def test_validation_names_field_and_value(key: str, value: object, message: str) -> None:
    with pytest.raises(ParameterError, match=message) as info:
        ref(**{key: value})
    assert info.value.key == f'delivery.{key}'
    assert f'delivery.{key}=' in str(info.value)


def test_load_params_overrides_are_validated() -> None:
    assert load_params('delivery', overrides={'law': 'harmonic'}).law == 'harmonic'
    with pytest.raises(ParameterError, match='alpha_m_deg'):
        load_params('delivery', overrides={'alpha_m_deg': 90.0})


def test_register_a_law(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(dlaws, 'LAWS', dict(dlaws.LAWS))
    cubic = ProfileLaw('cubic', lambda x: 3 * x**2 - 2 * x**3, lambda x: 6 * x - 6 * x**2, 'smoothstep')
    register_law(cubic)
    assert dlaws.law_names() == ('sinusoidal', 'harmonic', 'cubic')
    s = evaluate(ref(law='cubic'), [0.0, 0.5, 1.0])
    assert np.all(s.ok) and s.eta[2] == pytest.approx(hand(1.0)['eta'], rel=1e-12)  # same end state
    assert float(s.beta[1]) == pytest.approx(math.atan(1.5 * 0.4))
    with pytest.raises(ParameterError, match='registered'):
        register_law(cubic)
    register_law(cubic, replace=True)
    with pytest.raises(ParameterError, match='psi\\(1\\) = 1'):
        register_law(ProfileLaw('half', lambda x: x / 2, lambda x: 0 * x + 0.5, 'bad'))
    with pytest.raises(ParameterError, match='dpsi >= 0'):
        register_law(
            ProfileLaw(
                'wobble', lambda x: x + np.sin(2 * np.pi * x) / 2, lambda x: 1 + np.pi * np.cos(2 * np.pi * x), 'bad'
            )
        )
    with pytest.raises(ParameterError, match='sinusoidal, harmonic, cubic'):
        ref(law='quartic')


def test_stroke_minimum_arguments() -> None:
    with pytest.raises(ParameterError, match='quantity'):
        stroke_minimum(ref(), 'P_AB')  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match='n='):
        stroke_minimum(ref(), n=2)
    with pytest.raises(ParameterError, match='params'):
        evaluate({'Lambda': 0.4}, 0.5)  # type: ignore[arg-type]
    u, kv = stroke_minimum(ref(), 'K_v', return_section='paper_mirror')
    assert u == pytest.approx(0.31806, abs=1e-4) and kv == pytest.approx(0.945047, abs=1e-6)


# ------------------------------------------------------------------------ limits: alpha_m -> 90 deg, K_v -> 0, eta -> 0
def delivery(**over: Any) -> dl.DeliveryParams:
    base = dataclasses.asdict(load_params('delivery'))
    base.update(over)
    return dl.DeliveryParams(**base)


FRICTIONLESS = {key: 0.0 for key in ('f_Ap', 'f_Bp', 'f_A', 'f_B', 'f_O', 'r_A', 'r_B', 'r_O')}
STROKE = np.concatenate([np.linspace(0.0, 2.0, 4001), [1.0 - 1e-15, 1.0 + 1e-15, 2.0 - 1e-12]])


def all_finite(s: DeliverySamples) -> bool:
    return all(np.all(np.isfinite(getattr(s, f.name))) for f in dataclasses.fields(s))


def non_ok_zeroed(s: DeliverySamples) -> bool:
    bad = s.state != STATE_OK
    return all(
        np.all(getattr(s, n)[bad] == 0.0)
        for n in ('eta', 'eta_A', 'eta_B', 'p_AB', 'p_ch', 'm_1', 'p_AB_ideal', 'p_ch_ideal', 'm_1_ideal')
    )


class TestDeliveryLimits:
    """alpha_m -> 90 deg, K_v -> 0, eta -> 0: states, never NaN/inf, no warnings (mpmath references)."""

    @pytest.mark.parametrize('alpha_m', [89.9999, 90.0 - 1e-9, math.nextafter(90.0, 0.0)])
    @pytest.mark.parametrize('friction', [True, False])
    def test_alpha_m_to_90(self, alpha_m: float, friction: bool) -> None:
        """Near psi = 1 the rod stands almost across the guide: self_locking (geometric or by
        friction), everything finite; where the model still holds, 1/cos(alpha) matches mpmath
        (to the 1e-4 that the rounding of sin(alpha_m) next to 1 allows)."""
        p = delivery(alpha_m_deg=alpha_m, **({} if friction else FRICTIONLESS))
        for mode in dl.RETURN_SECTIONS:
            s = dl.evaluate_stroke(p, STROKE, return_section=mode)
            assert all_finite(s) and non_ok_zeroed(s)
            end = np.abs(s.u - 1.0) < 1e-12  # psi = 1: alpha = alpha_m
            assert np.all(s.state[end] == STATE_SELF_LOCKING) or (not friction and alpha_m == 89.9999)
            ok = s.state == STATE_OK
            assert ok.any()  # most of the stroke still works
            with mp.workdps(40):
                sa = mp.sin(mp.radians(mp.mpf(alpha_m)))
                cos_ref = np.array([float(mp.sqrt(1 - (mp.mpf(float(x)) * sa) ** 2)) for x in s.psi[ok]])
            assert np.allclose(s.p_AB_ideal[ok] * cos_ref, 1.0, rtol=1e-4, atol=0.0)
            for u in (1.0, 0.999999, 1.5):  # the scalar path agrees on the state
                assert dl.evaluate_stroke_point(p, u, return_section=mode).state == int(
                    dl.evaluate_stroke(p, [u], return_section=mode).state[0]
                )
        if not friction and alpha_m == 89.9999:  # cos(alpha_m) = 1.7e-6 > COS_ALPHA_TOL: ok, force ~ 5.7e5 P_k
            pt = dl.evaluate_point(p, 1.0)
            assert pt.state == STATE_OK and pt.p_AB == pytest.approx(1.0 / math.cos(math.radians(alpha_m)), rel=1e-4)
        with pytest.raises(ParameterError, match='alpha_m_deg'):
            delivery(alpha_m_deg=90.0)

    @staticmethod
    def kv_touch() -> tuple[float, float, float]:
        """(alpha_m, Lambda*, xi*) with min K_v = 0 on the geometric return (mpmath): there
        tan(alpha) tan|beta| = 1, i.e. Lambda* = 1 / max_xi(tan(alpha) psi'(xi))."""
        alpha_m = 60.0
        with mp.workdps(40):
            sm = mp.sin(mp.radians(alpha_m))

            def g(xi: Any) -> Any:  # tan(alpha) psi' for the sinusoidal law
                psi = xi - mp.sin(2 * mp.pi * xi) / (2 * mp.pi)
                sa = psi * sm
                return sa / mp.sqrt(1 - sa * sa) * (1 - mp.cos(2 * mp.pi * xi))

            xi = mp.findroot(lambda x: mp.diff(g, x), mp.mpf('0.67'))  # the maximum, near 0.67
            return alpha_m, float(1 / g(xi)), float(xi)

    @pytest.mark.parametrize('rel', [0.0, 1e-12, -1e-12, 1e-6, -1e-6])
    def test_kv_to_zero(self, rel: float) -> None:
        """K_v touches 0 at Lambda*: kv_zero there (|K_v| < 1e-9), carriage_reversed past it,
        forces and efficiencies 0 in those states, all finite, no warnings."""
        alpha_m, lam, xi = self.kv_touch()
        p = delivery(alpha_m_deg=alpha_m, Lambda=lam * (1.0 + rel))
        u_star = 2.0 - xi  # on the return section
        pt = dl.evaluate_stroke_point(p, u_star)
        # K_v(xi*) = cos(beta) (1 - tan(alpha) tan|beta|) ~ -rel cos(beta) near the touch
        assert abs(pt.K_v + rel * math.cos(pt.beta)) <= 1e-6 * abs(rel) + 1e-13
        if abs(pt.K_v) < dl.KV_TOL:
            expect = STATE_KV_ZERO
        elif pt.K_v < 0.0:
            expect = STATE_CARRIAGE_REVERSED
        else:  # eq. (3): eta_B = 1 - f_Bp |tan a| - f_B r_B |sin b| / (K_v cos^2 a) <= 0 locks by friction
            ca = math.cos(pt.alpha)
            eta_b = 1.0 - p.f_Bp * math.tan(pt.alpha) - p.f_B * p.r_B * abs(math.sin(pt.beta)) / (pt.K_v * ca * ca)
            expect = STATE_SELF_LOCKING if eta_b <= 0.0 else STATE_OK
        assert pt.state == expect
        if rel == 0.0:
            assert pt.state == STATE_KV_ZERO
        u = np.concatenate([STROKE, u_star + np.linspace(-1e-4, 1e-4, 201)])
        s = dl.evaluate_stroke(p, u)
        assert all_finite(s) and non_ok_zeroed(s)
        reversed_ = s.state == STATE_CARRIAGE_REVERSED
        assert reversed_.any() == (rel > 1e-9)
        assert np.all(s.K_v[reversed_] <= -dl.KV_TOL)

    @pytest.mark.parametrize('margin', [1e-6, 1e-11, 1e-13, 0.0, -1e-6])
    def test_eta_to_zero(self, margin: float) -> None:
        """Only pair B's sliding friction: eta = 1 - f_Bp tan(alpha), 0 at psi = 1 for
        f_Bp = (1 - margin) / tan(alpha_m). eta <= ETA_TOL is self_locking; above, the forces
        grow like 1/eta but stay finite."""
        alpha_m = 60.0
        f_bp = (1.0 - margin) / math.tan(math.radians(alpha_m))
        p = delivery(alpha_m_deg=alpha_m, **{**FRICTIONLESS, 'f_Bp': f_bp})
        pt = dl.evaluate_point(p, 1.0)
        with mp.workdps(40):
            eta_ref = float(1 - mp.mpf(f_bp) * mp.tan(mp.radians(mp.mpf(alpha_m))))
        if eta_ref > dl.ETA_TOL * 2:
            assert pt.state == STATE_OK
            assert pt.eta == pytest.approx(eta_ref, rel=1e-15 / eta_ref + 1e-12)
            assert pt.p_AB == pytest.approx(
                1.0 / (math.cos(math.radians(alpha_m)) * eta_ref), rel=1e-15 / eta_ref + 1e-12
            )
        elif eta_ref < dl.ETA_TOL / 2:
            assert pt.state == STATE_SELF_LOCKING and pt.eta == 0.0 and pt.p_AB == 0.0
        s = dl.evaluate(p, np.linspace(0.0, 1.0, 2001))
        assert all_finite(s) and non_ok_zeroed(s)
        assert np.all((s.eta >= 0.0) & (s.eta <= 1.0))
