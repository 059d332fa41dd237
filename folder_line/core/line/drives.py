"""The master drive of a scene under the supervisor's commands and the operator's tunings: :func:`make_drive`.

The motor's ODE if the scene lists ``motor_dynamics``
(:class:`folder_line.core.effects.motor_dynamics.MotorDrive`, integrated as far as the
line is asked for), else the drive profile with the ramp generator
(:func:`folder_line.core.mechanisms.drive.commanded_drive`); with ``speed_ripple`` that drive
rippled on top (:class:`folder_line.core.effects.speed_ripple.RippleDrive`, its phase drawn
from the seed). Without commands both are exactly the drives of a run without a
supervisor, and a command changes nothing before its effective time, bit for bit.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING

from folder_line.core.effects import motor_dynamics, speed_ripple
from folder_line.core.line.tuning import LineCommand, Tuning, belt_steps, scene_value
from folder_line.core.mechanisms.drive import Command, Drive, commanded_drive

if TYPE_CHECKING:
    from folder_line.core.line.scene import Scene

__all__ = ['make_drive']


def make_drive(scene: Scene, commands: Iterable[LineCommand] = (), previous: Drive | None = None) -> Drive:
    """The master drive of ``scene`` under ``commands`` (sorted by effective time).

    Parameters
    ----------
    scene : Scene
    commands : iterable of Command or Tuning
        The supervisor's drive commands; the operator's tunings of ``press.n_c`` set the
        speed the ramp generator heads for (as a factor of the scene's press speed).
    previous : Drive, optional
        The drive under the commands before (with ``motor_dynamics`` the integration done
        so far is kept up to the first command that changed).
    """
    commands = list(commands)
    drive_commands = [c for c in commands if isinstance(c, Command)]
    base: Drive
    if scene.has('motor_dynamics'):  # the press speed is not tunable there (core.line.tuning)
        prev = previous.base if isinstance(previous, speed_ripple.RippleDrive) else previous
        base = motor_dynamics.stream_drive(
            scene, drive_commands, prev if isinstance(prev, motor_dynamics.MotorDrive) else None
        )
    else:
        tunings = [c for c in commands if isinstance(c, Tuning)]
        speeds = belt_steps(tunings, 'press.n_c', scene_value(scene, 'press.n_c')) if scene.has_folder else []
        base = commanded_drive(scene.drive, drive_commands, speeds)
    if scene.has('speed_ripple'):
        return speed_ripple.RippleDrive(base, scene.effect_params('speed_ripple'), speed_ripple.draw_phase(scene.seed))
    return base
