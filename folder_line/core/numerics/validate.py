"""Value checks shared by the core's frozen parameter dataclasses.

Each check raises :class:`folder_line.errors.ParameterError` naming the key and
the value; none returns a modified value except :func:`as_float`.
"""

from __future__ import annotations

import math

from folder_line.errors import ParameterError

__all__ = ['as_float', 'positive', 'non_negative', 'in_range', 'one_of']


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
