"""The guide profile laws of the delivery transporter: :class:`ProfileLaw`, :data:`LAWS`, :func:`register_law`.

A law is the chain guide's shape ``y / y_max = psi(xi)`` over one section, ``xi`` in
[0, 1]; :mod:`folder_line.core.mechanisms.delivery` evaluates the transporter on it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from folder_line.core.numerics.arrays import FloatArray
from folder_line.errors import ParameterError

__all__ = ['LAWS', 'ProfileLaw', 'law_names', 'register_law']

ArrayOrFloat = FloatArray | float


@dataclass(frozen=True)
class ProfileLaw:
    """A guide profile law ``y / y_max = psi(xi)``, rising from 0 to 1 on ``xi`` in [0, 1].

    Parameters
    ----------
    name : str
        Key used in ``delivery.law``.
    psi : callable
        ``psi(xi)``, dimensionless; must accept a float or a float array (numpy ufuncs).
    dpsi : callable
        ``dpsi/dxi``, dimensionless, ``>= 0``; same calling convention.
    description : str
        One line for documentation and error messages.
    """

    name: str
    psi: Callable[[ArrayOrFloat], ArrayOrFloat]
    dpsi: Callable[[ArrayOrFloat], ArrayOrFloat]
    description: str


def _cycloidal_psi(xi: ArrayOrFloat) -> ArrayOrFloat:
    return xi - np.sin(2.0 * np.pi * xi) / (2.0 * np.pi)


def _cycloidal_dpsi(xi: ArrayOrFloat) -> ArrayOrFloat:
    return 1.0 - np.cos(2.0 * np.pi * xi)


def _harmonic_psi(xi: ArrayOrFloat) -> ArrayOrFloat:
    return (1.0 - np.cos(np.pi * xi)) / 2.0


def _harmonic_dpsi(xi: ArrayOrFloat) -> ArrayOrFloat:
    return (np.pi / 2.0) * np.sin(np.pi * xi)


#: name -> law; extend with :func:`register_law`
LAWS: dict[str, ProfileLaw] = {
    'sinusoidal': ProfileLaw(
        'sinusoidal', _cycloidal_psi, _cycloidal_dpsi, 'cycloidal: psi = xi - sin(2 pi xi)/(2 pi)'
    ),
    'harmonic': ProfileLaw('harmonic', _harmonic_psi, _harmonic_dpsi, 'harmonic: psi = (1 - cos(pi xi))/2'),
}


def law_names() -> tuple[str, ...]:
    """Names of the registered profile laws, in registration order."""
    return tuple(LAWS)


def register_law(law: ProfileLaw, *, replace: bool = False) -> None:
    """Add a profile law to :data:`LAWS` after checking it on a grid of 1001 points.

    Parameters
    ----------
    law : ProfileLaw
        The law; ``psi(0) = 0``, ``psi(1) = 1``, ``psi`` in [0, 1] and ``dpsi >= 0``
        finite (all to 1e-9) are required.
    replace : bool
        Allow overwriting a law of the same name.

    Raises
    ------
    ParameterError
        Name taken (without ``replace``) or the law fails a check.
    """
    key = 'delivery.law'
    if not isinstance(law, ProfileLaw):
        raise ParameterError(key, law, 'must be a ProfileLaw')
    if not law.name or not isinstance(law.name, str):
        raise ParameterError(key, law.name, 'law name must be a non-empty string')
    if law.name in LAWS and not replace:
        raise ParameterError(key, law.name, 'a law of that name is registered (pass replace=True)')
    grid = np.linspace(0.0, 1.0, 1001)
    psi = np.asarray(law.psi(grid), dtype=float)
    dpsi = np.asarray(law.dpsi(grid), dtype=float)
    if psi.shape != grid.shape or dpsi.shape != grid.shape:
        raise ParameterError(key, law.name, 'psi and dpsi must return an array shaped like xi')
    if not (np.all(np.isfinite(psi)) and np.all(np.isfinite(dpsi))):
        raise ParameterError(key, law.name, 'psi and dpsi must be finite on [0, 1]')
    if abs(psi[0]) > 1e-9 or abs(psi[-1] - 1.0) > 1e-9:
        raise ParameterError(key, law.name, f'needs psi(0) = 0 and psi(1) = 1, got {psi[0]!r}, {psi[-1]!r}')
    if psi.min() < -1e-9 or psi.max() > 1.0 + 1e-9 or dpsi.min() < -1e-9:
        raise ParameterError(key, law.name, 'needs 0 <= psi <= 1 and dpsi >= 0 on [0, 1]')
    LAWS[law.name] = law
