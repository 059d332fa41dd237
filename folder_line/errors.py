"""Every exception folder_line raises on purpose.

Messages are built first and then raised, and always name the offending
parameter (or crank angle) and its value, so that the command line can print
them as one line and exit with code 2.
"""

from __future__ import annotations

import reprlib

__all__ = [
    'MESSAGE_VALUE_CHARS',
    'AssemblyError',
    'BagError',
    'FolderLineError',
    'InputFileError',
    'IntegrationError',
    'MeasurementError',
    'NoConvergenceError',
    'NonFiniteValueError',
    'NotBracketedError',
    'OutputError',
    'ParameterError',
    'RootFindingError',
    'TransitionError',
    'bounded_repr',
    'path_repr',
    'shorten',
]

#: longest rendering of a user-given value (or key) inside an error message, characters
MESSAGE_VALUE_CHARS = 80


def shorten(text: str, limit: int = MESSAGE_VALUE_CHARS) -> str:
    """``text`` cut to at most ``limit`` characters, the cut marked by an ellipsis (``...``)."""
    if len(text) <= limit:
        return text
    return text[: max(limit - 3, 1)] + '...'


#: longest path printed whole in a message, characters (a longer one keeps its start and its end)
PATH_CHARS = 240


def path_repr(path: object, limit: int = PATH_CHARS) -> str:
    """``repr`` of a path for a message: whole up to ``limit`` characters, else its start and its end
    (where the file's name is) around an ellipsis, so that the reason after it is still read."""
    text = repr(str(path))
    if len(text) <= limit:
        return text
    half = (limit - 3) // 2
    return text[:half] + '...' + text[-half:]


class _BoundedRepr(reprlib.Repr):
    """``reprlib`` with bounded work as well as bounded output: an int too long for ``repr``
    (over 4300 digits raises ValueError) is described by its size, and nesting is cut early,
    so that a YAML bomb of shared nested lists costs microseconds to describe."""

    def __init__(self) -> None:
        super().__init__()
        self.maxlevel = 3
        self.maxstring = self.maxother = self.maxlong = MESSAGE_VALUE_CHARS
        self.maxlist = self.maxtuple = self.maxset = self.maxfrozenset = self.maxdeque = self.maxarray = 6
        self.maxdict = 4

    def repr_int(self, x: int, level: int) -> str:
        if x.bit_length() > 256:  # ~77 digits: repr of a huge int is slow or raises
            return f'<int of about {int(x.bit_length() * 0.30103) + 1} digits>'
        return super().repr_int(x, level)


_REPR = _BoundedRepr()


def bounded_repr(value: object, limit: int = MESSAGE_VALUE_CHARS) -> str:
    """``repr(value)`` for an error message: at most ``limit`` characters, in bounded time."""
    return shorten(_REPR.repr(value), limit)


class FolderLineError(Exception):
    """Base class of all folder_line errors."""


class ParameterError(FolderLineError, ValueError):
    """A configuration value is missing, unknown, of the wrong type or out of range.

    Parameters
    ----------
    key : str
        Dotted name of the parameter, e.g. ``'layup.R_kr'``.
    value : object
        The rejected value, as given.
    reason : str
        What is wrong and what would be accepted.
    """

    def __init__(self, key: str, value: object, reason: str) -> None:
        self.key = key
        self.value = value
        self.reason = reason
        msg = f'{shorten(str(key))}={bounded_repr(value)}: {reason}'
        super().__init__(msg)


class InputFileError(ParameterError):
    """A file given as input cannot be read: not a regular file, too large, not UTF-8, not
    the YAML we accept. Unlike other values the path is printed whole up to
    :data:`PATH_CHARS` characters; a longer one keeps its start and its end (its file name).

    Parameters
    ----------
    what : str
        The option or role of the file (``'--scene'``, ``'bag metadata'``).
    path : str
        The file.
    reason : str
        What is wrong, with the line and column where there is one.
    """

    def __init__(self, what: str, path: str, reason: str) -> None:
        super().__init__(what, path, reason)
        self.args = (f'{shorten(what)}={path_repr(path)}: {reason}',)


class OutputError(FolderLineError, OSError):
    """An output target cannot be written: it is not a regular file (or folder), it is in use
    by another run, or the operating system refused the write.

    Nothing was created or changed at the target when this is raised.

    Parameters
    ----------
    option : str or None
        The command-line option that named the target (``'--csv'``, ``'--out'``), or None
        when not known where the error is raised (the command line fills it in).
    path : str
        The target.
    reason : str
        Why, e.g. ``'is a FIFO, not a regular file'`` or the OS reason (``strerror``).
    """

    def __init__(self, option: str | None, path: str, reason: str) -> None:
        self.option, self.path, self.reason = option, path, reason
        super().__init__(self._message())

    def _message(self) -> str:
        where = f'{self.option}={path_repr(self.path)}' if self.option else path_repr(self.path)
        return f'{where}: {self.reason}'

    def __str__(self) -> str:
        return self._message()

    def with_option(self, option: str) -> OutputError:
        """The same error naming ``option`` (unless it already names one)."""
        return self if self.option else OutputError(option, self.path, self.reason)


class BagError(FolderLineError):
    """A bag cannot be written, read or repaired; the message names the path and the reason."""


class AssemblyError(FolderLineError, ValueError):
    """A linkage cannot be assembled at some input position.

    Parameters
    ----------
    mechanism : str
        Which loop failed, e.g. ``'layup loop O1-A-B-O2'``.
    phi : float
        Crank angle where it fails, rad (project frame).
    reason : str
        Which circles do not meet, by how much.
    """

    def __init__(self, mechanism: str, phi: float, reason: str) -> None:
        self.mechanism = mechanism
        self.phi = phi
        self.reason = reason
        msg = f'{mechanism} cannot be assembled at phi={phi!r} rad ({phi * 57.29577951308232:.3f} deg): {reason}'
        super().__init__(msg)


class RootFindingError(FolderLineError):
    """Base class of the root finder's failures."""


class NotBracketedError(RootFindingError, ValueError):
    """``f(a)`` and ``f(b)`` have the same sign, so ``[a, b]`` is not a bracket.

    Parameters
    ----------
    a, b : float
        Bracket ends, in the units of ``x``.
    fa, fb : float
        ``f(a)``, ``f(b)``, in the units of ``f``.
    """

    def __init__(self, a: float, b: float, fa: float, fb: float) -> None:
        self.a, self.b, self.fa, self.fb = a, b, fa, fb
        msg = (
            f'f(a) and f(b) must have opposite signs: f({a!r}) = {fa!r}, f({b!r}) = {fb!r}; '
            'the interval does not bracket a root'
        )
        super().__init__(msg)


class NonFiniteValueError(RootFindingError, ValueError):
    """``f`` returned NaN or infinity, or a bracket end is not finite.

    Parameters
    ----------
    x : float
        Where, in the units of ``x``.
    fx : float
        What ``f`` returned there (NaN or inf), or NaN for a non-finite ``x``.
    """

    def __init__(self, x: float, fx: float) -> None:
        self.x, self.fx = x, fx
        msg = f'f({x!r}) = {fx!r} is not finite: f must be finite and continuous on the bracket'
        super().__init__(msg)


class NoConvergenceError(RootFindingError, RuntimeError):
    """The iteration limit was reached before the tolerance.

    Parameters
    ----------
    x : float
        Last iterate, in the units of ``x``.
    maxiter : int
        The limit that was hit.
    width : float
        Width of the last bracket, in the units of ``x``.
    """

    def __init__(self, x: float, maxiter: int, width: float) -> None:
        self.x, self.maxiter, self.width = x, maxiter, width
        msg = f'no convergence in maxiter={maxiter} iterations: last iterate {x!r}, bracket width {width!r}'
        super().__init__(msg)


class IntegrationError(FolderLineError, RuntimeError):
    """An integration cannot go on: non-finite state, step below resolution, too many steps.

    Parameters
    ----------
    method : str
        ``'rk4'`` or ``'dopri5'``.
    step : int
        Index of the step that failed (0 = first).
    t : float
        Time at the start of that step, s (or the unit of ``t``).
    h : float
        Step size tried, same unit.
    reason : str
        What happened and what to do about it.
    """

    def __init__(self, method: str, step: int, t: float, h: float, reason: str) -> None:
        self.method, self.step, self.t, self.h, self.reason = method, step, t, h, reason
        msg = f'{method}: step {step} starting at t={t!r} with h={h!r}: {reason}'
        super().__init__(msg)


class MeasurementError(FolderLineError, RuntimeError):
    """A benchmark measurement would not mean what it claims (``folder-line bench accuracy``):
    a method missed or doubled an event, a live line skipped the ticks whose cost it measures,
    a reference failed its own check."""


class TransitionError(FolderLineError):
    """The supervisor refuses a command in its current state.

    Parameters
    ----------
    state : str
        Current PackML state.
    command : str
        The refused command.
    reason : str
        Why, and from which states the command is legal.
    """

    def __init__(self, state: str, command: str, reason: str) -> None:
        self.state, self.command, self.reason = state, command, reason
        msg = f'{command!r} refused in state {state}: {reason}'
        super().__init__(msg)
