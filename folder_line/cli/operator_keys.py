"""The operator keys of ``folder-line monitor``'s live view: a key -> a supervisor command, the ones
that take the line down confirmed first."""

from __future__ import annotations

__all__ = ['CONFIRM', 'OPERATOR_KEYS', 'OperatorKeys']


#: the live view's keys for the supervisor's operator commands
OPERATOR_KEYS: dict[str, str] = {
    'h': 'hold',
    'u': 'unhold',
    's': 'start',
    'x': 'stop',
    'r': 'reset',
    'c': 'clear',
    'a': 'abort',
}
#: commands the operator confirms with ``y`` first (they take the line down)
CONFIRM = frozenset({'stop', 'abort'})


class OperatorKeys:
    """The operator keys of the live view: a key -> a command to send, ``stop`` and ``abort`` confirmed first.

    Attributes
    ----------
    line : str
        What the view shows of it: the keys, a confirmation question, or the latest answer.
    pending : str or None
        A command waiting for its confirmation.
    keyed : bool
        The monitor has the line's key: a closed line answers only then (:mod:`folder_line.ros.line_key`).
    """

    def __init__(self, keyed: bool = True) -> None:
        self.pending: str | None = None
        self.line = ''
        self.keyed = keyed

    @staticmethod
    def keys() -> str:
        """``h hold  u unhold ...``."""
        return '  '.join(f'{k} {c}' for k, c in OPERATOR_KEYS.items())

    def press(self, key: str) -> str | None:
        """The command to send now for ``key``, or None (not a command key, or waiting for / refused a confirmation)."""
        if self.pending is not None:
            asked = self.pending
            self.pending = None
            if key in ('y', 'Y'):
                return asked
            self.line = f'{asked}: cancelled'
            return None
        command = OPERATOR_KEYS.get(key)
        if command is not None and command in CONFIRM:
            self.pending = command
            self.line = f'{command} the line? y: yes, any other key: no'
            return None
        return command

    def sent(self, command: str) -> None:
        """``command`` went out."""
        self.line = f'{command}: sent, waiting for the supervisor' + (
            '' if self.keyed else " (a closed line answers only a monitor started with the line's FOLDER_LINE_KEY)"
        )

    def answer(self, command: str, accepted: bool, message: str) -> None:
        """The supervisor answered ``command``."""
        self.line = f'{command}: {"accepted" if accepted else "refused"}: {message}'

    def no_service(self, command: str) -> None:
        """No supervisor offers ``command`` on this domain (yet)."""
        self.line = f'{command}: no supervisor service on this ROS domain; nothing sent'

    def styled(self) -> tuple[str, str]:
        """The operator row of the screen, with its style."""
        text = (f'operator: {self.line} | ' if self.line else 'operator keys: ') + self.keys()
        return text, 'alert' if self.pending is not None or ': refused:' in self.line else ''
