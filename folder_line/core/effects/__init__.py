"""Effects a scene may list; the simulator runs only the listed ones.

Each effect is a small module of this package defining a frozen dataclass
``Params`` (no defaults: a listed effect must give every parameter) and the
functions the simulator calls when, and only when, the scene lists the effect.
The registry below says which machine sections an effect needs; a scene's effect
parameters are built into the effect's ``Params`` by :func:`parse_effect_params`, with
the one builder of validated parameters, :func:`folder_line.core.numerics.validate.build`::

    | effect | machines | what it adds |
    |---|---|---|
    | chute_belts | layup | belts along the chutes at v_tr: exit speed sqrt(v_C² + v_tr²) (paper 000 eq. 25) |
    | leaf_flight | layup, container | flight from the chute exit to the floor, landing x, histogram |
    | guide_friction | layup | without belts: the leaf slides on the guide (gravity, Coulomb friction, swing) |
    | leaf_damage | layup | leaves leaving at or above v_damage are counted as damaged |
    | motor_dynamics | (any) | the master drive from a motor torque-speed curve and inertia (an ODE) |
    | chain_friction | delivery | efficiency, rod and chain forces, sprocket torque (paper 002) |
    | feed_slip | feed_transporter | the signature accelerated from V_d to V_tr by friction |
    | stop_bounce | feed_transporter | restitution at the front stops, settle time and rebound |
    | faults | (any) | seeded missing, double and late sheets, belt slow-downs |
    | arrival_jitter | feed_transporter | per-sheet hand-over position error (normal/uniform, σ mm): travel L_feed + δ |
    | length_scatter | feed_transporter | per-sheet length scatter (σ mm): leading edge ΔL on, travel L_feed - ΔL |
    | speed_ripple | (any) | master drive speed ripple locked to its phase (relative amplitude, Hz at nominal speed) |
    | property_scatter | feed_transporter | per-sheet scatter of stop_bounce's e and feed_slip's mu (relative σ) |

The four variation effects (the last rows) draw per sheet, from the scene seed's named
streams: sheet k's draw depends only on (seed, k), never on the horizon, on other
effects or on how many runs go on at once.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import ModuleType

from folder_line.core.effects import (
    arrival_jitter,
    chain_friction,
    chute_belts,
    faults,
    feed_slip,
    guide_friction,
    leaf_damage,
    leaf_flight,
    length_scatter,
    motor_dynamics,
    property_scatter,
    speed_ripple,
    stop_bounce,
)
from folder_line.core.numerics.validate import Dataclass, build
from folder_line.errors import ParameterError

__all__ = ['EFFECTS', 'EffectSpec', 'effect_spec', 'parse_effect_params']


@dataclass(frozen=True)
class EffectSpec:
    """One entry of the registry.

    Attributes
    ----------
    module : module
        The module implementing it (its frozen dataclass ``Params`` and the functions the
        simulators call).
    machines : tuple of str
        Machine sections the scene must have (empty: works with any).
    summary : str
        One line for error messages and docs.
    """

    module: ModuleType
    machines: tuple[str, ...]
    summary: str

    @property
    def name(self) -> str:
        """The name a scene lists: the module's own name."""
        return self.module.__name__.rpartition('.')[2]

    @property
    def params(self) -> type[Dataclass]:
        """The effect's frozen parameter dataclass."""
        cls: type[Dataclass] = self.module.Params
        return cls


EFFECTS: dict[str, EffectSpec] = {
    spec.name: spec
    for spec in (
        EffectSpec(chute_belts, ('layup',), 'belts along the chutes at v_tr (paper 000 eq. 25)'),
        EffectSpec(leaf_flight, ('layup', 'container'), 'leaf flight from the chute exit to the container floor'),
        EffectSpec(guide_friction, ('layup',), 'leaf braked by Coulomb friction on the guide (no belts)'),
        EffectSpec(leaf_damage, ('layup',), 'leaves leaving at or above the damage speed are damaged'),
        EffectSpec(motor_dynamics, (), 'master drive from a motor torque-speed curve and inertia (ODE)'),
        EffectSpec(chain_friction, ('delivery',), 'delivery efficiency, forces and sprocket torque (paper 002)'),
        EffectSpec(feed_slip, ('feed_transporter',), 'signature accelerated from V_d to V_tr by friction'),
        EffectSpec(stop_bounce, ('feed_transporter',), 'restitution at the front stops, damped by the strings'),
        EffectSpec(faults, (), 'seeded missing, double and late sheets and belt slow-downs'),
        EffectSpec(arrival_jitter, ('feed_transporter',), 'per-sheet position error at the hand-over onto the feed'),
        EffectSpec(length_scatter, ('feed_transporter',), 'per-sheet scatter of the signature length'),
        EffectSpec(speed_ripple, (), 'master drive speed ripple locked to its phase'),
        EffectSpec(property_scatter, ('feed_transporter',), 'per-sheet scatter of restitution and friction'),
    )
}


def effect_spec(name: str) -> EffectSpec:
    """The registry's entry of effect ``name`` (ParameterError naming the known ones if there is none)."""
    if name not in EFFECTS:
        raise ParameterError('effects', name, f'unknown effect; known: {", ".join(EFFECTS)}')
    return EFFECTS[name]


def parse_effect_params(name: str, values: Mapping[str, object] | None) -> Dataclass:
    """Validated ``Params`` of effect ``name`` from the scene's mapping (None: no parameters given).

    Raises
    ------
    ParameterError
        Unknown effect (listing the known ones), a value that is not a mapping, an unknown or
        missing parameter (named ``effects.<name>.<key>``, listing the known or required ones),
        or a bad value.
    """
    return build(
        effect_spec(name).params, {} if values is None else values, f'effects.{name}', f'parameter of effect {name}'
    )
