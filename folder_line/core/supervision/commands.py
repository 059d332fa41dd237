"""Command scheduling: the drive commands issued, their effective times, and when acting states end.

Drive commands (:mod:`folder_line.core.mechanisms.drive`): ``hold``, ``suspend`` and ``stop``
take the drive down from the next machine cycle boundary at least ``lead`` s after
the decision (:meth:`folder_line.core.line.cycles.MachineCycles.next_boundary`; the line
stops between two sheets), ``abort`` from ``lead`` s after it (``stop`` kind),
``start``, ``unhold`` and ``unsuspend`` bring it back ``lead`` s after the command.
``lead`` is the time the command needs to reach every node before it is due;
effective times are rounded to the nanosecond (the resolution of the command
topic), so that the supervisor and the nodes build the same drive.

The drive under the commands (:func:`folder_line.core.line.drives.make_drive`) is updated
in place when a command is issued: before its time a command changes nothing, bit for
bit, and with ``motor_dynamics`` the integration done so far is kept, so a command costs
the same at any line time.

An acting state ends at the first check-grid point at or after its drive command's
effective time where the drive is at speed (λ >= ``speed_reached``: STARTING,
UNHOLDING, UNSUSPENDING) or at standstill (λ = 0: HOLDING, SUSPENDING, STOPPING,
ABORTING, COMPLETING); RESETTING and CLEARING end at the next grid point
(:class:`ActingState`).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from folder_line.core.line.cycles import MachineCycles
from folder_line.core.line.drives import make_drive
from folder_line.core.line.scene import Scene
from folder_line.core.line.tuning import LineCommand
from folder_line.core.mechanisms.drive import Drive, target_rate
from folder_line.core.supervision.grid import CheckGrid
from folder_line.core.supervision.packml import ACTING, PackML, Transition

__all__ = [
    'ACTING_ENDS',
    'DRIVE_COMMANDS',
    'STOP_STATES',
    'ActingState',
    'DriveFactory',
    'DriveSchedule',
    'line_drives',
]

#: PackML command -> (drive command kind or None, waits for the next machine cycle boundary)
DRIVE_COMMANDS: dict[str, tuple[str | None, bool]] = {
    'start': ('start', False),
    'stop': ('stop', True),
    'hold': ('hold', True),
    'unhold': ('unhold', False),
    'suspend': ('hold', True),
    'unsuspend': ('unhold', False),
    'abort': ('stop', False),
    'complete': ('stop', True),
    'reset': (None, False),
    'clear': (None, False),
}
#: acting state -> what ends it
ACTING_ENDS: dict[str, str] = {
    'STARTING': 'speed',
    'UNHOLDING': 'speed',
    'UNSUSPENDING': 'speed',
    'HOLDING': 'standstill',
    'SUSPENDING': 'standstill',
    'STOPPING': 'standstill',
    'ABORTING': 'standstill',
    'COMPLETING': 'standstill',
    'RESETTING': 'next',
    'CLEARING': 'next',
}
if set(ACTING_ENDS) != set(ACTING):  # pragma: no cover - a programming error, caught on import
    raise RuntimeError('every acting state needs an end')
#: waiting states in which the line stands: the sheet balance is checked on entering them
STOP_STATES = ('HELD', 'SUSPENDED', 'STOPPED', 'ABORTED', 'COMPLETE')

_NS = 1_000_000_000
_CAUSES = {'speed': 'drive at speed', 'standstill': 'drive at standstill', 'next': 'done'}

#: ``(commands, the drive under the commands before) -> the drive under them``
DriveFactory = Callable[[tuple[LineCommand, ...], Drive | None], Drive]


def _ns_round(t: float) -> float:
    """``t`` rounded to the nanosecond (what a ``builtin_interfaces/Time`` carries), s."""
    return round(t * _NS) / _NS


def line_drives(scene: Scene) -> DriveFactory:
    """``(commands, previous) -> make_drive(scene, commands, previous)``."""

    def drive_factory(commands: tuple[LineCommand, ...], previous: Drive | None) -> Drive:
        return make_drive(scene, commands, previous)

    return drive_factory


class DriveSchedule:
    """The drive commands issued so far and the drive under them.

    Parameters
    ----------
    scene : Scene
        For the machine cycles (:class:`folder_line.core.line.cycles.MachineCycles`).
    factory : callable
        ``(commands, previous drive) -> Drive`` (:func:`line_drives`).
    lead : float
        Earliest effective time of a drive command after its decision, s (>= 0).

    Attributes
    ----------
    commands : tuple of Command
        Issued, sorted by effective time.
    issued : list of (float, Command)
        ``(decision time, command)`` not yet taken (:meth:`take`), in issue order.
    cycles : MachineCycles
    """

    def __init__(self, scene: Scene, factory: DriveFactory, lead: float) -> None:
        self._factory = factory
        self.lead = lead
        self.cycles = MachineCycles(scene)
        self.commands: tuple[LineCommand, ...] = ()
        self.issued: list[tuple[float, LineCommand]] = []
        self._drive: Drive | None = None
        self._drive_commands: tuple[LineCommand, ...] = ()

    @property
    def drive(self) -> Drive:
        """The drive under the commands issued so far (right at every time: a command changes nothing before
        its effective time)."""
        if self._drive is None or self._drive_commands != self.commands:
            self._drive = self._factory(self.commands, self._drive)
            self._drive_commands = self.commands
        return self._drive

    def effective(self, t: float, at_boundary: bool) -> float:
        """Effective time of a drive command decided at ``t``: ``lead`` later, then (``at_boundary``) at the
        next machine cycle boundary, rounded to the nanosecond."""
        earliest = t + self.lead
        if at_boundary:
            b = self.cycles.next_boundary(self.drive, earliest)
            if math.isfinite(b):  # else no further cycle (the line stands): at once
                earliest = b
        return _ns_round(earliest)

    def issue(self, t: float, cmd: LineCommand) -> None:
        """Command ``cmd``, decided at ``t``, is issued."""
        self.commands = tuple(sorted((*self.commands, cmd), key=lambda c: c.t))
        self.issued.append((t, cmd))

    def take(self) -> list[tuple[float, LineCommand]]:
        """``(decision time, drive command)`` issued since the last call, in issue order."""
        out, self.issued = self.issued, []
        return out


class ActingState:
    """When the current acting state ends, on the check grid.

    Parameters
    ----------
    grid : CheckGrid
    speed_reached : float
        Speed factor at which a run command's acting state ends.
    since : float
        When the current acting state's drive command is effective (or its command's
        time), s.
    """

    def __init__(self, grid: CheckGrid, speed_reached: float, since: float) -> None:
        self.grid = grid
        self.speed_reached = speed_reached
        self.since = since
        self._grid_from = -1  # first grid index not yet known to fail the acting state's condition

    def begin(self, since: float) -> None:
        """A command was applied: the new state's condition holds from ``since`` on (s)."""
        self.since = since
        self._grid_from = -1

    def completion(self, state: str, W: float, drive_before: Callable[[], Drive]) -> float | None:
        """Grid time at which acting state ``state`` ends, if by ``W`` (None for a waiting state).

        ``drive_before()`` gives the drive that is right before ``W`` (called only if the
        state ends at speed or at standstill).
        """
        end = ACTING_ENDS.get(state)
        if end is None:
            return None
        first = self.grid.index_after if end == 'next' else self.grid.index_at_or_after
        n0 = max(first(self.since), self._grid_from)
        n1 = self.grid.index_after(W) - 1  # last grid index <= W
        if n1 < n0:
            return None
        if end == 'next':
            return n0 * self.grid.h
        g = np.arange(n0, n1 + 1, dtype=float) * self.grid.h
        drive = drive_before()
        lam = np.asarray(drive.rate(g), dtype=float)
        # at speed: the speed the drive heads for (the press speed setting; 1 nominal), to speed_reached
        hit = lam >= self.speed_reached * target_rate(drive, g) if end == 'speed' else lam <= 0.0
        j = int(np.argmax(hit)) if hit.size else 0
        if hit.size and hit[j]:
            return float(g[j])
        self._grid_from = n1 + 1
        return None

    def end(self, packml: PackML, t: float) -> Transition:
        """End the acting state of ``packml`` at ``t`` (its :meth:`completion`)."""
        tr = packml.state_complete(t, _CAUSES[ACTING_ENDS[packml.state]])
        self._grid_from = -1
        return tr
