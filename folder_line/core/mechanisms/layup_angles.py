"""The layup's crank angle and its first loop's class: :func:`reduce_angle`, :func:`classify_fourbar`.

Crank-angle range. Every entry point of :mod:`folder_line.core.mechanisms.layup` reduces φ
to [-π, π] with the IEEE remainder by the float ``TAU = 2π`` (:func:`reduce_angle`; exact,
no rounding), so results are exactly periodic in ``TAU``. Precision is that of the input: a
float φ of magnitude ``|φ|`` carries an absolute error up to ``ulp(|φ|)/2`` (5.8e-11 rad at
1e6 rad, 4.8e-7 rad at 6.3e9 rad ≈ 1e9 turns), so callers that run for long keep the phase
as an integer number of turns plus a fraction and pass the fraction · TAU.
"""

from __future__ import annotations

import math
from typing import Any, overload

import numpy as np
import numpy.typing as npt

from folder_line.errors import ParameterError

__all__ = ['GRASHOF_REL_TOL', 'TAU', 'classify_fourbar', 'reduce_angle']

TAU = 2.0 * math.pi
_PI = math.pi
#: relative tolerance of the Grashof boundary s + l = p + q (a change-point linkage)
GRASHOF_REL_TOL = 1e-12


def classify_fourbar(
    ground: float, crank: float, coupler: float, rocker: float, *, rel_tol: float = GRASHOF_REL_TOL
) -> str:
    """Grashof class of a planar four-bar, seen from its input link ``crank``.

    Parameters
    ----------
    ground : float
        Fixed link (distance between the two ground pivots), m.
    crank : float
        Input link, pivoted on the ground, m.
    coupler : float
        Link opposite the ground, m.
    rocker : float
        Output link, pivoted on the ground, m.
    rel_tol : float, optional
        ``s + l`` and ``p + q`` closer than ``rel_tol · (s + l + p + q)`` count as equal.

    Returns
    -------
    str
        With ``s``, ``l`` the shortest and longest links and ``p``, ``q`` the others:
        ``'change-point'`` if ``s + l = p + q`` (within ``rel_tol``; the links can
        all line up and the linkage can switch branch there); ``'non-Grashof'``
        (triple rocker) if ``s + l > p + q``; otherwise, by which link is the unique
        shortest: ``'crank-rocker'`` (the input), ``'rocker-crank'`` (the output),
        ``'double-crank'`` (the ground; a drag link), ``'double-rocker'`` (the coupler).
    """
    links = (ground, crank, coupler, rocker)
    srt = sorted(links)
    shortest, p, q, longest = srt
    excess = (shortest + longest) - (p + q)
    if abs(excess) <= rel_tol * (shortest + longest + p + q):
        return 'change-point'
    if excess > 0.0:
        return 'non-Grashof'
    # Grashof: strictly s + l < p + q, hence s is unique (s = p would force l < q).
    return {0: 'double-crank', 1: 'crank-rocker', 2: 'double-rocker', 3: 'rocker-crank'}[links.index(shortest)]


@overload
def reduce_angle(phi: float) -> float: ...
@overload
def reduce_angle(phi: npt.NDArray[Any]) -> npt.NDArray[np.float64]: ...
@overload
def reduce_angle(phi: npt.ArrayLike) -> float | npt.NDArray[np.float64]: ...
def reduce_angle(phi: npt.ArrayLike) -> float | npt.NDArray[np.float64]:
    """Reduce crank angles to [-π, π] exactly: the IEEE remainder by the float ``TAU``.

    Parameters
    ----------
    phi : float or array_like
        Crank angle(s), rad; must be finite.

    Returns
    -------
    float or ndarray
        ``math.remainder(phi, TAU)`` elementwise (exact; at a tie ±π the sign of the
        array result follows ``phi``). Values already in [-π, π] come back unchanged.

    Raises
    ------
    ParameterError
        A crank angle is NaN or infinite.
    """
    if isinstance(phi, (float, int)) and not isinstance(phi, bool):
        x = float(phi)
        if -_PI <= x <= _PI:
            return x
        if not math.isfinite(x):
            raise ParameterError('phi', phi, 'crank angle must be finite')
        return math.remainder(x, TAU)
    arr = np.asarray(phi, dtype=np.float64)
    if arr.size == 0 or (arr.min() >= -_PI and arr.max() <= _PI):
        return arr
    if not np.isfinite(arr).all():
        bad = arr.reshape(-1)[np.flatnonzero(~np.isfinite(arr.reshape(-1)))[0]]
        raise ParameterError('phi', float(bad), 'crank angle must be finite')
    r = np.fmod(arr, TAU)  # exact
    r = np.where(r > _PI, r - TAU, r)  # exact (Sterbenz)
    reduced: npt.NDArray[np.float64] = np.where(r < -_PI, r + TAU, r)
    return reduced


def _reduce_chunk(ph: np.ndarray, r: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """:func:`reduce_angle` of a 1-D array into the buffer ``r`` (same results, no allocation)."""
    if not (math.isfinite(ph.min()) and math.isfinite(ph.max())):  # NaN propagates into min
        bad = ph[np.flatnonzero(~np.isfinite(ph))[0]]
        raise ParameterError('phi', float(bad), 'crank angle must be finite')
    np.fmod(ph, TAU, out=r)
    np.greater(r, _PI, out=mask)
    np.subtract(r, TAU, out=r, where=mask)
    np.less(r, -_PI, out=mask)
    np.add(r, TAU, out=r, where=mask)
    return r
