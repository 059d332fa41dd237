"""core.chain: the chain's arc length over the stroke, its inverse, the mapping and the carriage schedule."""

from __future__ import annotations

import math
from typing import Any

import mpmath as mp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose
from scipy.integrate import quad
from scipy.optimize import brentq

from folder_line.core.line.scene import Scene
from folder_line.core.mechanisms import chain
from folder_line.core.mechanisms import knife as knife_mod
from folder_line.core.mechanisms.chain import ChainPath
from folder_line.core.mechanisms.cyclogram import cycle_timing
from folder_line.core.mechanisms.delivery import evaluate_stroke
from folder_line.core.mechanisms.delivery_laws import LAWS
from folder_line.errors import ParameterError

from .._scenes import folder_scene


def make_scene(*, delivery: dict[str, Any] | None = None, chain_p: dict[str, Any] | None = None) -> Scene:
    """The shipped knife, cyclogram, feed transporter and delivery; no effects."""
    return folder_scene('chain', {}, delivery=delivery, chain=chain_p)


@pytest.fixture(scope='module')
def scene() -> Scene:
    return make_scene()


# ------------------------------------------------------------------ chain path


def _exact_arc(u: float, x_max: float = 0.3, lam: float = 0.4) -> float:
    def g(v: Any) -> Any:
        xi = v if v <= 1 else 2 - v
        return x_max * mp.sqrt(1 + (lam * (1 - mp.cos(2 * mp.pi * xi))) ** 2)

    mp.mp.dps = 30
    if u <= 1:
        return float(mp.quad(g, [0, u]))
    return float(mp.quad(g, [0, 1]) + mp.quad(g, [1, u]))


def test_path_length_and_arc_against_mpmath(scene: Scene) -> None:
    path = chain.chain_path(scene)
    assert path.length == pytest.approx(_exact_arc(2.0), abs=1e-13)
    for u in (0.0, 0.05, 0.3187, 0.5, 0.99, 1.0, 1.354, 1.9, 2.0):
        assert float(path.arc(u)) == pytest.approx(_exact_arc(u), abs=5e-14)


def test_chain_path_against_scipy(scene: Scene) -> None:
    d, ch = scene.machines['delivery'], scene.machines['delivery_chain']
    path = ChainPath(d, ch.x_max)

    def f(u: float) -> float:
        xi = u if u <= 1.0 else 2.0 - u
        return ch.x_max * math.sqrt(1.0 + (d.Lambda * float(LAWS[d.law].dpsi(xi))) ** 2)

    def ref_arc(u: float) -> float:
        return quad(f, 0.0, min(u, 1.0), epsabs=1e-15)[0] + (quad(f, 1.0, u, epsabs=1e-15)[0] if u > 1 else 0.0)

    for u in (0.0, 0.2, 0.5, 1.0, 1.3, 1.77, 2.0):
        assert float(path.arc(u)) == pytest.approx(ref_arc(u), abs=1e-14)
        assert float(path.slope(u)) == pytest.approx(f(u), rel=1e-15)
    s = np.linspace(0.0, path.length, 10_001)
    u = path.position(s)
    assert_allclose(path.arc(u), s, atol=1e-14)
    # the inverse against an independent one: brentq on scipy's quadrature
    for target in (0.0137, 0.2, 0.31, 0.5, path.length - 1e-3):
        u_ref = brentq(lambda x, target=target: ref_arc(x) - target, 0.0, 2.0, xtol=1e-15, rtol=4 * np.finfo(float).eps)
        assert float(path.position(target)) == pytest.approx(u_ref, abs=1e-13)
    assert path.length > 2 * ch.x_max  # the curved guide is longer than the straight stroke


def test_scalar_position_is_the_vector_one(scene: Scene) -> None:
    path = chain.chain_path(scene)
    s = np.concatenate([np.linspace(-0.1, path.length + 0.1, 2001), path.arc(np.linspace(0.0, 2.0, 4097)[::97])])
    vec = path.position(s)
    assert [path.position1(float(x)) for x in s] == vec.tolist()
    assert vec[0] == 0.0 and vec[2000] == 2.0 and np.all((vec >= 0.0) & (vec <= 2.0))


def test_flat_guide_has_the_straight_length() -> None:
    sc = make_scene(delivery={'Lambda': 1e-9})
    path = chain.chain_path(sc)
    assert path.length == pytest.approx(2 * 0.3, rel=1e-15)
    u = np.linspace(0, 2, 9)
    np.testing.assert_allclose(path.arc(u), 0.3 * u, rtol=1e-14, atol=1e-17)


def test_path_rejects_bad_arguments(scene: Scene) -> None:
    d = scene.machines['delivery']
    with pytest.raises(ParameterError) as info:
        ChainPath(d, 0.0)
    assert info.value.key == 'delivery_chain.x_max'
    for n in (0, 2.5, True):
        with pytest.raises(ParameterError):
            ChainPath(d, 0.3, n)  # type: ignore[arg-type]


# ------------------------------------------------------------------ chain <-> stroke


def test_chain_to_stroke_and_back(scene: Scene) -> None:
    to_u = chain.chain_to_stroke(scene)
    L = scene.machine('delivery_chain').L_transfer
    S = chain.chain_path(scene).length
    u = np.linspace(0.0, 2.0, 200_001)
    np.testing.assert_allclose(to_u(chain.stroke_to_chain(scene, u)), u, rtol=0, atol=1e-13)
    travel = np.linspace(L, L + S, 100_001)
    np.testing.assert_allclose(chain.stroke_to_chain(scene, to_u(travel)), travel, rtol=0, atol=1e-13)
    assert to_u(np.array([0.0, L - 1e-9, L + S + 1e-9, 5.0])).tolist() == [chain.OFF_STROKE] * 4
    assert float(to_u(L)) == 0.0 and float(to_u(L + S)) == 2.0
    # travel is monotone in u, and the slope is ds/du = x_max / cos(beta)
    st_ = evaluate_stroke(scene.machine('delivery'), u[::1000])
    slope = np.gradient(chain.stroke_to_chain(scene, u), u)[::1000]
    np.testing.assert_allclose(slope, 0.3 / np.cos(st_.beta), rtol=1e-6)


@settings(max_examples=200, deadline=None)
@given(st.floats(-10.0, 10.0, allow_nan=False))
def test_chain_to_stroke_never_nan(travel: float) -> None:
    sc = make_scene()
    u = float(chain.chain_to_stroke(sc)(travel))
    assert u == chain.OFF_STROKE or 0.0 <= u <= 2.0
    if u != chain.OFF_STROKE:
        assert float(chain.stroke_to_chain(sc, u)) == pytest.approx(travel, abs=1e-12)


def test_mapping_rejects_bad_input(scene: Scene) -> None:
    with pytest.raises(ParameterError):
        chain.chain_to_stroke(scene)(np.nan)
    with pytest.raises(ParameterError):
        chain.stroke_to_chain(scene, 2.5)


# ------------------------------------------------------------------ schedule: carriage k takes sheet k


def test_schedule_from_the_knife_and_chain(scene: Scene) -> None:
    sch = chain.schedule(scene)
    kn = scene.machine('knife')
    assert pytest.approx(0.072, rel=1e-15) == sch.T
    assert sch.v_A == pytest.approx(0.8 / 0.072, rel=1e-15)
    # carriage 0 takes sheet 0 when the knife passage that folds it (centred on Θ = T) ends
    assert sch.theta_pick0 == sch.T + knife_mod.window(kn).t_out
    assert sch.theta_enter0 == pytest.approx(sch.theta_pick0 + 0.4 / sch.v_A, rel=1e-15)
    np.testing.assert_allclose(sch.phase_of_travel([0.4, 0.4], [0, 3]), sch.theta_enter0 + np.array([0, 3]) * 0.072)
    assert chain.chain_path(scene).length == sch.S and sch.stroke_phase == sch.S / sch.v_A


def test_schedule_numbering_is_the_cycle_timing(scene: Scene) -> None:
    sch = chain.schedule(scene)
    tm = cycle_timing(scene.machine('cyclogram'), scene.machine('knife'))
    k = np.arange(0, 50_000, 997)
    assert sch.T == tm.T  # bit for bit: folder events and chain load share one clock
    # cycle k: hand-over after the knife exit kT + t_out, contact at (k+1)T + t_in, pickup at the next exit
    assert np.all(sch.pickup_phase(k) == k * tm.T + (tm.T + tm.knife.t_out))  # folder_sim's knife_exit of cycle k
    assert np.all(sch.pickup_phase(k) > (k + 1) * tm.T + tm.knife.t_in)
    assert_allclose(sch.travel(sch.phase_of_travel(0.7, k), k), 0.7, rtol=1e-9)


def test_stroke_travel_membership(scene: Scene) -> None:
    sch = chain.schedule(scene)
    theta = np.linspace(-1.0, 3.0, 400_001)
    a0, slack = sch.stroke_travel(theta)
    assert np.all(a0 >= -slack) and np.all(a0 < sch.pitch)
    # the last carriage to enter: the largest k with Θ_enter(k) <= Θ (brute force over k)
    k_last = np.floor((theta - sch.theta_enter0) / sch.T)
    assert_allclose(np.where(a0 < 0.0, a0 + sch.pitch, a0), sch.travel(theta, k_last) - sch.L_transfer, atol=1e-12)
    # exactly at an entry (to rounding) the new carriage counts as at u = 0, not at the far end
    e = sch.theta_enter0 + np.arange(-3, 200) * sch.T
    a_e, _ = sch.stroke_travel(e)
    assert np.all(np.abs(a_e) <= 1e-12)
    two = chain.schedule(make_scene(chain_p={'pitch': 0.25}))
    assert two.max_on_stroke == math.ceil(two.S / 0.25) + 1 == 4


@settings(max_examples=300, deadline=None)
@given(s=st.floats(-0.05, 1.5), theta=st.floats(-5.0, 4000.0))
def test_one_element_fast_paths_are_the_array_paths_bit_for_bit(s: float, theta: float) -> None:
    """A node's tick evaluates one element through plain-Python paths: same operations, same bits."""
    sc = make_scene()
    path, sch = chain.chain_path(sc), chain.schedule(sc)
    many_s = np.array([s, 0.1, 0.7])
    assert path.position(np.array([s])).tobytes() == path.position(many_s)[:1].tobytes()
    assert path.position(np.array(s)).shape == ()
    many_th = np.array([theta, 1.0, 2.0])
    a1, s1 = sch.stroke_travel(np.array([theta]))
    a3, s3 = sch.stroke_travel(many_th)
    assert a1.tobytes() == a3[:1].tobytes() and s1.tobytes() == s3[:1].tobytes()
    # the boundary case of the wrap: a phase a hair below a whole period
    edge = sch.theta_enter0 + 7 * sch.T - np.array([0.0, 1e-15, 1e-13])
    for e in edge:
        one = sch.stroke_travel(np.array([e]))
        vec = sch.stroke_travel(np.array([e, 0.0]))
        assert one[0].tobytes() == vec[0][:1].tobytes()
