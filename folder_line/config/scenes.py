"""Scene files: ``config/scenes/<name>.yaml`` (or any path), merged with the defaults.

A scene file's machine sections may give any subset of a machine's keys; the rest
come from ``config/<section>.yaml``. ``--set KEY=VALUE`` overrides are applied last:
``<machine>.<key>`` (``feed_transporter.V_tr=5.833``), ``<effect>.<key>`` for a
listed effect (``feed_slip.mu=0.2``), ``sheets.<key>``, ``drive.<key>``, ``seed``,
``sample_rate``. The merged mapping is validated by
:func:`folder_line.core.line.scene.parse_scene`.
"""

from __future__ import annotations

import contextlib
import copy
import os
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from folder_line.config.params import config_dir, read_yaml_mapping
from folder_line.core.effects import EFFECTS
from folder_line.core.line.scene import MACHINE_KINDS, Scene, parse_scene
from folder_line.errors import InputFileError, ParameterError
from folder_line.files.yamlio import load_yaml

__all__ = ['SET_VALUE_CHARS', 'list_scenes', 'load_scene', 'parse_set', 'resolve_scene', 'scene_mapping']

#: longest VALUE of ``--set KEY=VALUE``, characters
SET_VALUE_CHARS = 100


def list_scenes() -> list[str]:
    """Names of the scenes shipped in ``config/scenes``."""
    return sorted(p.stem for p in (config_dir() / 'scenes').glob('*.yaml'))


def resolve_scene(name_or_path: str | os.PathLike[str]) -> Path:
    """Path of a scene given by name (``folder``) or by file path."""
    text = str(name_or_path)
    path = Path(text)
    if path.suffix in ('.yaml', '.yml') or os.sep in text or (path.exists() and not path.is_dir()):
        if not path.exists():  # anything else that is there (a FIFO, a folder) is refused by the reader
            raise InputFileError('--scene', text, 'no such file')
        return path
    shipped = config_dir() / 'scenes' / f'{text}.yaml'
    if not shipped.is_file():
        raise ParameterError('--scene', text, f'no such scene; shipped scenes: {", ".join(list_scenes())}')
    return shipped


def parse_set(items: Iterable[str]) -> dict[str, Any]:
    """``['feed_transporter.V_tr=5.833', ...]`` -> ``{'feed_transporter.V_tr': 5.833}`` (values as YAML scalars)."""
    out: dict[str, Any] = {}
    for item in items:
        key, sep, raw = item.partition('=')
        key = key.strip()
        if not sep or not key:
            raise ParameterError('--set', item, 'must be KEY=VALUE, e.g. feed_transporter.V_tr=5.833')
        if not raw.strip():
            raise ParameterError(key, raw, 'needs a value (KEY=VALUE)')
        if len(raw) > SET_VALUE_CHARS:
            raise ParameterError(key, raw, f'value is {len(raw)} characters long; at most {SET_VALUE_CHARS}')
        try:
            value = load_yaml(raw, key, '--set') if raw.strip() else None
        except ParameterError:  # not a YAML scalar: the text as given
            value = raw
        if isinstance(value, str):  # YAML 1.1 reads 1e9 as a string; a user means the number
            with contextlib.suppress(ValueError):
                value = float(value)
        if isinstance(value, (dict, list)):
            raise ParameterError(key, raw, 'must be a single value')
        out[key] = value
    return out


def _effects_mapping(raw: Any) -> dict[str, Any]:
    if raw is None:
        return {}
    if isinstance(raw, list):  # effects: [name, {name: params}, ...]
        out: dict[str, Any] = {}
        for item in raw:
            if isinstance(item, str):
                out[item] = {}
            elif isinstance(item, Mapping) and len(item) == 1:
                out.update({k: dict(v or {}) for k, v in item.items()})
            else:
                raise ParameterError('effects', item, 'each entry must be a name or {name: {params}}')
        return out
    if isinstance(raw, Mapping):
        return {k: dict(v or {}) for k, v in raw.items()}
    raise ParameterError('effects', raw, 'must be a list or a mapping of effect names')


def scene_mapping(name_or_path: str | os.PathLike[str], overrides: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The complete mapping of a scene: file, defaults and overrides merged (not yet validated)."""
    path = resolve_scene(name_or_path)
    data = read_yaml_mapping(path, '--scene')
    data = copy.deepcopy(data)
    data.setdefault('name', path.stem)
    machines_in = data.get('machines')
    if not isinstance(machines_in, Mapping) or not machines_in:
        raise ParameterError(
            'machines', machines_in, f'scene {path} must list its machines: {", ".join(MACHINE_KINDS)}'
        )
    machines: dict[str, dict[str, Any]] = {}
    for section, values in machines_in.items():
        if section not in MACHINE_KINDS:
            raise ParameterError('machines', section, f'unknown machine; known: {", ".join(MACHINE_KINDS)}')
        if values is not None and not isinstance(values, Mapping):
            raise ParameterError(f'machines.{section}', values, 'must be a mapping of key: value')
        merged = read_yaml_mapping(config_dir() / f'{section}.yaml', f'{section} defaults')
        for key, value in (values or {}).items():
            if key not in merged:
                raise ParameterError(f'{section}.{key}', value, f'unknown key; known: {", ".join(merged)}')
            merged[key] = value
        machines[section] = merged
    data['machines'] = machines
    sheets = read_yaml_mapping(config_dir() / 'sheets.yaml', 'sheets defaults')
    sheets.update(data.get('sheets') or {})
    data['sheets'] = sheets
    data['effects'] = _effects_mapping(data.get('effects'))
    data.setdefault('drive', {'profile': 'constant'})
    for key, value in (overrides or {}).items():
        _apply(data, key, value)
    return data


def _apply(data: dict[str, Any], key: str, value: Any) -> None:
    if key in ('seed', 'sample_rate'):
        data[key] = value
        return
    head, sep, field = key.partition('.')
    if not sep or not field or '.' in field:
        raise ParameterError(
            key, value, 'must be SECTION.KEY (a machine, a listed effect, sheets or drive), seed or sample_rate'
        )
    if head in MACHINE_KINDS:
        section = data['machines'].get(head)
        if section is None:
            raise ParameterError(
                key, value, f'scene {data["name"]!r} has no machine {head!r}; it has {", ".join(data["machines"])}'
            )
    elif head in EFFECTS:
        section = data['effects'].get(head)
        if section is None:
            raise ParameterError(
                key,
                value,
                f'scene {data["name"]!r} does not list effect {head!r}; '
                f'it lists {", ".join(data["effects"]) or "none"}',
            )
    elif head in ('sheets', 'drive'):
        section = data[head]
    else:
        raise ParameterError(
            key,
            value,
            f'unknown section; a section is a machine ({", ".join(MACHINE_KINDS)}), '
            'sheets, drive, or an effect the scene lists',
        )
    if (head in MACHINE_KINDS or head == 'sheets') and field not in section:
        raise ParameterError(key, value, f'unknown key; {head} has {", ".join(section)}')
    section[field] = value


def load_scene(name_or_path: str | os.PathLike[str], overrides: Mapping[str, Any] | None = None) -> Scene:
    """Load, merge and validate a scene.

    Parameters
    ----------
    name_or_path : str or path-like
        A shipped scene name (``folder``, ``layup``, ``line``) or a YAML file.
    overrides : mapping, optional
        ``{'feed_transporter.V_tr': 5.833, ...}`` as from ``--set``.

    Raises
    ------
    ParameterError, AssemblyError
        Naming the offending key and value.
    """
    return parse_scene(scene_mapping(name_or_path, overrides))
