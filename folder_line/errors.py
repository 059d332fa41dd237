"""Every exception folder_line raises on purpose.

Messages are built first and then raised, and always name the offending
parameter (or crank angle) and its value, so that the command line can print
them as one line and exit with code 2.
"""

from __future__ import annotations

__all__ = [
    'FolderLineError',
    'ParameterError',
    'AssemblyError',
    'RootFindingError',
    'NotBracketedError',
    'NonFiniteValueError',
    'NoConvergenceError',
    'IntegrationError',
    'MeasurementError',
    'TransitionError',
]


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
        msg = f'{key}={value!r}: {reason}'
        super().__init__(msg)


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
        msg = (f'f(a) and f(b) must have opposite signs: f({a!r}) = {fa!r}, f({b!r}) = {fb!r}; '
               'the interval does not bracket a root')
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
