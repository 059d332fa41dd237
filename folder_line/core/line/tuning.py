"""Live tuning: the settings an operator changes on a running line, and when they take effect.

On a real line the operator turns a few knobs while the machine runs; geometry and
the process stay as built. Here those knobs are :data:`TUNABLES`:

=========================  =====  ==================================================
key                        unit   what changes from the effective time on
=========================  =====  ==================================================
``feed_transporter.V_tr``  m/s    the folder's 2nd transporter (feed belt) speed
``layup.v_tr``             m/s    the layup chute belts' speed (with ``chute_belts``)
``press.n_c``              rev/h  the press speed: the master drive ramps to
                                  ``value / scene value`` of nominal (every machine
                                  is geared to it), not with ``motor_dynamics``
``pile.t_lower``           s      the time the pile lift takes to lower one sheet
=========================  =====  ==================================================

A :class:`Tuning` carries a key, its new value and its effective time ``t``; like a
drive command it is decided by the supervisor and takes effect at the next machine
cycle boundary (:mod:`folder_line.core.supervision.commands`), so every node and the
batch model agree on it. Models take tunings with the commands
(:class:`folder_line.core.line.model.LineModel`): before ``t`` a tuning changes
nothing, bit for bit; after it:

* a belt's speed is the scene's speed times a factor ``value / scene value`` from
  ``t`` on (:func:`belt_steps`, combined with the ``faults`` effect's slow-downs by
  :func:`folder_line.core.mechanisms.belt.combine_factors`), so a signature or leaf on
  the belt at ``t`` rides the rest of its way at the new speed, exactly;
* the pile lift lowers each sheet counted at or after ``t`` over the new time;
* the master drive ramps from ``t`` to the new press speed at its ramp rates
  (:func:`folder_line.core.mechanisms.drive.ramp_generator`); the supervisor's acting
  states end at the speed set, not at nominal. With ``motor_dynamics`` the motor curve
  sets the speed: not tunable there.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from folder_line.core.limits import CYLINDER_SPEED, LINEAR_SPEED, PILE_LOWERING, Limit
from folder_line.core.mechanisms.drive import Command
from folder_line.core.mechanisms.pile import T_LOWER
from folder_line.core.numerics.validate import non_negative
from folder_line.errors import ParameterError

if TYPE_CHECKING:
    from folder_line.core.line.scene import Scene

__all__ = [
    'SCENE_KEYS',
    'SET_PREFIX',
    'TUNABLES',
    'LineCommand',
    'Tunable',
    'Tuning',
    'belt_steps',
    'check_tuning',
    'command_of',
    'parse_tuning_text',
    'scene_value',
    'tuning_text',
    'tunings_of',
    'values_from',
]

#: how a tuning reads on the supervisor's command topic and in the logs: ``'set feed_transporter.V_tr=9.5'``
SET_PREFIX = 'set '


@dataclass(frozen=True)
class Tunable:
    """One setting an operator may change on a running line.

    Attributes
    ----------
    key : str
        ``machine.field`` as ``--set`` names it.
    limit : Limit
        Its physical range.
    what : str
        What it is, for messages and ``--help``.
    needs : callable
        ``scene -> reason or ''``: why the scene cannot take it ('' if it can).
    """

    key: str
    limit: Limit
    what: str
    needs: Callable[[Scene], str]

    @property
    def unit(self) -> str:
        """Unit of the value."""
        return self.limit.unit


def _needs_folder(scene: Scene) -> str:
    return '' if scene.has_folder else f'scene {scene.name!r} has no knife folder (no feed transporter)'


def _needs_belts(scene: Scene) -> str:
    if not scene.has_layup:
        return f'scene {scene.name!r} has no layup device'
    if not scene.has('chute_belts'):
        return f'scene {scene.name!r} does not list chute_belts: its chutes have no belts to speed up or slow down'
    return ''


def _needs_press(scene: Scene) -> str:
    if not scene.has_folder:
        return f'scene {scene.name!r} has no knife folder: its press speed is the layup crank speed layup.n_kr'
    if scene.has('motor_dynamics'):
        return (
            f'scene {scene.name!r} lists motor_dynamics: its motor curve sets the press speed '
            '(effects.motor_dynamics.omega_nom); change it in the scene and restart'
        )
    return ''


def _needs_nothing(scene: Scene) -> str:
    return ''


TUNABLES: dict[str, Tunable] = {
    t.key: t
    for t in (
        Tunable('feed_transporter.V_tr', LINEAR_SPEED, "the feed transporter's belt speed", _needs_folder),
        Tunable('layup.v_tr', LINEAR_SPEED, 'the chute belt speed', _needs_belts),
        Tunable('press.n_c', CYLINDER_SPEED, 'the press speed (folding cylinder)', _needs_press),
        Tunable('pile.t_lower', PILE_LOWERING, 'the time the pile lift takes to lower one sheet', _needs_nothing),
    )
}


#: the tunables a scene also sets (``--set``, the scene file); ``pile.t_lower`` is the model's constant
SCENE_KEYS = frozenset(TUNABLES) - {'pile.t_lower'}


def scene_value(scene: Scene, key: str) -> float:
    """The scene's own value of tunable ``key`` (before any tuning)."""
    if key == 'pile.t_lower':
        return T_LOWER
    if key == 'press.n_c':
        return float(scene.machine('cyclogram').n_c)
    machine, _, field = key.partition('.')
    return float(getattr(scene.machine(machine), field))


def check_tuning(scene: Scene, key: str, value: object) -> float:
    """``value`` of tunable ``key`` as a float, if ``scene`` can take it.

    Raises
    ------
    ParameterError
        Naming the key and the value: not tunable (listing the tunables), out of its
        range, or the scene has nothing it acts on.
    """
    tunable = TUNABLES.get(key)
    if tunable is None:
        raise ParameterError(
            key,
            value,
            f'is not tunable on a running line; tunable: {", ".join(TUNABLES)} '
            '(geometry and the effects are set in the scene)',
        )
    x = tunable.limit.check(key, value)
    why = tunable.needs(scene)
    if why:
        raise ParameterError(key, value, why)
    return x


@dataclass(frozen=True)
class Tuning:
    """A change of a tunable setting, effective at ``t``.

    Attributes
    ----------
    t : float
        Effective time, s (finite, >= 0).
    key : str
        A key of :data:`TUNABLES`.
    value : float
        The new value, in the tunable's unit, inside its range.
    """

    t: float
    key: str
    value: float

    def __post_init__(self) -> None:
        object.__setattr__(self, 't', non_negative('tuning.t', self.t))
        tunable = TUNABLES.get(self.key)
        if tunable is None:
            raise ParameterError('tuning.key', self.key, f'must be one of {", ".join(TUNABLES)}')
        object.__setattr__(self, 'value', tunable.limit.check(self.key, self.value))

    @property
    def kind(self) -> str:
        """The command-topic text of this tuning (:func:`tuning_text`)."""
        return tuning_text(self.key, self.value)


#: what the supervisor issues and a line model takes: a drive command or a tuning, each with its effective time
LineCommand = Command | Tuning


def tuning_text(key: str, value: float) -> str:
    """``'set feed_transporter.V_tr=9.5'``: ``repr`` of the value, so it reads back exactly."""
    return f'{SET_PREFIX}{key}={float(value)!r}'


def parse_tuning_text(text: str) -> tuple[str, float]:
    """``(key, value)`` of :func:`tuning_text` (ValueError saying what is wrong)."""
    if not text.startswith(SET_PREFIX):
        raise ValueError(f'a tuning reads {SET_PREFIX!r}KEY=VALUE, got {text[:60]!r}')
    key, eq, value = text[len(SET_PREFIX) :].partition('=')
    if not eq or key not in TUNABLES:
        raise ValueError(f'unknown tunable in {text[:60]!r}; tunable: {", ".join(TUNABLES)}')
    x = float(value)
    if not math.isfinite(x):
        raise ValueError(f'value of {key} must be finite, got {value[:30]!r}')
    return key, x


def tunings_of(commands: Iterable[object]) -> tuple[Tuning, ...]:
    """The tunings among a model's commands, in order."""
    return tuple(c for c in commands if isinstance(c, Tuning))


def values_from(tunings: Iterable[Tuning], key: str, nominal: float) -> list[tuple[float, float]]:
    """``(t, value)`` of ``key`` from each of its tunings on (sorted by ``t``), starting with ``(0, nominal)``.

    A later tuning at the same time wins.
    """
    steps: list[tuple[float, float]] = [(0.0, float(nominal))]
    for tu in sorted((tu for tu in tunings if tu.key == key), key=lambda tu: tu.t):
        if tu.t == steps[-1][0]:
            steps[-1] = (tu.t, tu.value)
        else:
            steps.append((tu.t, tu.value))
    return steps


def belt_steps(tunings: Iterable[Tuning], key: str, nominal: float) -> list[tuple[float, float]]:
    """``(t, factor)`` of a belt from each tuning of ``key`` on: the new speed over the scene's ``nominal``.

    Empty when nothing tunes the belt (its phase then is bit for bit the untuned one).
    """
    tuned = [tu for tu in tunings if tu.key == key]
    if not tuned:
        return []
    return [(t, v / float(nominal)) for t, v in values_from(tuned, key, nominal)]


def command_of(t: float, text: str) -> LineCommand:
    """The command the supervisor published as ``text`` with effective time ``t`` (s): a tuning
    (:func:`tuning_text`) or a drive command kind. ValueError or ParameterError saying what is wrong."""
    if text.startswith(SET_PREFIX):
        key, value = parse_tuning_text(text)
        return Tuning(t, key, value)
    return Command(t, text)
