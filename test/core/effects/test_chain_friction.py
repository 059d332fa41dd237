"""Effect chain_friction: efficiency, forces, sprocket torque and the motor's view of the load."""

from __future__ import annotations

import dataclasses
import math
from itertools import pairwise
from typing import Any

import numpy as np
import pytest

from folder_line.core.effects import chain_friction as cf
from folder_line.core.line.scene import Scene, parse_scene
from folder_line.core.mechanisms import chain
from folder_line.core.mechanisms.delivery import evaluate, evaluate_stroke
from folder_line.core.mechanisms.delivery_results import STATE_OK
from folder_line.errors import ParameterError

from .._scenes import folder_scene

CF = {'P_k': 50.0, 'r': 0.1, 'return_section': 'geometric'}
MOTOR = dict(
    J=0.5,
    T_0=264.6,
    omega_0=157.08,
    omega_nom=152.4,
    b=0.03,
    method='dopri5',
    h=0.01,
    rtol=1e-8,
    atol=1e-10,
    t_stop=1e9,
    T_brake=0.0,
)


def make_scene(
    cf_params: dict[str, Any] | None = None,
    *,
    delivery: dict[str, Any] | None = None,
    chain: dict[str, Any] | None = None,
    motor: bool = True,
) -> Scene:
    effects: dict[str, Any] = {'chain_friction': {**CF, **(cf_params or {})}}
    if motor:
        effects['motor_dynamics'] = MOTOR
    return folder_scene('chain', effects, delivery=delivery, chain=chain)


@pytest.fixture(scope='module')
def scene() -> Scene:
    return make_scene()


# ------------------------------------------------------------------ parameters


@pytest.mark.parametrize(
    'key, value',
    [('P_k', -1.0), ('P_k', math.nan), ('r', 0.0), ('r', -0.1), ('return_section', 'mirror'), ('P_k', True)],
)
def test_bad_params_name_the_key(key: str, value: Any) -> None:
    with pytest.raises(ParameterError) as info:
        cf.Params(**{**CF, key: value})
    assert info.value.key == f'effects.chain_friction.{key}'


def test_scene_rejects_an_unknown_or_missing_parameter() -> None:
    with pytest.raises(ParameterError, match=r'effects.chain_friction.mu'):
        make_scene({'mu': 0.1})


# ------------------------------------------------------------------ efficiency and forces


def test_reference_numbers_of_delivery_py(scene: Scene) -> None:
    p = scene.effect('chain_friction')
    d = scene.machine('delivery')
    for rs in ('geometric', 'paper_mirror'):
        s = cf.stroke_state(dataclasses.replace(p, return_section=rs), d, np.array([0.0, 1.0, 2.0]))
        # eta = 0.6943 at xi = 1 (the section boundary), eta_O = 1/(1 + 0.015) = 0.9852 where alpha = beta = 0
        assert s.eta[1] == pytest.approx(0.6943, abs=5e-5)
        assert s.eta[0] == pytest.approx(1 / 1.015, rel=1e-14)
        assert s.eta[2] == pytest.approx(1 / 1.015, rel=1e-12)
    ref = evaluate(d, np.linspace(0.0, 1.0, 11))
    s = cf.stroke_state(p, d, np.linspace(0.0, 1.0, 11))
    np.testing.assert_array_equal(s.eta, ref.eta)
    np.testing.assert_allclose(s.M_1, ref.m_1 * p.P_k * p.r, rtol=1e-15)


def test_power_balance_where_ok(scene: Scene) -> None:
    p = scene.effect('chain_friction')
    sch = chain.schedule(scene)
    for rs in ('geometric', 'paper_mirror'):
        u = np.linspace(0.0, 2.0, 4001)
        s = cf.stroke_state(dataclasses.replace(p, return_section=rs), scene.machine('delivery'), u)
        assert s.ok.all()
        v_k = s.K_v * sch.v_A
        omega_s = sch.v_A / p.r
        np.testing.assert_allclose(p.P_k * v_k, s.eta * s.M_1 * omega_s, rtol=1e-13)
        # eq. (7): M_1 = P_ch r (1 + f_O r_O)
        np.testing.assert_allclose(s.M_1, s.P_ch * p.r * 1.015, rtol=1e-15)


def test_zero_useful_force_gives_zero_forces(scene: Scene) -> None:
    s = cf.stroke_state(cf.Params(0.0, 0.1, 'geometric'), scene.machine('delivery'), np.linspace(0, 2, 101))
    assert not s.M_1.any() and not s.P_AB.any() and s.eta.min() > 0.5


@pytest.mark.parametrize('alpha_m', [89.0, 89.9, 89.999999, 90.0 - 1e-12])
def test_no_nan_near_self_locking(alpha_m: float) -> None:
    sc = make_scene(delivery={'alpha_m_deg': alpha_m})
    u = np.linspace(0.0, 2.0, 20001)
    s = cf.stroke_state(sc.effect('chain_friction'), sc.machine('delivery'), u)
    for arr in (s.eta, s.K_v, s.P_AB, s.P_ch, s.M_1):
        assert np.all(np.isfinite(arr))
    assert (s.state != STATE_OK).any()  # the lock is reported as a state
    assert np.all(s.M_1[s.state != STATE_OK] == 0.0)
    th = np.linspace(0.0, 0.3, 30001)
    tq = cf.sprocket_torque(sc, th)
    assert np.all(np.isfinite(tq)) and np.all(tq >= 0.0)
    load = cf.master_load(sc)
    assert load.locked_u.size > 0
    assert np.isfinite(load.peak) and np.isfinite(load.mean)


# ------------------------------------------------------------------ torque on the line (carriages from core.chain)


def test_sprocket_torque_places_the_carriage_by_the_mapping(scene: Scene) -> None:
    sch = chain.schedule(scene)
    p = scene.effect('chain_friction')
    u = np.linspace(0.0, 2.0, 401)
    for cycle in (0, 1, 17, 5000):
        theta = sch.phase_of_travel(chain.stroke_to_chain(scene, u), cycle)
        ref = cf.stroke_state(p, scene.machine('delivery'), u).M_1
        np.testing.assert_allclose(cf.sprocket_torque(scene, theta), ref, rtol=1e-9, atol=1e-12)


def test_sprocket_torque_is_zero_off_the_stroke_and_periodic(scene: Scene) -> None:
    sch = chain.schedule(scene)
    theta = np.linspace(-1.0, 1.0, 20001)
    tq = cf.sprocket_torque(scene, theta)
    phase = np.mod(theta - sch.theta_enter0, sch.T) * sch.v_A
    off = phase > sch.S + 1e-9
    assert off.any() and np.all(tq[off] == 0.0)
    assert np.all(tq[~off] > 0.0)
    np.testing.assert_allclose(cf.sprocket_torque(scene, theta + 7 * sch.T), tq, rtol=1e-9, atol=1e-12)
    # the jump at the stroke entry: 0 just before, P_k r (1 + f_O r_O) just after
    e = sch.theta_enter0 + 3 * sch.T
    before, after = cf.sprocket_torque(scene, [e - 1e-9, e + 1e-12])
    assert before == 0.0 and after == pytest.approx(50.0 * 0.1 * 1.015, rel=1e-6)


def test_overlapping_carriages_add(scene: Scene) -> None:
    sc = make_scene(chain={'pitch': 0.25})  # S = 0.665 m: two or three carriages on the stroke at once
    sch = chain.schedule(sc)
    theta = np.linspace(0.0, 0.2, 2001)
    manual = np.zeros_like(theta)
    p = sc.effect('chain_friction')
    for k in range(-10, 10):
        a = sch.v_A * (theta - sch.theta_enter0 - k * sch.T)
        on = (a >= 0.0) & (a <= sch.S)
        u = chain.chain_path(sc).position(np.where(on, a, 0.0))
        manual += np.where(on, cf.stroke_state(p, sc.machine('delivery'), u).M_1, 0.0)
    np.testing.assert_allclose(cf.sprocket_torque(sc, theta), manual, rtol=1e-9, atol=1e-9)
    assert manual.max() > 1.6 * cf.sprocket_torque(scene, theta).max()


def test_master_load_torque_is_power_consistent(scene: Scene) -> None:
    sch = chain.schedule(scene)
    p = scene.effect('chain_friction')
    omega_nom = scene.effect('motor_dynamics').omega_nom
    theta = np.linspace(0.0, 0.5, 5001)
    T_load = cf.master_load_torque(scene, theta)
    M_1 = cf.sprocket_torque(scene, theta)
    np.testing.assert_allclose(T_load * omega_nom, M_1 * sch.v_A / p.r, rtol=1e-14)
    np.testing.assert_allclose(cf.master_load_torque(scene, theta, omega_nom=2 * omega_nom), T_load / 2, rtol=1e-14)


def test_master_load_torque_needs_omega_nom_without_motor() -> None:
    sc = make_scene(motor=False)
    with pytest.raises(ParameterError, match='omega_nom'):
        cf.master_load_torque(sc, [0.1])
    assert np.all(np.isfinite(cf.master_load_torque(sc, [0.1], omega_nom=100.0)))


def test_scene_without_chain_friction() -> None:
    sc = make_scene()
    bare = parse_scene({**dict(sc.source), 'effects': {}})
    with pytest.raises(ParameterError, match='chain_friction'):
        cf.sprocket_torque(bare, [0.0])


# ------------------------------------------------------------------ the motor's view: pieces, kinks, mean, peak


def test_kinks_are_where_alpha_equals_beta(scene: Scene) -> None:
    p = scene.effect('chain_friction')
    d = scene.machine('delivery')
    kinks = cf.stroke_kinks(p, d)
    assert 1.0 in kinks.tolist()
    inner = kinks[kinks != 1.0]
    assert inner.size == 1 and 0.5 < inner[0] < 0.7  # geometric return: beta <= 0 after u = 1, no second one
    s = evaluate_stroke(d, inner)
    assert abs(float(s.alpha[0] - s.beta[0])) < 1e-13
    # M_1 is continuous there but its slope jumps (pair A's friction reverses)
    h = 1e-6
    m = cf.stroke_state(p, d, inner[0] + np.array([-2 * h, -h, 0.0, h, 2 * h])).M_1
    left, right = (m[2] - m[0]) / (2 * h), (m[4] - m[2]) / (2 * h)
    assert abs(m[3] - m[1]) < 1e-4 and abs(right - left) > 1e-2 * abs(left)
    mirror = cf.stroke_kinks(dataclasses.replace(p, return_section='paper_mirror'), d)
    assert mirror.size == 3 and mirror[2] == pytest.approx(2.0 - inner[0], abs=1e-12)


def test_master_load_pieces_breaks_mean_and_peak(scene: Scene) -> None:
    load = cf.master_load(scene)
    sch = chain.schedule(scene)
    # breaks: strictly increasing, periodic, and the entry is a mark
    b = [0.0]
    for _ in range(20):
        b.append(load.next_break(b[-1]))
    b_arr = np.array(b[1:])
    assert np.all(np.diff(b_arr) > 0.0)
    n = len(load.offsets)
    np.testing.assert_allclose(b_arr[n:] - b_arr[:-n], sch.T, rtol=1e-12)
    assert load.is_entry(sch.theta_enter0 + 5 * sch.T) and not load.is_entry(sch.theta_enter0 + 0.01)
    # piecewise scalar torque equals the vectorised one inside each piece
    for lo, hi in pairwise(b_arr):
        th = np.linspace(lo, hi, 9)[1:-1]
        np.testing.assert_allclose(
            [load.torque_piece(x, (lo, hi)) for x in th], load.torque(th), rtol=1e-12, atol=1e-14
        )
        # and continues its own piece's formula past the ends (no jump inside the piece)
        assert load.torque_piece(lo, (lo, hi)) == pytest.approx(float(load.torque(lo + 1e-12)), rel=1e-6, abs=1e-9)
    # mean and peak against brute-force sampling of one period
    th = sch.theta_enter0 + np.linspace(0.0, sch.T, 2_000_001)
    vals = load.torque(th)
    assert load.mean == pytest.approx(np.trapezoid(vals, th) / sch.T, rel=1e-6)
    assert load.peak == pytest.approx(vals.max(), rel=1e-6)
    assert load.peak >= vals.max() - 1e-12
