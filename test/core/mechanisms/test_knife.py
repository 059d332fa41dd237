"""Knife crank-slider: closed forms, mpmath and finite-difference cross-checks, exact window ends."""

from __future__ import annotations

import dataclasses
import math
from fractions import Fraction
from typing import Any

import mpmath as mp
import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from folder_line.config.params import load_params
from folder_line.core.limits import KNIFE_SPEED
from folder_line.core.mechanisms import knife as kn
from folder_line.core.mechanisms.knife import KnifeParams
from folder_line.errors import ParameterError

from .._reference import DELTAS, EPS, angle_diff, exact_frac_turns, ulp

mp.mp.dps = 40


@pytest.fixture(scope='module')
def ref() -> KnifeParams:
    return load_params('knife')


def make(**kw: float) -> KnifeParams:
    base = {'r_k': 0.04, 'L_k': 0.16, 'e': 0.0, 'n_k': 50000.0, 's_clear': 0.1656}
    base.update(kw)
    return KnifeParams(**base)


def s_mp(p: KnifeParams, phi: mp.mpf) -> mp.mpf:
    r, L, e = mp.mpf(p.r_k), mp.mpf(p.L_k), mp.mpf(p.e)
    return r * mp.cos(phi) + mp.sqrt(L**2 - (r * mp.sin(phi) - e) ** 2)


def window_mp(p: KnifeParams) -> tuple[mp.mpf, mp.mpf]:
    """Window ends at 40 digits, by bisection-safe root finding on the mpmath s."""
    dc = kn.dead_centres(p)
    po = mp.asin(mp.mpf(p.e) / (mp.mpf(p.L_k) + mp.mpf(p.r_k)))
    pi_ = mp.pi + mp.asin(mp.mpf(p.e) / (mp.mpf(p.L_k) - mp.mpf(p.r_k)))
    assert abs(float(po) - dc.phi_outer) < 1e-15
    sc = mp.mpf(p.s_clear)

    def bisect(neg: mp.mpf, pos: mp.mpf) -> mp.mpf:  # s(neg) < s_clear < s(pos)
        for _ in range(150):
            mid = (neg + pos) / 2
            if s_mp(p, mid) < sc:
                neg = mid
            else:
                pos = mid
        return (neg + pos) / 2

    return bisect(pi_ - 2 * mp.pi, po), bisect(pi_, po)


# ----------------------------------------------------------------------------- parameters


def test_params_have_no_defaults_and_load_from_yaml(ref: KnifeParams) -> None:
    for f in dataclasses.fields(KnifeParams):
        assert f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
    assert ref == make()
    assert isinstance(ref.n_k, float)
    with pytest.raises(dataclasses.FrozenInstanceError):
        ref.r_k = 1.0  # type: ignore[misc]


def test_omega_and_period(ref: KnifeParams) -> None:
    assert ref.omega_k == pytest.approx(87.266, abs=5e-4)  # the paper's omega_k
    assert abs(kn.period(ref) - 0.072) < 1e-12
    assert kn.omega(ref) * kn.period(ref) == pytest.approx(2 * math.pi, rel=1e-15)


@pytest.mark.parametrize(
    ('kw', 'key', 'words'),
    [
        ({'r_k': 0.0}, 'knife.r_k', 'must be in [0.0001, 100] m'),
        ({'r_k': 5e-324}, 'knife.r_k', 'must be in [0.0001, 100] m'),
        ({'r_k': 1e308}, 'knife.r_k', 'must be in [0.0001, 100] m'),
        ({'L_k': 1e308}, 'knife.L_k', 'must be in [0.0001, 100] m'),  # was an OverflowError
        ({'e': 1e308}, 'knife.e', 'must be in [-100, 100] m'),
        ({'e': -1.0}, 'knife.L_k', 'knife.e=-1.0'),  # the rule tying the three names the others too
        ({'L_k': -0.1}, 'knife.L_k', '> 0'),
        ({'L_k': 0.04}, 'knife.L_k', 'cannot be assembled'),  # L = r
        ({'e': 0.12}, 'knife.L_k', 'cannot be assembled'),  # L = r + |e| exactly
        ({'e': -0.13}, 'knife.L_k', 'cannot be assembled'),
        ({'n_k': 0.0}, 'knife.n_k', 'must be in [2, 200000]'),
        ({'n_k': 1e-300}, 'knife.n_k', 'must be in [2, 200000]'),
        ({'n_k': 1e308}, 'knife.n_k', 'must be in [2, 200000]'),
        ({'n_k': math.inf}, 'knife.n_k', 'finite'),
        ({'e': math.nan}, 'knife.e', 'finite'),
        ({'s_clear': 0.2}, 'knife.s_clear', 'never'),  # = s_max
        ({'s_clear': 0.25}, 'knife.s_clear', 'never'),
        ({'s_clear': 0.12}, 'knife.s_clear', 'always'),  # = s_min
        ({'s_clear': 0.0}, 'knife.s_clear', 'always'),
        ({'r_k': True}, 'knife.r_k', 'number'),
        ({'s_clear': '0.17'}, 'knife.s_clear', 'number'),
    ],
)
def test_validation_names_field_and_value(kw, key, words) -> None:
    with pytest.raises(ParameterError) as info:
        make(**kw)
    assert info.value.key == key
    assert words in str(info.value)
    assert repr(next(iter(kw.values()))) in str(info.value)


def test_load_params_overrides_are_validated() -> None:
    with pytest.raises(ParameterError, match=r'knife.s_clear'):
        load_params('knife', overrides={'s_clear': 0.3})
    p = load_params('knife', overrides={'e': 0.01})
    assert p.e == 0.01


# ----------------------------------------------------------------------------- kinematics


def test_dead_centres_closed_form_central(ref: KnifeParams) -> None:
    dc = kn.dead_centres(ref)
    assert (dc.phi_outer, dc.s_max, dc.phi_inner, dc.s_min) == (0.0, 0.2, math.pi, 0.12)
    assert dc.stroke == pytest.approx(2 * ref.r_k, rel=1e-14)
    assert kn.position(ref, 0.0) == 0.2
    assert kn.position(ref, math.pi) == pytest.approx(0.12, abs=1e-16)


offsets = st.floats(-0.11, 0.11, allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(e=offsets)
def test_dead_centres_are_the_extremes(e: float) -> None:
    p = make(e=e, s_clear=0.15)
    dc = kn.dead_centres(p)
    L, r = p.L_k, p.r_k
    assert dc.s_max == pytest.approx(math.sqrt((L + r) ** 2 - e * e), rel=1e-15)
    assert dc.s_min == pytest.approx(math.sqrt((L - r) ** 2 - e * e), rel=1e-15)
    assert kn.position(p, dc.phi_outer) == pytest.approx(dc.s_max, rel=1e-14)
    assert kn.position(p, dc.phi_inner) == pytest.approx(dc.s_min, rel=1e-14)
    assert abs(kn.velocity(p, dc.phi_outer)) < 1e-12 and abs(kn.velocity(p, dc.phi_inner)) < 1e-12
    assert kn.acceleration(p, dc.phi_outer) < 0.0 < kn.acceleration(p, dc.phi_inner)
    phi = np.linspace(-math.pi, math.pi, 100001)
    s = kn.position(p, phi)
    assert s.max() <= dc.s_max * (1 + 1e-15) and s.max() == pytest.approx(dc.s_max, abs=1e-9)
    assert s.min() >= dc.s_min * (1 - 1e-15) and s.min() == pytest.approx(dc.s_min, abs=1e-9)


@pytest.mark.parametrize('e', [0.0, 0.03, -0.07, 0.115])
def test_derivatives_against_mpmath(e: float) -> None:
    p = make(e=e, s_clear=0.15)
    w = p.omega_k
    phis = np.linspace(-3.0, 3.0, 13)
    v = kn.velocity(p, phis)
    a = kn.acceleration(p, phis)
    for i, ph in enumerate(phis.tolist()):
        x = mp.mpf(ph)
        assert abs(kn.position(p, ph) - float(s_mp(p, x))) < 1e-16
        assert abs(v[i] - float(w * mp.diff(lambda y: s_mp(p, y), x, 1))) < 1e-13 * w
        assert abs(a[i] - float(w**2 * mp.diff(lambda y: s_mp(p, y), x, 2))) < 1e-12 * w**2


@settings(max_examples=60, deadline=None)
@given(e=offsets, phi=st.floats(-10.0, 10.0))
def test_derivatives_against_finite_differences(e: float, phi: float) -> None:
    p = make(e=e, s_clear=0.15)
    w = p.omega_k
    h = 1e-5
    fd_v = w * (kn.position(p, phi + h) - kn.position(p, phi - h)) / (2 * h)
    fd_a = w * (kn.velocity(p, phi + h) - kn.velocity(p, phi - h)) / (2 * h)
    assert kn.velocity(p, phi) == pytest.approx(fd_v, abs=1e-8 * w)
    assert kn.acceleration(p, phi) == pytest.approx(fd_a, abs=1e-7 * w * w)


def test_vectorised_equals_scalar(ref: KnifeParams) -> None:
    phi = np.linspace(-7.0, 7.0, 57).reshape(3, 19)
    for fn in (kn.position, kn.velocity, kn.acceleration):
        arr = fn(ref, phi)
        assert arr.shape == phi.shape
        assert_allclose(arr, [[fn(ref, x) for x in row] for row in phi.tolist()], rtol=1e-15, atol=1e-18)
        assert isinstance(fn(ref, 0.3), float)
    st_ = kn.state(ref, phi)
    assert st_.occupies.shape == phi.shape
    assert np.array_equal(st_.occupies, st_.s >= ref.s_clear)


def test_non_finite_angles_rejected(ref: KnifeParams) -> None:
    with pytest.raises(ParameterError, match='phi'):
        kn.position(ref, math.nan)
    with pytest.raises(ParameterError, match='phi'):
        kn.velocity(ref, np.array([0.0, math.inf]))
    with pytest.raises(ParameterError, match='t'):
        kn.state_at_time(ref, [0.0, math.nan])


# ----------------------------------------------------------------------------- the window


def test_reference_window_is_the_papers_0_03_s(ref: KnifeParams) -> None:
    w = kn.window(ref)
    assert w.duration == pytest.approx(0.030, rel=0.005)
    assert w.phi_in == -w.phi_out  # e = 0: exactly symmetric about 0
    assert w.t_in == pytest.approx(-w.duration / 2, rel=1e-15)
    assert w.fraction == pytest.approx(w.duration / 0.072, rel=1e-12)


def closed_form_phi(p: KnifeParams) -> float:
    """e = 0: s = s_c is the law of cosines, cos(phi) = (s_c^2 + r^2 - L^2) / (2 s_c r)."""
    r, L, sc = mp.mpf(p.r_k), mp.mpf(p.L_k), mp.mpf(p.s_clear)
    return float(mp.acos((sc**2 + r**2 - L**2) / (2 * sc * r)))


@settings(max_examples=80, deadline=None)
@given(r=st.floats(0.01, 0.1), ratio=st.floats(1.05, 20.0), q=st.floats(0.001, 0.999))
def test_central_window_closed_form(r: float, ratio: float, q: float) -> None:
    L = r * ratio
    sc = (L - r) + q * 2 * r
    assume((L - r) < sc < (L + r))
    p = make(r_k=r, L_k=L, s_clear=sc)
    w = kn.window(p)
    phi = closed_form_phi(p)
    # conditioning of the end: a rounding of s (a few ulp) moves it by ulp / |ds/dphi|
    tol = 4 * np.spacing(L + r) * p.omega_k / abs(kn.velocity(p, phi)) + 1e-14 * phi
    assert abs(w.phi_out - phi) <= tol
    assert w.phi_in == -w.phi_out
    assert abs(kn.position(p, w.phi_in) - sc) < 1e-12 and abs(kn.position(p, w.phi_out) - sc) < 1e-12
    assert abs(w.duration - 2 * phi / p.omega_k) <= 2 * tol / p.omega_k


@settings(max_examples=60, deadline=None)
@given(e=offsets, q=st.floats(0.01, 0.99))
def test_offset_windows_exact_ends_and_asymmetry(e: float, q: float) -> None:
    probe = make(e=e, s_clear=0.15)
    sc = probe.s_min + q * (probe.s_max - probe.s_min)
    p = make(e=e, s_clear=sc)
    w = kn.window(p)
    dc = kn.dead_centres(p)
    assert w.phi_in < dc.phi_outer < w.phi_out
    assert dc.phi_inner - 2 * math.pi < w.phi_in and w.phi_out < dc.phi_inner
    assert abs(kn.position(p, w.phi_in) - sc) <= 1e-12
    assert abs(kn.position(p, w.phi_out) - sc) <= 1e-12
    assert kn.velocity(p, w.phi_in) > 0.0 > kn.velocity(p, w.phi_out)  # entering, leaving
    a, b = window_mp(p)
    assert abs(w.phi_in - float(a)) < 1e-12 and abs(w.phi_out - float(b)) < 1e-12
    # dense-sampling estimate of the occupied share of a turn
    n = 200_000
    phi = dc.phi_outer + np.linspace(-math.pi, math.pi, n, endpoint=False)
    est = np.count_nonzero(kn.position(p, phi) >= sc) * 2 * math.pi / n
    assert abs(est - (w.phi_out - w.phi_in)) <= 2 * 2 * math.pi / n


def test_offset_makes_the_window_asymmetric() -> None:
    p = make(e=0.05, s_clear=0.17)
    w = kn.window(p)
    dc = kn.dead_centres(p)
    assert dc.phi_outer > 0.0
    # the offset crank-slider has a quick return: the two halves of the window differ
    assert abs((dc.phi_outer - w.phi_in) - (w.phi_out - dc.phi_outer)) > 1e-3
    assert abs(w.phi_in + w.phi_out) > 1e-3


def test_level_a_picometre_below_s_max(ref: KnifeParams) -> None:
    p = make(s_clear=0.2 - 1e-12)
    w = kn.window(p)  # no exception: the window just shrinks
    exact = closed_form_phi(p)
    # s is flat at the top: the end is conditioned to ~1e-10 rad here
    assert w.phi_out == pytest.approx(exact, rel=1e-4)
    assert abs(kn.position(p, w.phi_out) - p.s_clear) <= 1e-16
    k = 0.05  # -s''(0) = r + r^2 / L
    assert w.duration == pytest.approx(2 * math.sqrt(2e-12 / k) / p.omega_k, rel=1e-4)
    assert 0.0 < w.duration < 2e-7


def test_level_one_ulp_below_s_max() -> None:
    sc = math.nextafter(0.2, 0.0)
    w = kn.window(make(s_clear=sc))
    assert 0.0 <= w.duration < 1e-8
    assert w.phi_in <= 0.0 <= w.phi_out
    with pytest.raises(ParameterError, match='never'):
        make(s_clear=0.2)


def test_level_just_above_s_min() -> None:
    w = kn.window(make(s_clear=0.12 + 1e-12))
    assert w.duration == pytest.approx(0.072, rel=1e-4)  # almost the whole turn
    assert w.phi_out - w.phi_in < 2 * math.pi


@pytest.mark.parametrize('n_k', [KNIFE_SPEED.lo, 7.0, 50000.0, KNIFE_SPEED.hi])  # the physical range
def test_window_scales_with_speed(ref: KnifeParams, n_k: float) -> None:
    w0 = kn.window(ref)
    w = kn.window(make(n_k=n_k))
    assert (w.phi_in, w.phi_out) == (w0.phi_in, w0.phi_out)
    assert w.duration == pytest.approx(w0.duration * 50000.0 / n_k, rel=1e-14)
    assert w.fraction == pytest.approx(w0.fraction, rel=1e-14)


def test_state_at_time_agrees_with_window(ref: KnifeParams) -> None:
    w = kn.window(ref)
    t = np.linspace(w.t_in - 0.01, w.t_out + 0.01, 2001)
    occ = kn.state_at_time(ref, t).occupies
    inside = (t > w.t_in + 1e-12) & (t < w.t_out - 1e-12)
    outside = (t < w.t_in - 1e-12) | (t > w.t_out + 1e-12)
    assert occ[inside].all() and not occ[outside].any()
    s0 = kn.state_at_time(ref, 0.0)
    assert s0.occupies is True and s0.s == 0.2 and isinstance(s0.v, float)


# --------------------------------------------------------------------- dead centres (mpmath at 40 digits) and 1e9 turns


class TestDeadCentres:
    """v changes sign smoothly through the outer and inner dead centres, +-1e-12 rad."""

    @pytest.mark.parametrize('e', [0.0, 0.012, -0.02])
    @pytest.mark.parametrize('which', ['outer', 'inner'])
    def test_knife_dead_centres(self, e: float, which: str) -> None:
        """v changes sign through 0 with slope omega s''(phi_dc) (mpmath), a finite and continuous."""
        p = kn.KnifeParams(r_k=0.04, L_k=0.16, e=e, n_k=50000.0, s_clear=0.1656)
        dc = kn.dead_centres(p)
        phi0 = dc.phi_outer if which == 'outer' else dc.phi_inner
        with mp.workdps(40):
            r, L, ee = mp.mpf(p.r_k), mp.mpf(p.L_k), mp.mpf(e)

            def s(x: Any) -> Any:
                return r * mp.cos(x) + mp.sqrt(L * L - (r * mp.sin(x) - ee) ** 2)

            exact = mp.asin(ee / (L + r)) if which == 'outer' else mp.pi + mp.asin(ee / (L - r))
            assert abs(float(exact) - phi0) <= ulp(phi0)
            s2 = float(mp.diff(s, exact, 2))
            s3 = float(mp.diff(s, exact, 3))
        w = p.omega_k
        assert (s2 < 0) == (which == 'outer')  # a maximum of s at the outer, a minimum at the inner dead centre
        for d in DELTAS:
            st = kn.state(p, phi0 + d)
            assert all(math.isfinite(float(v)) for v in (st.s, st.v, st.a))
            with mp.workdps(40):
                off = float(mp.mpf(phi0 + d) - exact)  # d as represented, from the exact centre
            v_ref = w * (s2 * off + 0.5 * s3 * off * off)
            assert math.copysign(1.0, st.v) == math.copysign(1.0, s2 * d)
            assert abs(st.v - v_ref) <= 4 * EPS * w * p.r_k + 1e-6 * abs(v_ref)
            assert abs(st.s - (dc.s_max if which == 'outer' else dc.s_min)) <= 4 * ulp(p.L_k)
            assert abs(st.a - w * w * s2) <= 1e-9 * abs(w * w * s2)


class TestLongRuns:
    """1e9 crank turns without drift (exact rational references of :mod:`_reference`)."""

    def test_knife_float_path_at_a_billion_turns(self, ref: KnifeParams) -> None:
        """knife.state_at_time computes phi = omega_k t afresh (no accumulation): at 1e9 turns
        (t = 7.2e7 s) its phase error is a few ulp of phi, i.e. ~1e-8 s, 1.5e-16 of t."""
        T = Fraction(3600) / Fraction(ref.n_k)
        for t in (1e7 + 0.0123, 7.2e7 + 0.0123, float(10**9 * T + Fraction(1, 50))):
            st_ = kn.state_at_time(ref, t)
            with mp.workdps(50):
                frac = exact_frac_turns(t, Fraction(ref.n_k) / 3600)
                phi_ref = float(2 * mp.pi * mp.mpf(frac.numerator) / frac.denominator)
            dphi = angle_diff(float(st_.phi), phi_ref)
            assert dphi <= 8 * ulp(float(st_.phi))
            assert dphi / ref.omega_k <= 1e-15 * t  # 6 orders inside 1e-9 relative
            slope = abs(st_.v) / ref.omega_k  # |ds/dphi|, m/rad
            assert st_.s == pytest.approx(kn.position(ref, phi_ref), abs=1.01 * slope * dphi + 0.05 * dphi**2 + 1e-15)
