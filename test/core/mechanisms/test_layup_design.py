"""Layup design constraints against closed forms and against the validated model's own checks."""

from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from folder_line.config.params import load_params
from folder_line.core.mechanisms.layup import LayupModel, LayupParams, check_assembly
from folder_line.core.mechanisms.layup_angles import TAU, classify_fourbar
from folder_line.core.mechanisms.layup_design import (
    crank_rocker_margin,
    exit_clearance,
    fourbar_transmission_cos,
    transmission_check,
    transmission_cosines,
)
from folder_line.errors import AssemblyError


@pytest.fixture(scope='module')
def lp() -> LayupParams:
    params = load_params('layup')
    assert isinstance(params, LayupParams)
    return params


# ------------------------------------------------------------------ Grashof crank-rocker


@pytest.mark.parametrize(
    ('ground', 'crank', 'coupler', 'rocker', 'margin'),
    [
        (4.0, 1.0, 3.0, 3.0, 1.0),  # s + l = 5 < p + q = 6, crank shortest: a crank-rocker
        (7.0, 2.0, 6.0, 5.0, 2.0),  # 9 < 11; the crank is 3 shorter than the next link, Grashof by 2
        (5.0, 1.0, 2.0, 5.0, 1.0),  # 6 < 7 by 1, crank shorter than the coupler by 1
        (1.0, 3.0, 4.0, 3.5, -2.0),  # the ground is shortest: a double crank (drag link)
        (3.0, 3.5, 1.0, 4.0, -2.5),  # the coupler is shortest: a double rocker
        (4.0, 2.0, 2.0, 5.0, -1.0),  # 2 + 5 > 4 + 2: non-Grashof
        (4.0, 1.0, 2.0, 3.0, 0.0),  # 1 + 4 = 2 + 3: the change point
    ],
)
def test_crank_rocker_margin_on_known_fourbars(
    ground: float, crank: float, coupler: float, rocker: float, margin: float
) -> None:
    assert crank_rocker_margin(ground, crank, coupler, rocker) == pytest.approx(margin, abs=1e-15)
    kind = classify_fourbar(ground, crank, coupler, rocker)
    assert (kind == 'crank-rocker') == (margin > 0.0)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.floats(0.05, 2.0), min_size=4, max_size=4))
def test_crank_rocker_margin_sign_is_the_classification(links: list[float]) -> None:
    ground, crank, coupler, rocker = links
    m = crank_rocker_margin(ground, crank, coupler, rocker)
    if abs(m) > 1e-9:
        assert (m > 0.0) == (classify_fourbar(ground, crank, coupler, rocker) == 'crank-rocker')


# ------------------------------------------------------------------ transmission angle


def test_fourbar_transmission_angle_by_the_law_of_cosines() -> None:
    # ground 4, crank 1, coupler 3, rocker 3: the diagonal is 3 at θ = 0 (an equilateral triangle: μ = 60°),
    # 5 at θ = π (cos μ = (9 + 9 − 25)/18), sqrt(17) at θ = π/2 (cos μ = 1/18)
    cos = fourbar_transmission_cos(4.0, 1.0, 3.0, 3.0, np.array([0.0, math.pi, math.pi / 2]))
    assert_allclose(cos, [0.5, -7.0 / 18.0, 1.0 / 18.0], rtol=0, atol=1e-15)
    assert math.degrees(math.acos(cos[0])) == pytest.approx(60.0, abs=1e-12)


def test_sixbar_transmission_angles_are_the_models_toggle_margins(lp: LayupParams) -> None:
    # sin μ from the law of cosines against the model's Heron discriminants (another formula)
    phi = np.linspace(-math.pi, math.pi, 2001)
    st_ = LayupModel(lp).arrays(phi, accelerations=False)
    cos1, cos2 = transmission_cosines(lp, phi)
    assert_allclose(np.sqrt(1.0 - cos1**2), st_.margin1, rtol=0, atol=1e-12)
    assert_allclose(np.sqrt(1.0 - cos2**2), st_.margin2, rtol=0, atol=1e-12)


def test_loop1_worst_transmission_is_at_the_crank_on_the_ground_line(lp: LayupParams) -> None:
    # |A − O2| runs from g − R to g + R (g = |O1O2|): the extremes of cos μ1 are there, in closed form
    g = math.hypot(lp.a, lp.b)
    two_cs = 2.0 * lp.l2 * lp.O2B
    closed = max(abs(lp.l2**2 + lp.O2B**2 - (g - lp.R_kr) ** 2), abs(lp.l2**2 + lp.O2B**2 - (g + lp.R_kr) ** 2))
    tc = transmission_check(lp)
    assert tc.worst_cos1 == pytest.approx(closed / two_cs, abs=1e-14)
    assert tc.mu1 == pytest.approx(math.acos(closed / two_cs), abs=1e-12)


def test_loop2_worst_transmission_matches_check_assembly(lp: LayupParams) -> None:
    # check_assembly refines the smallest toggle margin (sin μ) independently, by golden section
    tc = transmission_check(lp)
    margins = check_assembly(lp)
    assert math.sin(tc.mu2) == pytest.approx(margins.margin2, abs=1e-9)
    assert math.sin(tc.mu1) == pytest.approx(margins.margin1, abs=1e-9)
    assert tc.margin(math.radians(40.0)) == pytest.approx(
        math.cos(math.radians(40.0)) - max(tc.worst_cos1, tc.worst_cos2), abs=0
    )
    assert tc.margin(math.radians(40.0)) > 0.0 > tc.margin(tc.mu2 + 1e-6)  # the binding loop is loop 2


def test_an_open_loop2_is_seen_and_the_model_refuses_it_too(lp: LayupParams) -> None:
    # l4 + l5 = 1.2 m, while |C − O3| sweeps about 0.99..1.32 m: loop 2 opens for part of the turn
    values = {f.name: getattr(lp, f.name) for f in dataclasses.fields(lp)} | {'l4': 0.6, 'l5': 0.6}
    tc = transmission_check(SimpleNamespace(**values))
    assert tc.worst_cos2 > 1.0
    assert tc.mu2 is None
    assert tc.margin(math.radians(1.0)) < 0.0
    with pytest.raises(AssemblyError, match='O2-C-E-O3'):
        LayupParams(**values)


def test_exit_clearance_is_the_swept_range_inside_the_walls(lp: LayupParams) -> None:
    phi = np.arange(200_000) * (TAU / 200_000)
    st_ = LayupModel(lp).arrays(phi, accelerations=False)
    x = np.concatenate([st_.xC, st_.xE])
    y = np.concatenate([st_.yC, st_.yE])
    ec = exit_clearance(lp, -0.45, 1.10, -1.25)
    assert ec.left == pytest.approx(x.min() + 0.45, abs=1e-9)
    assert ec.right == pytest.approx(1.10 - x.max(), abs=1e-9)
    assert ec.floor == pytest.approx(y.min() + 1.25, abs=1e-9)
    narrow = exit_clearance(lp, float(x.min()) + 0.01, 1.10, -1.25)
    assert narrow.left == pytest.approx(-0.01, abs=1e-9)
