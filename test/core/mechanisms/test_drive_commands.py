"""Supervisor commands on the master drive: the ramp generator (closed forms, inverse, causality)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from folder_line.config.params import config_dir, read_yaml_mapping
from folder_line.core.line.scene import parse_scene
from folder_line.core.mechanisms.drive import (
    COMMAND_KINDS,
    Command,
    ConstantDrive,
    Drive,
    DriveSpec,
    PiecewiseLinearDrive,
    RampDrive,
    SplicedDrive,
    check_commands,
    commanded_drive,
    ramp_generator,
    running_switches,
    theta_rate,
)
from folder_line.errors import ParameterError

CONST = DriveSpec('constant', t_brake=0.5)
RAMP = DriveSpec('ramp', t_ramp=2.0, t_brake=0.8)


def _cmds(*pairs: tuple[float, str]) -> tuple[Command, ...]:
    return tuple(Command(t, k) for t, k in pairs)


# ------------------------------------------------------------------ commands and spec


@pytest.mark.parametrize(
    't, kind, key',
    [
        (-1.0, 'hold', 'command.t'),
        (math.nan, 'hold', 'command.t'),
        (math.inf, 'stop', 'command.t'),
        (1.0, 'pause', 'command.kind'),
        ('1', 'hold', 'command.t'),
    ],
)
def test_bad_commands_name_the_key(t: Any, kind: str, key: str) -> None:
    with pytest.raises(ParameterError) as exc:
        Command(t, kind)
    assert exc.value.key == key


def test_commands_must_be_sorted_and_be_commands() -> None:
    with pytest.raises(ParameterError, match='sorted'):
        check_commands(_cmds((2.0, 'hold'), (1.0, 'unhold')))
    with pytest.raises(ParameterError, match='sorted'):
        commanded_drive(CONST, _cmds((2.0, 'hold'), (1.0, 'unhold')))
    with pytest.raises(ParameterError, match='Command'):
        check_commands([(1.0, 'hold')])  # type: ignore[list-item]
    assert check_commands(_cmds((1.0, 'hold'), (1.0, 'unhold'))) == _cmds((1.0, 'hold'), (1.0, 'unhold'))


def test_running_switches_drop_what_changes_nothing() -> None:
    cmds = _cmds((0.5, 'start'), (1.0, 'hold'), (1.5, 'stop'), (1.5, 'hold'), (2.0, 'unhold'), (3.0, 'start'))
    assert running_switches(cmds) == [(1.0, False), (2.0, True)]
    assert running_switches(()) == []
    assert {c for c in COMMAND_KINDS if Command(0.0, c).running} == {'unhold', 'start'}


def test_drive_spec_t_brake_and_restart() -> None:
    assert DriveSpec('constant').t_brake == 0.5
    assert DriveSpec('constant').t_restart == 0.5  # no ramp of its own: restart at the brake's pace
    assert DriveSpec('constant', t_ramp=2.0).t_restart == 2.0
    assert RAMP.t_restart == 2.0
    for bad in (0.0, -1.0, math.nan):
        with pytest.raises(ParameterError) as exc:
            DriveSpec('constant', t_brake=bad)
        assert exc.value.key == 'drive.t_brake'
    sections = ['knife', 'cyclogram', 'feed_transporter']
    scene = parse_scene(
        {
            'name': 's',
            'machines': {s: read_yaml_mapping(config_dir() / f'{s}.yaml', s) for s in sections},
            'sheets': read_yaml_mapping(config_dir() / 'sheets.yaml', 'sheets'),
            'drive': {'profile': 'constant', 't_brake': 1.25},
        }
    )
    assert scene.drive.t_brake == 1.25


def test_no_effective_command_keeps_the_profile_drive() -> None:
    assert isinstance(commanded_drive(CONST), ConstantDrive)
    assert isinstance(commanded_drive(CONST, _cmds((1.0, 'start'), (2.0, 'unhold'))), ConstantDrive)
    r = commanded_drive(RAMP, ())
    assert isinstance(r, RampDrive) and r.t_ramp == 2.0


# ------------------------------------------------------------------ closed forms


def test_hold_then_unhold_closed_form_constant_profile() -> None:
    th, tb, tu = 3.0, CONST.t_brake, 7.0
    d = commanded_drive(CONST, _cmds((th, 'hold'), (tu, 'unhold')))
    assert isinstance(d, SplicedDrive) and isinstance(d, Drive)
    t = np.linspace(0.0, 12.0, 24001)
    tau = t - th
    sig = t - tu
    up = CONST.t_restart
    theta_hold = th + tb / 2.0
    expect = np.select(
        [t < th, t < th + tb, t < tu, t < tu + up],
        [t, th + tau - tau * tau / (2.0 * tb), theta_hold, theta_hold + sig * sig / (2.0 * up)],
        theta_hold + up / 2.0 + (t - tu - up),
    )
    lam = np.select([t < th, t < th + tb, t < tu, t < tu + up], [1.0, 1.0 - tau / tb, 0.0, sig / up], 1.0)
    np.testing.assert_allclose(d.theta(t), expect, rtol=0, atol=1e-13)
    np.testing.assert_allclose(d.rate(t), lam, rtol=0, atol=1e-13)
    acc = np.select([t < th, t < th + tb, t < tu, t < tu + up], [0.0, -1.0 / tb, 0.0, 1.0 / up], 0.0)
    assert np.array_equal(d.rate_dot(t), acc)
    # held: Θ stands still exactly; the plateau's phase maps to the earliest time
    held = (t >= th + tb) & (t < tu)
    assert np.all(d.theta(t[held]) == d.theta(th + tb)) and np.all(d.rate(t[held]) == 0.0)
    assert float(d.time_of(theta_hold)) == pytest.approx(th + tb, abs=1e-12)
    # before the command: the constant drive itself, bit for bit
    early = t < th
    assert np.array_equal(d.theta(t[early]), t[early]) and np.array_equal(d.time_of(t[early]), t[early])


def test_command_mid_ramp_continues_from_the_current_speed() -> None:
    th, x = 2.0, 0.3  # unhold 0.3 s into a 0.5 s ramp down: λ = 0.4 there
    tb, up = CONST.t_brake, CONST.t_restart
    d = commanded_drive(CONST, _cmds((th, 'hold'), (th + x, 'unhold')))
    lam_u = 1.0 - x / tb
    theta_u = th + x - x * x / (2.0 * tb)
    t_back = th + x + (1.0 - lam_u) * up
    assert float(d.rate(th + x)) == pytest.approx(lam_u, abs=1e-15)
    assert float(d.theta(th + x)) == pytest.approx(theta_u, abs=1e-15)
    s = 0.1
    assert float(d.rate(th + x + s)) == pytest.approx(lam_u + s / up, abs=1e-15)
    assert float(d.theta(th + x + s)) == pytest.approx(theta_u + lam_u * s + s * s / (2 * up), abs=1e-14)
    theta_back = theta_u + lam_u * (t_back - th - x) + (t_back - th - x) ** 2 / (2 * up)
    assert float(d.theta(t_back + 1.0)) == pytest.approx(theta_back + 1.0, abs=1e-13)
    assert float(d.rate(t_back)) == 1.0 and float(d.rate_dot(t_back)) == 0.0


def test_hold_during_the_spin_up_of_the_ramp_profile() -> None:
    th = 1.0  # λ = 0.5 then; brake at 1/0.8 per s: standstill 0.4 s later
    d = commanded_drive(RAMP, _cmds((th, 'hold'), (4.0, 'start')))
    base = RampDrive(2.0)
    t = np.linspace(0.0, th, 1001)[:-1]
    assert np.array_equal(d.theta(t), base.theta(t)) and np.array_equal(d.rate(t), base.rate(t))
    theta_h = th * th / 4.0
    assert float(d.theta(1.4)) == pytest.approx(theta_h + 0.5 * 0.4 - 0.4**2 / (2 * 0.8), abs=1e-15)
    assert float(d.rate(1.4)) == 0.0 and float(d.theta(3.9)) == float(d.theta(1.4))
    assert float(d.rate(5.0)) == pytest.approx(0.5, abs=1e-15)  # restart at the profile's ramp rate 1/t_ramp
    assert float(d.rate(6.0)) == 1.0


def test_duplicates_are_idempotent_bit_for_bit() -> None:
    a = commanded_drive(CONST, _cmds((1.0, 'hold'), (3.0, 'unhold')))
    b = commanded_drive(CONST, _cmds((1.0, 'hold'), (1.2, 'hold'), (2.0, 'stop'), (3.0, 'unhold'), (3.1, 'start')))
    t = np.linspace(0.0, 8.0, 8001)
    assert a.theta(t).tobytes() == b.theta(t).tobytes() and a.rate(t).tobytes() == b.rate(t).tobytes()


def test_held_forever_never_reaches_a_later_phase() -> None:
    d = commanded_drive(CONST, _cmds((1.0, 'stop')))
    end = float(d.theta(100.0))
    assert end == 1.25 and float(d.rate(1e6)) == 0.0 and float(d.rate_dot(1e6)) == 0.0
    assert float(d.time_of(end)) == 1.5
    assert float(d.time_of(end + 1e-9)) == math.inf  # never: callers only ask for phases the run reaches
    with pytest.raises(ParameterError):
        d.time_of(math.nan)


def test_piecewise_linear_drive_knots_are_checked() -> None:
    with pytest.raises(ValueError):
        PiecewiseLinearDrive([0.0, 0.0], [0.0, 0.0], [1.0, 1.0], [0.0, 0.0])
    with pytest.raises(ValueError):
        PiecewiseLinearDrive([0.0, 1.0], [0.0, -1.0], [1.0, 1.0], [0.0, 0.0])
    with pytest.raises(ValueError):
        PiecewiseLinearDrive([0.0], [0.0], [math.nan], [0.0])
    with pytest.raises(ValueError):
        PiecewiseLinearDrive([0.0, 1.0], [0.0], [1.0], [0.0])
    # the generator from the start of a run: λ 0 -> 1 in 2 s is the ramp profile's closed form
    g = ramp_generator(0.0, 0.0, 0.0, True, [], 2.0, 0.5)
    t = np.linspace(0.0, 5.0, 501)
    np.testing.assert_allclose(g.theta(t), RampDrive(2.0).theta(t), rtol=0, atol=1e-15)
    np.testing.assert_allclose(g.time_of(g.theta(t)), t, rtol=0, atol=1e-12)


# ------------------------------------------------------------------ properties over command sequences

_kinds = st.sampled_from(COMMAND_KINDS)
_sequences = st.lists(st.tuples(st.floats(0.0, 20.0), _kinds), min_size=1, max_size=8).map(
    lambda xs: tuple(Command(t, k) for t, k in sorted(xs, key=lambda p: p[0]))
)
_specs = st.sampled_from([CONST, RAMP, DriveSpec('constant', t_ramp=0.3, t_brake=2.0)])


@settings(max_examples=150, deadline=None)
@given(spec=_specs, cmds=_sequences, u=st.lists(st.floats(0.0, 1.0), min_size=1, max_size=50))
def test_time_of_inverts_theta(spec: DriveSpec, cmds: tuple[Command, ...], u: list[float]) -> None:
    d = commanded_drive(spec, cmds)
    end = float(d.theta(30.0))
    th = np.asarray(u) * end
    t = d.time_of(th)
    assert np.all(np.isfinite(t)) and np.all(t >= 0.0) and np.all(t <= 30.0 + 1e-12)
    np.testing.assert_allclose(d.theta(t), th, rtol=1e-12, atol=1e-12)
    # earliest time: just before it the phase is below the target (where the drive moves at all)
    before = d.theta(np.maximum(t - 1e-7, 0.0))
    assert np.all(before <= th + 1e-12)
    # and the other way round where the drive moves: time_of(Θ(t)) = t
    ts = np.asarray(u) * 30.0
    moving = d.rate(ts) > 1e-3
    np.testing.assert_allclose(d.time_of(d.theta(ts[moving])), ts[moving], rtol=0, atol=1e-9)


@settings(max_examples=150, deadline=None)
@given(spec=_specs, cmds=_sequences, t=st.lists(st.floats(0.0, 40.0), min_size=2, max_size=60))
def test_continuous_monotone_bounded_and_finite(spec: DriveSpec, cmds: tuple[Command, ...], t: list[float]) -> None:
    d = commanded_drive(spec, cmds)
    tt = np.sort(np.asarray(t))
    th, lam, acc = d.theta(tt), d.rate(tt), d.rate_dot(tt)
    assert np.all(np.isfinite(th)) and np.all(np.isfinite(lam)) and np.all(np.isfinite(acc))
    assert np.all(np.diff(th) >= -1e-13) and np.all((lam >= 0.0) & (lam <= 1.0))
    a, b = theta_rate(d, tt[:1])
    assert a.tobytes() == th[:1].tobytes() and b.tobytes() == lam[:1].tobytes()
    # knots: Θ and λ continuous
    if isinstance(d, SplicedDrive):
        knots = np.asarray(d.tail.t)  # type: ignore[attr-defined]
        for k in knots:
            lo, hi = np.nextafter(k, -np.inf), k
            assert abs(float(d.theta(hi)) - float(d.theta(lo))) < 1e-12
            assert abs(float(d.rate(hi)) - float(d.rate(lo))) < 1e-12
    # derivatives: λ = dΘ/dt, dλ/dt = rate_dot (central differences, away from the knots)
    h = 1e-6
    mid = tt[(tt > h)]
    if isinstance(d, SplicedDrive):  # λ may jump at a knot (a zero-length ramp): no derivative there
        knots = np.asarray(d.tail.t)  # type: ignore[attr-defined]
        mid = mid[np.all(np.abs(mid[:, None] - knots[None, :]) > 2 * h, axis=1)] if knots.size else mid
    np.testing.assert_allclose((d.theta(mid + h) - d.theta(mid - h)) / (2 * h), d.rate(mid), rtol=0, atol=1e-6)


@settings(max_examples=150, deadline=None)
@given(spec=_specs, cmds=_sequences, k=st.integers(0, 7), u=st.lists(st.floats(0.0, 1.0), min_size=1, max_size=40))
def test_a_later_command_leaves_the_past_unchanged_bit_for_bit(
    spec: DriveSpec, cmds: tuple[Command, ...], k: int, u: list[float]
) -> None:
    k = min(k, len(cmds) - 1)
    t_k = cmds[k].t
    early = commanded_drive(spec, cmds[:k])
    late = commanded_drive(spec, cmds)
    t = np.asarray(u) * t_k
    t = t[t < t_k]
    for f in ('theta', 'rate', 'rate_dot'):
        assert getattr(early, f)(t).tobytes() == getattr(late, f)(t).tobytes(), f
    th = early.theta(t)
    assert early.time_of(th).tobytes() == late.time_of(th).tobytes()
