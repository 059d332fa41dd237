"""Scene files: defaults merged, overrides, and every rejection names what is wrong."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import pytest

from folder_line.config.scenes import (
    InputNames,
    list_scenes,
    load_scene,
    parse_set,
    scene_mapping,
    shared_scene,
    write_scene,
)
from folder_line.core.effects import EFFECTS, chain_friction, motor_dynamics
from folder_line.core.line.scene import Scene
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


def test_errors_name_the_inputs_in_the_callers_words(tmp_path: Path) -> None:
    cli = InputNames(scene='--scene', overrides='--set')
    for names, scene, overrides in ((cli, '--scene', '--set'), (InputNames(), 'scene', 'overrides')):
        with pytest.raises(ParameterError, match=rf"^{scene}='nope': no such scene; shipped scenes: folder, "):
            load_scene('nope', names=names)
        with pytest.raises(ParameterError, match=rf"^{scene}='{tmp_path}/none.yaml': no such file"):
            load_scene(tmp_path / 'none.yaml', names=names)
        with pytest.raises(ParameterError, match=rf"^{overrides}='V_tr': must be KEY=VALUE"):
            parse_set(['V_tr'], names)


def test_a_scene_is_parsed_once_per_process_and_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    parses: list[str] = []
    build = Scene.__init__

    def counted(self: Scene, *args: Any, **kwargs: Any) -> None:
        build(self, *args, **kwargs)
        parses.append(self.name)

    monkeypatch.setattr(Scene, '__init__', counted)
    path = _write(tmp_path, MINIMAL)
    first = shared_scene(path, {'seed': 2})
    assert shared_scene(str(path), {'seed': 2}) is first and len(parses) == 1
    assert shared_scene(path, {'seed': 3}).seed == 3 and len(parses) == 2  # other overrides: another scene
    os.utime(path, ns=(0, 0))  # the file changed: parsed again
    assert shared_scene(path, {'seed': 2}) == first and len(parses) == 3
    # a merged scene written by write_scene is that scene: loading it shares it, parsing it gives it
    merged = tmp_path / 'out' / 'scene.yaml'
    text = write_scene(merged, first)
    assert merged.read_text() == text and len(parses) == 3
    assert shared_scene(merged) is first and len(parses) == 3
    assert load_scene(merged) == first and len(parses) == 4


def test_unknown_keys_are_judged_once_by_the_builder(tmp_path: Path) -> None:
    """Merging places values; the builder names the unknown key and lists the known ones."""
    with pytest.raises(ParameterError) as exc:
        load_scene(_write(tmp_path, MINIMAL), {'feed_transporter.V_x': 1})
    assert str(exc.value).startswith('feed_transporter.V_x=1: unknown feed_transporter parameter; known: ')
    data = scene_mapping(_write(tmp_path, MINIMAL + 'sheets: {bogus: 2}\n'))  # placed, not judged
    assert data['sheets']['bogus'] == 2
    with pytest.raises(ParameterError, match=r'^sheets\.bogus=2: unknown sheets parameter; known: interval, '):
        load_scene(_write(tmp_path, MINIMAL + 'sheets: {bogus: 2}\n'))
    with pytest.raises(ParameterError, match=r'^effects\.faults=5: must be a mapping of key: value'):
        load_scene(_write(tmp_path, MINIMAL + 'effects: {faults: 5}\n'))


def test_effect_params_are_typed_and_name_an_unlisted_effect() -> None:
    line = load_scene('line')
    assert 'motor_dynamics' in line.effects
    assert isinstance(line.effect_params('motor_dynamics'), motor_dynamics.Params)
    assert line.effect_params('motor_dynamics') is line.effect('motor_dynamics')
    folder = load_scene('folder')
    assert isinstance(folder.effect_params('chain_friction'), chain_friction.Params)
    with pytest.raises(ParameterError, match=r"effects='motor_dynamics'.*does not list this effect; it lists"):
        folder.effect_params('motor_dynamics')
