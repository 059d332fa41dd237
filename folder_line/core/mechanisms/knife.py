"""F: the crank-slider drive of the folding knife (paper 001; docs/machines.md, section F).

Geometry
--------
The crank (radius ``r_k``) turns about its centre O at the constant speed
``omega_k = 2 pi n_k / 3600`` (``n_k`` in rev/h). The rod (``L_k``) drives the
knife along a straight stroke axis at the lateral offset ``e`` from O (``e = 0``:
central crank-slider). The knife position, measured from O along the stroke
towards the table, is::

    s(phi) = r_k cos(phi) + sqrt(L_k**2 - (r_k sin(phi) - e)**2)

with ``phi`` the crank angle from the stroke axis and ``phi(t) = omega_k t``.
The crank centre is on the far side of the knife from the table, so a larger
``s`` is a knife edge further down: the knife occupies the table (is over or
through the signature, the feed must stay out) while ``s >= s_clear``, i.e.
while its edge is below the clearance level ``s_clear``.

The mechanism assembles for a full crank turn iff ``L_k > r_k + |e|`` (the
rod must reach the stroke axis at every crank angle). ``s`` then has exactly
two extremes per turn, the dead centres where crank and rod are collinear::

    outer  s_max = sqrt((L_k + r_k)**2 - e**2)   at phi = asin(e / (L_k + r_k))
    inner  s_min = sqrt((L_k - r_k)**2 - e**2)   at phi = pi + asin(e / (L_k - r_k))

and ``s`` rises monotonically from the inner to the outer dead centre and falls
back. So ``{s >= s_clear}`` is one arc ``[phi_in, phi_out]`` around the outer
dead centre, with ``phi_in`` on the rising branch and ``phi_out`` on the falling
one; both are found by Brent's method on ``s(phi) - s_clear`` in the brackets
``[phi_inner - 2 pi, phi_outer]`` and ``[phi_outer, phi_inner]``.

Degenerate levels: ``s_clear`` must lie strictly between ``s_min`` and
``s_max`` (closed form); otherwise the knife would never (or only at one
instant) reach the level, or never leave it, and :class:`KnifeParams` raises
:class:`~folder_line.errors.ParameterError`. Any level strictly inside is
accepted, however close to ``s_max``: the window then shrinks continuously to
zero (e.g. ``s_max - s_clear = 1e-12`` m gives a window of 1.45e-7 s at the
default geometry); the brackets use the closed-form extremes at the dead
centres, so rounding in ``s`` at ``phi_outer`` cannot break them.

Default geometry (``config/knife.yaml``): ``r_k = 0.04``, ``L_k = 0.16``,
``e = 0``, ``n_k = 50000`` rev/h, ``s_clear = 0.1656`` m: the window is
``phi = +-75.02 deg``, 0.03001 s of the 0.072 s cycle, the paper's "folding
plus knife exit from under the table takes 0.03 s".
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from types import ModuleType
from typing import TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from folder_line.core.limits import KNIFE_SPEED, MACHINE_LENGTH
from folder_line.core.numerics.roots import brent
from folder_line.core.numerics.validate import as_float, positive
from folder_line.errors import ParameterError

__all__ = [
    'DeadCentres',
    'KnifeParams',
    'KnifeState',
    'KnifeWindow',
    'acceleration',
    'dead_centres',
    'omega',
    'period',
    'position',
    'state',
    'state_at_time',
    'velocity',
    'window',
]

TWO_PI = 2.0 * math.pi
#: crank angle(s): a float, or a float64 array; the kinematics return the same kind
Phi = TypeVar('Phi', float, NDArray[np.float64])
#: root tolerance of the window ends, rad (Brent stops at ~1 ulp of the angle)
WINDOW_XTOL = 1e-15


def _extremes(r: float, L: float, e: float) -> tuple[float, float, float, float]:
    """(phi_outer, s_max, phi_inner, s_min) in closed form."""
    s_max = math.sqrt((L + r) ** 2 - e * e)
    s_min = math.sqrt((L - r) ** 2 - e * e)
    phi_outer = math.asin(e / (L + r))
    phi_inner = math.pi + math.asin(e / (L - r))
    return phi_outer, s_max, phi_inner, s_min


@dataclass(frozen=True)
class KnifeParams:
    """Validated parameters of the knife crank-slider.

    Parameters
    ----------
    r_k : float
        Crank radius, m; in [1e-4, 100] (:data:`folder_line.core.limits.MACHINE_LENGTH`).
    L_k : float
        Connecting rod length, m; > r_k + |e|.
    e : float
        Offset of the stroke axis from the crank centre, m (any sign; 0 = central); in [-100, 100].
    n_k : float
        Crank speed, rev/h; > 0.
    s_clear : float
        Knife position (from the crank centre along the stroke) beyond which the
        knife occupies the table, m; strictly between s_min and s_max.

    Raises
    ------
    ParameterError
        A value out of range; the message names the field and the value. ``L_k``, like ``r_k``, is
        at most 100 m (:data:`folder_line.core.limits.MACHINE_LENGTH`).
    """

    r_k: float
    L_k: float
    e: float
    n_k: float
    s_clear: float

    def __post_init__(self) -> None:
        r = MACHINE_LENGTH.check('knife.r_k', self.r_k)
        L = MACHINE_LENGTH.check('knife.L_k', positive('knife.L_k', self.L_k))
        e = as_float('knife.e', self.e)
        if not abs(e) <= MACHINE_LENGTH.hi:
            raise ParameterError('knife.e', self.e, f'must be in [-{MACHINE_LENGTH.hi:g}, {MACHINE_LENGTH.hi:g}] m')
        n = KNIFE_SPEED.check('knife.n_k', self.n_k)
        s_clear = as_float('knife.s_clear', self.s_clear)
        if not r + abs(e) < L:
            raise ParameterError(
                'knife.L_k',
                self.L_k,
                f'must be > r_k + |e| = {r + abs(e)!r} m (knife.r_k={r!r}, knife.e={e!r}), otherwise '
                'the crank-slider cannot be assembled for a full crank turn',
            )
        _, s_max, _, s_min = _extremes(r, L, e)
        if not s_clear < s_max:
            raise ParameterError(
                'knife.s_clear',
                self.s_clear,
                f'must be < s_max = {s_max!r} m (outer dead centre): the knife would never '
                'occupy the table (or only at one instant)',
            )
        if not s_clear > s_min:
            raise ParameterError(
                'knife.s_clear',
                self.s_clear,
                f'must be > s_min = {s_min!r} m (inner dead centre): the knife would always occupy the table',
            )
        for name, value in (('r_k', r), ('L_k', L), ('e', e), ('n_k', n), ('s_clear', s_clear)):
            object.__setattr__(self, name, value)

    @property
    def omega_k(self) -> float:
        """Crank angular speed ``2 pi n_k / 3600``, rad/s."""
        return TWO_PI * self.n_k / 3600.0

    @property
    def period(self) -> float:
        """One crank turn ``2 pi / omega_k``, s."""
        return 3600.0 / self.n_k

    @property
    def s_max(self) -> float:
        """Outer dead-centre position ``sqrt((L_k + r_k)^2 - e^2)``, m."""
        return _extremes(self.r_k, self.L_k, self.e)[1]

    @property
    def s_min(self) -> float:
        """Inner dead-centre position ``sqrt((L_k - r_k)^2 - e^2)``, m."""
        return _extremes(self.r_k, self.L_k, self.e)[3]


def omega(params: KnifeParams) -> float:
    """Crank angular speed, rad/s.

    Parameters
    ----------
    params : KnifeParams
        The knife.

    Returns
    -------
    float
        ``2 pi n_k / 3600``, rad/s.
    """
    return params.omega_k


def period(params: KnifeParams) -> float:
    """Cycle time (one crank turn), s.

    Parameters
    ----------
    params : KnifeParams
        The knife.

    Returns
    -------
    float
        ``2 pi / omega_k = 3600 / n_k``, s.
    """
    return params.period


@dataclass(frozen=True)
class DeadCentres:
    """The two extremes of the knife position (crank and rod collinear).

    Attributes
    ----------
    phi_outer : float
        Crank angle of the outer dead centre, rad, in (-pi/2, pi/2).
    s_max : float
        Knife position there, m.
    phi_inner : float
        Crank angle of the inner dead centre, rad, in (pi/2, 3 pi/2).
    s_min : float
        Knife position there, m.
    stroke : float
        ``s_max - s_min``, m (``2 r_k`` for e = 0).
    """

    phi_outer: float
    s_max: float
    phi_inner: float
    s_min: float
    stroke: float


def dead_centres(params: KnifeParams) -> DeadCentres:
    """Dead centres of the knife in closed form.

    Parameters
    ----------
    params : KnifeParams
        The knife.

    Returns
    -------
    DeadCentres
        ``s_max = sqrt((L+r)^2 - e^2)`` at ``asin(e/(L+r))``,
        ``s_min = sqrt((L-r)^2 - e^2)`` at ``pi + asin(e/(L-r))``.
    """
    po, smax, pi_, smin = _extremes(params.r_k, params.L_k, params.e)
    return DeadCentres(po, smax, pi_, smin, smax - smin)


def _phi_array(phi: ArrayLike) -> NDArray[np.float64]:
    a = np.asarray(phi, dtype=float)
    if not np.all(np.isfinite(a)):
        raise ParameterError('phi', phi, 'crank angle must be finite (rad)')
    return a


# The kernels take the namespace ``xp`` (``math`` for a float, ``numpy`` for an array) and
# return what it computes: a float or a float64 array, as ``phi`` is.
def _s(xp: ModuleType, r: float, L: float, e: float, phi: Phi) -> Phi:
    u = r * xp.sin(phi) - e
    s: Phi = r * xp.cos(phi) + xp.sqrt(L * L - u * u)
    return s


def _ds(xp: ModuleType, r: float, L: float, e: float, phi: Phi) -> Phi:
    sn, cs = xp.sin(phi), xp.cos(phi)
    u = r * sn - e
    w = xp.sqrt(L * L - u * u)
    ds: Phi = -r * sn - u * r * cs / w
    return ds


def _dds(xp: ModuleType, r: float, L: float, e: float, phi: Phi) -> Phi:
    sn, cs = xp.sin(phi), xp.cos(phi)
    u = r * sn - e
    du = r * cs
    w = xp.sqrt(L * L - u * u)
    dds: Phi = -r * cs - (du * du - u * r * sn) / w - (u * du) ** 2 / w**3
    return dds


def _of_angle(kernel: Callable[[ModuleType, float, float, float, Phi], Phi], params: KnifeParams, phi: Phi) -> Phi:
    """``kernel`` at crank angle(s) ``phi``: a float for a Python/NumPy scalar, else an array of its shape."""
    if isinstance(phi, (bool, float, int)):
        return float(kernel(math, params.r_k, params.L_k, params.e, as_float('phi', phi)))
    out: NDArray[np.float64] = kernel(np, params.r_k, params.L_k, params.e, _phi_array(phi))
    return out


def position(params: KnifeParams, phi: Phi) -> Phi:
    """Knife position ``s(phi)`` from the crank centre along the stroke.

    Parameters
    ----------
    params : KnifeParams
        The knife.
    phi : float or array_like of float
        Crank angle(s), rad; any shape.

    Returns
    -------
    float or ndarray
        ``s``, m; a float for a Python/NumPy scalar, else an array of ``phi``'s shape.
    """
    return _of_angle(_s, params, phi)


def velocity(params: KnifeParams, phi: Phi) -> Phi:
    """Knife velocity ``v = omega_k ds/dphi`` at constant crank speed.

    Parameters
    ----------
    params : KnifeParams
        The knife.
    phi : float or array_like of float
        Crank angle(s), rad.

    Returns
    -------
    float or ndarray
        ``v``, m/s, positive towards the table (increasing ``s``).
    """
    return params.omega_k * _of_angle(_ds, params, phi)


def acceleration(params: KnifeParams, phi: Phi) -> Phi:
    """Knife acceleration ``a = omega_k^2 d2s/dphi2`` at constant crank speed.

    Parameters
    ----------
    params : KnifeParams
        The knife.
    phi : float or array_like of float
        Crank angle(s), rad.

    Returns
    -------
    float or ndarray
        ``a``, m/s^2, positive towards the table.
    """
    return params.omega_k**2 * _of_angle(_dds, params, phi)


@dataclass(frozen=True)
class KnifeState:
    """Knife position, velocity and acceleration at some crank angle(s).

    Attributes
    ----------
    phi : float or ndarray
        Crank angle, rad.
    s : float or ndarray
        Position from the crank centre, m.
    v : float or ndarray
        Velocity, m/s.
    a : float or ndarray
        Acceleration, m/s^2.
    occupies : bool or ndarray of bool
        ``s >= s_clear``: the knife is over/through the table.
    """

    phi: float | NDArray[np.float64]
    s: float | NDArray[np.float64]
    v: float | NDArray[np.float64]
    a: float | NDArray[np.float64]
    occupies: bool | NDArray[np.bool_]


def state(params: KnifeParams, phi: ArrayLike) -> KnifeState:
    """Position, velocity, acceleration and table occupation at crank angle(s) ``phi``.

    Parameters
    ----------
    params : KnifeParams
        The knife.
    phi : float or array_like of float
        Crank angle(s), rad.

    Returns
    -------
    KnifeState
        Floats for a scalar ``phi``, arrays of its shape otherwise.
    """
    if not (isinstance(phi, (bool, float, int))):
        phi = _phi_array(phi)
    s = position(params, phi)
    occ: bool | NDArray[np.bool_] = bool(s >= params.s_clear) if isinstance(s, float) else s >= params.s_clear
    return KnifeState(phi, s, velocity(params, phi), acceleration(params, phi), occ)


def state_at_time(params: KnifeParams, t: ArrayLike) -> KnifeState:
    """Knife state at time(s) ``t`` with ``phi = omega_k t`` (phi = 0 at t = 0).

    Parameters
    ----------
    params : KnifeParams
        The knife.
    t : float or array_like of float
        Time(s), s.

    Returns
    -------
    KnifeState
        As :func:`state`, with ``phi = omega_k t``.
    """
    if isinstance(t, (bool, float, int)):
        return state(params, params.omega_k * as_float('t', t))
    ta = np.asarray(t, dtype=float)
    if not np.all(np.isfinite(ta)):
        raise ParameterError('t', t, 'time must be finite (s)')
    return state(params, params.omega_k * ta)


@dataclass(frozen=True)
class KnifeWindow:
    """The crank-angle and time window in which the knife occupies the table (``s >= s_clear``).

    Attributes
    ----------
    phi_in : float
        Crank angle where ``s`` rises through ``s_clear`` (knife enters), rad,
        in (phi_inner - 2 pi, phi_outer).
    phi_out : float
        Crank angle where ``s`` falls through ``s_clear`` (knife clears the
        table), rad, in (phi_outer, phi_inner). ``phi_in < phi_out``; for e = 0,
        ``phi_in = -phi_out``.
    t_in, t_out : float
        The same as times ``phi / omega_k``, s (t = 0 at phi = 0).
    duration : float
        ``(phi_out - phi_in) / omega_k``, s.
    fraction : float
        ``duration / T``: share of the cycle, dimensionless.
    """

    phi_in: float
    phi_out: float
    t_in: float
    t_out: float
    duration: float
    fraction: float


def window(params: KnifeParams) -> KnifeWindow:
    """Exact ends of the table-occupation window, by Brent's method on ``s(phi) - s_clear``.

    Parameters
    ----------
    params : KnifeParams
        The knife.

    Returns
    -------
    KnifeWindow
        Ends to about one ulp in angle (``|s(phi_end) - s_clear|`` at rounding level).
    """
    r, L, e, sc = params.r_k, params.L_k, params.e, params.s_clear
    po, smax, pin, smin = _extremes(r, L, e)

    def g(phi: float) -> float:
        # closed-form extremes at the dead centres keep the brackets valid under rounding
        if phi == po:
            return smax - sc
        if phi == pin or phi == pin - TWO_PI:
            return smin - sc
        s: float = _s(math, r, L, e, phi)
        return s - sc

    # both brackets ordered (g < 0, g > 0), so for e = 0 the iterates mirror: phi_in = -phi_out exactly
    phi_in = brent(g, pin - TWO_PI, po, xtol=WINDOW_XTOL, maxiter=200).root
    phi_out = brent(g, pin, po, xtol=WINDOW_XTOL, maxiter=200).root
    w = params.omega_k
    span = phi_out - phi_in
    return KnifeWindow(phi_in, phi_out, phi_in / w, phi_out / w, span / w, span / TWO_PI)
