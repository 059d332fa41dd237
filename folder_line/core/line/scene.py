"""A scene: which machines the line has, their parameters, the drive, the sheet
stream and the effects to simulate. Validated once, frozen.

:data:`MACHINES` is the one registry of machine sections: section name -> its
parameter dataclass. :func:`parse_scene` takes the complete mapping (the YAML loader in
:mod:`folder_line.config.scenes` has already merged the defaults and any ``--set``
overrides) and builds every part with :func:`folder_line.core.numerics.validate.build`,
which rejects anything it does not know, naming it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Literal, TypeAlias, overload

from folder_line.core import effects as fx
from folder_line.core.effects import EFFECTS, parse_effect_params
from folder_line.core.limits import SAMPLE_RATE
from folder_line.core.mechanisms.cyclogram import KNIFE_PER_CYLINDER, CyclogramParams
from folder_line.core.mechanisms.delivery import DeliveryParams
from folder_line.core.mechanisms.drive import DriveSpec
from folder_line.core.mechanisms.knife import KnifeParams
from folder_line.core.mechanisms.layup import LayupParams
from folder_line.core.numerics.validate import build, check_keys
from folder_line.core.types.machines import ChainParams, ContainerParams, FeedTransporterParams, StreamParams
from folder_line.errors import ParameterError

__all__ = ['MACHINES', 'SCENE_KEYS', 'MachineParams', 'Scene', 'check_press_speed', 'machine_class', 'parse_scene']

#: the parameters of one machine section
MachineParams: TypeAlias = (
    LayupParams | ContainerParams | KnifeParams | CyclogramParams | FeedTransporterParams | DeliveryParams | ChainParams
)

#: machine section -> its parameter dataclass: the one registry (scenes, ``folder-line kinematics``)
MACHINES: Mapping[str, type[MachineParams]] = MappingProxyType(
    {
        'layup': LayupParams,
        'container': ContainerParams,
        'knife': KnifeParams,
        'cyclogram': CyclogramParams,
        'feed_transporter': FeedTransporterParams,
        'delivery': DeliveryParams,
        'delivery_chain': ChainParams,
    }
)

#: sections a machine needs alongside it
_NEEDS: dict[str, tuple[str, ...]] = {
    'knife': ('cyclogram', 'feed_transporter'),
    'cyclogram': ('knife', 'feed_transporter'),
    'feed_transporter': ('knife', 'cyclogram'),
    'delivery': ('delivery_chain', 'knife'),
    'delivery_chain': ('delivery',),
    'container': ('layup',),
}

#: relative difference of ``knife.n_k`` and ``2 cyclogram.n_c`` that is still rounding
_PRESS_RTOL = 1e-9

SCENE_KEYS = ('name', 'description', 'machines', 'drive', 'sheets', 'effects', 'seed', 'sample_rate')


def machine_class(section: object) -> type[MachineParams]:
    """Parameter dataclass of a machine section (ParameterError naming the known ones)."""
    if not isinstance(section, str) or section not in MACHINES:
        raise ParameterError('machines', section, f'unknown machine; known: {", ".join(MACHINES)}')
    return MACHINES[section]


@dataclass(frozen=True)
class Scene:
    """A validated scene (see :func:`parse_scene`).

    Equal scenes hash equal, so a scene can key a cache (the line models of the nodes
    of one process, :func:`folder_line.ros.nodes.machine.scene_model`).

    Attributes
    ----------
    name, description : str
        For humans.
    machines : Mapping[str, MachineParams]
        Machine section -> validated parameters (``LayupParams``, ``KnifeParams`` ...), in the
        order the scene lists them; :meth:`machine` gives each with its own type.
    drive : DriveSpec
        Master drive profile.
    sheets : StreamParams
        The sheet/leaf stream.
    effects : Mapping[str, object]
        Listed effect -> its validated ``Params`` (of its module in :mod:`folder_line.core.effects`),
        in the order the scene lists them.
    seed : int
        Seed of every random draw (faults, leaf jitter).
    sample_rate : float
        Joint-state sampling rate, Hz (0: events only).
    source : Mapping[str, object]
        The complete mapping it was parsed from (not compared).
    """

    name: str
    description: str
    machines: Mapping[str, MachineParams]
    drive: DriveSpec
    sheets: StreamParams
    effects: Mapping[str, object]
    seed: int
    sample_rate: float
    source: Mapping[str, object] = field(default_factory=dict, compare=False, repr=False)

    def __hash__(self) -> int:
        return hash(
            (
                self.name,
                self.description,
                frozenset(self.machines.items()),
                self.drive,
                self.sheets,
                frozenset(self.effects.items()),
                self.seed,
                self.sample_rate,
            )
        )

    def has(self, effect: str) -> bool:
        """Whether the scene lists ``effect``."""
        return effect in self.effects

    def effect(self, name: str) -> Any:
        """Params of a listed effect, or None (untyped; :meth:`effect_params` gives them typed)."""
        return self.effects.get(name)

    @overload
    def effect_params(self, name: Literal['arrival_jitter']) -> fx.arrival_jitter.Params: ...
    @overload
    def effect_params(self, name: Literal['chain_friction']) -> fx.chain_friction.Params: ...
    @overload
    def effect_params(self, name: Literal['chute_belts']) -> fx.chute_belts.Params: ...
    @overload
    def effect_params(self, name: Literal['faults']) -> fx.faults.Params: ...
    @overload
    def effect_params(self, name: Literal['feed_slip']) -> fx.feed_slip.Params: ...
    @overload
    def effect_params(self, name: Literal['guide_friction']) -> fx.guide_friction.Params: ...
    @overload
    def effect_params(self, name: Literal['leaf_damage']) -> fx.leaf_damage.Params: ...
    @overload
    def effect_params(self, name: Literal['leaf_flight']) -> fx.leaf_flight.Params: ...
    @overload
    def effect_params(self, name: Literal['length_scatter']) -> fx.length_scatter.Params: ...
    @overload
    def effect_params(self, name: Literal['motor_dynamics']) -> fx.motor_dynamics.Params: ...
    @overload
    def effect_params(self, name: Literal['property_scatter']) -> fx.property_scatter.Params: ...
    @overload
    def effect_params(self, name: Literal['speed_ripple']) -> fx.speed_ripple.Params: ...
    @overload
    def effect_params(self, name: Literal['stop_bounce']) -> fx.stop_bounce.Params: ...
    @overload
    def effect_params(self, name: str) -> object: ...

    def effect_params(self, name: str) -> object:
        """Params of a listed effect, typed by name (ParameterError if the scene does not list it)."""
        try:
            return self.effects[name]
        except KeyError:
            raise ParameterError(
                'effects',
                name,
                f'scene {self.name!r} does not list this effect; it lists {", ".join(self.effects) or "none"}',
            ) from None

    @overload
    def machine(self, section: Literal['layup']) -> LayupParams: ...
    @overload
    def machine(self, section: Literal['container']) -> ContainerParams: ...
    @overload
    def machine(self, section: Literal['knife']) -> KnifeParams: ...
    @overload
    def machine(self, section: Literal['cyclogram']) -> CyclogramParams: ...
    @overload
    def machine(self, section: Literal['feed_transporter']) -> FeedTransporterParams: ...
    @overload
    def machine(self, section: Literal['delivery']) -> DeliveryParams: ...
    @overload
    def machine(self, section: Literal['delivery_chain']) -> ChainParams: ...
    @overload
    def machine(self, section: str) -> MachineParams: ...

    def machine(self, section: str) -> MachineParams:
        """Params of a machine section, typed by section (ParameterError if the scene has none)."""
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


def check_press_speed(n_k: float, n_c: float) -> None:
    """Refuse a knife speed that is not :data:`~folder_line.core.mechanisms.cyclogram.KNIFE_PER_CYLINDER` times the
    folding cylinder's (to rounding: a relative 1e-9).

    Parameters
    ----------
    n_k : float
        Knife crank speed, rev/h (``knife.n_k``).
    n_c : float
        Folding cylinder speed, rev/h (``cyclogram.n_c``).

    Raises
    ------
    ParameterError
        Naming both keys and values, and ``press.n_c``, which sets both.
    """
    if abs(n_k - KNIFE_PER_CYLINDER * n_c) > _PRESS_RTOL * max(abs(n_k), KNIFE_PER_CYLINDER * abs(n_c)):
        raise ParameterError(
            'knife.n_k',
            n_k,
            f'must be {KNIFE_PER_CYLINDER:g} x cyclogram.n_c={n_c!r} rev/h (the knife turns twice per cylinder '
            f'turn, paper 001); set both with press.n_c=<cylinder rev/h>',
        )


def parse_scene(data: Mapping[str, object]) -> Scene:
    """Validate a complete scene mapping.

    Parameters
    ----------
    data : mapping
        Keys :data:`SCENE_KEYS`; ``machines`` maps sections to complete parameter
        mappings; ``effects`` maps effect names to parameter mappings.

    Raises
    ------
    ParameterError
        Names the offending key (``knife.r_k``, ``effects.feed_slip.mu`` ...)
        and value; an unknown effect lists the known ones; an effect whose machine is
        not in the scene says which machine is missing.
    """
    if not isinstance(data, Mapping):
        raise ParameterError('scene', data, 'must be a mapping')
    check_keys(data, SCENE_KEYS, '', 'scene key')
    name = data.get('name')
    if not isinstance(name, str) or not name:
        raise ParameterError('name', name, 'must be a non-empty string')
    description = data.get('description', '')
    if not isinstance(description, str):
        raise ParameterError('description', description, 'must be a string')
    machines = _parse_machines(data.get('machines') or {})
    effects = _parse_effects(data.get('effects') or {}, name, machines)
    drive = build(DriveSpec, data.get('drive') or {'profile': 'constant'}, 'drive', 'drive parameter')
    sheets = build(StreamParams, data.get('sheets') or {}, 'sheets', 'sheets parameter')
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


def _parse_machines(sections: object) -> dict[str, MachineParams]:
    """The scene's ``machines``: each section validated, each machine's companions present, the press speed one."""
    if not isinstance(sections, Mapping) or not sections:
        raise ParameterError('machines', sections, f'must map at least one machine; known: {", ".join(MACHINES)}')
    machines: dict[str, MachineParams] = {
        sec: build(machine_class(sec), values, sec, f'{sec} parameter') for sec, values in sections.items()
    }
    for sec in machines:
        for need in _NEEDS.get(sec, ()):
            if need not in machines:
                raise ParameterError('machines', sec, f'needs machine {need!r} in the scene as well')
    knife, cylinder = machines.get('knife'), machines.get('cyclogram')
    if isinstance(knife, KnifeParams) and isinstance(cylinder, CyclogramParams):
        check_press_speed(knife.n_k, cylinder.n_c)
    return machines


def _parse_effects(effects_in: object, name: str, machines: Mapping[str, MachineParams]) -> dict[str, object]:
    """The scene's ``effects``: each a known effect whose machines scene ``name`` has, its parameters validated."""
    if not isinstance(effects_in, Mapping):
        raise ParameterError('effects', effects_in, 'must map effect names to their parameters')
    effects: dict[str, object] = {}
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
    return effects
