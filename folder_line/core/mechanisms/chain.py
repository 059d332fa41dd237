"""D: the delivery chain's guide geometry and carriage schedule (kinematics only, no friction).

Used by the folder simulation (:mod:`folder_line.core.line.folder_sim`: release timing,
carriage samples, the ``release_at_min_speed`` constraint) whether or not the scene
lists ``chain_friction``, and by that effect
(:mod:`folder_line.core.effects.chain_friction`) to place the carriages whose load it
computes. The papers give no line timing; this is ours.

Carriage numbering (the one convention of the line)
---------------------------------------------------
The knife crank is at ``φ_k = ω_k Θ`` (Θ the master phase in nominal seconds,
:mod:`folder_line.core.mechanisms.drive`), period ``T = 2π/ω_k``; the knife occupies the table for
``Θ mod T`` in ``[t_in, t_out]`` (:func:`folder_line.core.mechanisms.knife.window`). **Cycle k**
runs from the knife exit ``kT + t_out`` to the next one, ``(k+1)T + t_out``. Sheet
(signature) k is handed over in cycle k, **folded in cycle k** by the knife passage
centred on ``(k+1)T`` (contact at ``(k+1)T + t_in``) and **taken by carriage k** at
the folding rollers when that passage ends::

    Θ_pick(k) = (k + 1) T + t_out = theta_pick0 + k T,      theta_pick0 = T + t_out

One carriage per cycle: the chain runs at ``v_A = pitch / T`` per unit Θ (m/s at
nominal speed), so carriage k has moved ``v_A (Θ - Θ_pick(k))`` of chain since its
pickup. It reaches the stroke after ``L_transfer`` (``Θ_enter(k) = theta_enter0 +
kT``) and leaves it after ``L_transfer + S``, ``S`` the chain length over the stroke.
The chain carries a carriage every ``pitch`` whether or not it holds a sheet, so
everything about the carriages is periodic in Θ with period ``T`` (carriages of
negative index are the ones already on the chain at Θ = 0). Where ``S > pitch``
several carriages are on the stroke at once (:attr:`ChainSchedule.max_on_stroke`).
:class:`ChainSchedule` holds this; :func:`schedule` builds it for a scene.

Chain path over the stroke
--------------------------
Stroke position ``u`` in [0, 2] is the chain pin's abscissa in units of ``x_max`` (as
in :func:`folder_line.core.mechanisms.delivery.evaluate_stroke`): the guide is ``y = y_max ψ(ξ)``
with ``ξ = u`` on the first section and ``ξ = 2 - u`` on the second (it descends
again), so the pin moves ``dx = x_max du`` while the chain moves
``ds = dx / cos β``::

    s(u) = x_max ∫_0^u sqrt(1 + (Λ ψ'(ξ(v)))²) dv,      S = s(2)

:class:`ChainPath` integrates the slope ``ds/du`` by 8-point Gauss-Legendre on
``PATH_INTERVALS`` equal intervals per section (``u = 1`` is an interval end, so the
kink of ``ψ'`` there is never inside one), sums the pieces with Neumaier's
compensation and interpolates ``s(u)`` by cubic Hermite pieces with the exact slopes at
the nodes (error ~4e-15 m on the defaults, tested against mpmath). The inverse ``u(s)``
solves the same Hermite cubic by Newton's method, so :meth:`ChainPath.arc` and
:meth:`ChainPath.position` are inverse to rounding; :meth:`ChainPath.position1` is the
scalar path (plain Python, for ODE right-hand sides). :func:`chain_to_stroke` and
:func:`stroke_to_chain` map chain travel since pickup to stroke position and back.
"""

from __future__ import annotations

import bisect
import functools
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from folder_line.core.limits import LINEAR_SPEED
from folder_line.core.mechanisms import knife as knife_mod
from folder_line.core.mechanisms.delivery import DeliveryParams
from folder_line.core.mechanisms.delivery_laws import LAWS
from folder_line.core.mechanisms.scene_view import SceneView
from folder_line.core.numerics.arrays import FloatArray
from folder_line.core.numerics.constants import EPS
from folder_line.core.numerics.validate import positive
from folder_line.core.types.machines import ChainParams
from folder_line.errors import ParameterError

__all__ = [
    'MAX_ON_STROKE',
    'MAX_STROKE',
    'OFF_STROKE',
    'PATH_INTERVALS',
    'ChainPath',
    'ChainSchedule',
    'chain_path',
    'chain_to_stroke',
    'schedule',
    'stroke_to_chain',
]


#: :func:`chain_to_stroke` returns this where the carriage is not on the stroke
OFF_STROKE = -1.0
#: intervals of the arc-length table per section
PATH_INTERVALS = 2048
#: Newton iterations on the Hermite cubic (the chord guess is within ~1e-4 of the interval; 3 reach rounding)
_NEWTON = 4
_GL_X, _GL_W = np.polynomial.legendre.leggauss(8)


# --------------------------------------------------------------------------- chain path


def _cumsum_compensated(values: list[float]) -> list[float]:
    """``[0, v0, v0 + v1, ...]`` with Neumaier's compensation (rounding ~1 ulp, not ~n ulp)."""
    out = [0.0]
    total, comp = 0.0, 0.0
    for v in values:
        t = total + v
        comp += (total - t) + v if abs(total) >= abs(v) else (v - t) + total
        total = t
        out.append(total + comp)
    return out


class ChainPath:
    """Arc length of the chain along the curved guide over the stroke, ``s(u)``, and its inverse.

    Parameters
    ----------
    delivery : DeliveryParams
        Profile law and ``Lambda``.
    x_max : float
        Section length, m (> 0).
    n : int
        Table intervals per section (>= 1).

    Attributes
    ----------
    length : float
        ``S = s(2)``: chain travel over the whole stroke, m.
    x_max : float
        Section length, m.
    """

    def __init__(self, delivery: DeliveryParams, x_max: float, n: int = PATH_INTERVALS) -> None:
        if isinstance(n, bool) or not isinstance(n, int) or n < 1:
            raise ParameterError('n', n, 'must be an int >= 1')
        self.x_max = positive('delivery_chain.x_max', x_max)
        self.Lambda = delivery.Lambda
        self._dpsi = LAWS[delivery.law].dpsi
        self._n = n
        u = np.linspace(0.0, 2.0, 2 * n + 1)
        du = np.diff(u)
        nodes = u[:-1, None] + 0.5 * du[:, None] * (_GL_X[None, :] + 1.0)
        pieces = 0.5 * du * (self.slope(nodes) @ _GL_W)
        s = np.array(_cumsum_compensated(pieces.tolist()))
        g = self.slope(u)
        ds = np.diff(s)
        self._u: FloatArray = u
        self._s: FloatArray = s
        self._du: FloatArray = du
        # cubic Hermite in tau = (u - u_i)/du_i: s = c0 + c1 tau + c2 tau^2 + c3 tau^3
        self._c: FloatArray = np.stack(
            [s[:-1], du * g[:-1], 3.0 * ds - 2.0 * du * g[:-1] - du * g[1:], du * (g[:-1] + g[1:]) - 2.0 * ds]
        )
        self.length = float(s[-1])
        # plain lists for the scalar path (the ODE right-hand side)
        self._u_list: list[float] = u.tolist()
        self._s_list: list[float] = s.tolist()
        self._c_list: list[list[float]] = self._c.T.tolist()

    def slope(self, u: npt.ArrayLike) -> FloatArray:
        """``ds/du = x_max sqrt(1 + (Λ ψ'(ξ))²) = x_max / cos β`` at stroke positions ``u`` in [0, 2], m."""
        uu = np.asarray(u, dtype=np.float64)
        xi = np.where(uu > 1.0, 2.0 - uu, uu)
        return self.x_max * np.hypot(1.0, self.Lambda * np.asarray(self._dpsi(xi), dtype=np.float64))

    def arc(self, u: npt.ArrayLike) -> FloatArray:
        """Chain travel from the start of the stroke to position ``u`` (in [0, 2], clipped), m."""
        uu = np.clip(np.asarray(u, dtype=np.float64), 0.0, 2.0)
        # uniform nodes: the interval is floor(u n) (continuous C1 pieces: a node is fine either side)
        i = np.minimum((uu * self._n).astype(np.int64), self._du.size - 1)
        tau = (uu - self._u[i]) / self._du[i]
        c: FloatArray = self._c[:, i]
        travel: FloatArray = ((c[3] * tau + c[2]) * tau + c[1]) * tau + c[0]  # c[k] is typed Any
        return travel

    def position(self, s: npt.ArrayLike) -> FloatArray:
        """Stroke position ``u`` at chain travel ``s`` from the stroke start (in [0, S], clipped).

        One element goes through :meth:`position1` (the same operations in plain
        Python, bit for bit the same result, ~20 times faster than the array path).
        """
        sa = np.asarray(s, dtype=np.float64)
        if sa.size == 1:
            return np.full(sa.shape, self.position1(float(sa.reshape(-1)[0])))
        ss = np.clip(sa, 0.0, self.length)
        i = np.clip(np.searchsorted(self._s, ss, side='right') - 1, 0, self._du.size - 1)
        c: FloatArray = self._c[:, i]
        tau: FloatArray = (ss - c[0]) / (self._s[i + 1] - c[0])
        for _ in range(_NEWTON):  # Newton on the monotone cubic, from the chord guess
            p = ((c[3] * tau + c[2]) * tau + c[1]) * tau + c[0] - ss
            d = (3.0 * c[3] * tau + 2.0 * c[2]) * tau + c[1]
            tau = np.clip(tau - p / d, 0.0, 1.0)
        return np.clip(self._u[i] + tau * self._du[i], 0.0, 2.0)

    def position1(self, s: float) -> float:
        """Scalar :meth:`position` (plain Python, ~2.5 µs: for the ODE right-hand side)."""
        ss = min(max(s, 0.0), self.length)
        i = min(max(bisect.bisect_right(self._s_list, ss) - 1, 0), len(self._c_list) - 1)
        c0, c1, c2, c3 = self._c_list[i]
        tau = (ss - c0) / (self._s_list[i + 1] - c0)
        for _ in range(_NEWTON):
            p = ((c3 * tau + c2) * tau + c1) * tau + c0 - ss
            d = (3.0 * c3 * tau + 2.0 * c2) * tau + c1
            tau = min(max(tau - p / d, 0.0), 1.0)
        u0 = self._u_list[i]
        return min(max(u0 + tau * (self._u_list[i + 1] - u0), 0.0), 2.0)


@functools.lru_cache(maxsize=32)
def _path(delivery: DeliveryParams, chain: ChainParams) -> ChainPath:
    return ChainPath(delivery, chain.x_max)


def chain_path(scene: SceneView) -> ChainPath:
    """The scene's :class:`ChainPath` (cached per delivery and chain parameters)."""
    return _path(scene.machine('delivery'), scene.machine('delivery_chain'))


# --------------------------------------------------------------------------- schedule


@dataclass(frozen=True)
class ChainSchedule:
    """Where the carriages are, in master phase Θ (nominal s); numbering in the module docstring.

    Attributes
    ----------
    T : float
        Knife cycle = one carriage, ``2π/ω_k``, s.
    pitch : float
        Chain length between carriages, m.
    v_A : float
        Chain speed at nominal line speed, ``pitch / T``, m/s.
    L_transfer : float
        Chain travel from pickup to the stroke start, m.
    S : float
        Chain travel over the stroke (``u`` 0 -> 2), m.
    theta_pick0 : float
        Θ at which carriage 0 takes sheet 0, ``T + t_out``, nominal s.
    """

    T: float
    pitch: float
    v_A: float
    L_transfer: float
    S: float
    theta_pick0: float

    @property
    def theta_enter0(self) -> float:
        """Θ at which carriage 0 enters the stroke, nominal s."""
        return self.theta_pick0 + self.L_transfer / self.v_A

    @property
    def stroke_phase(self) -> float:
        """Θ a carriage spends on the stroke, ``S / v_A``, nominal s."""
        return self.S / self.v_A

    @property
    def max_on_stroke(self) -> int:
        """An upper bound on the carriages on the stroke at once, ``ceil(S / pitch) + 1``."""
        return math.ceil(self.S / self.pitch) + 1

    def pickup_phase(self, cycle: npt.ArrayLike) -> FloatArray:
        """Θ at which carriage ``cycle`` takes sheet ``cycle``, nominal s."""
        return self.theta_pick0 + np.asarray(cycle, dtype=float) * self.T

    def phase_of_travel(self, travel: npt.ArrayLike, cycle: npt.ArrayLike) -> FloatArray:
        """Θ at which carriage ``cycle`` has moved ``travel`` m of chain since its pickup."""
        return self.pickup_phase(cycle) + np.asarray(travel, dtype=float) / self.v_A

    def travel(self, Theta: npt.ArrayLike, cycle: npt.ArrayLike) -> FloatArray:
        """Chain travel of carriage ``cycle`` since its pickup, at master phase Θ, m.

        The inverse of :meth:`phase_of_travel`.
        """
        return self.v_A * (np.asarray(Theta, dtype=float) - self.pickup_phase(cycle))

    def stroke_travel(self, Theta: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Chain travel past the stroke entry of the carriage that entered last, at Θ (vectorised).

        The carriage that entered ``m`` carriages earlier is at ``a0 + m pitch``; a
        carriage is on the stroke where its travel is in ``[-slack, S + slack]``.

        Parameters
        ----------
        Theta : array_like of float
            Master phase, nominal s (any finite value).

        Returns
        -------
        a0 : ndarray
            In ``[-slack, pitch - slack)``, m.
        slack : ndarray
            4 eps of the magnitudes involved, in m of chain: a carriage exactly at the
            entry or the exit (to rounding) counts as there, not as off the stroke.
        """
        th = np.asarray(Theta, dtype=float)
        if th.size == 1:  # one node tick: the same operations on Python floats, bit for bit
            v = float(th.reshape(-1)[0])
            x1 = v - self.theta_enter0
            p1 = x1 - math.floor(x1 / self.T) * self.T
            s1 = 4.0 * EPS * (abs(v) + abs(self.theta_enter0) + self.T)
            if p1 >= self.T - s1:
                p1 = p1 - self.T
            return np.full(th.shape, self.v_A * p1), np.full(th.shape, self.v_A * s1)
        x = th - self.theta_enter0
        ph = x - np.floor(x / self.T) * self.T
        slack = 4.0 * EPS * (np.abs(th) + abs(self.theta_enter0) + self.T)
        ph = np.where(ph >= self.T - slack, ph - self.T, ph)
        return self.v_A * ph, self.v_A * slack


MAX_STROKE = 100.0
"""Longest delivery stroke a scene may have, m of chain (the paper's: 0.67 m)."""

MAX_ON_STROKE = 100
"""Most carriages a scene may put on the delivery stroke at once (:attr:`ChainSchedule.max_on_stroke`):
the chain load sums over every one at every step, so the work grows with it (752 carriages, from
``delivery.Lambda=1000``, took 27 s before the scene's first tick)."""


@functools.lru_cache(maxsize=32)
def _schedule(delivery: DeliveryParams, chain: ChainParams, knife: knife_mod.KnifeParams) -> ChainSchedule:
    T = 2.0 * math.pi / knife.omega_k  # as folder_line.core.mechanisms.cyclogram.cycle_timing, bit for bit
    with np.errstate(over='ignore', invalid='ignore'):  # a non-finite length is refused just below
        S = _path(delivery, chain).length
    if not math.isfinite(S) or S > MAX_STROKE:
        reason = (
            f'makes the delivery stroke {S:.4g} m of chain long (a guide Lambda x_max high); at most {MAX_STROKE:g} m'
        )
        raise ParameterError('delivery.Lambda', delivery.Lambda, reason)
    on_stroke = S / chain.pitch
    if not on_stroke < MAX_ON_STROKE:
        reason = (
            f'puts {on_stroke:.4g} carriages on the delivery stroke at once (its chain travel is {S:.4g} m); '
            f'at most {MAX_ON_STROKE}: a longer pitch, or a shorter stroke (delivery.Lambda, delivery_chain.x_max)'
        )
        raise ParameterError('delivery_chain.pitch', chain.pitch, reason)
    v_A = chain.pitch / T
    if not v_A <= LINEAR_SPEED.hi:
        reason = (
            f'drives the chain at pitch / T = {v_A:.4g} m/s (one pitch per knife cycle); at most {LINEAR_SPEED.text()}'
        )
        raise ParameterError('delivery_chain.pitch', chain.pitch, reason)
    return ChainSchedule(
        T=T,
        pitch=chain.pitch,
        v_A=v_A,
        L_transfer=chain.L_transfer,
        S=S,
        theta_pick0=T + knife_mod.window(knife).t_out,
    )


def schedule(scene: SceneView) -> ChainSchedule:
    """The scene's :class:`ChainSchedule` (needs the ``knife``, ``delivery``, ``delivery_chain`` sections).

    Raises
    ------
    ParameterError
        The work the scene asks of the chain is unbounded: a stroke longer than :data:`MAX_STROKE`
        (``delivery.Lambda``), more than :data:`MAX_ON_STROKE` carriages on it at once, or a chain
        faster than :data:`~folder_line.core.limits.LINEAR_SPEED` (``delivery_chain.pitch``).
    """
    return _schedule(scene.machine('delivery'), scene.machine('delivery_chain'), scene.machine('knife'))


# --------------------------------------------------------------------------- chain <-> stroke


def chain_to_stroke(scene: SceneView) -> Callable[[npt.ArrayLike], FloatArray]:
    """Map chain travel since pickup (m) to stroke position ``u``.

    Returns
    -------
    callable
        ``f(travel) -> u``, vectorised: ``u`` in [0, 2] where ``L_transfer <= travel <=
        L_transfer + S`` (ends widened by 4 eps of the magnitudes, so that
        ``f(stroke_to_chain(scene, 2.0))`` is 2.0, not off the stroke),
        :data:`OFF_STROKE` (-1.0) elsewhere. Never NaN; a non-finite travel is a
        ``ParameterError``.
    """
    path = chain_path(scene)
    L: float = scene.machine('delivery_chain').L_transfer

    def to_stroke(travel: npt.ArrayLike) -> FloatArray:
        tr = np.asarray(travel, dtype=float)
        if not np.all(np.isfinite(tr)):
            raise ParameterError('travel', travel, 'must be finite')
        s = tr - L
        slack = 4.0 * EPS * (np.abs(tr) + L + path.length)  # rounding of travel = L + arc, not a position
        on = (s >= -slack) & (s <= path.length + slack)
        return np.where(on, path.position(np.where(on, s, 0.0)), OFF_STROKE)

    return to_stroke


def stroke_to_chain(scene: SceneView, u: npt.ArrayLike) -> FloatArray:
    """Chain travel since pickup (m) at which the carriage is at stroke position ``u`` (in [0, 2])."""
    uu = np.asarray(u, dtype=float)
    if not np.all(np.isfinite(uu)) or np.any((uu < -1e-9) | (uu > 2.0 + 1e-9)):
        raise ParameterError('u', u, 'must be finite and in [0, 2]')
    l_transfer: float = scene.machine('delivery_chain').L_transfer
    return l_transfer + chain_path(scene).arc(uu)
