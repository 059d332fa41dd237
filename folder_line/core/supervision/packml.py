"""The supervisor's state machine after PackML (ISA-TR88.00.02).

Pure logic, no time and no ROS: :meth:`PackML.command` applies an operator or
internal command and either moves to the next state or refuses with a reason
(:class:`folder_line.errors.TransitionError`); :meth:`PackML.state_complete`
ends an acting state ("-ING") in its waiting state.

=============  ==========================================================
command        legal from -> acting state -> (state complete) -> waiting
=============  ==========================================================
reset          STOPPED, COMPLETE -> RESETTING -> IDLE
start          IDLE -> STARTING -> EXECUTE
complete       EXECUTE -> COMPLETING -> COMPLETE
hold           EXECUTE, SUSPENDED -> HOLDING -> HELD
unhold         HELD -> UNHOLDING -> EXECUTE
suspend        EXECUTE -> SUSPENDING -> SUSPENDED
unsuspend      SUSPENDED -> UNSUSPENDING -> EXECUTE
stop           every state but STOPPED, STOPPING, ABORTING, ABORTED, CLEARING
               -> STOPPING -> STOPPED
abort          every state but ABORTING, ABORTED -> ABORTING -> ABORTED
clear          ABORTED -> CLEARING -> STOPPED
=============  ==========================================================
"""

from __future__ import annotations

from dataclasses import dataclass, field

from folder_line.errors import TransitionError

__all__ = ['ACTING', 'COMMANDS', 'STATES', 'PackML', 'Transition']

STATES: tuple[str, ...] = (
    'STOPPED',
    'RESETTING',
    'IDLE',
    'STARTING',
    'EXECUTE',
    'COMPLETING',
    'COMPLETE',
    'HOLDING',
    'HELD',
    'UNHOLDING',
    'SUSPENDING',
    'SUSPENDED',
    'UNSUSPENDING',
    'STOPPING',
    'ABORTING',
    'ABORTED',
    'CLEARING',
)

#: acting state -> the waiting state it ends in
ACTING: dict[str, str] = {
    'RESETTING': 'IDLE',
    'STARTING': 'EXECUTE',
    'COMPLETING': 'COMPLETE',
    'HOLDING': 'HELD',
    'UNHOLDING': 'EXECUTE',
    'SUSPENDING': 'SUSPENDED',
    'UNSUSPENDING': 'EXECUTE',
    'STOPPING': 'STOPPED',
    'ABORTING': 'ABORTED',
    'CLEARING': 'STOPPED',
}

_NOT_STOPPABLE = frozenset({'STOPPED', 'STOPPING', 'ABORTING', 'ABORTED', 'CLEARING'})

#: command -> (states it is legal from, acting state it leads to)
COMMANDS: dict[str, tuple[frozenset[str], str]] = {
    'reset': (frozenset({'STOPPED', 'COMPLETE'}), 'RESETTING'),
    'start': (frozenset({'IDLE'}), 'STARTING'),
    'complete': (frozenset({'EXECUTE'}), 'COMPLETING'),
    'hold': (frozenset({'EXECUTE', 'SUSPENDED'}), 'HOLDING'),
    'unhold': (frozenset({'HELD'}), 'UNHOLDING'),
    'suspend': (frozenset({'EXECUTE'}), 'SUSPENDING'),
    'unsuspend': (frozenset({'SUSPENDED'}), 'UNSUSPENDING'),
    'stop': (frozenset(STATES) - _NOT_STOPPABLE, 'STOPPING'),
    'abort': (frozenset(STATES) - {'ABORTING', 'ABORTED'}, 'ABORTING'),
    'clear': (frozenset({'ABORTED'}), 'CLEARING'),
}


@dataclass(frozen=True)
class Transition:
    """One state change: at line time ``t`` (s), ``source`` -> ``target`` because of ``cause``."""

    t: float
    source: str
    target: str
    cause: str


@dataclass
class PackML:
    """The state machine; ``history`` keeps every transition.

    Parameters
    ----------
    state : str
        Initial state (default ``STOPPED``).
    """

    state: str = 'STOPPED'
    history: list[Transition] = field(default_factory=list)

    def __post_init__(self) -> None:
        if self.state not in STATES:
            raise TransitionError(self.state, 'init', f'unknown state; states: {", ".join(STATES)}')

    def allowed(self, command: str) -> bool:
        """Whether ``command`` is legal now."""
        return command in COMMANDS and self.state in COMMANDS[command][0]

    def command(self, command: str, t: float, cause: str = '') -> Transition:
        """Apply ``command`` at time ``t`` or raise :class:`TransitionError` with the reason."""
        if command not in COMMANDS:
            raise TransitionError(self.state, command, f'unknown command; commands: {", ".join(COMMANDS)}')
        legal, target = COMMANDS[command]
        if self.state not in legal:
            raise TransitionError(self.state, command, f'legal only in {", ".join(s for s in STATES if s in legal)}')
        return self._move(target, t, cause or command)

    def state_complete(self, t: float, cause: str = 'state complete') -> Transition:
        """End the current acting state in its waiting state."""
        if self.state not in ACTING:
            raise TransitionError(self.state, 'state_complete', 'not an acting state')
        return self._move(ACTING[self.state], t, cause)

    def _move(self, target: str, t: float, cause: str) -> Transition:
        tr = Transition(t, self.state, target, cause)
        self.state = target
        self.history.append(tr)
        return tr
