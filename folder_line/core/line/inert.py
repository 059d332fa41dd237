"""Scene values that would do nothing: the keys a scene's machines and effects never read.

A value a user gives (in a scene file or with ``--set``) that the model never reads for
that scene is an error, not a silent no-op: :func:`inert_reason` says why a key does
nothing in a scene with these machines and effects, and what to use instead. The loader
(:mod:`folder_line.config.scenes`) asks it for every value the user gave that differs
from the default (a merged scene written by ``run`` carries the defaults, and those stay
harmless)::

    | key | read only with | otherwise |
    |---|---|---|
    | ``sheets.interval``, ``sheets.jitter`` | the layup (L) | F takes one signature per knife cycle |
    | ``drive.*`` | no ``motor_dynamics`` | the motor's ODE sets the speed and brakes |
    | ``delivery.f_*``, ``delivery.r_*`` | ``chain_friction`` | only the efficiency and forces use friction |
    | ``layup.v_tr`` | ``chute_belts`` | without belts a leaf leaves with the swing speed |
    | ``container.*`` | ``leaf_flight`` | no leaf reaches the container |
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass

__all__ = ['INERT_RULES', 'InertRule', 'inert_reason']

#: the delivery's friction parameters (:class:`folder_line.core.mechanisms.delivery.DeliveryParams`)
_DELIVERY_FRICTION = ('f_Ap', 'f_Bp', 'f_A', 'f_B', 'f_O', 'r_A', 'r_B', 'r_O')


@dataclass(frozen=True)
class InertRule:
    """Keys of one section that need something in the scene to be read.

    Attributes
    ----------
    section : str
        Scene section (a machine, ``sheets`` or ``drive``).
    fields : tuple of str
        Its fields the rule covers (empty: all).
    why : str
        Why the keys then do nothing, and what to use instead.
    machine, effect : str
        The machine that must be in the scene, or the effect it must list (``''``: no such need).
    without : str
        An effect whose presence makes the keys inert (``''``: none).
    """

    section: str
    fields: tuple[str, ...]
    why: str
    machine: str = ''
    effect: str = ''
    without: str = ''

    def covers(self, key: str) -> bool:
        """Whether the dotted ``key`` (``sheets.jitter``) is one of the rule's."""
        head, _, field = key.partition('.')
        return head == self.section and (not self.fields or field in self.fields)

    def inert(self, machines: Collection[str], effects: Collection[str]) -> bool:
        """Whether the rule's keys do nothing in a scene with these machines and effects."""
        if self.machine and self.machine not in machines:
            return True
        if self.effect and self.effect not in effects:
            return True
        return bool(self.without) and self.without in effects


#: every key a scene may hold that some scenes never read
INERT_RULES: tuple[InertRule, ...] = (
    InertRule(
        'sheets',
        ('interval', 'jitter'),
        machine='layup',
        why='the folder takes one signature per knife cycle; only the layup (L) reads sheets.interval and '
        'sheets.jitter (for jitter of the sheet arrivals list the effect arrival_jitter)',
    ),
    InertRule(
        'drive',
        (),
        without='motor_dynamics',
        why='the scene lists motor_dynamics, whose ODE sets the speed (and T_brake the braking); leave the drive out',
    ),
    InertRule(
        'delivery',
        _DELIVERY_FRICTION,
        effect='chain_friction',
        why='only the chain_friction effect (efficiency, forces, sprocket torque) reads the delivery friction; list it',
    ),
    InertRule(
        'layup',
        ('v_tr',),
        effect='chute_belts',
        why='layup.v_tr is the chute belt speed, read only with the effect chute_belts; list it',
    ),
    InertRule(
        'container',
        (),
        effect='leaf_flight',
        why='no leaf reaches the container without the effect leaf_flight; list it',
    ),
)


def inert_reason(key: str, machines: Collection[str], effects: Collection[str]) -> str | None:
    """Why ``key`` does nothing in a scene with ``machines`` and ``effects``, or None if it is read.

    Parameters
    ----------
    key : str
        Dotted scene key (``sheets.jitter``, ``drive.t_brake``, ``delivery.f_A``).
    machines, effects : collection of str
        The scene's machine sections and listed effects.

    Returns
    -------
    str or None
        Why, and what to use instead (:attr:`InertRule.why`).
    """
    for rule in INERT_RULES:
        if rule.covers(key) and rule.inert(machines, effects):
            return rule.why
    return None
