"""L part of the line: ``simulate_layup`` — stream, exits, flight, damage, faults, samples, summary."""

from __future__ import annotations

import dataclasses
import inspect
import json
import math
from itertools import pairwise
from typing import Any

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.integrate import quad

from folder_line.config.params import config_dir, load_params, read_yaml_mapping
from folder_line.core.effects import chute_belts, faults, guide_friction, leaf_damage, leaf_flight
from folder_line.core.line.layup_figures import LayupFigures
from folder_line.core.line.layup_kinematics import LayupKinematics
from folder_line.core.line.layup_sim import leaf_stream, simulate_layup
from folder_line.core.line.model import sample_times, simulate
from folder_line.core.line.scene import Scene, parse_scene
from folder_line.core.mechanisms.drive import ConstantDrive, RampDrive
from folder_line.core.mechanisms.layup import LayupModel
from folder_line.core.mechanisms.layup_angles import TAU
from folder_line.core.mechanisms.layup_reach import swing_extremes
from folder_line.errors import ParameterError
from folder_line.interfaces import EVENT_KINDS

P = load_params('layup')
LAYUP = dataclasses.asdict(P)
CONTAINER = read_yaml_mapping(config_dir() / 'container.yaml', 'container')
SHEETS = read_yaml_mapping(config_dir() / 'sheets.yaml', 'sheets')
OMEGA = P.omega
EXT = swing_extremes(P)

BELTS = {'chute_belts': {'v_min': 2.0}}
FLIGHT = {'leaf_flight': {'drag': 0.0}}
DAMAGE = {'leaf_damage': {'v_damage': 4.5}}
FRICTION = {'guide_friction': {'mu': 0.5, 's0': 0.0, 'v0': 1.0, 'h': 0.002}}
FAULTS0 = {
    'p_missing': 0.0,
    'p_double': 0.0,
    'p_late': 0.0,
    'late_delay': 0.0,
    'p_slowdown': 0.0,
    'slowdown_factor': 1.0,
    'slowdown_duration': 0.0,
}


def scene(
    effects: dict[str, Any] | None = None,
    *,
    sheets: dict[str, float] | None = None,
    seed: int = 1,
    rate: float = 0.0,
    layup: dict[str, Any] | None = None,
    container: dict[str, Any] | None = None,
    drive: dict[str, Any] | None = None,
) -> Scene:
    data: dict[str, Any] = {
        'name': 'layup-test',
        'machines': {'layup': {**LAYUP, **(layup or {})}, 'container': {**CONTAINER, **(container or {})}},
        'sheets': {**SHEETS, **(sheets or {})},
        'effects': effects or {},
        'seed': seed,
        'sample_rate': rate,
    }
    if drive:
        data['drive'] = drive
    return parse_scene(data)


def run(sc: Scene, duration: float, drive: Any = None, t_samples: np.ndarray | None = None):
    return simulate_layup(sc, drive or ConstantDrive(), duration, np.zeros(0) if t_samples is None else t_samples)


def events(res: Any, kind: str) -> np.ndarray:
    return res.events[res.events['kind'] == EVENT_KINDS.index(kind)]


def at_extreme(kind: str = 'folded') -> float:
    """Stream phase that puts leaf 0 exactly at a swing extreme (jitter 0)."""
    return next(e.phi for e in EXT if e.kind == kind) / OMEGA


# ---------------------------------------------------------------------------- stream


def test_stream_times_alternate_and_are_increasing() -> None:
    j, t = leaf_stream(dataclasses.replace(scene().sheets, jitter=0.9), 100.0, 1)
    assert (np.diff(t) > 0.0625 * 0.1 - 1e-15).all()
    assert j.tolist() == list(range(j.size))
    res = run(scene(sheets={'jitter': 0.9}), 100.0)
    ev = events(res, 'leaf_enter')
    assert ((ev['t'] >= 0.0) & (ev['t'] <= 100.0)).all()
    assert ev.size == int(((t >= 0.0) & (t <= 100.0)).sum())
    jitter = (ev['t'] - ev['sheet'] * 0.0625) / 0.0625
    assert (np.abs(jitter) <= 0.45).all() and jitter.std() > 0.2


def test_jitter_zero_stream_is_the_nominal_grid() -> None:
    res = run(scene(sheets={'jitter': 0.0, 'phase': 0.01}), 10.0)
    ev = events(res, 'leaf_enter')
    assert_allclose(ev['t'], 0.01 + np.arange(ev.size) * 0.0625, rtol=0, atol=1e-14)
    assert ev['sheet'].tolist() == list(range(ev.size))


# ---------------------------------------------------------------------------- exits


def test_belts_exit_after_the_chute_length_with_eq25_speed() -> None:
    res = run(scene(BELTS, sheets={'jitter': 0.5}), 20.0)
    enter = events(res, 'leaf_enter')
    exit_ = events(res, 'leaf_exit')
    t_in = dict(zip(enter['sheet'].tolist(), enter['t'].tolist(), strict=True))
    model = LayupModel(P)
    for row in exit_[::7]:
        i = int(row['sheet'])
        l_chute = P.l5 if i % 2 else P.l3
        assert row['t'] == pytest.approx(t_in[i] + l_chute / 2.8, abs=1e-13)
        pt = model.point(OMEGA * row['t'])
        expected = pt.vaE if i % 2 else pt.vaC  # sqrt(v² + v_tr²), paper eq. (25)
        assert row['value'] == pytest.approx(expected, rel=1e-12)
        assert row['cycle'] == math.floor(row['t'] * P.n_kr / 60.0)


def test_with_belts_at_2_8_the_exit_speed_never_drops_below_2_8() -> None:
    sc = scene({**BELTS, **FLIGHT, **DAMAGE}, sheets={'jitter': 0.0, 'phase': at_extreme() - 1.0 / 2.8})
    res = run(sc, 60.0)
    speeds = events(res, 'leaf_exit')['value']
    assert speeds.min() >= 2.8
    assert res.summary.min_exit_speed >= 2.8
    assert speeds[0] == pytest.approx(2.8, abs=1e-12)  # leaf 0 leaves exactly at the extreme
    assert res.summary.max_exit_speed == pytest.approx(math.hypot(res.summary.swing_speed.max, 2.8), rel=1e-3)
    assert res.summary.leaves_damaged == 0
    cons = res.constraints[0]
    assert cons.name == 'chute_speed' and cons.unit == 'm/s'
    assert (cons.margin >= 0.8 - 1e-12).all()  # v_min = 2.0


@pytest.mark.parametrize('kind', ['extended', 'folded'])
def test_without_belts_the_exit_speed_reaches_zero_at_the_swing_extremes(kind: str) -> None:
    sc = scene({**FLIGHT}, sheets={'jitter': 0.0, 'phase': at_extreme(kind)})
    res = run(sc, 60.0)
    exit_ = events(res, 'leaf_exit')
    enter = events(res, 'leaf_enter')
    assert_allclose(exit_['t'], enter['t'], rtol=0, atol=0)  # dropped at the exit at entry time
    assert exit_['value'][0] < 1e-9
    assert res.summary.min_exit_speed < 1e-9
    assert res.summary.exit_speed_at_extremes[kind].exit_speed.min < 1e-9
    assert res.summary.max_exit_speed == pytest.approx(res.summary.swing_speed.max, rel=1e-3)
    # and the leaf falls straight from the exit (no velocity): lands at the exit x
    landed = events(res, 'leaf_landed')
    x_exit = LayupModel(P).point(EXT[0 if kind == 'extended' else 1].phi)
    assert landed['value'][0] == pytest.approx(x_exit.xC, abs=1e-9)


def test_exit_velocity_direction_with_belts() -> None:
    """The flight starts at the exit with v_C n̂ + v_tr t̂: check the landing point of one leaf by hand."""
    sc = scene({**BELTS, **FLIGHT}, sheets={'jitter': 0.0, 'phase': 0.3})
    res = run(sc, 2.0)
    t_x = events(res, 'leaf_exit')['t'][0]
    pt = LayupModel(P).point(OMEGA * t_x)
    tx, ty = math.cos(pt.theta3), math.sin(pt.theta3)
    vx = 2.8 * tx - pt.vC * ty
    vy = 2.8 * ty + pt.vC * tx
    h = pt.yC - CONTAINER['y_floor']
    t_f = (vy + math.sqrt(vy * vy + 2 * 9.80665 * h)) / 9.80665
    landed = events(res, 'leaf_landed')
    assert landed['t'][0] == pytest.approx(t_x + t_f, abs=1e-12)
    assert landed['value'][0] == pytest.approx(pt.xC + vx * t_f, abs=1e-12)


def test_ramp_drive_belt_travel_is_the_chute_length() -> None:
    drive = RampDrive(4.0)
    sc = scene({**BELTS}, sheets={'jitter': 0.3, 'phase': 0.05}, drive={'profile': 'ramp', 't_ramp': 4.0})
    res = run(sc, 8.0, drive=drive)
    enter = events(res, 'leaf_enter')
    t_in = dict(zip(enter['sheet'].tolist(), enter['t'].tolist(), strict=True))
    for row in events(res, 'leaf_exit')[::5]:
        i = int(row['sheet'])
        travel = quad(
            lambda t: 2.8 * float(drive.rate(t)), t_in[i], row['t'], points=[4.0], epsabs=1e-13, epsrel=1e-13
        )[0]
        assert travel == pytest.approx(P.l5 if i % 2 else P.l3, abs=1e-11)
        # exit speed with the drive's λ: the belt and the swing both scale
        lam = float(drive.rate(row['t']))
        pt = LayupModel(P).point(OMEGA * float(drive.theta(row['t'])))
        v = pt.vE if i % 2 else pt.vC
        assert row['value'] == pytest.approx(lam * math.hypot(v, 2.8), rel=1e-12, abs=1e-15)


# ---------------------------------------------------------------------------- damage and constraint


def test_damage_at_exactly_v_damage_counts_and_violates() -> None:
    sc = scene({**BELTS, 'leaf_damage': {'v_damage': 2.8}}, sheets={'jitter': 0.0, 'phase': at_extreme() - 1 / 2.8})
    res = run(sc, 4.0)
    exit_ = events(res, 'leaf_exit')
    assert exit_['value'][0] == 2.8
    dmg = events(res, 'leaf_damaged')
    assert dmg.size == exit_.size == res.summary.leaves_damaged  # every speed >= 2.8
    cons = res.constraints[0]
    assert (cons.margin < 0.0).all()
    assert cons.margin[0] == -(2.8 - np.nextafter(2.8, 0.0))


def test_paper_belt_speeds_damage() -> None:
    """5.6 m/s belts damage every leaf, 2.8 m/s none (v_damage 4.5)."""
    fast = run(scene({**BELTS, **DAMAGE}, layup={'v_tr': 5.6}), 30.0)
    slow = run(scene({**BELTS, **DAMAGE}), 30.0)
    assert fast.summary.leaves_damaged == fast.summary.leaves_exited > 400
    assert slow.summary.leaves_damaged == 0
    assert fast.constraints[0].violated.all() and not slow.constraints[0].violated.any()


# ---------------------------------------------------------------------------- landing histograms


def _hist(effects: dict[str, Any], duration: float = 3600.0) -> LayupFigures:
    # an interval incommensurate with the 2 s crank turn, so the leaves sample every crank phase
    res = run(scene({**effects, **FLIGHT}, sheets={'interval': 0.0617, 'jitter': 0.0}), duration)
    return res.summary


def test_landing_histograms_with_and_without_belts() -> None:
    """Belts make the layup more uniform (numbers reported to the lead).

    Default geometry, 1 h, drag-free flight, every crank phase sampled: landing_cv
    0.518 with 2.8 m/s belts vs 0.716 without. Without belts the leaves pile up under
    the outer swing extremes (the exits linger there) and none reach the bins at the
    walls; with belts a leaf keeps the chute's direction, lands where the chute's
    axis meets the floor, fills the wall bins and flattens the edge peaks. Both pile
    up in mid-container, where C's right extreme and E's left extreme meet.
    """
    with_b = _hist(BELTS)
    without = _hist({})
    assert with_b.landing.histogram.cv < 0.8 * without.landing.histogram.cv
    assert with_b.landing.histogram.cv == pytest.approx(0.518, abs=0.01)
    assert without.landing.histogram.cv == pytest.approx(0.716, abs=0.01)
    cb_, cn = np.array(with_b.landing.histogram.counts), np.array(without.landing.histogram.counts)
    assert cn[0] == 0 and cn[-1] == 0 and cb_[0] > 0 and cb_[-1] > 0  # walls reached only with belts
    assert cn[1] > 3 * np.median(cn) and cn[-2] > 3 * np.median(cn)  # edge peaks without belts
    assert cb_[:3].max() < 0.7 * cn[:3].max() and cb_[-3:].max() < 0.7 * cn[-3:].max()  # flattened by belts
    for c in (cb_, cn):
        assert c[13:18].mean() > 2.5 * np.median(c)  # the mid-container pile
    assert with_b.leaves_spilled == without.leaves_spilled == 0


def test_histogram_is_json_and_consistent() -> None:
    s = run(scene({**BELTS, **FLIGHT}, sheets={'jitter': 0.5}), 30.0).summary
    json.dumps(s.as_json(), allow_nan=False)
    h = s.landing.histogram
    assert len(h.edges) == CONTAINER['bins'] + 1 and len(h.counts) == CONTAINER['bins']
    assert sum(h.counts) == s.leaves_landed
    assert h.edges[0] == CONTAINER['x_left'] and h.edges[-1] == pytest.approx(CONTAINER['x_right'])


def test_narrow_container_spills() -> None:
    res = run(scene({**BELTS, **FLIGHT}, container={'x_left': 0.0, 'x_right': 0.5}), 20.0)
    sp = events(res, 'leaf_spilled')
    ld = events(res, 'leaf_landed')
    assert sp.size == res.summary.leaves_spilled > 0 and ld.size == res.summary.leaves_landed > 0
    assert ((sp['value'] < 0.0) | (sp['value'] > 0.5)).all()
    assert ((ld['value'] >= 0.0) & (ld['value'] <= 0.5)).all()
    assert res.summary.landing.spilled_left + res.summary.landing.spilled_right == sp.size


def test_floor_above_an_exit_is_rejected() -> None:
    with pytest.raises(ParameterError) as exc:
        run(scene({**FLIGHT}, container={'y_floor': -0.9}), 1.0)
    assert exc.value.key == 'container.y_floor'


def test_zero_belt_speed_with_belts_is_rejected() -> None:
    with pytest.raises(ParameterError) as exc:
        run(scene({**BELTS}, layup={'v_tr': 0.0}), 1.0)
    assert exc.value.key == 'layup.v_tr'


# ---------------------------------------------------------------------------- guide friction in the line


def test_guide_friction_exit_speeds_vs_crank_phase() -> None:
    """What the model shows about the paper's observation (μ = 0.5, 2 min, every crank phase sampled):

    * leaves leaving within 5° of a swing extreme are slower (absolute exit speed)
      than those leaving at mid-swing, and they stayed longer on the guide — as the
      paper says; the swing speed v_C → 0 and the centrifugal push ω² s fades there;
    * with friction the slowest leaves leave shortly *before* each extreme (within
      60° of crank): they crossed mid-swing on the chute, where the Coriolis push
      2 ω ṡ on the wall, and with it the friction, is largest;
    * friction slows every leaf and lengthens every transit (vs μ = 0).
    """
    kin = LayupKinematics(P, ConstantDrive())

    def exits(mu: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        fr = {'guide_friction': {'mu': mu, 's0': 0.0, 'v0': 1.0, 'h': 0.002}}
        res = run(scene(fr, sheets={'interval': 0.0617, 'jitter': 0.0}), 120.0)
        ex = events(res, 'leaf_exit')
        en = events(res, 'leaf_enter')
        t_in = dict(zip(en['sheet'].tolist(), en['t'].tolist(), strict=True))
        transit = ex['t'] - np.array([t_in[i] for i in ex['sheet'].tolist()])
        return kin.chute(ex['t'], ex['sheet'] % 2)['phi'], ex['value'], transit, res.summary

    phi, speed, transit, summary = exits(0.5)

    def near(angle: float, width: float = math.radians(5.0)) -> np.ndarray:
        return np.abs(np.remainder(phi - angle + math.pi, TAU) - math.pi) <= width

    e0, e1 = EXT[0].phi, EXT[1].phi
    extreme = near(e0) | near(e1)
    mid = near(0.5 * (e0 + e1)) | near(0.5 * (e1 + e0 + TAU))
    assert extreme.sum() > 50 and mid.sum() > 50
    assert speed[extreme].mean() < speed[mid].mean() - 0.05
    assert transit[extreme].mean() > transit[mid].mean() + 0.005
    by_phase = np.array(summary.exit_speed_by_phase.mean, dtype=float)
    slowest = math.radians(10.0 * int(np.argmin(by_phase)) + 5.0)
    before = [np.remainder(e - slowest, TAU) for e in (e0, e1)]
    assert min(before) <= math.radians(60.0)
    assert summary.guide_friction.sticks == 0
    _, speed0, transit0, _ = exits(0.0)
    assert speed.mean() < speed0.mean() - 0.3 and transit.mean() > transit0.mean() + 0.02


def test_guide_friction_stick_slip_events_in_the_line() -> None:
    fr = {'guide_friction': {'mu': 4.0, 's0': 0.0, 'v0': 0.5, 'h': 0.002}}
    res = run(scene(fr, sheets={'jitter': 0.3}), 20.0)
    st = events(res, 'leaf_stick')
    sl = events(res, 'leaf_slip')
    assert st.size > 10 and 0 < st.size - sl.size <= 6  # the last few are still held at the end
    ex = events(res, 'leaf_exit')['sheet']
    for i in ex:
        assert (st['sheet'] == i).sum() == (sl['sheet'] == i).sum()  # every exited leaf slipped off each stick
    for i in np.unique(st['sheet'])[:20]:
        assert (sl['t'][sl['sheet'] == i] > st['t'][st['sheet'] == i][:1]).all()
        assert st['cycle'][st['sheet'] == i][0] == math.floor(st['t'][st['sheet'] == i][0] / 2.0)
    assert res.summary.guide_friction.sticks == st.size


def test_belts_win_over_guide_friction(monkeypatch: pytest.MonkeyPatch) -> None:
    _forbid(monkeypatch, guide_friction)
    a = run(scene({**BELTS, **FRICTION, **FLIGHT}), 10.0)
    b = run(scene({**BELTS, **FLIGHT}), 10.0)
    assert a.events.tobytes() == b.events.tobytes()


def test_guide_friction_geometry_is_checked() -> None:
    with pytest.raises(ParameterError) as exc:
        run(scene({'guide_friction': {'mu': 0.5, 's0': 0.95, 'v0': 1.0, 'h': 0.002}}), 1.0)
    assert exc.value.key == 'effects.guide_friction.s0'


# ---------------------------------------------------------------------------- effects run only when listed


def _forbid(monkeypatch: pytest.MonkeyPatch, module: Any) -> None:
    def boom(*_a: Any, **_k: Any) -> None:
        raise AssertionError(f'{module.__name__} called but not listed')

    for name, obj in vars(module).items():
        if inspect.isfunction(obj) and obj.__module__ == module.__name__:
            monkeypatch.setattr(module, name, boom)


@pytest.mark.parametrize('listed', [{}, BELTS, FLIGHT, DAMAGE, FRICTION, {**FRICTION, **FLIGHT}])
def test_effects_not_listed_are_never_called(monkeypatch: pytest.MonkeyPatch, listed: dict[str, Any]) -> None:
    names = {
        'chute_belts': chute_belts,
        'leaf_flight': leaf_flight,
        'leaf_damage': leaf_damage,
        'guide_friction': guide_friction,
        'faults': faults,
    }
    for name, mod in names.items():
        if name not in listed:
            _forbid(monkeypatch, mod)
    res = run(scene(listed), 5.0, t_samples=sample_times(5.0, 20.0))
    assert events(res, 'leaf_exit').size > 50
    if 'leaf_flight' not in listed:
        assert res.summary.leaves_landed == 0 and res.summary.landing is None
    if 'chute_belts' not in listed:
        assert 'belts' not in res.samples and res.constraints == []


# ---------------------------------------------------------------------------- faults


def _faults(**over: float) -> dict[str, Any]:
    return {'faults': {**FAULTS0, **over}}


def test_missing_double_and_late_leaves() -> None:
    base = run(scene({**BELTS, **FLIGHT}), 20.0)
    n = events(base, 'leaf_enter').size
    gone = run(scene({**BELTS, **FLIGHT, **_faults(p_missing=1.0)}), 20.0)
    assert events(gone, 'leaf_enter').size == 0 and events(gone, 'fault_missing').size == n
    dbl = run(scene({**BELTS, **FLIGHT, **_faults(p_double=1.0)}), 20.0)
    e2 = events(dbl, 'leaf_enter')
    assert e2.size == 2 * n and events(dbl, 'fault_double').size == n
    assert np.array_equal(e2['t'][::2], e2['t'][1::2]) and np.array_equal(e2['sheet'][::2], e2['sheet'][1::2])
    assert events(dbl, 'leaf_landed').size == 2 * events(base, 'leaf_landed').size
    late = run(scene({**BELTS, **_faults(p_late=1.0, late_delay=0.01)}), 20.0)
    e3 = events(late, 'leaf_enter')
    e0 = events(base, 'leaf_enter')
    k = min(e3.size, e0.size)
    assert_allclose(e3['t'][:k], e0['t'][:k] + 0.01, atol=1e-13)
    fl = events(late, 'fault_late')
    assert_allclose(fl['t'], e0['t'], atol=0) and (fl['value'] == 0.01).all()


def test_fault_draws_are_seeded() -> None:
    f = _faults(p_missing=0.2, p_double=0.1, p_late=0.1, late_delay=0.02)
    a = run(scene({**BELTS, **f}, seed=3), 20.0)
    b = run(scene({**BELTS, **f}, seed=3), 20.0)
    c = run(scene({**BELTS, **f}, seed=4), 20.0)
    assert a.events.tobytes() == b.events.tobytes()
    assert events(a, 'fault_missing')['sheet'].tolist() != events(c, 'fault_missing')['sheet'].tolist()


def test_belt_slowdowns_delay_the_exits_exactly() -> None:
    f = _faults(p_slowdown=0.5, slowdown_factor=0.4, slowdown_duration=0.7)
    res = run(scene({**BELTS, **f}, sheets={'jitter': 0.2}, seed=11), 40.0, t_samples=sample_times(40.0, 50.0))
    starts = events(res, 'belt_slowdown_start')
    ends = events(res, 'belt_slowdown_end')
    assert starts.size > 3 and (starts['value'] == 0.4).all()
    brk = sorted(starts['t'].tolist() + ends['t'].tolist())

    def factor(t: float) -> float:
        i = np.searchsorted(starts['t'], t, side='right') - 1
        return 0.4 if i >= 0 and (i >= ends.size or t < ends['t'][i]) else 1.0

    enter = events(res, 'leaf_enter')
    t_in = dict(zip(enter['sheet'].tolist(), enter['t'].tolist(), strict=True))
    slowed = 0
    for row in events(res, 'leaf_exit'):
        i = int(row['sheet'])
        a, b = t_in[i], float(row['t'])
        pts = [x for x in brk if a < x < b]
        travel = sum(2.8 * factor(0.5 * (u + v)) * (v - u) for u, v in pairwise([a, *pts, b]))
        assert travel == pytest.approx(P.l5 if i % 2 else P.l3, abs=1e-12)
        slowed += bool(pts) or factor(a) < 1.0
        pt = LayupModel(P).point(OMEGA * b)
        v = pt.vE if i % 2 else pt.vC
        assert row['value'] == pytest.approx(math.hypot(v, 2.8 * factor(b)), rel=1e-12)
    assert slowed > 5
    belt = res.samples['belts']
    assert belt.names == ('chute_belts',)
    # position is the integral of velocity (trapezoid on the 50 Hz grid, exact between slow-downs)
    dv = np.diff(belt.position[:, 0]) - 0.5 * (belt.velocity[1:, 0] + belt.velocity[:-1, 0]) * 0.02
    assert np.abs(dv).max() <= 2.8 * 0.6 * 0.02 + 1e-12
    assert (np.diff(belt.position[:, 0]) > 0).all()


# ---------------------------------------------------------------------------- samples


def test_samples() -> None:
    t = sample_times(6.0, 25.0)
    res = run(scene({**BELTS}), 6.0, t_samples=t)
    cd = res.samples['drive']
    assert cd.names == ('layup_crank', 'transporter3', 'transporter4')
    assert cd.position.shape == cd.velocity.shape == (t.size, 3) and cd.effort is None
    assert ((cd.position[:, 0] >= 0.0) & (cd.position[:, 0] < TAU)).all()
    d = np.remainder(cd.position[:, 0] - OMEGA * t + math.pi, TAU) - math.pi
    assert np.abs(d).max() <= 1e-12
    assert_allclose(cd.velocity[:, 0], OMEGA)
    st = LayupModel(P).arrays(OMEGA * t)
    assert_allclose(cd.position[:, 1], st.theta3, atol=1e-12)
    assert_allclose(cd.velocity[:, 2], st.omega5, atol=1e-12)
    belt = res.samples['belts']
    assert_allclose(belt.position[:, 0], 2.8 * t, atol=1e-12)
    assert_allclose(belt.velocity[:, 0], 2.8)
    assert all(np.isfinite(a).all() for a in (cd.position, cd.velocity, belt.position, belt.velocity))


def test_samples_follow_a_ramp_drive() -> None:
    drive = RampDrive(2.0)
    t = sample_times(4.0, 10.0)
    res = run(scene({**BELTS}, drive={'profile': 'ramp', 't_ramp': 2.0}), 4.0, drive=drive, t_samples=t)
    cd = res.samples['drive']
    assert_allclose(cd.velocity[:, 0], OMEGA * drive.rate(t))
    assert_allclose(res.samples['belts'].position[:, 0], 2.8 * drive.theta(t), atol=1e-12)


def test_no_samples_when_the_grid_is_empty() -> None:
    assert run(scene({**BELTS}), 2.0).samples == {}


# ---------------------------------------------------------------------------- determinism, line, cost


def test_determinism_bit_for_bit() -> None:
    eff = {**BELTS, **FLIGHT, **DAMAGE}
    a = run(scene(eff, seed=7), 60.0)
    b = run(scene(eff, seed=7), 60.0)
    c = run(scene(eff, seed=8), 60.0)
    assert a.events.tobytes() == b.events.tobytes()
    assert json.dumps(a.summary.as_json()) == json.dumps(b.summary.as_json())
    ta, tc = events(a, 'leaf_enter')['t'], events(c, 'leaf_enter')['t']
    assert not np.array_equal(ta[:100], tc[:100])
    fr = {**FRICTION, **FLIGHT}
    assert run(scene(fr, seed=7), 20.0).events.tobytes() == run(scene(fr, seed=7), 20.0).events.tobytes()


def test_through_the_line_orchestrator() -> None:
    sc = scene({**BELTS, **FLIGHT, **DAMAGE}, rate=10.0)
    res = simulate(sc, 30.0)
    s = res.summary()
    json.dumps(s.as_json(), allow_nan=False)
    assert s.cycles == 15
    assert s.sheets_counted == res.parts['layup'].leaves_landed > 400
    assert 'landing_cv' in s.as_json()
    assert np.isfinite(res.events['t']).all() and np.isfinite(res.events['value']).all()
    assert (np.diff(res.events['t']) >= 0).all()
    assert res.constraint('chute_speed').margin.size == res.parts['layup'].leaves_exited


def test_events_end_with_the_run() -> None:
    res = run(scene({**BELTS, **FLIGHT}), 5.0)
    assert res.events['t'].max() <= 5.0
    s = res.summary
    assert s.leaves > s.leaves_exited > s.leaves_landed  # some still on a chute / in the air


@pytest.mark.parametrize('effects', [{**BELTS, **FLIGHT, **DAMAGE}, {**FRICTION, **FLIGHT}, {**FLIGHT}])
def test_a_run_without_leaves(effects: dict[str, Any]) -> None:
    res = run(scene(effects, sheets={'phase': 0.5}), 0.1, t_samples=np.array([0.0, 0.05]))
    assert res.events.size == 0 and res.summary.leaves == 0
    assert res.summary.min_exit_speed is None
    json.dumps(res.summary.as_json(), allow_nan=False)
    assert res.samples['drive'].position.shape == (2, 3)


def test_one_hour_with_belts() -> None:
    """An hour of the layup with belts, flight and damage lays every leaf (what it costs is measured side by
    side with the other effects by bench/bench_line.py, not here: a timed test fails on a loaded machine)."""
    res = run(scene({**BELTS, **FLIGHT, **DAMAGE}), 3600.0)
    assert res.summary.leaves == 57601


def test_one_hour_with_guide_friction() -> None:
    """An hour of the layup with guide friction (its cost: bench/bench_line.py)."""
    res = run(scene({**FRICTION, **FLIGHT, **DAMAGE}), 3600.0)
    assert res.summary.leaves_exited > 57500
