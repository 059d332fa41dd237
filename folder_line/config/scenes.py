"""Scene files: ``config/scenes/<name>.yaml`` (or any path), merged with the defaults.

A scene file's machine sections may give any subset of a machine's keys; the rest
come from ``config/<section>.yaml``. ``--set KEY=VALUE`` overrides are applied last:
``<machine>.<key>`` (``feed_transporter.V_tr=5.833``), ``<effect>.<key>`` for a
listed effect (``feed_slip.mu=0.2``), ``sheets.<key>``, ``drive.<key>``, ``seed``,
``sample_rate``, and ``press.n_c``: the press speed, the folding cylinder in rev/h, which sets
``cyclogram.n_c`` and ``knife.n_k`` (twice it, :data:`~folder_line.core.mechanisms.cyclogram.KNIFE_PER_CYLINDER`)
together; a scene file may say the same as ``press: {n_c: 30000}``. Merging only places values; the
merged mapping is validated once, by :func:`folder_line.core.line.scene.parse_scene`, which names every
unknown key and refuses a knife and cylinder speed that do not match.

A value the user gives (in the scene file or an override) that the scene would never read
is refused too (:func:`folder_line.core.line.inert.inert_reason`: ``sheets.jitter`` on the
folder, ``drive.*`` with ``motor_dynamics`` ...), unless it is the default anyway.

The loader's two inputs, the scene and its overrides, are named in errors by the caller's
:class:`InputNames`: the command line says ``--scene``/``--set``, a node ``scene``/``overrides``.

``folder-line run`` writes the merged scene once (:func:`write_scene`, ``<out>/scene.yaml``)
and gives its path to the nodes; :func:`shared_scene` parses a scene once per process
(the nodes of one process, and ``run`` itself in-process, share one :class:`Scene`).
"""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import errno
import os
from collections.abc import Hashable, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeAlias

import yaml

from folder_line.config.params import config_dir, read_yaml_mapping
from folder_line.core.effects import EFFECTS
from folder_line.core.limits import CYLINDER_SPEED
from folder_line.core.line.inert import inert_reason
from folder_line.core.line.scene import MACHINES, Scene, parse_scene
from folder_line.core.mechanisms.cyclogram import KNIFE_PER_CYLINDER
from folder_line.core.mechanisms.drive import DriveSpec
from folder_line.errors import InputFileError, ParameterError
from folder_line.files.atomic import write_text_atomic
from folder_line.files.yamlio import load_yaml

__all__ = [
    'DRIVE_DEFAULT',
    'PRESS_KEYS',
    'SET_VALUE_CHARS',
    'InputNames',
    'SceneMapping',
    'apply_overrides',
    'default_value',
    'list_scenes',
    'load_scene',
    'parse_set',
    'resolve_scene',
    'scene_mapping',
    'scene_text',
    'set_press',
    'shared_scene',
    'write_scene',
]

#: longest VALUE of ``--set KEY=VALUE``, characters
SET_VALUE_CHARS = 100
#: the keys of the ``press`` section: ``press.n_c``, the folding cylinder's speed, rev/h, sets ``cyclogram.n_c``
#: and ``knife.n_k`` = :data:`~folder_line.core.mechanisms.cyclogram.KNIFE_PER_CYLINDER` times it
PRESS_KEYS = ('n_c',)
#: a complete scene mapping before :func:`~folder_line.core.line.scene.parse_scene` judges it: the user's YAML
#: with the defaults merged in (``Any``: the merge made ``machines``, ``effects``, ``sheets`` dicts, and any
#: other value is as the user typed it, for the parser to refuse)
SceneMapping: TypeAlias = dict[str, Any]
#: the ``drive`` section of a scene that gives none, with every field at its default
DRIVE_DEFAULT: dict[str, object] = {
    'profile': 'constant',
    **{f.name: f.default for f in dataclasses.fields(DriveSpec) if f.default is not dataclasses.MISSING},
}


@dataclass(frozen=True)
class InputNames:
    """What a front end calls the loader's inputs, so that the loader's errors name them in its words.

    Attributes
    ----------
    scene : str
        The scene name or file (the command line: ``--scene``; a node: ``scene``).
    overrides : str
        The ``KEY=VALUE`` overrides (the command line: ``--set``; a node: ``overrides``).
    """

    scene: str = 'scene'
    overrides: str = 'overrides'


def list_scenes() -> list[str]:
    """Names of the scenes shipped in ``config/scenes``."""
    return sorted(p.stem for p in (config_dir() / 'scenes').glob('*.yaml'))


def resolve_scene(name_or_path: str | os.PathLike[str], names: InputNames = InputNames()) -> Path:
    """Path of a scene given by name (``folder``) or by file path (errors name ``names.scene``)."""
    text = str(name_or_path)
    path = Path(text)
    if path.is_symlink() and not path.exists():  # a loop or a dangling link: say which, not "no such file"
        looped = False
        try:
            path.resolve(strict=True)
        except RuntimeError:  # Python 3.11's Path.resolve on a symlink loop
            looped = True
        except OSError as exc:
            looped = exc.errno == errno.ELOOP
        why = 'a symbolic link that loops (it leads to itself)' if looped else 'a broken symbolic link'
        raise InputFileError(names.scene, text, why if looped else f'{why}: {os.readlink(path)!r} does not exist')
    if path.suffix in ('.yaml', '.yml') or os.sep in text or (path.exists() and not path.is_dir()):
        if not path.exists():  # anything else that is there (a FIFO, a folder) is refused by the reader
            raise InputFileError(names.scene, text, 'no such file')
        return path
    shipped = config_dir() / 'scenes' / f'{text}.yaml'
    if not shipped.is_file():
        raise ParameterError(names.scene, text, f'no such scene; shipped scenes: {", ".join(list_scenes())}')
    return shipped


def parse_set(items: Iterable[str], names: InputNames = InputNames()) -> dict[str, object]:
    """``['feed_transporter.V_tr=5.833', ...]`` -> ``{'feed_transporter.V_tr': 5.833}`` (values as YAML scalars).

    An item that is not ``KEY=VALUE`` is refused naming ``names.overrides``; a bad value, naming its key.
    """
    out: dict[str, object] = {}
    for item in items:
        key, sep, raw = item.partition('=')
        key = key.strip()
        if not sep or not key:
            raise ParameterError(names.overrides, item, 'must be KEY=VALUE, e.g. feed_transporter.V_tr=5.833')
        if not raw.strip():
            raise ParameterError(key, raw, 'needs a value (KEY=VALUE)')
        if len(raw) > SET_VALUE_CHARS:
            raise ParameterError(key, raw, f'value is {len(raw)} characters long; at most {SET_VALUE_CHARS}')
        try:
            value = load_yaml(raw, key, names.overrides) if raw.strip() else None
        except ParameterError:  # not a YAML scalar: the text as given
            value = raw
        if isinstance(value, str):  # YAML 1.1 reads 1e9 as a string; a user means the number
            with contextlib.suppress(ValueError):
                value = float(value)
        if isinstance(value, (dict, list)):
            raise ParameterError(key, raw, 'must be a single value')
        out[key] = value
    return out


def _section(values: object) -> object:
    """A section's mapping, copied (None: empty); anything else as given, for the builder to refuse."""
    if values is None:
        return {}
    return dict(values) if isinstance(values, Mapping) else values


def _effects_mapping(raw: object) -> dict[str, object]:
    if raw is None:
        return {}
    if isinstance(raw, list):  # effects: [name, {name: params}, ...]
        out: dict[str, object] = {}
        for item in raw:
            if isinstance(item, str):
                out[item] = {}
            elif isinstance(item, Mapping) and len(item) == 1:
                out.update({k: _section(v) for k, v in item.items()})
            else:
                raise ParameterError('effects', item, 'each entry must be a name or {name: {params}}')
        return out
    if isinstance(raw, Mapping):
        return {k: _section(v) for k, v in raw.items()}
    raise ParameterError('effects', raw, 'must be a list or a mapping of effect names')


def scene_mapping(
    name_or_path: str | os.PathLike[str],
    overrides: Mapping[str, object] | None = None,
    *,
    names: InputNames = InputNames(),
) -> SceneMapping:
    """The complete mapping of a scene: file, defaults and overrides merged (not yet validated).

    Merging places values and checks only what it must to place them (the file holds a
    mapping of machines; an override addresses a section the scene has); every key and
    value is judged once, by :func:`folder_line.core.line.scene.parse_scene`.
    """
    return _merge(resolve_scene(name_or_path, names), overrides, names)


def _merge(path: Path, overrides: Mapping[str, object] | None, names: InputNames) -> SceneMapping:
    data: SceneMapping = copy.deepcopy(read_yaml_mapping(path, names.scene))
    data.setdefault('name', path.stem)
    press = _press_section(data)
    given = _given_keys(data)
    machines_in = data.get('machines')
    if not isinstance(machines_in, Mapping) or not machines_in:
        raise ParameterError('machines', machines_in, f'scene {path} must list its machines: {", ".join(MACHINES)}')
    machines: dict[object, object] = {}
    for section, values in machines_in.items():
        if section not in MACHINES:  # refused by parse_scene, naming the known ones
            machines[section] = values
            continue
        if values is not None and not isinstance(values, Mapping):
            raise ParameterError(f'machines.{section}', values, 'must be a mapping of key: value')
        merged = read_yaml_mapping(config_dir() / f'{section}.yaml', f'{section} defaults')
        merged.update(values or {})
        machines[section] = merged
    data['machines'] = machines
    sheets = read_yaml_mapping(config_dir() / 'sheets.yaml', 'sheets defaults')
    sheets_in = data.get('sheets')
    if sheets_in is not None and not isinstance(sheets_in, Mapping):
        raise ParameterError('sheets', sheets_in, 'must be a mapping of key: value')
    sheets.update(sheets_in or {})
    data['sheets'] = sheets
    data['effects'] = _effects_mapping(data.get('effects'))
    data.setdefault('drive', {'profile': 'constant'})
    for key, value in press.items():
        _apply(data, f'press.{key}', value)
    for key, value in (overrides or {}).items():
        _apply(data, key, value)
    _check_read(data, [*given, *(overrides or {})])
    return data


def _press_section(data: dict[str, object]) -> dict[str, object]:
    """The scene file's ``press`` section, taken out of ``data`` (it is applied as ``press.<key>`` overrides).

    The file must not give the speeds it sets a second time (``knife.n_k``, ``cyclogram.n_c``).
    """
    press = data.pop('press', None)
    if press is None:
        return {}
    if not isinstance(press, Mapping):
        raise ParameterError('press', press, f'must be a mapping of {", ".join(PRESS_KEYS)}')
    for key, value in press.items():
        if key not in PRESS_KEYS:
            raise ParameterError(f'press.{key}', value, f'unknown press key; known: {", ".join(PRESS_KEYS)}')
    machines = data.get('machines')
    for section, field in (('knife', 'n_k'), ('cyclogram', 'n_c')):
        values = machines.get(section) if isinstance(machines, Mapping) else None
        if isinstance(values, Mapping) and field in values:
            raise ParameterError(
                f'{section}.{field}',
                values[field],
                f'the scene gives press.n_c={press.get("n_c")!r} as well: give the press speed once',
            )
    return dict(press)


def _given_keys(data: Mapping[str, object]) -> list[str]:
    """The dotted keys a scene file gives values for itself (machine sections, sheets, drive)."""
    keys: list[str] = []
    machines = data.get('machines')
    if isinstance(machines, Mapping):
        for section, values in machines.items():
            if isinstance(values, Mapping):
                keys += [f'{section}.{field}' for field in values]
    for section in ('sheets', 'drive'):
        values = data.get(section)
        if isinstance(values, Mapping):
            keys += [f'{section}.{field}' for field in values]
    return keys


def default_value(key: str) -> object:
    """The default of a dotted machine, ``sheets`` or ``drive`` key (``config/<section>.yaml``,
    :data:`DRIVE_DEFAULT`), or None if it has none (an effect's parameters have no defaults)."""
    section, _, field = key.partition('.')
    if section == 'drive':
        return DRIVE_DEFAULT.get(field)
    if section == 'sheets' or section in MACHINES:
        return read_yaml_mapping(config_dir() / f'{section}.yaml', f'{section} defaults').get(field)
    return None


def _section_value(data: SceneMapping, key: str) -> object:
    section, _, field = key.partition('.')
    values = data['machines'].get(section) if section in MACHINES else data.get(section)
    return values.get(field) if isinstance(values, Mapping) else None


def _check_read(data: SceneMapping, keys: Iterable[str]) -> None:
    """Refuse a value the user gave for one of ``keys`` that the scene never reads (unless it is the default)."""
    machines = [m for m in data['machines'] if isinstance(m, str)]
    effects = [e for e in data['effects'] if isinstance(e, str)]
    for key in keys:
        why = inert_reason(key, machines, effects)
        if why is None:
            continue
        value = _section_value(data, key)
        if value != default_value(key):
            raise ParameterError(key, value, f'does nothing in scene {data["name"]!r}: {why}')


def apply_overrides(data: Mapping[str, object], overrides: Mapping[str, object]) -> SceneMapping:
    """A copy of a complete scene mapping (:func:`scene_mapping`) with ``overrides`` applied, as ``--set`` does.

    The design studies vary keys of one merged scene this way, point by point; ``data`` is not changed.
    """
    out: SceneMapping = copy.deepcopy(dict(data))
    for key, value in overrides.items():
        _apply(out, key, value)
    _check_read(out, overrides)
    return out


def set_press(machines: Mapping[str, object], key: str, value: object, where: str) -> None:
    """Apply ``press.<field>``: ``press.n_c`` puts the folding cylinder at ``value`` rev/h and the knife at
    :data:`~folder_line.core.mechanisms.cyclogram.KNIFE_PER_CYLINDER` times it.

    Parameters
    ----------
    machines : mapping
        Machine section -> its (mutable) mapping of values; ``cyclogram`` and ``knife`` are changed.
    key : str
        ``press.n_c`` (another field is refused).
    value : object
        The cylinder speed, rev/h, in :data:`~folder_line.core.limits.CYLINDER_SPEED`.
    where : str
        What holds the machines, for the error if there is no folder (``scene 'layup'``).

    Raises
    ------
    ParameterError
        Naming ``key`` and the value: an unknown field, a speed out of range, no knife and cylinder.
    """
    field = key.partition('.')[2]
    if field not in PRESS_KEYS:
        raise ParameterError(key, value, f'unknown press key; known: {", ".join(f"press.{k}" for k in PRESS_KEYS)}')
    n_c = CYLINDER_SPEED.check(key, value)
    cylinder, knife = machines.get('cyclogram'), machines.get('knife')
    if not isinstance(cylinder, dict) or not isinstance(knife, dict):
        raise ParameterError(
            key,
            value,
            f'{where} has no folder (knife and cyclogram), whose speeds press.n_c sets; '
            f'it has {", ".join(map(str, machines))}',
        )
    cylinder['n_c'] = n_c
    knife['n_k'] = KNIFE_PER_CYLINDER * n_c


def _apply(data: SceneMapping, key: str, value: object) -> None:
    if key in ('seed', 'sample_rate'):
        data[key] = value
        return
    head, sep, field = key.partition('.')
    if not sep or not field or '.' in field:
        raise ParameterError(
            key,
            value,
            'must be SECTION.KEY (a machine, a listed effect, sheets, drive or press), seed or sample_rate',
        )
    if head == 'press':
        set_press(data['machines'], key, value, f'scene {data["name"]!r}')
        return
    if head in MACHINES:
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
            f'unknown section; a section is a machine ({", ".join(MACHINES)}), '
            'sheets, drive, press, or an effect the scene lists',
        )
    if not isinstance(section, dict):  # a section the file gave as something else: parse_scene names it
        return
    section[field] = value


def load_scene(
    name_or_path: str | os.PathLike[str],
    overrides: Mapping[str, object] | None = None,
    *,
    names: InputNames = InputNames(),
) -> Scene:
    """Load, merge and validate a scene.

    Parameters
    ----------
    name_or_path : str or path-like
        A shipped scene name (``folder``, ``layup``, ``line``) or a YAML file.
    overrides : mapping, optional
        ``{'feed_transporter.V_tr': 5.833, ...}`` as from ``--set``.
    names : InputNames, optional
        What the caller calls the scene and the overrides, for the errors.

    Raises
    ------
    ParameterError, AssemblyError
        Naming the offending key and value.
    """
    return parse_scene(scene_mapping(name_or_path, overrides, names=names))


# --------------------------------------------------------------------------- one parse per process

#: scenes parsed in this process, by (file identity, overrides); the oldest goes beyond :data:`_SHARED_MAX`
_SHARED: dict[Hashable, Scene] = {}
_SHARED_MAX = 8


def _identity(path: Path) -> tuple[str, int, int, int, int]:
    """The file as it is now: a rewritten or replaced file is another one."""
    st = path.stat()
    return (str(path.resolve()), st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns)


def _remember(key: Hashable, scene: Scene) -> None:
    _SHARED.pop(key, None)
    _SHARED[key] = scene
    while len(_SHARED) > _SHARED_MAX:
        del _SHARED[next(iter(_SHARED))]


def shared_scene(
    name_or_path: str | os.PathLike[str],
    overrides: Mapping[str, object] | None = None,
    *,
    names: InputNames = InputNames(),
) -> Scene:
    """:func:`load_scene`, parsed once per process for the same file (unchanged) and overrides.

    The nodes of one process share the scene this way, and in-process with ``folder-line run``
    the scene it wrote (:func:`write_scene`). Errors are not remembered: a bad scene is refused
    at every call.
    """
    path = resolve_scene(name_or_path, names)
    try:
        key: Hashable = (_identity(path), tuple((overrides or {}).items()))
        hash(key)
    except (OSError, TypeError):  # cannot be told apart from another version or overrides: no sharing
        return parse_scene(_merge(path, overrides, names))
    scene = _SHARED.get(key)
    if scene is None:
        scene = parse_scene(_merge(path, overrides, names))
        _remember(key, scene)
    return scene


def scene_text(scene: Scene) -> str:
    """The YAML of a scene's complete mapping (what it was parsed from): defaults and overrides merged in."""
    return yaml.safe_dump(dict(scene.source), sort_keys=False)


def write_scene(path: str | os.PathLike[str], scene: Scene) -> str:
    """Write the merged scene to ``path`` atomically, for nodes to load; returns the text written.

    Loading the file gives ``scene`` again (every key at its value, nothing left to merge), so it
    is remembered as the file's scene: :func:`shared_scene` of ``path`` in this process does not
    parse it again.

    Raises
    ------
    OutputError
        ``path`` must not be replaced or cannot be written (:func:`folder_line.files.atomic.write_text_atomic`).
    """
    text = scene_text(scene)
    write_text_atomic(path, text)
    _remember((_identity(Path(path)), ()), scene)
    return text
