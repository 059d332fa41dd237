"""L six-bar: validation, loop closure, velocities, accelerations, extremes, hard cases."""

from __future__ import annotations

import dataclasses
import math
import re
from fractions import Fraction
from itertools import pairwise
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import mpmath as mp
import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose, assert_array_equal

from folder_line.config.params import config_dir, load_params
from folder_line.core.limits import CRANK_SPEED
from folder_line.core.mechanisms import layup as L
from folder_line.core.mechanisms.layup import (
    LOOP1,
    LOOP2,
    LayupModel,
    LayupParams,
    check_assembly,
    layup_kinematics,
    layup_point,
)
from folder_line.core.mechanisms.layup_angles import TAU, classify_fourbar, reduce_angle
from folder_line.core.mechanisms.layup_reach import sweep, swing_extremes
from folder_line.core.mechanisms.layup_state import LayupPoint, LayupState
from folder_line.core.numerics.loop import (
    TOGGLE_TOL,
    circle_point_acceleration,
    circle_point_velocity,
    tracked_intersection,
)
from folder_line.core.numerics.roots import find_sign_changes, golden_section
from folder_line.errors import AssemblyError, ParameterError

from .._reference import DELTAS, EPS, crank_turns_fully, mp_rate, mp_sixbar

P = load_params('layup')
M = LayupModel(P)
BASE = dataclasses.asdict(P)
FIELDS = [f.name for f in dataclasses.fields(LayupParams)]
DENSE = np.linspace(0.0, TAU, 7201)[:-1]


def params(**over: float) -> LayupParams:
    return LayupParams(**{**BASE, **over})


def raw(**over: float) -> SimpleNamespace:
    """An unvalidated parameter object (LayupModel and check_assembly accept any such)."""
    return SimpleNamespace(**{**BASE, **over})


def residuals(p: LayupParams, s: LayupState) -> np.ndarray:
    """Loop-closure residuals, m, from the six-bar's definitions (module docstring of core/mechanisms/layup.py)."""
    ax = p.a + p.R_kr * np.cos(s.phi)
    ay = p.b + p.R_kr * np.sin(s.phi)
    return np.stack(
        [
            np.hypot(s.xA - ax, s.yA - ay),
            np.hypot(s.xA - s.xB, s.yA - s.yB) - p.l2,
            np.hypot(s.xB, s.yB) - p.O2B,
            np.hypot(s.xC - s.xB * p.l3 / p.O2B, s.yC - s.yB * p.l3 / p.O2B),
            np.hypot(s.xC - s.xE, s.yC - s.yE) - p.l4,
            np.hypot(s.xE - p.O2O3, s.yE) - p.l5,
        ]
    )


def d3_deg(s: LayupState | LayupPoint) -> np.ndarray:
    """Angle at C between C->O2 and C->E (the paper's δ3), degrees, from positions."""
    ux, uy = -np.asarray(s.xC), -np.asarray(s.yC)
    vx, vy = np.asarray(s.xE) - s.xC, np.asarray(s.yE) - s.yC
    return np.degrees(np.arctan2(np.abs(ux * vy - uy * vx), ux * vx + uy * vy))


# =========================================================================== parameters
def test_dataclass_fields_are_the_yaml_keys_without_defaults() -> None:
    keys = list(yaml.safe_load((config_dir() / 'layup.yaml').read_text()).keys())
    assert keys == FIELDS
    assert all(
        f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
        for f in dataclasses.fields(LayupParams)
    )
    assert dataclasses.is_dataclass(P) and P.__dataclass_params__.frozen
    with pytest.raises(dataclasses.FrozenInstanceError):
        P.R_kr = 0.1  # type: ignore[misc]


def test_defaults_are_a_healthy_crank_rocker() -> None:
    ground = math.hypot(P.a, P.b)
    assert classify_fourbar(ground, P.R_kr, P.l2, P.O2B) == 'crank-rocker'
    margins = check_assembly(P)
    # sine of the smallest transmission angle: > 0.9 means it stays within 90° ± 25°
    assert margins.margin1 > 0.9 and margins.margin2 > 0.9
    s = M.arrays(DENSE)
    assert_allclose(s.margin1.min(), margins.margin1, rtol=1e-6)
    assert_allclose(s.margin2.min(), margins.margin2, rtol=1e-6)


def test_omega() -> None:
    assert_allclose(P.omega, math.pi * P.n_kr / 30.0, rtol=1e-15)
    assert P.n_kr == 30.0 and P.omega == pytest.approx(math.pi)


@pytest.mark.parametrize('field', FIELDS)
@pytest.mark.parametrize('bad', [math.nan, math.inf, -math.inf, '0.5', True, None])
def test_rejects_non_numbers_naming_the_key(field: str, bad: object) -> None:
    with pytest.raises(ParameterError) as err:
        params(**{field: bad})
    assert err.value.key == f'layup.{field}'
    assert err.value.value is bad or (isinstance(bad, float) and math.isnan(bad))


@pytest.mark.parametrize('field', ['R_kr', 'l2', 'O2B', 'l3', 'l4', 'l5', 'O2O3'])
@pytest.mark.parametrize('bad', [0.0, -0.1])
def test_rejects_non_positive_lengths(field: str, bad: float) -> None:
    with pytest.raises(ParameterError, match=f'layup.{field}=') as err:
        params(**{field: bad})
    assert err.value.reason == 'must be > 0'


@pytest.mark.parametrize('bad', [0.0, -0.1, 5e-324, 1e-300, 6000.1, 1e308])
def test_crank_speed_outside_its_physical_range_is_refused(bad: float) -> None:
    with pytest.raises(ParameterError, match=r'layup.n_kr=') as err:
        params(n_kr=bad)
    assert err.value.reason == f'must be in [{CRANK_SPEED.lo:g}, {CRANK_SPEED.hi:g}] rev/min'
    assert params(n_kr=CRANK_SPEED.lo).n_kr == CRANK_SPEED.lo and params(n_kr=CRANK_SPEED.hi).n_kr == CRANK_SPEED.hi


def test_belt_speed_may_be_zero_not_negative() -> None:
    assert params(v_tr=0).v_tr == 0.0
    assert isinstance(params(v_tr=3).v_tr, float)
    with pytest.raises(ParameterError, match=r'layup.v_tr=-0.1'):
        params(v_tr=-0.1)


# =========================================================================== Grashof
@pytest.mark.parametrize(
    'links, kind',
    [
        ((4.0, 1.0, 3.0, 3.5), 'crank-rocker'),
        ((1.0, 4.0, 3.0, 3.5), 'double-crank'),
        ((4.0, 3.5, 1.0, 3.0), 'double-rocker'),
        ((4.0, 3.0, 3.5, 1.0), 'rocker-crank'),
        ((4.0, 2.0, 3.0, 3.0), 'change-point'),
        ((2.0, 1.0, 2.0, 1.0), 'change-point'),  # parallelogram
        ((5.0, 2.0, 3.0, 3.0), 'non-Grashof'),
        ((0.65, 0.08, 0.6, 0.25), 'crank-rocker'),
    ],
)
def test_classify_fourbar(links: tuple[float, float, float, float], kind: str) -> None:
    assert classify_fourbar(*links) == kind


@pytest.mark.parametrize(
    'rel, kind',
    [
        (0.0, 'change-point'),
        (5e-13, 'change-point'),
        (-5e-13, 'change-point'),
        (3e-12, 'crank-rocker'),
        (-3e-12, 'non-Grashof'),
        (1e-9, 'crank-rocker'),
        (-1e-9, 'non-Grashof'),
    ],
)
def test_classify_near_the_grashof_boundary(rel: float, kind: str) -> None:
    # s + l = 0.1 + 1.0 = p + q = 0.8 + 0.3; rel moves p + q by rel·(s + l + p + q)
    q = 0.3 + rel * 2.2
    assert classify_fourbar(1.0, 0.1, 0.8, q) == kind


#: crank pivot straight below O2, so the change-point position (A, B, O2 in line) has the chute hanging down
BOUNDARY = dict(a=0.0, b=-0.75, l2=0.58, O2B=0.25)  # 0.08 + 0.75 = 0.58 + 0.25


def test_on_the_grashof_boundary_is_rejected_as_change_point() -> None:
    for eps in (0.0, 1e-14, -1e-13):
        with pytest.raises(ParameterError) as err:
            params(**{**BOUNDARY, 'O2B': 0.25 + eps})
        assert err.value.key == 'layup.R_kr,a,b,l2,O2B'
        assert 'Grashof boundary' in err.value.reason and 'change-point' in err.value.reason
    with pytest.raises(ParameterError, match='non-Grashof'):
        params(**{**BOUNDARY, 'O2B': 0.25 - 1e-9})
    with pytest.raises(ParameterError, match='double-crank'):
        params(a=0.05, b=0.0, l2=0.3, O2B=0.28)


@pytest.mark.parametrize('eps', [1e-11, 1e-9, 1e-7])
def test_just_inside_the_boundary_is_accepted_with_a_small_reported_margin(eps: float) -> None:
    p = params(**{**BOUNDARY, 'O2B': 0.25 + eps})
    margins = check_assembly(p)
    # the change-point toggle is at phi = 3π/2 (A straight below O1); margin ~ sqrt(eps)
    assert_allclose(margins.phi1, 1.5 * math.pi, atol=1e-6)
    assert 0.1 * math.sqrt(eps) < margins.margin1 < 10 * math.sqrt(eps)
    near = 1.5 * math.pi + np.concatenate([np.linspace(-0.1, 0.1, 2001), [0.0, 1e-12, -1e-12]])
    phi = np.concatenate([DENSE, near])
    s = layup_kinematics(p, phi)
    outs = [getattr(s, f.name) for f in dataclasses.fields(s)]
    assert all(np.isfinite(o).all() for o in outs)
    assert np.abs(residuals(p, s)).max() < 1e-9
    assert s.margin1.min() >= margins.margin1 * (1 - 1e-6)


def test_the_grashof_message_names_the_lengths() -> None:
    with pytest.raises(ParameterError) as err:
        load_params('layup', overrides={'R_kr': 0.3})  # crank no longer the shortest
    assert isinstance(err.value.value, dict) and err.value.value['R_kr'] == 0.3
    assert 'crank-rocker' in str(err.value)


# =========================================================================== assembly
def test_unassemblable_second_loop_raises_at_the_sign_change() -> None:
    with pytest.raises(AssemblyError) as err:
        load_params('layup', overrides={'l5': 0.7})
    e = err.value
    assert e.mechanism == LOOP2
    m = LayupModel(raw(l5=0.7))
    # the discriminant changes sign there (it is the entry of the failing interval)...
    assert m.discriminants_scalar(e.phi - 1e-9)[1] > 0.0
    assert m.discriminants_scalar(e.phi + 1e-9)[1] < 0.0
    # ... and it is the first one turning forward from 0
    before = np.linspace(0.0, e.phi - 1e-9, 20001)
    assert m.discriminants(before)[1].min() >= 0.0
    assert_allclose(e.phi, 3.0469168221, atol=1e-9)
    assert f'phi={e.phi!r}' in str(e) and 'stop meeting' in e.reason
    # the evaluations of an unvalidated model name the first failing angle too
    with pytest.raises(AssemblyError) as err2:
        m.arrays(np.array([0.0, 1.0, 3.1, 3.12, 0.5]))
    assert err2.value.phi == 3.1 and err2.value.mechanism == LOOP2
    with pytest.raises(AssemblyError) as err3:
        m.point(3.12)
    assert err3.value.phi == 3.12


def test_failure_between_samples_is_found() -> None:
    geo = raw(l5=0.7009)
    m = LayupModel(geo)
    coarse = np.arange(16) * (TAU / 16)
    assert m.discriminants(coarse)[1].min() > 0.0  # no coarse sample fails ...
    assert m.discriminants(DENSE)[1].min() < 0.0  # ... but the loop does
    with pytest.raises(AssemblyError) as coarse_err:
        check_assembly(geo, n=16)
    with pytest.raises(AssemblyError) as fine_err:
        check_assembly(geo)
    assert coarse_err.value.mechanism == fine_err.value.mechanism == LOOP2
    assert_allclose(coarse_err.value.phi, fine_err.value.phi, rtol=0, atol=1e-11)
    at = fine_err.value.phi
    assert m.discriminants_scalar(at - 1e-9)[1] > 0.0 > m.discriminants_scalar(at + 1e-9)[1]


def _min_d2(l5: float) -> tuple[float, float]:
    m = LayupModel(raw(l5=l5))
    i = int(np.argmin(m.discriminants(DENSE)[1]))
    return golden_section(lambda x: m.discriminants_scalar(x)[1], DENSE[i] - 1e-3, DENSE[i] + 1e-3, maxiter=80).best


def test_grazing_a_toggle_is_rejected_as_locking() -> None:
    # find l5 where the second loop just grazes its toggle: min D2 = TOL/2
    lo, hi = 0.700, 0.705
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if _min_d2(mid)[1] < 0.5 * TOGGLE_TOL:
            lo = mid
        else:
            hi = mid
    phi_min, dmin = _min_d2(hi)
    assert 0.0 < dmin <= TOGGLE_TOL
    with pytest.raises(AssemblyError) as err:
        params(l5=hi)
    assert err.value.mechanism == LOOP2 and 'toggle' in err.value.reason and 'locks' in err.value.reason
    assert_allclose(err.value.phi, phi_min, atol=1e-6)
    # a hair longer chute 4 clears the toggle and is accepted, with a tiny reported margin
    ok = params(l5=hi + 1e-6)
    assert check_assembly(ok).margin2 < 1e-2


def test_unvalidated_first_loop_failure_names_the_first_angle() -> None:
    m = LayupModel(raw(l2=0.45))  # non-Grashof: loop 1 does not close for every angle
    d1 = m.discriminants(DENSE)[0]
    bad = DENSE[d1 < 0]
    assert bad.size > 0
    phis = np.array([DENSE[d1 > 0][0], bad[3], bad[0]])
    with pytest.raises(AssemblyError) as err:
        m.arrays(phis)
    assert err.value.phi == bad[3] and err.value.mechanism == LOOP1
    with pytest.raises(AssemblyError):
        check_assembly(raw(l2=0.45))


# =========================================================================== positions
def test_definitions_branches_and_residuals() -> None:
    s = M.arrays(DENSE)
    assert np.abs(residuals(P, s)).max() < 1e-14
    # branches exactly as the module docstring of core/mechanisms/layup.py states them
    cross_b = (0.0 - s.xA) * (s.yB - s.yA) - (0.0 - s.yA) * (s.xB - s.xA)
    cross_e = (P.O2O3 - s.xC) * (s.yE - s.yC) - (0.0 - s.yC) * (s.xE - s.xC)
    assert (cross_b < 0).all() and (cross_e < 0).all()
    assert_allclose(s.theta3, np.arctan2(s.yC, s.xC), rtol=0, atol=1e-15)
    assert_allclose(s.theta5, np.arctan2(s.yE, s.xE - P.O2O3), rtol=0, atol=1e-15)
    # chutes hang down
    assert (s.yC < -0.9).all() and (s.yE < -0.85).all()


def test_scalar_path_equals_vectorised_path() -> None:
    rng = np.random.default_rng(7)
    phi = np.concatenate([DENSE[::7], rng.uniform(-1e3, 1e3, 300), [math.pi, -math.pi, 0.0, -0.0]])
    s = M.arrays(phi)
    names = LayupPoint._fields
    vec = np.stack([getattr(s, n) for n in names])
    sca = np.array([M.point(float(x)) for x in phi]).T
    assert_allclose(sca, vec, rtol=1e-12, atol=1e-12)
    assert layup_point(P, 0.3) == M.point(0.3)
    assert_array_equal(layup_kinematics(P, phi).omega5, s.omega5)


def test_shapes_and_optional_accelerations() -> None:
    grid = np.linspace(0, 6, 12).reshape(3, 4)
    s = M.arrays(grid)
    for f in dataclasses.fields(s):
        assert getattr(s, f.name).shape == (3, 4)
    assert_array_equal(s.xE.ravel(), M.arrays(grid.ravel()).xE)
    assert M.arrays(0.3).xC.shape == ()
    assert M.arrays(np.empty(0)).vaE.shape == (0,)
    lean = M.arrays(grid, accelerations=False)
    assert lean.eps3 is None and lean.eps5 is None
    assert_array_equal(lean.omega5, s.omega5)
    # a non-contiguous view and a chunk boundary give the same numbers
    big = np.linspace(-4, 4, 2 * L.CHUNK + 17)
    assert_allclose(M.arrays(big[::-1]).xE[::-1], M.arrays(big).xE, rtol=1e-15, atol=0)


# =========================================================================== velocities
def _fd5(f, x: np.ndarray, h: float) -> np.ndarray:
    return (-f(x + 2 * h) + 8 * f(x + h) - 8 * f(x - h) + f(x - 2 * h)) / (12 * h)


def test_velocities_match_finite_differences_of_positions() -> None:
    phi = DENSE[::10]
    w = P.omega
    s = M.arrays(phi)
    h = 1e-4
    for name, ref in (('theta3', s.omega3), ('theta5', s.omega5)):
        fd = _fd5(lambda x, n=name: getattr(M.arrays(x), n), phi, h) * w
        assert_allclose(ref, fd, rtol=0, atol=1e-9)
    for pos, vel in (
        ('xC', lambda: -s.omega3 * s.yC),
        ('yC', lambda: s.omega3 * s.xC),
        ('xE', lambda: -s.omega5 * s.yE),
        ('yE', lambda: s.omega5 * (s.xE - P.O2O3)),
    ):
        fd = _fd5(lambda x, n=pos: getattr(M.arrays(x), n), phi, h) * w
        assert_allclose(vel(), fd, rtol=0, atol=1e-9)
    assert_allclose(s.vC, s.omega3 * P.l3, rtol=1e-15)
    assert_allclose(s.vE, s.omega5 * P.l5, rtol=1e-15)


def test_accelerations_match_finite_differences_of_velocities() -> None:
    phi = DENSE[::10]
    w = P.omega
    s = M.arrays(phi)
    h = 1e-4
    for name, ref in (('omega3', s.eps3), ('omega5', s.eps5)):
        fd = _fd5(lambda x, n=name: getattr(M.arrays(x), n), phi, h) * w
        assert_allclose(ref, fd, rtol=0, atol=1e-8)
    # second difference of the angle itself (coarser)
    th = lambda x: M.arrays(x).theta3  # noqa: E731
    h2 = 1e-3
    fd2 = (-th(phi + 2 * h2) + 16 * th(phi + h2) - 30 * th(phi) + 16 * th(phi - h2) - th(phi - 2 * h2)) / (12 * h2 * h2)
    assert_allclose(s.eps3, fd2 * w * w, rtol=0, atol=1e-6)


def test_velocities_agree_with_the_general_two_by_two_solver() -> None:
    """Independent formulation: loop.circle_point_velocity/acceleration on each dyad."""
    phi = DENSE[::5]
    w = P.omega
    alpha = 0.7
    s = M.arrays(phi, alpha=alpha)
    c, sn = np.cos(phi), np.sin(phi)
    vax, vay = -w * P.R_kr * sn, w * P.R_kr * c
    aax = -alpha * P.R_kr * sn - w * w * P.R_kr * c
    aay = alpha * P.R_kr * c - w * w * P.R_kr * sn
    z = np.zeros_like(phi)
    vbx, vby = circle_point_velocity(s.xB, s.yB, 0, 0, 0, 0, s.xA, s.yA, vax, vay)
    assert_allclose(np.stack([vbx, vby]), np.stack([-s.omega3 * s.yB, s.omega3 * s.xB]), rtol=0, atol=1e-13)
    abx, aby = circle_point_acceleration(s.xB, s.yB, vbx, vby, z, z, z, z, z, z, s.xA, s.yA, vax, vay, aax, aay)
    eps3 = (s.xB * aby - s.yB * abx) / P.O2B**2
    assert_allclose(s.eps3, eps3, rtol=0, atol=1e-12)
    k = P.l3 / P.O2B
    vcx, vcy, acx, acy = k * vbx, k * vby, k * abx, k * aby
    vex, vey = circle_point_velocity(s.xE, s.yE, P.O2O3, 0, 0, 0, s.xC, s.yC, vcx, vcy)
    omega5 = ((s.xE - P.O2O3) * vey - s.yE * vex) / P.l5**2
    assert_allclose(s.omega5, omega5, rtol=0, atol=1e-13)
    aex, aey = circle_point_acceleration(s.xE, s.yE, vex, vey, P.O2O3, 0, 0, 0, 0, 0, s.xC, s.yC, vcx, vcy, acx, acy)
    assert_allclose(s.eps5, ((s.xE - P.O2O3) * aey - s.yE * aex) / P.l5**2, rtol=0, atol=1e-12)


def test_crank_speed_scaling() -> None:
    phi = DENSE[::11]
    base = M.arrays(phi)
    w2 = 2.5
    s = M.arrays(phi, omega=w2, alpha=-0.4)
    assert_allclose(s.omega3, base.omega3 * w2 / P.omega, rtol=1e-13, atol=1e-15)
    # eps = θ'' ω² + θ' α
    assert_allclose(s.eps5, base.eps5 * (w2 / P.omega) ** 2 + base.omega5 / P.omega * -0.4, rtol=0, atol=1e-13)
    assert_allclose(M.point(1.0, 2.5).omega5, M.arrays(1.0, omega=2.5).omega5, rtol=1e-13)


# =========================================================================== swing extremes
def test_exit_speeds_vanish_at_the_closed_form_extremes() -> None:
    ext = swing_extremes(P)
    assert [e.kind for e in ext] == ['extended', 'folded']
    typical = np.abs(M.arrays(DENSE).vC).max()
    for e in ext:
        pt = e.point
        assert abs(pt.omega3) < 1e-14 and abs(pt.omega5) < 1e-14
        assert abs(pt.vC) < 1e-14 * typical and abs(pt.vE) < 1e-14 * typical
        assert pt.vaC == P.v_tr and pt.vaE == P.v_tr
        # the definition: O1, A, B in line with |O1B| = l2 ± R
        st_ = M.arrays(e.phi)
        o1b = math.hypot(float(st_.xB) - P.a, float(st_.yB) - P.b)
        assert_allclose(o1b, P.l2 + (P.R_kr if e.kind == 'extended' else -P.R_kr), rtol=1e-14)
    s = M.arrays(DENSE)
    assert s.vaC.min() >= P.v_tr and s.vaE.min() >= P.v_tr
    assert_allclose(s.vaC.max(), math.hypot(np.abs(s.vC).max(), P.v_tr), rtol=1e-15)
    # θ3 extremes over the turn are reached at those two angles
    assert_allclose(s.theta3.max(), ext[0].point.theta3, atol=1e-6)
    assert s.theta3.max() <= ext[0].point.theta3 + 1e-15
    assert_allclose(s.theta3.min(), ext[1].point.theta3, atol=1e-6)
    assert s.theta3.min() >= ext[1].point.theta3 - 1e-15


def test_extremes_agree_with_a_root_of_omega3() -> None:
    def bisect(lo: float, hi: float) -> float:
        flo = M.point(lo).omega3
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            if mid in (lo, hi):
                break
            if (M.point(mid).omega3 > 0) == (flo > 0):
                lo = mid
            else:
                hi = mid
        return 0.5 * (lo + hi)

    s = M.arrays(DENSE)
    flips = np.flatnonzero(np.sign(s.omega3) != np.sign(np.roll(s.omega3, -1)))
    roots = sorted(bisect(DENSE[i], DENSE[i] + TAU / DENSE.size) % TAU for i in flips)
    assert len(roots) == 2
    closed = sorted(e.phi for e in swing_extremes(P))
    assert_allclose(roots, closed, rtol=0, atol=1e-10)


@pytest.mark.parametrize('which', [0, 1])
def test_rocker_extremes_plus_minus_1e12(which: int) -> None:
    e = swing_extremes(P)[which]
    pts = [M.point(e.phi + d) for d in (-1e-12, 0.0, 1e-12)]
    for pt in pts:
        assert all(math.isfinite(v) for v in pt)
    assert abs(pts[0].xC - pts[1].xC) < 1e-12 and abs(pts[2].xE - pts[1].xE) < 1e-12
    before, after = pts[0].omega3, pts[2].omega3
    assert before * after < 0.0
    # θ3 is a maximum at the extended dead centre here (ω3 goes + to -), a minimum at the folded one
    is_max = e.point.theta3 > M.point(e.phi + 1e-3).theta3 and e.point.theta3 > M.point(e.phi - 1e-3).theta3
    assert is_max == (which == 0)
    assert (before > 0) == is_max and (after < 0) == is_max
    # and the size is ε3 · 1e-12 / ω to a few per cent
    eps3 = float(M.arrays(e.phi).eps3)
    assert_allclose([before, after], [-eps3 * 1e-12 / P.omega, eps3 * 1e-12 / P.omega], rtol=1e-2)
    assert np.sign(pts[0].omega5) == np.sign(before) and np.sign(pts[2].omega5) == np.sign(after)


def test_sweep_matches_the_extremes_and_the_yaml_comment() -> None:
    sw = sweep(P)
    ext = swing_extremes(P)
    assert_allclose(sw.xC, sorted(e.point.xC for e in ext), rtol=0, atol=1e-15)
    assert_allclose(sw.xE, sorted(e.point.xE for e in ext), rtol=0, atol=1e-15)
    s = M.arrays(np.random.default_rng(3).uniform(0, TAU, 20000))
    assert sw.xC[0] <= s.xC.min() and s.xC.max() <= sw.xC[1]
    assert sw.xE[0] <= s.xE.min() and s.xE.max() <= sw.xE[1]
    assert sw.yC[0] <= s.yC.min() and sw.yE[1] >= s.yE.max()
    # the chutes pass straight down: the exits' lowest points are -l3 and -l5 exactly
    assert sw.yC[0] == -P.l3 and sw.yE[0] == -P.l5
    assert_allclose([sw.yC[1], sw.yE[1]], [max(e.point.yC for e in ext), max(e.point.yE for e in ext)], atol=1e-15)
    assert sw.x == (sw.xC[0], sw.xE[1])
    # the numbers quoted in config/layup.yaml
    text = (config_dir() / 'layup.yaml').read_text()
    quoted = [float(v) for v in re.findall(r'(-?\d\.\d{3})\.\.(-?\d\.\d{3})', text)[0]]
    assert_allclose(quoted, [sw.x[0], sw.x[1]], atol=6e-4)
    assert 'C sweeps x -0.321..0.320, E 0.298..0.937' in text
    assert_allclose([*sw.xC, *sw.xE], [-0.321, 0.320, 0.298, 0.937], atol=6e-4)
    # the two exits' sweeps overlap in the middle (no gap in the container)
    assert sw.xE[0] < sw.xC[1]


# =========================================================================== δ3 = 90°
def test_delta3_passes_90_degrees_smoothly() -> None:
    s = M.arrays(DENSE)
    d3 = d3_deg(s)
    assert d3.min() < 90.0 < d3.max()
    flips = np.flatnonzero(np.sign(d3 - 90) != np.sign(np.roll(d3 - 90, -1)))
    assert len(flips) == 2
    step = TAU / DENSE.size
    vmax = max(np.abs(s.vE).max(), np.abs(s.vC).max())
    for i in flips:
        lo, hi = DENSE[i], DENSE[i] + step
        for _ in range(100):
            mid = 0.5 * (lo + hi)
            if (d3_deg(M.point(mid)) > 90) == (d3[i] > 90):
                lo = mid
            else:
                hi = mid
        pts = [M.point(lo + d) for d in (-1e-12, 0.0, 1e-12)]
        for a, b in pairwise(pts):
            assert math.hypot(a.xE - b.xE, a.yE - b.yE) < 1e-12 * vmax / P.omega * 2 + 1e-15
            assert abs(a.omega5 - b.omega5) < 1e-10
    # E moves continuously over the whole turn: no step bigger than the speed allows
    dE = np.hypot(np.diff(s.xE), np.diff(s.yE))
    assert dE.max() <= np.abs(s.vE).max() / P.omega * step * (1 + 1e-6)
    # and tracked stepping (nearest to the previous point) gives the same branch everywhere
    px, py = float(s.xE[0]), float(s.yE[0])
    for i in range(0, DENSE.size, 3):
        px, py, br = tracked_intersection(
            P.O2O3, 0.0, P.l5, float(s.xC[i]), float(s.yC[i]), P.l4, px, py, inputs=float(DENSE[i])
        )
        assert br == 1
        assert abs(px - s.xE[i]) < 1e-14 and abs(py - s.yE[i]) < 1e-14


# =========================================================================== crank angle range
def test_exact_multiples_of_tau_give_phi_zero_exactly() -> None:
    k = 2**30  # ~1.07e9 turns; k·TAU is exact in floating point
    big = TAU * k
    assert Fraction(big) == k * Fraction(TAU)
    assert reduce_angle(big) == 0.0
    assert M.point(big) == M.point(0.0)
    assert_array_equal(np.stack(list(M.point(-big))), np.stack(list(M.point(0.0))))
    a, b = M.arrays(np.array([big, -big, 0.0])), M.arrays(np.zeros(3))
    for f in dataclasses.fields(a):
        if f.name != 'phi':
            assert_array_equal(getattr(a, f.name), getattr(b, f.name))


def test_a_billion_turns_loses_only_the_input_rounding() -> None:
    k = 10**9
    x = TAU * k  # rounded: carries up to ulp(x)/2 = 4.8e-7 rad of error
    r = reduce_angle(x)
    assert Fraction(r) == Fraction(x) - k * Fraction(TAU)  # the reduction itself is exact
    assert abs(r) <= math.ulp(x) / 2
    p0, pk = M.point(0.0), M.point(x)
    # results move by (rate of change) × r, not more
    assert abs(pk.xC - p0.xC) <= abs(p0.omega3 * p0.yC / P.omega * r) * 1.01 + 1e-15
    assert abs(pk.xC - p0.xC) < 1e-6
    # the limits quoted in the module docstring
    assert math.ulp(1e6) / 2 < 5.9e-11 and 4.7e-7 < math.ulp(x) / 2 < 4.8e-7


@settings(max_examples=300, deadline=None)
@given(st.floats(-1e12, 1e12, allow_nan=False))
def test_vector_reduction_is_the_ieee_remainder(x: float) -> None:
    r = float(reduce_angle(np.array([x]))[0])
    ref = math.remainder(x, TAU)
    if abs(ref) != math.pi:
        assert r == ref
    assert Fraction(r) == Fraction(x) - round((Fraction(x) - Fraction(r)) / Fraction(TAU)) * Fraction(TAU)
    assert reduce_angle(x) == ref
    assert -math.pi <= r <= math.pi


def test_evaluations_reduce_like_reduce_angle() -> None:
    rng = np.random.default_rng(11)
    phi = np.concatenate([rng.uniform(-1e6, 1e6, 5000), rng.uniform(-4, 4, 5000)])
    a, b = M.arrays(phi), M.arrays(reduce_angle(phi))
    for f in dataclasses.fields(a):
        if f.name != 'phi':
            assert_array_equal(getattr(a, f.name), getattr(b, f.name))
    assert_array_equal(a.phi, phi)  # the state keeps the angles as given


def test_non_finite_crank_angles_are_rejected() -> None:
    for bad in (math.nan, math.inf, -math.inf):
        with pytest.raises(ParameterError, match='phi'):
            M.point(bad)
        with pytest.raises(ParameterError, match='phi'):
            M.arrays(np.array([0.0, bad]))


# =========================================================================== properties
@settings(max_examples=60, deadline=None)
@given(
    factors=st.lists(st.floats(0.9, 1.1), min_size=len(FIELDS), max_size=len(FIELDS)),
    phis=st.lists(st.floats(-50.0, 50.0), min_size=1, max_size=20),
)
def test_perturbed_geometries_either_fail_validation_or_are_finite_and_closed(
    factors: list[float], phis: list[float]
) -> None:
    kw = {k: BASE[k] * f for k, f in zip(FIELDS, factors, strict=True)}
    try:
        p = LayupParams(**kw)
    except ParameterError as err:
        assert err.key.startswith('layup.')
        return
    except AssemblyError as err:
        assert err.mechanism in (LOOP1, LOOP2) and 0.0 <= err.phi < TAU
        return
    m = LayupModel(p)
    phi = np.concatenate([DENSE[::9], phis, [e.phi for e in swing_extremes(p)]])
    s = m.arrays(phi)
    outs = np.stack([getattr(s, f.name) for f in dataclasses.fields(s)])
    assert np.isfinite(outs).all()
    assert np.abs(residuals(p, s)).max() < 1e-9
    assert (s.vaC >= p.v_tr).all() and (s.vaE >= p.v_tr).all()
    assert s.margin1.min() > 0 and s.margin2.min() > 0
    for x in phis[:5]:
        assert_allclose(
            list(m.point(x)), [float(getattr(m.arrays(x), n)) for n in LayupPoint._fields], rtol=1e-12, atol=1e-12
        )


@settings(max_examples=200, deadline=None)
@given(st.floats(-1e4, 1e4))
def test_belt_keeps_exit_speeds_at_or_above_v_tr(phi: float) -> None:
    pt = M.point(phi)
    assert pt.vaC >= P.v_tr and pt.vaE >= P.v_tr
    assert_allclose(pt.vaC, math.hypot(pt.vC, P.v_tr), rtol=1e-15)
    assert_allclose(pt.vaE, math.hypot(pt.vE, P.v_tr), rtol=1e-15)


def test_benchmark_script_exists() -> None:
    assert (Path(__file__).resolve().parents[3] / 'bench' / 'bench_layup.py').is_file()


# ----------------------------------------------------------------------- dead centres and toggles (mpmath at 40 digits)


class TestDeadCentresAndToggles:
    """The six-bar at +-1e-12 rad of its dead centres and toggles, Grashof change points,
    delta3 = 90 deg: against the mpmath loop closure of :mod:`_reference`."""

    # ---- L six-bar: the rocker dead centres (swing extremes), both loops ----------------
    @pytest.mark.parametrize('which', [0, 1])
    def test_sixbar_swing_extremes(self, which: int) -> None:
        """At the closed-form dead centres O1, A, B are collinear: omega3 = omega5 = 0.

        Exact references: the dead-centre angle is the mpmath root of d(theta3)/dphi;
        omega3, omega5 at phi_e +- 1e-12 are mpmath derivatives of the mpmath loop
        closure at the same float angles; eps3 likewise (second derivative).
        """
        model = LayupModel(P)
        w = P.omega
        ext = swing_extremes(P)[which]
        with mp.workdps(40):

            def th3(x: Any) -> Any:
                return mp_sixbar(P, x)['theta3']

            def th5(x: Any) -> Any:
                return mp_sixbar(P, x)['theta5']

            root = mp.findroot(lambda x: mp.diff(th3, x), mp.mpf(ext.phi))
            assert abs(float(root) - ext.phi) <= 4 * EPS  # the closed form is exact to rounding (of O(1) terms)
            slope3 = float(mp.diff(th3, root, 2)) * w  # d(omega3)/dphi at the dead centre, rad/s per rad
        pts = {d: model.point(ext.phi + d) for d in (*DELTAS, 0.0)}
        arr = model.arrays(np.array([ext.phi + d for d in (*DELTAS, 0.0)]))
        for pt in pts.values():
            assert all(math.isfinite(v) for v in pt)
        assert np.all(np.isfinite(np.stack([arr.eps3, arr.eps5])))
        for d in DELTAS:
            x = ext.phi + d
            w3, w5 = pts[d].omega3, pts[d].omega5
            w3_ref, w5_ref = mp_rate(th3, x) * w, mp_rate(th5, x) * w
            with mp.workdps(40):
                off = float(mp.mpf(x) - root)  # d, up to the 4.5e-17 of phi_e
            # magnitude ~ |slope| 1e-12 and the sign of slope * d: a smooth sign change through 0
            assert math.copysign(1.0, w3) == math.copysign(1.0, slope3 * d) == math.copysign(1.0, w3_ref)
            assert abs(w3_ref - slope3 * off) <= 1e-6 * abs(slope3 * d)  # the reference is linear here
            assert abs(w3 - w3_ref) <= 1e-14  # absolute rounding of omega3
            assert abs(w3 - w3_ref) <= 1e-3 * abs(w3_ref)  # i.e. 0.1 % of a 1e-12-size value
            assert abs(w5 - w5_ref) <= 1e-14 and math.copysign(1.0, w5) == math.copysign(1.0, w5_ref)
            # positions continuous: the exits move by O(d^2) at a dead centre
            assert math.hypot(pts[d].xC - pts[0.0].xC, pts[d].yC - pts[0.0].yC) <= 1e-15
            assert math.hypot(pts[d].xE - pts[0.0].xE, pts[d].yE - pts[0.0].yE) <= 1e-15
        # accelerations finite, continuous across, and equal to the mpmath second derivative
        eps_ref = mp_rate(th3, ext.phi, 2) * w * w
        assert np.allclose(arr.eps3, eps_ref, rtol=1e-9, atol=0.0)
        assert abs(float(arr.eps3[0]) - float(arr.eps3[1])) <= 1e-9 * abs(eps_ref)

    def test_sixbar_chute4_has_no_dead_centre_of_its_own(self) -> None:
        """omega5 = 2 omega3 (E-C).C_perp / S2 vanishes only with omega3 on the defaults (O2, C, E never
        in line): so the dead centres of both loops are the two swing extremes tested above."""
        model = LayupModel(P)
        phi = np.linspace(0.0, TAU, 20001)
        s = model.arrays(phi, accelerations=False)
        ratio = s.omega5 / np.where(s.omega3 == 0.0, 1.0, s.omega3)
        assert ratio.min() > 0.5  # omega5 / omega3 bounded away from 0: no extra turning point of chute 4

    def test_sixbar_toggle_geometry_is_rejected_and_finite_just_inside(self) -> None:
        """Loop 1 on the Grashof boundary reaches a toggle (all four links in line) once a turn:
        LayupParams rejects it (ParameterError naming the lengths); the raw model is finite at
        phi_t - 1e-12 and +1e-12, or raises the documented AssemblyError naming phi, never NaN."""
        base = dataclasses.asdict(P)
        ground = math.hypot(P.a, P.b)
        # ground longest: toggle where |A - O2| = ground + R_kr = l2 + O2B (crank pointing away from O2)
        over = {**base, 'l2': ground + P.R_kr - P.O2B}
        assert classify_fourbar(ground, P.R_kr, over['l2'], P.O2B) == 'change-point'
        with pytest.raises(ParameterError, match='Grashof boundary') as info:
            LayupParams(**over)
        assert info.value.key == 'layup.R_kr,a,b,l2,O2B'
        raw = LayupModel(type('Raw', (), over)())  # unvalidated: the model itself must stay finite or raise
        phi_t = math.atan2(P.b, P.a)  # A farthest from O2
        for d in (-1e-12, 1e-12, 0.0, -1e-9, 1e-9, -1e-6, 1e-6):
            d1, d2 = raw.discriminants_scalar(phi_t + d)
            assert math.isfinite(d1) and math.isfinite(d2)
            assert -16 * EPS <= d1 <= 2 * d * d + 16 * EPS  # loop 1 touches its toggle: D1 ~ c d^2 >= 0
            try:
                pt = raw.point(phi_t + d)
            except AssemblyError as exc:  # the documented error, naming the loop and the angle
                assert exc.phi == phi_t + d and (exc.mechanism == LOOP1 or d2 < 0.0)
            else:
                assert all(math.isfinite(v) for v in pt)

    # ---- Grashof classification and change points -------------------------------------------
    @settings(max_examples=60, deadline=None, derandomize=True)
    @given(
        links=st.lists(st.integers(1, 2**20), min_size=3, max_size=3),
        order=st.permutations(range(4)),
        rel=st.sampled_from([0.0, 1e-13, -1e-13, 1e-9, -1e-9]),
    )
    def test_change_point_geometries(self, links: list[int], order: list[int], rel: float) -> None:
        """s + l = p + q exactly (dyadic lengths, exact sums) is 'change-point' whichever link is ground
        or input, and so is 1e-13 off (inside GRASHOF_REL_TOL). 1e-9 off it is a proper class that
        agrees with the geometry (exact arithmetic): the input link turns fully iff 'crank-rocker' or
        'double-crank'; a longest link made longer is 'non-Grashof'."""
        a, b, c = sorted(links)
        four = [a * 2.0**-20, b * 2.0**-20, c * 2.0**-20, (b + c - a) * 2.0**-20]  # s + l = p + q
        four[3] *= 1.0 + rel
        g = [four[i] for i in order]
        kind = classify_fourbar(*g)
        if abs(rel) < 1e-12:
            assert kind == 'change-point'
            return
        assert kind != 'change-point'
        assert crank_turns_fully(*g) == (kind in ('crank-rocker', 'double-crank'))
        if rel > 0:
            assert kind == 'non-Grashof'

    # ---- delta3 = 90 deg ------------------------------------------------------------------
    def test_branch_tracking_across_delta3_90(self) -> None:
        """Where the paper switches root (delta3 = 90 deg) the loop closure has no choice to make:
        E is continuous to O(step) on every scale from 1e-3 down to 1e-12 rad."""
        model = LayupModel(P)

        def d3(phi: float) -> float:  # angle at C between C->O2 and C->E, deg
            pt = model.point(phi)
            ux, uy, vx, vy = -pt.xC, -pt.yC, pt.xE - pt.xC, pt.yE - pt.yC
            return math.degrees(math.atan2(abs(ux * vy - uy * vx), ux * vx + uy * vy))

        grid = np.linspace(0.0, TAU, 3601)
        vals = np.array([d3(x) for x in grid]) - 90.0
        sc = find_sign_changes(lambda x: d3(x) - 90.0, grid, values=vals, xtol=1e-15)
        assert len(sc) == 2
        vmax = float(np.abs(model.arrays(grid, accelerations=False).vE).max()) / P.omega  # |dE/dphi|, m/rad
        for phi_s in sc.x:
            for h in (1e-3, 1e-6, 1e-9, 1e-12):
                a, b = model.point(phi_s - h), model.point(phi_s + h)
                assert math.hypot(a.xE - b.xE, a.yE - b.yE) <= 2 * h * vmax * (1 + 1e-9) + 4 * EPS
                assert abs(a.omega5 - b.omega5) <= 2 * h * 10.0 + 1e-13  # |d omega5/dphi| < 10 rad/s per rad
            # and it is the mpmath loop closure's E (the one root of the unsquared equations)
            with mp.workdps(40):
                ref = mp_sixbar(P, mp.mpf(float(phi_s)))['E']
            pt = model.point(float(phi_s))
            assert abs(pt.xE - float(ref[0])) <= 1e-15 and abs(pt.yE - float(ref[1])) <= 1e-15
