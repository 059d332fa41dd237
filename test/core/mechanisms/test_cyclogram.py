"""F cycle timing: the paper's published figures (001, eqs. 4-6) and the model's closed forms."""

from __future__ import annotations

import dataclasses
import math

import mpmath as mp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from folder_line.config.params import load_params
from folder_line.core.limits import KNIFE_SPEED
from folder_line.core.mechanisms import cyclogram as cg
from folder_line.core.mechanisms import knife as kn
from folder_line.core.mechanisms.cyclogram import CyclogramParams
from folder_line.core.mechanisms.knife import KnifeParams
from folder_line.errors import ParameterError

# the paper's published figures
PAPER_V_D = 5.83  # m/s, D = 267.38 mm at 25000 rev/h (printed 5.829; computed 5.833)
PAPER_T = 0.072  # s, one knife-crank turn at 50000 rev/h
PAPER_L_A = 0.420  # m, cut-sheet length
PAPER_T_KNIFE = 0.030  # s, folding plus knife exit from under the table
PAPER_T_FEED = 0.025  # s, feed time with the 10 % reserve
PAPER_L_FEED = 0.230  # m, feed travel
PAPER_V_TR = 9.2  # m/s, eq. (5): 0.230 / 0.025 (printed "9.02")
PAPER_RATIO = 1.6  # eq. (6)


@pytest.fixture(scope='module')
def params() -> CyclogramParams:
    return load_params('cyclogram')


@pytest.fixture(scope='module')
def knife() -> KnifeParams:
    return load_params('knife')


@pytest.fixture(scope='module')
def timing(params: CyclogramParams, knife: KnifeParams) -> cg.CycleTiming:
    return cg.cycle_timing(params, knife)


def closed_form_t_knife(k: KnifeParams) -> float:
    """e = 0: window ends at +-acos((s_c^2 + r^2 - L^2) / (2 s_c r)) (law of cosines)."""
    r, L, sc = mp.mpf(k.r_k), mp.mpf(k.L_k), mp.mpf(k.s_clear)
    phi = mp.acos((sc**2 + r**2 - L**2) / (2 * sc * r))
    return float(2 * phi / (2 * mp.pi * mp.mpf(k.n_k) / 3600))


# ----------------------------------------------------------------------------- parameters


def test_params_have_no_defaults_and_match_the_paper(params: CyclogramParams) -> None:
    for f in dataclasses.fields(CyclogramParams):
        assert f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
    assert params == CyclogramParams(D_fc=0.26738, n_c=25000.0, L_feed=0.230, L_a=0.420, reserve=0.10, dwell_frac=0.2)
    with pytest.raises(dataclasses.FrozenInstanceError):
        params.reserve = 0.2  # type: ignore[misc]


@pytest.mark.parametrize(
    ('kw', 'key'),
    [
        ({'D_fc': 0.0}, 'cyclogram.D_fc'),
        ({'n_c': -1.0}, 'cyclogram.n_c'),
        ({'L_feed': math.nan}, 'cyclogram.L_feed'),
        ({'L_a': math.inf}, 'cyclogram.L_a'),
        ({'reserve': 1.0}, 'cyclogram.reserve'),
        ({'reserve': -0.01}, 'cyclogram.reserve'),
        ({'dwell_frac': 1.0}, 'cyclogram.dwell_frac'),
        ({'dwell_frac': '0.2'}, 'cyclogram.dwell_frac'),
    ],
)
def test_params_validation(params: CyclogramParams, kw, key) -> None:
    with pytest.raises(ParameterError) as info:
        dataclasses.replace(params, **kw)
    assert info.value.key == key
    assert repr(next(iter(kw.values()))) in str(info.value)


def test_load_params_rejects_unknown_and_bad_keys() -> None:
    with pytest.raises(ParameterError, match='unknown cyclogram parameter'):
        load_params('cyclogram', overrides={'V_tr': 9.3})
    with pytest.raises(ParameterError, match=r'cyclogram.reserve'):
        load_params('cyclogram', overrides={'reserve': 1.5})


def test_no_feed_window_is_a_parameter_error(knife: KnifeParams) -> None:
    p = load_params('cyclogram', overrides={'dwell_frac': 0.6})  # 0.6 T + 0.03 s > T
    with pytest.raises(ParameterError, match='no time is left') as info:
        cg.cycle_timing(p, knife)
    assert info.value.key == 'cyclogram.dwell_frac'


# ----------------------------------------------------------------------------- published figures


def test_printing_speed_cycle_and_sheet_length(timing: cg.CycleTiming, params: CyclogramParams) -> None:
    assert timing.V_d == pytest.approx(PAPER_V_D, abs=0.005)
    assert timing.V_d == pytest.approx(43.6332313 * 0.13369, rel=1e-9)
    assert timing.omega_c == pytest.approx(43.6, abs=0.05)
    assert timing.omega_k == pytest.approx(87.266, abs=5e-4)
    assert abs(timing.T - PAPER_T) < 1e-12
    assert timing.speed_ratio == 2.0
    # eq. (4): L_c = V_d T = pi R_fc: the 267.38 mm cylinder cuts 420 mm per knife turn
    assert timing.L_c == pytest.approx(math.pi * params.D_fc / 2, rel=1e-14)
    assert timing.L_c == pytest.approx(PAPER_L_A, abs=1e-6)
    assert abs(timing.L_c_error) < 1e-6


def test_papers_own_arithmetic(timing: cg.CycleTiming) -> None:
    v = PAPER_L_FEED / PAPER_T_FEED
    assert v == pytest.approx(PAPER_V_TR, rel=1e-12)  # eq. (5) (the paper prints 9.02)
    assert v / timing.V_d == pytest.approx(PAPER_RATIO, abs=0.03)  # eq. (6)


def test_knife_window_is_the_papers_0_03_s(timing: cg.CycleTiming, knife: KnifeParams) -> None:
    assert timing.t_knife == pytest.approx(PAPER_T_KNIFE, rel=0.005)
    assert timing.t_knife == pytest.approx(closed_form_t_knife(knife), rel=1e-13)


def test_model_reproduces_the_papers_conclusion(timing: cg.CycleTiming) -> None:
    assert timing.t_allowed == pytest.approx(PAPER_T_FEED, rel=0.01)
    v_min = timing.min_feed_speed(0.10)
    assert v_min == pytest.approx(PAPER_V_TR, rel=0.015)
    assert v_min / timing.V_d == pytest.approx(PAPER_RATIO, abs=0.03)
    assert timing.V_tr_min == v_min and timing.ratio_min == pytest.approx(v_min / timing.V_d, rel=1e-15)
    assert cg.min_feed_speed(timing) == v_min


def test_feed_window_closed_form(timing: cg.CycleTiming, knife: KnifeParams) -> None:
    T = 3600.0 / 50000.0
    t_k = closed_form_t_knife(knife)
    assert timing.t_dwell == pytest.approx(0.2 * T, rel=1e-15)
    assert timing.t_fw == pytest.approx(T - t_k - 0.2 * T, rel=1e-13)
    assert timing.t_allowed == pytest.approx(0.9 * (T - t_k - 0.2 * T), rel=1e-13)
    assert timing.min_feed_speed(0.0) == pytest.approx(0.230 / (0.8 * T - t_k), rel=1e-13)


def test_no_speed_up_fails_by_the_closed_form_margin(
    timing: cg.CycleTiming, knife: KnifeParams, params: CyclogramParams
) -> None:
    V_d = 2 * math.pi * 25000.0 / 3600.0 * 0.26738 / 2
    T = 0.072
    expected = 0.9 * (T - closed_form_t_knife(knife) - 0.2 * T) - 0.230 / V_d
    chk = cg.check_feed(timing, timing.V_d)
    assert chk.margin == pytest.approx(expected, rel=1e-12)
    assert chk.margin == pytest.approx(-0.01460, abs=5e-6)
    assert not chk.passes and chk.ratio == 1.0
    assert chk.t_rest < timing.t_dwell  # it arrives too late to settle
    assert cg.cyclogram(params, knife, timing.V_d) == chk


def test_the_papers_speed_passes(timing: cg.CycleTiming) -> None:
    chk = cg.check_feed(timing, 9.3)
    assert chk.passes and chk.margin > 0.0
    assert chk.margin == pytest.approx(timing.t_allowed - 0.230 / 9.3, rel=1e-12)
    assert chk.t_rest == pytest.approx(timing.t_dwell + 0.1 * timing.t_fw + chk.margin, rel=1e-12)


# ----------------------------------------------------------------------------- timeline


def test_timeline_is_one_contiguous_cycle(timing: cg.CycleTiming) -> None:
    knife_ph, feed, dwell = timing.timeline
    assert [p.name for p in timing.timeline] == ['knife', 'feed', 'dwell']
    w = timing.knife
    assert (knife_ph.t_start, knife_ph.t_end) == (w.t_in, w.t_out)
    assert feed.t_start == w.t_out
    assert feed.t_end == pytest.approx(w.t_in + timing.T - timing.t_dwell, rel=1e-15)
    assert dwell.t_end == pytest.approx(w.t_in + timing.T, rel=1e-15)
    assert knife_ph.t_end == feed.t_start and feed.t_end == dwell.t_start
    assert sum(p.duration for p in timing.timeline) == pytest.approx(timing.T, rel=1e-14)
    assert feed.duration == pytest.approx(timing.t_fw, rel=1e-13)
    assert dwell.phi_end - knife_ph.phi_start == pytest.approx(2 * math.pi, rel=1e-14)


def test_knife_is_off_the_table_during_feed_and_dwell(timing: cg.CycleTiming, knife: KnifeParams) -> None:
    _, feed, dwell = timing.timeline
    t = np.linspace(feed.t_start + 1e-9, dwell.t_end - 1e-9, 5001)
    assert not kn.state_at_time(knife, t).occupies.any()
    t = np.linspace(timing.knife.t_in + 1e-9, timing.knife.t_out - 1e-9, 5001)
    assert kn.state_at_time(knife, t).occupies.all()


# ----------------------------------------------------------------------------- vectorised speeds


def test_vectorised_margin(timing: cg.CycleTiming) -> None:
    v = np.linspace(1.0, 30.0, 2901)
    m = cg.feed_margin(timing, v)
    assert m.shape == v.shape
    assert_allclose(m, [cg.check_feed(timing, x).margin for x in v.tolist()], rtol=1e-15, atol=1e-18)
    assert np.all(np.diff(m) > 0)
    assert_allclose(timing.feed_margin(v), m, rtol=0, atol=0)
    assert_allclose(cg.feed_time(timing, v), 0.230 / v, rtol=1e-15)
    assert abs(cg.feed_margin(timing, timing.V_tr_min)) < 1e-17
    first_pass = v[np.argmax(m >= 0)]
    assert timing.V_tr_min <= first_pass < timing.V_tr_min + 0.01


@pytest.mark.parametrize('bad', [0.0, -9.3, math.nan, math.inf, [9.3, 0.0], [9.3, math.nan], True])
def test_bad_speeds(timing: cg.CycleTiming, bad) -> None:
    with pytest.raises(ParameterError, match='V_tr'):
        cg.feed_margin(timing, bad)
    if not isinstance(bad, list):
        with pytest.raises(ParameterError, match='V_tr'):
            cg.check_feed(timing, bad)


@settings(max_examples=100, deadline=None)
@given(r1=st.floats(0.0, 0.9), r2=st.floats(0.0, 0.9))
def test_min_speed_grows_with_reserve(timing: cg.CycleTiming, r1: float, r2: float) -> None:
    lo, hi = sorted((r1, r2))
    assert timing.min_feed_speed(lo) <= timing.min_feed_speed(hi)
    assert timing.min_feed_speed(lo) == pytest.approx(0.230 / ((1 - lo) * timing.t_fw), rel=1e-15)


def test_bad_reserve_argument(timing: cg.CycleTiming) -> None:
    with pytest.raises(ParameterError, match='reserve'):
        timing.min_feed_speed(1.0)


@settings(max_examples=60, deadline=None)
@given(n_k=st.floats(1e3, KNIFE_SPEED.hi), dwell=st.floats(0.0, 0.3))  # the whole physical range above 1e3
def test_cycle_scales_with_knife_speed(params: CyclogramParams, n_k: float, dwell: float) -> None:
    k = KnifeParams(r_k=0.04, L_k=0.16, e=0.0, n_k=n_k, s_clear=0.1656)
    p = dataclasses.replace(params, dwell_frac=dwell)
    t = cg.cycle_timing(p, k)
    T = 3600.0 / n_k
    assert pytest.approx(T, rel=1e-15) == t.T
    # the occupied share of the cycle is geometric, independent of speed
    assert t.t_fw / T == pytest.approx(1.0 - 0.030009804483720214 / 0.072 - dwell, rel=1e-12)
    assert t.V_tr_min * t.t_allowed == pytest.approx(0.230, rel=1e-15)
