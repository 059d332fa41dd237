"""The paper's projection-theorem formulas (1)-(19), (23)-(24) against loop closure."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from folder_line.config.params import load_params
from folder_line.core.mechanisms.layup import LayupModel, LayupParams
from folder_line.core.mechanisms.layup_angles import TAU
from folder_line.core.mechanisms.layup_paper import beta5, paper_frame, paper_speeds
from folder_line.errors import ParameterError

P = load_params('layup')
BASE = dataclasses.asdict(P)
PHI = np.linspace(0.0, TAU, 3601)[:-1]
#: l3² + l4² = O2O3² + l5²: δ3 = 90° is exactly where quadrilateral O2-O3-E-C is cyclic
RIGHT = LayupParams(**{**BASE, 'l5': math.sqrt(P.l3**2 + P.l4**2 - P.O2O3**2)})


def delta3_true(s) -> np.ndarray:
    """Angle at C between C->O2 and C->E from the loop-closure positions, rad."""
    ux, uy = -s.xC, -s.yC
    vx, vy = s.xE - s.xC, s.yE - s.yC
    return np.arctan2(np.abs(ux * vy - uy * vx), ux * vx + uy * vy)


def close(p: LayupParams, root: str) -> tuple[np.ndarray, np.ndarray, object, object]:
    """Boolean masks where vB, vC, vE all agree to 1e-9 relative (1e-12 of the peak near zero)."""
    s = LayupModel(p).arrays(PHI)
    ps = paper_speeds(p, PHI, root=root)
    peak = np.abs(s.vC).max()
    ok = np.ones(PHI.shape, bool)
    for mine, theirs in ((s.omega3 * p.O2B, ps.vB), (s.vC, ps.vC), (s.vE, ps.vE)):
        ok &= np.abs(mine - theirs) <= 1e-9 * np.abs(mine) + 1e-12 * peak
    healthy = (np.abs(np.cos(ps.gamma2)) > 1e-3) & (np.abs(np.cos(ps.gamma4)) > 1e-3)
    return ok, healthy, s, ps


def test_angle_mapping() -> None:
    a_p, b_p, phi_p = paper_frame(P, PHI)
    assert (a_p, b_p) == (-P.a, -P.b)
    # A - O2 of the paper, (a + R cos φp, b - R sin φp), is ours turned by 180°
    s = LayupModel(P).arrays(PHI)
    assert_allclose(a_p + P.R_kr * np.cos(phi_p), -s.xA, atol=1e-15)
    assert_allclose(b_p - P.R_kr * np.sin(phi_p), -s.yA, atol=1e-15)
    ps = paper_speeds(P, PHI, root='eq17')
    # β is the chute's angle from the downward vertical: β = -θ3 - 90°
    assert_allclose(ps.beta, -s.theta3 - 0.5 * np.pi, rtol=0, atol=1e-12)
    # δ1 is the angle at E between E->C and E->O3
    ux, uy = s.xC - s.xE, s.yC - s.yE
    vx, vy = P.O2O3 - s.xE, -s.yE
    assert_allclose(ps.delta1, np.arctan2(np.abs(ux * vy - uy * vx), ux * vx + uy * vy), atol=1e-12)
    assert_allclose(ps.delta3, delta3_true(s), atol=1e-12)
    assert_allclose(ps.vA, P.omega * P.R_kr, rtol=1e-15)


@pytest.mark.parametrize('p', [P, RIGHT], ids=['defaults', 'right-angle-cyclic'])
def test_projection_theorem_with_the_eq17_root_agrees_everywhere(p: LayupParams) -> None:
    ok, healthy, s, ps = close(p, 'eq17')
    assert healthy.all()  # no toggle on these geometries: every angle is compared
    assert ok.all()
    # the comparison includes δ3 = 90° (the switch of the paper's root sign) and both dead centres
    d3 = np.degrees(delta3_true(s))
    assert d3.min() < 89.0 and d3.max() > 91.0
    assert np.abs(s.vC).min() < 1e-2 * np.abs(s.vC).max()
    assert_allclose(ps.omega3, s.omega3, rtol=1e-9, atol=1e-12)
    assert_allclose(ps.omega5, s.omega5, rtol=1e-9, atol=1e-12)


def test_paper_root_rule_is_exact_when_delta3_90_is_the_cyclic_position() -> None:
    ok, healthy, s, ps = close(RIGHT, 'paper')
    assert healthy.all() and ok.all()
    # and δ3 = 90° is where the paper's sign changes, at β5
    switch = np.flatnonzero(np.diff(ps.root) != 0)
    assert switch.size == 2
    for i in switch:
        assert min(ps.beta[i], ps.beta[i + 1]) <= beta5(RIGHT) <= max(ps.beta[i], ps.beta[i + 1])
        d3 = np.degrees(delta3_true(s))[i : i + 2]
        assert d3.min() <= 90.0 <= d3.max()


def test_paper_root_rule_on_the_defaults_fails_exactly_between_delta3_90_and_the_cyclic_position() -> None:
    ok, healthy, s, ps = close(P, 'paper')
    assert healthy.all()
    b5 = beta5(P)
    good = paper_speeds(P, PHI, root='eq17')
    # the true sign flips where a1 = 0 (cyclic quadrilateral), the paper's at β5 (δ3 = 90°)
    band = np.sign(good.root) != np.sign(ps.root)
    assert band.any() and not band.all()
    # inside the band: β lies between β5 and the β where a1 changes sign
    flips = np.flatnonzero(np.diff(np.sign(good.a1)) != 0)
    beta_cyclic = np.mean([0.5 * (ps.beta[i] + ps.beta[i + 1]) for i in flips])
    lo, hi = sorted((b5, beta_cyclic))
    assert ((ps.beta[band] >= lo - 1e-3) & (ps.beta[band] <= hi + 1e-3)).all()
    # there the spurious root gives a wrong v_E; everywhere else the paper agrees to 1e-9
    assert not ok[band].any()
    assert ok[~band].all()
    err = np.abs(ps.vE - s.vE)[band].max() / np.abs(s.vE).max()
    assert 1e-4 < err < 1e-1


def test_beta5_is_where_delta3_is_90_degrees() -> None:
    m = LayupModel(P)
    b5 = beta5(P)
    ps = paper_speeds(P, PHI, root='eq17')
    i = int(np.flatnonzero(np.diff(np.sign(ps.beta - b5)) != 0)[0])
    lo, hi = PHI[i], PHI[i + 1]
    beta = lambda x: -m.point(x).theta3 - 0.5 * math.pi  # noqa: E731
    up = beta(hi) > beta(lo)
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        if (beta(mid) < b5) == up:
            lo = mid
        else:
            hi = mid
    s = m.arrays(np.array([lo]))
    assert_allclose(np.degrees(delta3_true(s)), 90.0, atol=1e-9)


def test_bad_root_choice_is_rejected() -> None:
    with pytest.raises(ParameterError, match='root'):
        paper_speeds(P, PHI, root='plus')
