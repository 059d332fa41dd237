"""The dyad kernel: the joint of two hinged links, once, for a float or an array, and in place.

A dyad is a link of length ``r0`` from a pivot to a joint X and a link of length ``r1`` from X to
a centre P. With ``p = P - pivot`` and ``d2 = |p|²``, X closes both links at

``X - pivot = k1 p + k2 p⊥``, ``k1 = 1/2 + (r0² - r1²) / (2 d2)``, ``k2 = s / (2 d2)``,

where ``s = ±sqrt(e)`` picks the branch and ``e = ((r0 + r1)² - d2) (d2 - (r0 - r1)²)`` is Heron's
product (16 × the area² of the triangle pivot-X-P; ``e = 4 r0² r1² sin² μ``, ``μ`` the angle at X).
``e < 0``: the links cannot meet. The layup six-bar's two loops (:mod:`..mechanisms.layup`, a
float per tick and arrays per window) and the circle intersection of :mod:`.loop` (the accuracy
bench's four-bar) all close their dyads here.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TypeVar

import numpy as np

__all__ = ['DyadLinks', 'heron', 'heron_into', 'joint', 'joint_into']

#: a float, or an array of floats: the generic functions take either, and all their arguments alike
F = TypeVar('F', float, np.ndarray)


@dataclass(frozen=True)
class DyadLinks:
    """The two link lengths of a dyad and the constants of its kernel.

    Parameters
    ----------
    r0 : float
        Pivot to joint, m.
    r1 : float
        Joint to the moving centre, m.

    Attributes
    ----------
    plus2 : float
        ``(r0 + r1)²``, m² (products here: an overflow gives inf, not an exception).
    minus2 : float
        ``(r0 - r1)²``, m².
    half_diff : float
        ``(r0² - r1²) / 2``, m².
    norm : float
        ``1 / (2 r0 r1)``, 1/m²: ``e norm²`` is ``sin² μ``.
    """

    r0: float
    r1: float
    plus2: float = field(init=False)
    minus2: float = field(init=False)
    half_diff: float = field(init=False)
    norm: float = field(init=False)

    def __post_init__(self) -> None:
        r0, r1 = self.r0, self.r1
        object.__setattr__(self, 'plus2', (r0 + r1) * (r0 + r1))
        object.__setattr__(self, 'minus2', (r0 - r1) * (r0 - r1))
        object.__setattr__(self, 'half_diff', 0.5 * (r0 * r0 - r1 * r1))
        object.__setattr__(self, 'norm', 1.0 / (2.0 * r0 * r1))


def heron(d2: F, plus2: F | float, minus2: F | float) -> F:
    """Heron's product ``e = (plus2 - d2) (d2 - minus2)``, m⁴: ``< 0`` where the links cannot meet."""
    return (plus2 - d2) * (d2 - minus2)


def joint(px: F, py: F, d2: F, s: F, half_diff: F | float) -> tuple[F, F]:
    """The joint relative to the pivot, ``k1 p + k2 p⊥`` (see the module), m.

    Parameters
    ----------
    px, py : float or ndarray
        The moving centre relative to the pivot, m.
    d2 : float or ndarray
        ``px² + py²``, m².
    s : float or ndarray
        ``±sqrt(e)`` (the sign is the branch; 0 at a toggle), m².
    half_diff : float or ndarray
        ``(r0² - r1²) / 2``, m².
    """
    q = 1.0 / d2
    k1 = 0.5 + half_diff * q
    k2 = 0.5 * s * q
    return k1 * px - k2 * py, k1 * py + k2 * px


def heron_into(
    px: np.ndarray, py: np.ndarray, plus2: float, minus2: float, d2: np.ndarray, e: np.ndarray, tmp: np.ndarray
) -> None:
    """:func:`heron` in place, for arrays: fills ``d2 = px² + py²`` and ``e``; ``tmp`` is scratch."""
    np.multiply(px, px, out=d2)
    np.multiply(py, py, out=e)
    np.add(d2, e, out=d2)
    np.subtract(plus2, d2, out=e)
    np.subtract(d2, minus2, out=tmp)
    np.multiply(e, tmp, out=e)


def joint_into(
    px: np.ndarray,
    py: np.ndarray,
    d2: np.ndarray,
    s: np.ndarray,
    half_diff: float,
    ox: np.ndarray,
    oy: np.ndarray,
    k1: np.ndarray,
    k2: np.ndarray,
) -> None:
    """:func:`joint` in place, for arrays: writes ``(ox, oy)``; ``d2`` becomes ``1 / d2``, ``k1`` and ``k2``
    are scratch (``k2`` may be ``d2``)."""
    np.divide(1.0, d2, out=d2)  # q
    np.multiply(d2, half_diff, out=k1)
    np.add(k1, 0.5, out=k1)
    np.multiply(s, d2, out=k2)
    np.multiply(k2, 0.5, out=k2)
    np.multiply(k1, px, out=ox)
    np.multiply(k2, py, out=oy)
    np.subtract(ox, oy, out=ox)
    np.multiply(k1, py, out=oy)
    np.multiply(k2, px, out=k1)
    np.add(oy, k1, out=oy)
