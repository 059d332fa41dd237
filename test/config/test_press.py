"""One press speed (``press.n_c`` sets the cylinder and the knife), and values a scene would never read."""

from __future__ import annotations

from pathlib import Path

import pytest

from folder_line.config.scenes import apply_overrides, load_scene, scene_mapping, write_scene
from folder_line.core.line.scene import parse_scene
from folder_line.core.mechanisms.cyclogram import cycle_timing
from folder_line.errors import ParameterError


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / 'scene.yaml'
    path.write_text(text)
    return path


FOLDER = """
name: tiny
machines:
  knife: {}
  cyclogram: {}
  feed_transporter: {V_tr: 9.5}
"""


def test_press_speed_sets_cylinder_and_knife_and_the_cycle_follows() -> None:
    scene = load_scene('folder', {'press.n_c': 30000})
    assert scene.machine('cyclogram').n_c == 30000.0
    assert scene.machine('knife').n_k == 60000.0
    tm = cycle_timing(scene.machine('cyclogram'), scene.machine('knife'))
    cycle = tm.T
    assert cycle == pytest.approx(3600.0 / 60000.0, rel=1e-15)  # one signature per knife turn
    assert tm.L_c_error == pytest.approx(0.0, abs=1e-4)  # V_d T = pi R = L_a at any press speed
    # V_tr,min = L_feed / ((1 - reserve) t_fw), t_fw = T (1 - dwell) - t_knife: the knife window scales with 1/n_k
    base = cycle_timing(load_scene('folder').machine('cyclogram'), load_scene('folder').machine('knife'))
    assert tm.V_tr_min == pytest.approx(base.V_tr_min * 60000.0 / 50000.0, rel=1e-12)
    assert tm.V_tr_min == pytest.approx(11.115, abs=5e-4)  # the hand bisection at 60000 rev/h


def test_a_knife_speed_alone_is_refused_naming_both_keys() -> None:
    with pytest.raises(ParameterError) as info:
        load_scene('folder', {'knife.n_k': 60000})
    text = str(info.value)
    assert text.startswith('knife.n_k=60000') and 'cyclogram.n_c=25000.0' in text and 'press.n_c' in text
    with pytest.raises(ParameterError, match=r'knife.n_k=50000.0: must be 2 x cyclogram.n_c=30000'):
        load_scene('folder', {'cyclogram.n_c': 30000})
    load_scene('folder', {'knife.n_k': 60000, 'cyclogram.n_c': 30000})  # a consistent pair is fine
    # rounding is not an inconsistency, a part in a million is
    load_scene('folder', {'knife.n_k': 50000 * (1 + 1e-12)})
    with pytest.raises(ParameterError, match=r'knife.n_k'):
        load_scene('folder', {'knife.n_k': 50000 * (1 + 1e-6)})


def test_press_speed_is_checked_and_needs_a_folder() -> None:
    for bad in (0.0, 100001.0, 'fast'):
        with pytest.raises(ParameterError) as info:
            load_scene('folder', {'press.n_c': bad})
        assert info.value.key == 'press.n_c'
    with pytest.raises(ParameterError, match=r"press.n_c=20000: scene 'layup' has no folder"):
        load_scene('layup', {'press.n_c': 20000})
    with pytest.raises(ParameterError, match='unknown press key'):
        load_scene('folder', {'press.n_k': 20000})


def test_apply_overrides_takes_the_press_speed_as_a_sweep_does() -> None:
    base = scene_mapping('folder')
    for n_c in (20000.0, 30000.0):
        scene = parse_scene(apply_overrides(base, {'press.n_c': n_c}))
        assert (scene.machine('cyclogram').n_c, scene.machine('knife').n_k) == (n_c, 2 * n_c)
    assert base['machines']['knife']['n_k'] == 50000.0  # the base is not changed


def test_a_scene_file_may_give_the_press_speed_once(tmp_path: Path) -> None:
    scene = load_scene(_write(tmp_path, FOLDER + 'press: {n_c: 30000}\n'))
    assert (scene.machine('cyclogram').n_c, scene.machine('knife').n_k) == (30000.0, 60000.0)
    # --set goes last
    assert (
        load_scene(_write(tmp_path, FOLDER + 'press: {n_c: 30000}\n'), {'press.n_c': 20000}).machine('knife').n_k
        == 40000.0
    )
    twice = FOLDER.replace('knife: {}', 'knife: {n_k: 60000}') + 'press: {n_c: 30000}\n'
    with pytest.raises(ParameterError, match=r'knife.n_k=60000: the scene gives press.n_c=30000 as well'):
        load_scene(_write(tmp_path, twice))
    with pytest.raises(ParameterError, match=r'press.n_k=1: unknown press key'):
        load_scene(_write(tmp_path, FOLDER + 'press: {n_k: 1}\n'))


# --------------------------------------------------------------------------- values that do nothing


def test_sheet_jitter_on_the_folder_is_an_error_naming_what_to_use() -> None:
    with pytest.raises(ParameterError) as info:
        load_scene('folder', {'sheets.jitter': 0.3})
    assert info.value.key == 'sheets.jitter' and info.value.value == 0.3
    assert "does nothing in scene 'folder'" in info.value.reason and 'arrival_jitter' in info.value.reason
    with pytest.raises(ParameterError, match=r'sheets.interval=0.1: does nothing'):
        load_scene('folder', {'sheets.interval': 0.1})
    assert load_scene('layup', {'sheets.jitter': 0.3}).sheets.jitter == 0.3  # the layup reads it
    load_scene('folder', {'sheets.jitter': 0.5})  # the default: what the folder gets anyway


def test_only_values_the_user_gave_count(tmp_path: Path) -> None:
    with pytest.raises(ParameterError, match=r'sheets.jitter=0.3: does nothing'):
        load_scene(_write(tmp_path, FOLDER + 'sheets: {jitter: 0.3}\n'))
    load_scene(_write(tmp_path, FOLDER))  # config/sheets.yaml's jitter is merged in and harmless
    # a merged scene written by run carries every default, and loads again
    written = tmp_path / 'written.yaml'
    for name in ('folder', 'line', 'layup_no_belts'):
        write_scene(written, load_scene(name))
        assert load_scene(written) == load_scene(name)
        written.unlink()


@pytest.mark.parametrize(
    ('scene', 'key', 'value', 'words'),
    [
        ('line', 'drive.t_brake', 2.0, 'motor_dynamics'),
        ('line', 'drive.profile', 'ramp', 'motor_dynamics'),
        ('layup_no_belts', 'layup.v_tr', 4.0, 'chute_belts'),
    ],
)
def test_other_values_a_scene_never_reads_are_errors(scene: str, key: str, value: object, words: str) -> None:
    with pytest.raises(ParameterError) as info:
        load_scene(scene, {key: value})
    assert info.value.key == key and words in info.value.reason
    with pytest.raises(ParameterError) as again:  # a sweep's point is refused the same way
        apply_overrides(scene_mapping(scene), {key: value})
    assert str(again.value) == str(info.value)


def test_delivery_friction_and_the_container_need_their_effects(tmp_path: Path) -> None:
    no_friction = FOLDER + '  delivery: {f_A: 0.3}\n  delivery_chain: {}\n'
    with pytest.raises(ParameterError, match=r'delivery.f_A=0.3: does nothing .*chain_friction'):
        load_scene(_write(tmp_path, no_friction))
    load_scene('folder', {'delivery.f_A': 0.3})  # the folder lists chain_friction
    no_flight = 'name: l\nmachines:\n  layup: {}\n  container: {bins: 10}\n'
    with pytest.raises(ParameterError, match=r'container.bins=10: does nothing .*leaf_flight'):
        load_scene(_write(tmp_path, no_flight))
