"""Live tuning in the line model: a change acts from its effective time on, exactly, and nothing before it."""

from __future__ import annotations

import numpy as np
import pytest

from folder_line.config.scenes import load_scene
from folder_line.core.line.model import LineModel
from folder_line.core.line.tuning import Tuning, belt_steps, check_tuning, command_of, tuning_text
from folder_line.core.mechanisms.belt import BeltPhase, combine_factors
from folder_line.core.mechanisms.drive import Command, ConstantDrive, target_rate
from folder_line.core.mechanisms.pile import T_LOWER
from folder_line.core.supervision.commands import ActingState
from folder_line.core.supervision.grid import CheckGrid
from folder_line.core.supervision.settings import SPEED_REACHED
from folder_line.core.types.events import EVENT_KINDS
from folder_line.errors import ParameterError

T_E = 4.0


@pytest.fixture(scope='module')
def folder() -> tuple[LineModel, LineModel]:
    scene = load_scene('folder')
    return LineModel(scene, 8.0), LineModel(scene, 8.0, [Tuning(T_E, 'feed_transporter.V_tr', 8.0)])


def test_nothing_changes_before_the_effective_time(folder: tuple[LineModel, LineModel]) -> None:
    plain, tuned = folder
    before = plain.events[plain.events['t'] < T_E]
    assert np.array_equal(before, tuned.events[tuned.events['t'] < T_E])
    t = np.linspace(0.0, T_E, 801)
    assert np.array_equal(plain.sample('feed', t).position, tuned.sample('feed', t).position)


def test_the_feed_belt_runs_at_the_new_speed_from_then_on(folder: tuple[LineModel, LineModel]) -> None:
    plain, tuned = folder
    t = np.array([T_E - 1e-6, T_E, T_E + 1e-6, 6.0])
    js0, js1 = plain.sample('feed', t), tuned.sample('feed', t)
    col = js1.names.index('feed_belt')
    v0, v1 = js0.velocity[:, col], js1.velocity[:, col]
    assert v1[0] == v0[0]
    np.testing.assert_allclose(v1[1:], v0[1:] * 8.0 / 9.3, rtol=1e-12)
    # travel is continuous at the change and grows at the new speed after it (constant drive: V t)
    x = js1.position[:, col]
    np.testing.assert_allclose(x[2] - x[0], 9.3e-6 + 8.0e-6, rtol=1e-6)
    np.testing.assert_allclose(x[3] - x[1], 8.0 * (6.0 - T_E), rtol=1e-12)


def test_a_slower_feed_violates_the_feed_window_only_after_the_change(folder: tuple[LineModel, LineModel]) -> None:
    plain, tuned = folder
    assert not any(c.violated.any() for c in plain.constraints)
    feed = next(c for c in tuned.constraints if c.name == 'feed_window')
    bad = feed.t[feed.violated]
    assert bad.size and bad.min() > T_E
    # V_tr,min = 9.2625 m/s: 8 m/s misses the deadline in every cycle fed wholly after the change
    assert np.all(feed.violated[feed.t > T_E + 0.2])


def test_combined_factors_are_the_product_of_slowdowns_and_steps() -> None:
    ts, te, f = combine_factors([1.0, 3.0], [2.0, 5.0], [0.5, 0.8], [(2.5, 1.25), (4.0, 0.9)])
    drive = ConstantDrive()
    phase = BeltPhase(drive, 10.0, ts, te, f)
    grid = np.linspace(0.0, 9.99, 2000)

    def expected(t: float) -> float:
        slow = 0.5 if 1.0 <= t < 2.0 else (0.8 if 3.0 <= t < 5.0 else 1.0)
        step = 1.0 if t < 2.5 else (1.25 if t < 4.0 else 0.9)
        return slow * step

    np.testing.assert_allclose(phase.factor(grid), [expected(t) for t in grid], rtol=1e-15)
    # the phase is the integral of the factor (constant drive): trapezoid on a fine grid
    fine = np.linspace(0.0, 9.99, 200_001)
    integral = np.concatenate(([0.0], np.cumsum(np.diff(fine) * np.array([expected(t) for t in fine[:-1]]))))
    np.testing.assert_allclose(phase.at(fine[::1000]), integral[::1000], atol=1e-4)
    np.testing.assert_allclose(phase.theta_of(phase.at(grid)), grid, atol=1e-12)


def test_no_step_leaves_the_belt_untouched() -> None:
    assert belt_steps([Tuning(1.0, 'pile.t_lower', 0.05)], 'feed_transporter.V_tr', 9.3) == []


def test_the_pile_lowers_each_sheet_over_the_time_in_force_at_its_count() -> None:
    scene = load_scene('folder')
    tuned = LineModel(scene, 6.0, [Tuning(3.0, 'pile.t_lower', 0.05)])
    times = tuned.events['t'][tuned.events['kind'] == EVENT_KINDS.index('released_on_pile')]
    h = float(scene.sheets.thickness)
    for t_i, tau in ((float(times[times < 3.0][-1]), T_LOWER), (float(times[times >= 3.0][2]), 0.05)):
        # halfway through its lowering: the sheets lowering then, each at h / its own tau
        t = t_i + tau / 2
        taus = np.where(times >= 3.0, 0.05, T_LOWER)
        lowering = (times <= t) & (times + taus > t)
        expected = -float(np.sum(h / taus[lowering]))
        assert tuned.sample('counter', [t]).velocity[0, 0] == pytest.approx(expected, rel=1e-12)
        # once every sheet up to it has ended its lowering, the table is down by h per sheet
        done = float(np.max(times[times <= t_i] + taus[times <= t_i]))
        if not np.any((times > t_i) & (times <= done)):
            z = tuned.sample('counter', [done]).position[0, 0]
            assert z == pytest.approx(-h * int(np.count_nonzero(times <= t_i)), rel=1e-12)


def test_a_tuning_reads_back_from_its_text_and_the_scene_must_have_it() -> None:
    tu = Tuning(1.5, 'feed_transporter.V_tr', 9.123456789)
    assert command_of(1.5, tuning_text(tu.key, tu.value)) == tu
    with pytest.raises(ParameterError, match=r'layup.v_tr=3.0: scene .folder. has no layup device'):
        check_tuning(load_scene('folder'), 'layup.v_tr', 3.0)
    with pytest.raises(ParameterError, match='is not tunable'):
        check_tuning(load_scene('folder'), 'knife.n_k', 3.0)
    with pytest.raises(ParameterError, match=r'must be in \[0.001, 1000\] m/s'):
        Tuning(1.0, 'feed_transporter.V_tr', 0.0)


def test_the_press_speed_ramps_to_its_setting_and_an_unhold_ends_there() -> None:
    scene = load_scene('folder')
    n_c = float(scene.machine('cyclogram').n_c)
    speed = 0.8
    commands = [Tuning(2.0, 'press.n_c', speed * n_c), Command(4.0, 'hold'), Command(6.0, 'unhold')]
    model = LineModel(scene, 10.0, commands)
    plain = LineModel(scene, 10.0)
    t = np.linspace(0.0, 2.0, 401)
    assert np.array_equal(model.drive.theta(t), plain.drive.theta(t))  # nothing before it
    assert float(model.drive.rate(np.array(3.9))) == pytest.approx(speed, abs=1e-12)  # ramped down by then
    np.testing.assert_array_equal(target_rate(model.drive, np.array([1.0, 3.0, 5.0, 9.0])), [1.0, speed, 0.0, speed])
    # the knife cycles at the setting: a cycle lasts 1 / 0.8 of nominal in line time
    b1 = model.next_cycle_boundary(3.0)
    b2 = model.next_cycle_boundary(b1)
    p1 = plain.next_cycle_boundary(3.0)
    assert b2 - b1 == pytest.approx((plain.next_cycle_boundary(p1) - p1) / speed, rel=1e-9)
    # UNHOLDING ends when the drive reaches the speed set (to speed_reached), not nominal, which it never reaches
    grid = CheckGrid(0.005)
    acting = ActingState(grid, SPEED_REACHED, 6.0)
    end = acting.completion('UNHOLDING', 9.0, lambda: model.drive)
    assert end is not None
    assert float(model.drive.rate(np.array(end))) >= SPEED_REACHED * speed
    assert float(model.drive.rate(np.array(end - 0.005))) < SPEED_REACHED * speed
    assert float(np.max(model.drive.rate(np.linspace(6.0, 10.0, 801)))) == pytest.approx(speed, abs=1e-12)


def test_a_press_speed_change_leaves_a_ramp_profile_bit_for_bit_before_it() -> None:
    """The drive is the profile's own until the first change of speed (not the ramp generator from t = 0)."""
    scene = load_scene('folder', {'drive.profile': 'ramp', 'drive.t_ramp': 1.5})
    n_c = float(scene.machine('cyclogram').n_c)
    plain = LineModel(scene, 4.0)
    tuned = LineModel(scene, 4.0, [Tuning(2.0, 'press.n_c', 0.9 * n_c)])
    assert np.array_equal(tuned.events[tuned.events['t'] < 2.0], plain.events[plain.events['t'] < 2.0])
    t = np.linspace(0.0, 2.0, 801)
    assert np.array_equal(tuned.drive.theta(t), plain.drive.theta(t))
