"""Scene files: defaults merged, overrides, and every rejection names what is wrong."""

from __future__ import annotations

from pathlib import Path

import pytest

from folder_line.config.scenes import list_scenes, load_scene, parse_set, scene_mapping
from folder_line.core.effects import EFFECTS
from folder_line.errors import ParameterError

MINIMAL = """
name: tiny
machines:
  knife: {}
  cyclogram: {}
  feed_transporter: {V_tr: 9.5}
"""


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / 'scene.yaml'
    path.write_text(text)
    return path


def test_shipped_scenes_load() -> None:
    assert {'folder', 'layup', 'line'} <= set(list_scenes())
    for name in ('folder', 'layup', 'line'):
        scene = load_scene(name)
        assert scene.name == name
        assert scene.effects  # every shipped scene lists effects


def test_defaults_fill_what_a_scene_omits(tmp_path: Path) -> None:
    scene = load_scene(_write(tmp_path, MINIMAL))
    assert scene.machine('feed_transporter').V_tr == 9.5
    assert scene.machine('knife').n_k == 50000.0  # from config/knife.yaml
    assert scene.effects == {}
    assert scene.drive.profile == 'constant'
    assert scene.has_folder and not scene.has_layup and not scene.has_delivery


def test_set_overrides_machine_effect_and_top_level(tmp_path: Path) -> None:
    text = (
        MINIMAL + 'effects:\n  faults: {p_missing: 0.0, p_double: 0.0, p_late: 0.0, late_delay: 0.0,'
        ' p_slowdown: 0.0, slowdown_factor: 1.0, slowdown_duration: 0.0}\n'
    )
    scene = load_scene(
        _write(tmp_path, text),
        parse_set(['feed_transporter.V_tr=5.833', 'faults.p_missing=0.5', 'seed=42', 'sheets.phase=0.001']),
    )
    assert scene.machine('feed_transporter').V_tr == 5.833
    assert scene.effect('faults').p_missing == 0.5
    assert scene.seed == 42 and scene.sheets.phase == 0.001


@pytest.mark.parametrize(
    ('overrides', 'expected'),
    [
        (['feed_transporter.V_x=1'], 'feed_transporter.V_x'),
        (['layup.R_kr=0.1'], "has no machine 'layup'"),
        (['feed_slip.mu=0.1'], "does not list effect 'feed_slip'"),
        (['gearbox.ratio=2'], 'gearbox.ratio=2: unknown section; a section is a machine (layup, '),
        (['V_tr=9'], 'must be SECTION.KEY'),
        (['feed_transporter.V_tr'], 'must be KEY=VALUE'),
        (['feed_transporter.V_tr=-1'], 'feed_transporter.V_tr=-1'),
        (['feed_transporter.V_tr=.nan'], 'feed_transporter.V_tr=nan'),
        (['knife.n_k=fast'], "knife.n_k='fast'"),
    ],
)
def test_bad_overrides_are_named(tmp_path: Path, overrides: list[str], expected: str) -> None:
    with pytest.raises(ParameterError, match=None) as exc:
        load_scene(_write(tmp_path, MINIMAL), parse_set(overrides))
    assert expected in str(exc.value)


def test_unknown_effect_lists_the_known_ones(tmp_path: Path) -> None:
    with pytest.raises(ParameterError) as exc:
        load_scene(_write(tmp_path, MINIMAL + 'effects: [warp_drive]\n'))
    msg = str(exc.value)
    assert 'warp_drive' in msg
    assert all(name in msg for name in EFFECTS)


def test_effect_whose_machine_is_missing(tmp_path: Path) -> None:
    with pytest.raises(ParameterError) as exc:
        load_scene(
            _write(tmp_path, MINIMAL + 'effects:\n  chain_friction: {P_k: 10.0, r: 0.05, return_section: geometric}\n')
        )
    assert "needs machine 'delivery'" in str(exc.value)


def test_effect_missing_a_parameter(tmp_path: Path) -> None:
    with pytest.raises(ParameterError) as exc:
        load_scene(_write(tmp_path, MINIMAL + 'effects:\n  faults: {p_missing: 0.1}\n'))
    assert 'effects.faults.p_double' in str(exc.value) and 'missing' in str(exc.value)


def test_effect_unknown_parameter(tmp_path: Path) -> None:
    with pytest.raises(ParameterError) as exc:
        load_scene(_write(tmp_path, MINIMAL + 'effects:\n  faults: {p_gremlins: 0.1}\n'))
    assert 'effects.faults.p_gremlins' in str(exc.value)


@pytest.mark.parametrize(
    ('text', 'expected'),
    [
        ('name: x\nmachines: {}\n', 'must list its machines'),
        ('name: x\nmachines:\n  gearbox: {}\n', "machines='gearbox'"),
        ('name: x\nmachines:\n  knife: {}\n', "needs machine 'cyclogram'"),
        ('name: x\nmachines:\n  knife: {bogus: 1}\n  cyclogram: {}\n  feed_transporter: {}\n', 'knife.bogus'),
        (MINIMAL + 'colour: red\n', "colour='red': unknown scene key"),
        (MINIMAL + 'seed: -1\n', 'seed=-1'),
        (MINIMAL + 'drive: {profile: warp}\n', "drive.profile='warp'"),
        (MINIMAL + 'drive: {profile: ramp}\n', 'drive.t_ramp'),
    ],
)
def test_bad_scene_files(tmp_path: Path, text: str, expected: str) -> None:
    with pytest.raises(ParameterError) as exc:
        load_scene(_write(tmp_path, text))
    assert expected in str(exc.value)


def test_unknown_scene_name_lists_shipped() -> None:
    with pytest.raises(ParameterError) as exc:
        load_scene('no_such_scene')
    assert 'folder' in str(exc.value) and 'layup' in str(exc.value)


def test_scene_mapping_keeps_effect_order(tmp_path: Path) -> None:
    data = scene_mapping(_write(tmp_path, MINIMAL + 'effects: [b_first, {a_second: {k: 1}}]\n'))
    assert list(data['effects']) == ['b_first', 'a_second']
