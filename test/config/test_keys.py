"""``--set`` keys of a scene: every printed range is what the validation accepts, units agree with the limits."""

from __future__ import annotations

import math
from typing import Any

import pytest

from folder_line.config.keys import KeyInfo, field_docs, inert_keys, scene_keys
from folder_line.config.scenes import apply_overrides, default_value, list_scenes, scene_mapping
from folder_line.core.effects import EFFECTS
from folder_line.core.limits import LIMITS
from folder_line.core.line.scene import MACHINES, parse_scene
from folder_line.core.types.machines import StreamParams
from folder_line.errors import AssemblyError, ParameterError

#: the knife turns twice per cylinder turn: a speed is accepted only with its partner at the matching value
_PARTNER = {
    'knife.n_k': lambda v: {'cyclogram.n_c': v / 2.0},
    'cyclogram.n_c': lambda v: {'knife.n_k': 2.0 * v},
}


def _error_key(key: str) -> str:
    """How a refusal names ``key``: an effect's keys as ``effects.<effect>.<field>``."""
    head = key.partition('.')[0]
    return f'effects.{key}' if head in EFFECTS else key


def _load(base: dict[str, Any], key: str, value: float, partner: bool) -> None:
    extra = _PARTNER[key](value) if partner and key in _PARTNER else {}
    parse_scene(apply_overrides(base, {key: value, **extra}))


def _probes(info: KeyInfo) -> list[tuple[float, float]]:
    """(just outside, just inside) at each finite end of the range."""
    out = []
    for end, outward in ((info.lo, -math.inf), (info.hi, math.inf)):
        if not math.isfinite(end):
            continue
        is_open = info.lo_open if outward < 0 else info.hi_open
        if info.whole:
            step, e = (-1 if outward < 0 else 1), int(end)
            out.append((e, e - step) if is_open else (e + step, e))
        elif is_open:
            out.append((end, math.nextafter(end, -outward)))
        else:
            out.append((math.nextafter(end, outward), end))
    return out


def _cross_field(exc: Exception, info: KeyInfo) -> bool:
    """A refusal of a value inside the key's own range by a rule tying it to another field of its section
    (Grashof, ``omega_nom < omega_0``, ``x_left < x_right``): the error names the other field."""
    if isinstance(exc, AssemblyError):
        return True
    assert isinstance(exc, ParameterError)
    field = info.key.rpartition('.')[2]
    others = [name for name in _section_fields(info.key) if name != field]
    return exc.key != _error_key(info.key) or any(name in exc.reason for name in others)


def _section_fields(key: str) -> list[str]:
    head = key.partition('.')[0]
    cls = MACHINES.get(head) or (EFFECTS[head].params if head in EFFECTS else StreamParams)
    return list(cls.__dataclass_fields__)


@pytest.mark.parametrize('scene', list_scenes())
def test_every_printed_range_is_what_the_validation_accepts(scene: str) -> None:
    base = scene_mapping(scene)
    checked = accepted = 0
    for info in scene_keys(base):
        if not info.has_range:
            continue
        for outside, inside in _probes(info):
            with pytest.raises(ParameterError) as refused:
                _load(base, info.key, outside, partner=False)
            assert refused.value.key == _error_key(info.key), (info.key, outside, str(refused.value))
            try:
                _load(base, info.key, inside, partner=True)
                accepted += 1
            except (ParameterError, AssemblyError) as exc:
                assert _cross_field(exc, info), (info.key, inside, str(exc))
            checked += 1
    assert checked >= 20 and accepted >= 0.75 * checked, (checked, accepted)


def test_the_ranges_are_the_documented_ones() -> None:
    keys = {k.key: k for k in scene_keys(scene_mapping('line'))}
    assert keys['press.n_c'].range_text() == '[1, 100000]' and keys['press.n_c'].unit == 'rev/h'
    assert keys['knife.n_k'].range_text() == '[2, 200000]'
    assert keys['stop_bounce.e'].range_text() == '[0, 1)'
    assert keys['sheets.thickness'].range_text() == '(0, 0.1]'
    assert keys['feed_slip.m'].range_text() == '(0, inf)' and keys['feed_slip.m'].unit == 'kg'
    assert keys['motor_dynamics.b'].unit == 'N m s'
    assert keys['container.bins'].whole and keys['container.bins'].range_text() == '[2, 10000]'
    assert keys['knife.L_k'].range_text() == '> r_k + |e|'  # no numeric range: the documented rule
    assert keys['delivery.law'].choices and 'sinusoidal' in keys['delivery.law'].range_text()
    assert keys['feed_transporter.V_tr'].value == 9.6  # the scene's value, not config/feed_transporter.yaml's


def test_a_documented_unit_agrees_with_the_limit_of_the_key() -> None:
    """Two sources of a unit, the dataclass's numpydoc and core/limits.py, never disagree."""
    compared = 0
    for info in scene_keys(scene_mapping('line')):
        head, _, field = info.key.partition('.')
        cls = MACHINES.get(head) or (EFFECTS[head].params if head in EFFECTS else None)
        limit = next((lim for lim in LIMITS.values() if f'`{info.key}`' in lim.what), None)
        if cls is None or limit is None:
            continue
        doc = field_docs(cls)[field]
        assert f', {limit.unit}' in doc, (info.key, doc, limit.unit)
        compared += 1
    assert compared >= 4


@pytest.mark.parametrize('scene', list_scenes())
def test_every_field_is_documented(scene: str) -> None:
    for info in scene_keys(scene_mapping(scene)):
        assert info.note, info.key


def test_inert_keys_are_not_listed_but_named_and_refused() -> None:
    folder = scene_mapping('folder')
    listed = {k.key for k in scene_keys(folder)}
    inert = inert_keys(folder)
    assert set(inert) == {'sheets.interval', 'sheets.jitter'} and not listed & set(inert)
    assert {'press.n_c', 'knife.n_k', 'sheets.phase', 'seed', 'sample_rate', 'chain_friction.P_k'} <= listed
    for key in inert:
        with pytest.raises(ParameterError) as info:
            apply_overrides(folder, {key: default_value(key) * 0.5})
        assert info.value.key == key and 'arrival_jitter' in info.value.reason
    layup = scene_mapping('layup')
    assert 'press.n_c' not in {k.key for k in scene_keys(layup)}
    assert {'sheets.jitter', 'layup.v_tr'} <= {k.key for k in scene_keys(layup)}
    assert 'layup.v_tr' in inert_keys(scene_mapping('layup_no_belts'))
    assert {'drive.profile', 'drive.t_ramp', 'drive.t_brake'} <= set(inert_keys(scene_mapping('line')))
