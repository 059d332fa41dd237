"""Value checks shared by the core's frozen parameter dataclasses, and the one builder of them.

Each check raises :class:`folder_line.errors.ParameterError` naming the key and
the value, and returns the value to keep (a number as a finite float). A dataclass's
``__post_init__`` runs its checks with :func:`check_fields` (:func:`within` and :func:`among`
make checks of :func:`in_range` and :func:`one_of` with their bounds). :func:`build` turns
a mapping (from YAML or the command line) into a frozen dataclass, refusing unknown
and missing keys by name; the dataclass checks its values itself.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterable, Mapping
from typing import Any, ClassVar, Protocol, TypeVar

from folder_line.errors import ParameterError

__all__ = [
    'Check',
    'Dataclass',
    'among',
    'as_float',
    'build',
    'check_fields',
    'check_keys',
    'in_range',
    'non_negative',
    'one_of',
    'positive',
    'within',
]

#: a value check: ``check(key, value)`` returns the value to keep, or raises naming ``key``
Check = Callable[[str, object], object]


def as_float(key: str, value: object) -> float:
    """Return ``value`` as a finite float, or raise naming ``key``.

    Booleans and strings are rejected even where ``float()`` would accept them.
    """
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ParameterError(key, value, 'must be a number')
    x = float(value)
    if not math.isfinite(x):
        raise ParameterError(key, value, 'must be finite (not NaN or inf)')
    return x


def positive(key: str, value: object) -> float:
    """Finite and > 0."""
    x = as_float(key, value)
    if x <= 0.0:
        raise ParameterError(key, value, 'must be > 0')
    return x


def non_negative(key: str, value: object) -> float:
    """Finite and >= 0."""
    x = as_float(key, value)
    if x < 0.0:
        raise ParameterError(key, value, 'must be >= 0')
    return x


def in_range(key: str, value: object, lo: float, hi: float, *, lo_open: bool = False, hi_open: bool = False) -> float:
    """Finite and inside [lo, hi] (either end open on request)."""
    x = as_float(key, value)
    bad_lo = x <= lo if lo_open else x < lo
    bad_hi = x >= hi if hi_open else x > hi
    if bad_lo or bad_hi:
        left = '(' if lo_open else '['
        right = ')' if hi_open else ']'
        raise ParameterError(key, value, f'must be in {left}{lo:g}, {hi:g}{right}')
    return x


def one_of(key: str, value: object, allowed: tuple[str, ...]) -> str:
    """A string from ``allowed``."""
    if not isinstance(value, str) or value not in allowed:
        raise ParameterError(key, value, f'must be one of {", ".join(allowed)}')
    return value


def within(lo: float, hi: float, *, lo_open: bool = False, hi_open: bool = False) -> Callable[[str, object], float]:
    """The check :func:`in_range` with these bounds."""

    def check(key: str, value: object) -> float:
        return in_range(key, value, lo, hi, lo_open=lo_open, hi_open=hi_open)

    return check


def among(allowed: tuple[str, ...]) -> Callable[[str, object], str]:
    """The check :func:`one_of` ``allowed``."""

    def check(key: str, value: object) -> str:
        return one_of(key, value, allowed)

    return check


def check_fields(obj: object, prefix: str, **checks: Check) -> None:
    """Check fields of the frozen dataclass ``obj`` in the order given and keep what the checks return.

    For a dataclass's ``__post_init__``: ``check_fields(self, 'knife', r_k=positive, e=as_float)``.

    Parameters
    ----------
    obj : dataclass instance
        The instance being made (its fields are set with ``object.__setattr__``).
    prefix : str
        Dotted name of the dataclass in messages; a field is named ``<prefix>.<field>`` (the bare
        field name for ``''``).
    **checks : Check
        Field name to its check.

    Raises
    ------
    ParameterError
        From the first check that fails.
    """
    for name, check in checks.items():
        object.__setattr__(obj, name, check(_dotted(prefix, name), getattr(obj, name)))


# --------------------------------------------------------------------------- mapping -> frozen dataclass


class Dataclass(Protocol):
    """Any dataclass type (what :func:`build` builds)."""

    __dataclass_fields__: ClassVar[dict[str, dataclasses.Field[object]]]


D = TypeVar('D', bound=Dataclass)


def _dotted(key: str, name: object) -> str:
    return f'{key}.{name}' if key else str(name)


# Any: a file's keys may be of any type (a YAML key may be a number), and Mapping is invariant in its key
def check_keys(values: Mapping[Any, object], known: Iterable[str], key: str, what: str) -> None:
    """Refuse the first key of ``values`` that is not in ``known``.

    Parameters
    ----------
    values : mapping
        What a file or the command line gave.
    known : iterable of str
        The accepted keys, in the order the message lists them.
    key : str
        Dotted name of ``values`` in messages (``'knife'``, ``'effects.faults'``; ``''`` at the top).
    what : str
        What one key is, in words (``'knife parameter'``, ``'scene key'``).

    Raises
    ------
    ParameterError
        ``<key>.<unknown>=<value>: unknown <what>; known: ...``.
    """
    names = tuple(known)
    for name, value in values.items():
        if name not in names:
            raise ParameterError(_dotted(key, name), value, f'unknown {what}; known: {", ".join(names) or "none"}')


def build(cls: type[D], values: object, key: str, what: str) -> D:
    """The frozen dataclass ``cls`` from a mapping of its fields: the one mapping-to-dataclass validator.

    Machines, effects, the scene's ``drive`` and ``sheets`` and the kinematics' ``--params`` are built
    here; the dataclass's ``__post_init__`` checks the values.

    Parameters
    ----------
    cls : dataclass type
        What to build.
    values : object
        Must be a mapping of field name to value; fields with a default may be left out.
    key : str
        Dotted name of the mapping in messages; a field is named ``<key>.<field>``.
    what : str
        What one field is, in words (``'knife parameter'``, ``'parameter of effect faults'``).

    Returns
    -------
    cls
        The validated instance.

    Raises
    ------
    ParameterError
        ``values`` is not a mapping (naming ``key``); an unknown key (listing the known ones); a
        field with no default left out (listing the required ones); or the dataclass's own
        refusal, its key prefixed with ``<key>.`` if it names a bare field.
    """
    if not isinstance(values, Mapping):
        raise ParameterError(key, values, 'must be a mapping of key: value')
    fields = [f for f in dataclasses.fields(cls) if f.init]
    check_keys(values, (f.name for f in fields), key, what)
    required = [f.name for f in fields if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING]
    missing = [name for name in required if name not in values]
    if missing:
        raise ParameterError(_dotted(key, missing[0]), None, f'missing {what}; required: {", ".join(required)}')
    try:
        return cls(**values)
    except ParameterError as exc:
        if not key or '.' in exc.key:
            raise
        raise ParameterError(_dotted(key, exc.key), exc.value, exc.reason) from None
