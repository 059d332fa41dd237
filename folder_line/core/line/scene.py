"""A scene: which machines the line has, their parameters, the drive, the sheet
stream and the effects to simulate. Validated once, frozen.

:func:`parse_scene` takes the complete mapping (the YAML loader in
:mod:`folder_line.config.scenes` has already merged the defaults and any ``--set``
overrides) and rejects anything it does not know, naming it.
"""

from __future__ import annotations

import dataclasses
import importlib
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from folder_line.core.effects import EFFECTS, parse_effect_params
from folder_line.core.limits import SAMPLE_RATE
from folder_line.core.line.machines import StreamParams
from folder_line.core.mechanisms.drive import DriveSpec
from folder_line.errors import ParameterError

__all__ = ['MACHINE_KINDS', 'SCENE_KEYS', 'Scene', 'parse_scene']

#: machine section -> (module, parameter dataclass)
MACHINE_KINDS: dict[str, tuple[str, str]] = {
    'layup': ('folder_line.core.mechanisms.layup', 'LayupParams'),
    'container': ('folder_line.core.line.machines', 'ContainerParams'),
    'knife': ('folder_line.core.mechanisms.knife', 'KnifeParams'),
    'cyclogram': ('folder_line.core.mechanisms.cyclogram', 'CyclogramParams'),
    'feed_transporter': ('folder_line.core.line.machines', 'FeedTransporterParams'),
    'delivery': ('folder_line.core.mechanisms.delivery', 'DeliveryParams'),
    'delivery_chain': ('folder_line.core.line.machines', 'ChainParams'),
}

#: sections a machine needs alongside it
_NEEDS: dict[str, tuple[str, ...]] = {
    'knife': ('cyclogram', 'feed_transporter'),
    'cyclogram': ('knife', 'feed_transporter'),
    'feed_transporter': ('knife', 'cyclogram'),
    'delivery': ('delivery_chain', 'knife'),
    'delivery_chain': ('delivery',),
    'container': ('layup',),
}

SCENE_KEYS = ('name', 'description', 'machines', 'drive', 'sheets', 'effects', 'seed', 'sample_rate')


def machine_class(section: str) -> type:
    """Parameter dataclass of a machine section."""
    if section not in MACHINE_KINDS:
        raise ParameterError('machines', section, f'unknown machine; known: {", ".join(MACHINE_KINDS)}')
    module, name = MACHINE_KINDS[section]
    return getattr(importlib.import_module(module), name)


def _build(cls: type, prefix: str, values: Mapping[str, Any]) -> Any:
    if not isinstance(values, Mapping):
        raise ParameterError(prefix, values, 'must be a mapping of key: value')
    names = [f.name for f in dataclasses.fields(cls)]
    for key, value in values.items():
        if key not in names:
            raise ParameterError(f'{prefix}.{key}', value, f'unknown key; known: {", ".join(names)}')
    missing = [n for n in names if n not in values and cls.__dataclass_fields__[n].default is dataclasses.MISSING]
    if missing:
        raise ParameterError(f'{prefix}.{missing[0]}', None, 'missing')
    try:
        return cls(**values)
    except ParameterError as exc:
        if exc.key.startswith(prefix + '.') or '.' in exc.key:
            raise
        raise ParameterError(f'{prefix}.{exc.key}', exc.value, exc.reason) from None


@dataclass(frozen=True)
class Scene:
    """A validated scene (see :func:`parse_scene`).

    Attributes
    ----------
    name, description : str
        For humans.
    machines : Mapping[str, object]
        Machine section -> validated parameters (``LayupParams``, ``KnifeParams`` ...).
    drive : DriveSpec
        Master drive profile.
    sheets : StreamParams
        The sheet/leaf stream.
    effects : Mapping[str, object]
        Listed effect -> its validated ``Params``, in the order the scene lists them.
    seed : int
        Seed of every random draw (faults, leaf jitter).
    sample_rate : float
        Joint-state sampling rate, Hz (0: events only).
    """

    name: str
    description: str
    machines: Mapping[str, Any]
    drive: DriveSpec
    sheets: StreamParams
    effects: Mapping[str, Any]
    seed: int
    sample_rate: float
    source: Mapping[str, Any] = field(default_factory=dict, compare=False, repr=False)

    def has(self, effect: str) -> bool:
        """Whether the scene lists ``effect``."""
        return effect in self.effects

    def effect(self, name: str) -> Any:
        """Params of a listed effect, or None."""
        return self.effects.get(name)

    def machine(self, section: str) -> Any:
        """Params of a machine section (ParameterError if the scene has none)."""
        try:
            return self.machines[section]
        except KeyError:
            raise ParameterError(
                'machines',
                section,
                f'scene {self.name!r} has no such machine; it has {", ".join(self.machines) or "none"}',
            ) from None

    @property
    def has_layup(self) -> bool:
        """L is on the line."""
        return 'layup' in self.machines

    @property
    def has_folder(self) -> bool:
        """F is on the line."""
        return 'knife' in self.machines

    @property
    def has_delivery(self) -> bool:
        """D is on the line."""
        return 'delivery' in self.machines


def parse_scene(data: Mapping[str, Any]) -> Scene:
    """Validate a complete scene mapping.

    Parameters
    ----------
    data : mapping
        Keys :data:`SCENE_KEYS`; ``machines`` maps sections to complete parameter
        mappings; ``effects`` maps effect names to parameter mappings.

    Raises
    ------
    ParameterError
        Names the offending key (``machines.knife.r_k``, ``effects.feed_slip.mu`` ...)
        and value; an unknown effect lists the known ones; an effect whose machine is
        not in the scene says which machine is missing.
    """
    if not isinstance(data, Mapping):
        raise ParameterError('scene', data, 'must be a mapping')
    for key in data:
        if key not in SCENE_KEYS:
            raise ParameterError(str(key), data[key], f'unknown scene key; known: {", ".join(SCENE_KEYS)}')
    name = data.get('name')
    if not isinstance(name, str) or not name:
        raise ParameterError('name', name, 'must be a non-empty string')
    description = data.get('description', '')
    if not isinstance(description, str):
        raise ParameterError('description', description, 'must be a string')

    sections = data.get('machines') or {}
    if not isinstance(sections, Mapping) or not sections:
        raise ParameterError('machines', sections, f'must map at least one machine; known: {", ".join(MACHINE_KINDS)}')
    machines = {sec: _build(machine_class(sec), sec, values) for sec, values in sections.items()}
    for sec in machines:
        for need in _NEEDS.get(sec, ()):
            if need not in machines:
                raise ParameterError('machines', sec, f'needs machine {need!r} in the scene as well')

    effects_in = data.get('effects') or {}
    if not isinstance(effects_in, Mapping):
        raise ParameterError('effects', effects_in, 'must map effect names to their parameters')
    effects: dict[str, Any] = {}
    for ename, evalues in effects_in.items():
        if ename not in EFFECTS:
            raise ParameterError('effects', ename, f'unknown effect; known: {", ".join(EFFECTS)}')
        for need in EFFECTS[ename].machines:
            if need not in machines:
                raise ParameterError(
                    f'effects.{ename}',
                    ename,
                    f'needs machine {need!r}, which scene {name!r} does not have (it has {", ".join(machines)})',
                )
        effects[ename] = parse_effect_params(ename, evalues)

    drive = _build(DriveSpec, 'drive', data.get('drive') or {'profile': 'constant'})
    sheets = _build(StreamParams, 'sheets', data.get('sheets') or {})
    seed = data.get('seed', 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**63:
        raise ParameterError('seed', seed, 'must be a whole number in [0, 2**63)')
    rate = SAMPLE_RATE.check('sample_rate', data.get('sample_rate', 0.0))
    return Scene(
        name=name,
        description=description,
        machines=MappingProxyType(machines),
        drive=drive,
        sheets=sheets,
        effects=MappingProxyType(effects),
        seed=seed,
        sample_rate=rate,
        source=MappingProxyType(dict(data)),
    )
