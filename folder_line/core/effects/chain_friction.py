"""Effect ``chain_friction``: efficiency, forces and sprocket torque of the delivery (D).

Source: paper 002, eqs. (1)-(9) (docs/machines.md, section D and "The papers' results, recomputed"), as
implemented (friction terms as losses, states instead of NaN) in :mod:`folder_line.core.mechanisms.delivery`::

    P_AB = P_k / (cos a - f_Bp |sin a| - f_B r_B |sin b| / (K_v cos a))        (1)
    P_ch = P_AB (cos(a - b) + f_Ap |sin(a - b)| + f_A r_A |sin b| / cos a)      (4)
    M_1  = P_ch r (1 + f_O r_O)                                                 (7)
    eta  = eta_O eta_A eta_B = P_k v_k / (M_1 omega_sprocket)                   (9)

with ``v_k = K_v v_A`` and ``omega_sprocket = v_A / r``. Wherever the delivery
reports a state other than ``'ok'`` (self-locking, ``K_v`` = 0, carriage reversed)
the forces and ``M_1`` are 0 and ``eta`` is 0 -- the state says why; nothing is NaN.

Where the carriages are
-----------------------
:mod:`folder_line.core.mechanisms.chain` (kinematics, shared with the folder simulation): carriage
``k`` takes sheet ``k`` at ``Θ_pick(k) = (k + 1) T + t_out``, the chain runs at
``v_A = pitch / T``, and a carriage is on the stroke from ``L_transfer`` to
``L_transfer + S`` of chain travel after its pickup; its stroke position ``u`` follows
from :class:`~folder_line.core.mechanisms.chain.ChainPath`.

* **Every carriage loads the chain.** The chain carries a carriage every ``pitch``
  whether or not it holds a sheet, so the load is periodic in Θ with period ``T``.
  ``P_k`` is the useful force of a carriage on the stroke. **Off the stroke a carriage
  pulls nothing** (idle chain torque 0: its friction is in the motor's viscous term).
  The sprocket torque therefore jumps from 0 to ``P_k r (1 + f_O r_O)`` where a carriage
  enters the stroke (``u = 0``: ``alpha = beta = 0``, ``K_v = 1``) and back where it
  leaves (``u = 2``). Inside the stroke ``M_1(u)`` has kinks where a friction term
  changes sign (``alpha = beta``: pair A's sliding friction reverses) and may jump at
  the section boundary ``u = 1`` (:func:`stroke_kinks`). :class:`MasterLoad` gives the
  motor all of these as breaks, so that the integrator never steps across one. Where
  the stroke is longer than the pitch several carriages are on it at once and their
  torques add. A carriage exactly at the entry or exit (to rounding) counts as on the
  stroke.

Reflected to the master shaft (``motor_dynamics`` lists ``omega_nom``), the torque is
``T_load = M_1 omega_sprocket / omega_nom``: the chain is geared to the master shaft,
so ``T_load omega_master = M_1 omega_sprocket`` (power) at any speed.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from folder_line.core.limits import CARRIAGE_FORCE, MOTOR_SPEED, SPROCKET_RADIUS
from folder_line.core.mechanisms.chain import ChainPath, ChainSchedule, chain_path, schedule
from folder_line.core.mechanisms.delivery import (
    RETURN_SECTIONS,
    DeliveryParams,
    ReturnSection,
    evaluate_stroke,
    evaluate_stroke_point,
)
from folder_line.core.mechanisms.delivery_results import STATE_OK, StateCoded
from folder_line.core.mechanisms.scene_view import SceneView
from folder_line.core.numerics.arrays import FloatArray, Int8Array
from folder_line.core.numerics.roots import find_sign_changes
from folder_line.core.numerics.validate import among, check_fields
from folder_line.errors import ParameterError

__all__ = [
    'ChainFrictionState',
    'MasterLoad',
    'Params',
    'master_load',
    'master_load_torque',
    'sprocket_torque',
    'stroke_kinks',
    'stroke_state',
]


_GL_X, _GL_W = np.polynomial.legendre.leggauss(8)


@dataclass(frozen=True)
class Params:
    """Parameters of the ``chain_friction`` effect (no defaults: the scene gives all).

    Attributes
    ----------
    P_k : float
        Useful carriage force on the stroke, N, in [0, 1e6] (:data:`folder_line.core.limits.CARRIAGE_FORCE`).
    r : float
        Sprocket radius, m, in [0.001, 10] (:data:`folder_line.core.limits.SPROCKET_RADIUS`).
    return_section : {'geometric', 'paper_mirror'}
        Slope sign on the second section, as in
        :func:`folder_line.core.mechanisms.delivery.evaluate_stroke` (``'geometric'`` is the
        kinematically consistent one).
    """

    P_k: float
    r: float
    return_section: ReturnSection

    def __post_init__(self) -> None:
        check_fields(
            self,
            'effects.chain_friction',
            P_k=CARRIAGE_FORCE.check,
            r=SPROCKET_RADIUS.check,
            return_section=among(RETURN_SECTIONS),
        )


@dataclass(frozen=True, eq=False)
class ChainFrictionState(StateCoded):
    """Efficiency and forces along the stroke (arrays shaped like ``u``).

    Attributes
    ----------
    u : ndarray
        Stroke position in [0, 2].
    eta : ndarray
        Efficiency (eq. 9); 0 where the state is not ``'ok'``.
    K_v : ndarray
        Carriage speed over chain speed.
    state : ndarray of int8
        :data:`folder_line.core.mechanisms.delivery_results.STATE_NAMES` index.
    P_AB, P_ch : ndarray
        Rod force and chain pull, N.
    M_1 : ndarray
        Sprocket torque, N m.
    ok : ndarray of bool
        The ``'ok'`` samples (a property).
    """

    u: FloatArray
    eta: FloatArray
    K_v: FloatArray
    state: Int8Array
    P_AB: FloatArray
    P_ch: FloatArray
    M_1: FloatArray


def stroke_state(params: Params, delivery: DeliveryParams, u: npt.ArrayLike) -> ChainFrictionState:
    """Efficiency, forces and sprocket torque at stroke positions ``u`` (vectorised).

    Parameters
    ----------
    params : Params
        ``P_k`` (N), ``r`` (m), ``return_section``.
    delivery : DeliveryParams
        The delivery mechanism.
    u : array_like of float
        Stroke positions in [0, 2] (``ParameterError`` outside, as in ``evaluate_stroke``).

    Returns
    -------
    ChainFrictionState
        All finite; locked samples carry 0 forces and ``eta = 0`` with their state.
    """
    s = evaluate_stroke(delivery, u, return_section=params.return_section)
    f = s.forces(params.P_k, params.r)
    return ChainFrictionState(u=s.u, eta=s.eta, K_v=s.K_v, state=s.state, P_AB=f.P_AB, P_ch=f.P_ch, M_1=f.M_1)


# --------------------------------------------------------------------------- torques


def _params(scene: SceneView) -> Params:
    p: Params | None = scene.effect('chain_friction')
    if p is None:
        raise ParameterError('effects', 'chain_friction', f'scene {scene.name!r} does not list chain_friction')
    return p


def sprocket_torque(scene: SceneView, Theta: npt.ArrayLike) -> FloatArray:
    """Sprocket torque M_1 (N m) of all carriages on the stroke at master phase Θ (vectorised).

    Parameters
    ----------
    scene : SceneView
        Lists ``chain_friction``; has the knife and the delivery.
    Theta : array_like of float
        Master phase, nominal s (any real; the load is periodic with period ``T``).

    Returns
    -------
    ndarray
        Shaped like ``Theta``; 0 where no carriage is on the stroke (and where the
        delivery reports a locked state).
    """
    th = np.asarray(Theta, dtype=float)
    if not np.all(np.isfinite(th)):
        raise ParameterError('Theta', Theta, 'must be finite')
    return _stroke_torque(_params(scene), scene.machine('delivery'), chain_path(scene), schedule(scene), th)


def _stroke_torque(
    p: Params, delivery: DeliveryParams, path: ChainPath, sch: ChainSchedule, th: FloatArray
) -> FloatArray:
    """Sum of M_1 (N m) over the carriages on the stroke at Θ (membership by Θ itself).

    A carriage exactly at the entry or the exit (to rounding) counts as on the stroke,
    at ``u = 0`` or ``u = 2`` (:meth:`folder_line.core.mechanisms.chain.ChainSchedule.stroke_travel`).
    """
    a0, slack = sch.stroke_travel(th)
    total = np.zeros(th.shape)
    for m in range(sch.max_on_stroke):  # carriages on the stroke at once (1 if S < pitch)
        a = a0 + m * sch.pitch
        on = (a >= -slack) & (a <= sch.S + slack)
        if np.any(on):  # evaluate the delivery only where a carriage is on the stroke
            u = path.position(np.clip(a[on], 0.0, sch.S))
            total[on] += stroke_state(p, delivery, u).M_1
    return total


def master_load_torque(scene: SceneView, Theta: npt.ArrayLike, omega_nom: float | None = None) -> FloatArray:
    """Sprocket torque reflected to the master shaft, ``M_1 omega_sprocket / omega_nom`` (N m).

    Parameters
    ----------
    scene : SceneView
        As for :func:`sprocket_torque`.
    Theta : array_like of float
        Master phase, nominal s.
    omega_nom : float, optional
        Nominal master-shaft speed, rad/s; default the scene's ``motor_dynamics.omega_nom``.
    """
    return sprocket_torque(scene, Theta) * master_load(scene, omega_nom).ratio


def stroke_kinks(params: Params, delivery: DeliveryParams, n: int = 4001) -> FloatArray:
    """Stroke positions in (0, 2) where the torque ``M_1(u)`` is not smooth.

    The friction terms are magnitudes (:mod:`folder_line.core.mechanisms.delivery`):
    ``|sin(alpha - beta)|`` and ``|tan(alpha - beta)|`` have a kink where
    ``alpha - beta`` changes sign (pair A's sliding friction reverses), ``|sin beta|``
    where ``beta`` does -- only at the section ends, since ``psi' >= 0`` keeps the sign
    of ``beta`` within a section -- and the formula switches sections at ``u = 1``
    (a jump if ``psi'(1) != 0``). Returns ``u = 1`` and every sign change of
    ``alpha - beta`` on a grid of ``n`` points per section, refined by Brent's method
    (:func:`folder_line.core.numerics.roots.find_sign_changes`; touches are smooth and are not
    reported).
    """
    rs = params.return_section
    out = [1.0]
    for lo, hi in ((0.0, 1.0), (1.0, 2.0)):
        grid = np.linspace(lo, hi, n)
        st = evaluate_stroke(delivery, grid, return_section=rs)
        vals = st.alpha - st.beta

        def f(u: float) -> float:
            pt = evaluate_stroke_point(delivery, u, return_section=rs)
            return pt.alpha - pt.beta

        found = find_sign_changes(f, grid, values=vals, xtol=1e-15)
        out.extend(float(x) for x in found.x if 0.0 < x < 2.0)
    return np.unique(np.array(out))


class MasterLoad:
    """The chain load as the motor ODE needs it: vectorised torque, scalar piecewise torque, breaks.

    Parameters
    ----------
    scene : SceneView
        Lists ``chain_friction``.
    omega_nom : float
        Nominal master-shaft speed, rad/s.

    Attributes
    ----------
    ratio : float
        ``omega_sprocket / omega_nom`` with ``omega_sprocket = v_A / r``.
    period : float
        Θ-period of the load, ``T``.
    offsets : tuple of float
        Θ of the breaks within a period, counted from ``schedule.theta_enter0``:
        0 (a carriage enters), ``(S mod pitch)/v_A`` (one leaves) and the kinks of
        :func:`stroke_kinks` (``arc(u_k)/v_A mod T``).
    kinks_u : ndarray
        Stroke positions where ``M_1`` has a kink or a jump (:func:`stroke_kinks`).
    peak : float
        Largest master-shaft load torque over a period (grid of 20001 points per piece,
        the best refined by golden-section search), N m.
    mean : float
        Mean over a period in Θ (Gauss-Legendre per piece), N m.
    locked_u : ndarray
        Stroke positions (of a 4001-point grid) where the delivery reports a state
        other than ``'ok'``: there the model's forces are 0 but the real mechanism jams.
    """

    def __init__(self, scene: SceneView, omega_nom: float) -> None:
        self.params = _params(scene)
        self.delivery: DeliveryParams = scene.machine('delivery')
        self.schedule = schedule(scene)
        self.path = chain_path(scene)
        sch = self.schedule
        self.omega_nom = MOTOR_SPEED.check('effects.motor_dynamics.omega_nom', omega_nom)
        self.omega_sprocket = sch.v_A / self.params.r
        self.ratio = self.omega_sprocket / self.omega_nom
        self.period = sch.T
        self.theta0 = sch.theta_enter0
        self.n_over = sch.max_on_stroke
        self.kinks_u = stroke_kinks(self.params, self.delivery)
        arcs = np.concatenate([[0.0, sch.S], self.path.arc(self.kinks_u)])
        offs = np.sort(np.mod(arcs / sch.v_A, sch.T))
        keep = np.concatenate([[True], np.diff(offs) > 1e-12 * sch.T]) & (offs < sch.T * (1.0 - 1e-12))
        self.offsets = tuple(float(o) for o in offs[keep])
        self._scale = self.params.P_k * self.params.r * self.ratio
        grid = np.linspace(0.0, 2.0, 4001)
        st = evaluate_stroke(self.delivery, grid, return_section=self.params.return_section)
        self.locked_u = grid[st.state != STATE_OK]
        ends = [*list(self.offsets), sch.T]
        peak, area = 0.0, 0.0
        for lo, hi in itertools.pairwise(ends):
            th = self.theta0 + np.linspace(lo, hi, 20001)
            mid = 0.5 * (lo + hi) + self.theta0
            vals = self._torque_piece_vec(th, mid)
            peak = max(peak, self._refine_peak(th, vals, (lo + self.theta0, hi + self.theta0)))
            edges = np.linspace(lo, hi, 257) + self.theta0
            w = np.diff(edges)
            nodes = edges[:-1, None] + 0.5 * w[:, None] * (_GL_X[None, :] + 1.0)
            area += float(np.sum(0.5 * w * (self._torque_piece_vec(nodes.ravel(), mid).reshape(nodes.shape) @ _GL_W)))
        self.peak = peak
        self.mean = area / sch.T

    def _refine_peak(self, th: FloatArray, vals: FloatArray, piece: tuple[float, float]) -> float:
        """Golden-section refinement of the grid maximum on the piece's scalar formula."""
        i = int(np.argmax(vals))
        a, b = float(th[max(i - 1, 0)]), float(th[min(i + 1, th.size - 1)])
        g = (math.sqrt(5.0) - 1.0) / 2.0
        c, d = b - g * (b - a), a + g * (b - a)
        fc, fd = self.torque_piece(c, piece), self.torque_piece(d, piece)
        for _ in range(60):
            if fc >= fd:
                b, d, fd = d, c, fc
                c = b - g * (b - a)
                fc = self.torque_piece(c, piece)
            else:
                a, c, fc = c, d, fd
                d = a + g * (b - a)
                fd = self.torque_piece(d, piece)
        return max(float(vals[i]), fc, fd)

    # breaks ------------------------------------------------------------------------------
    def next_break(self, v: float) -> float:
        """Smallest break Θ strictly above ``v``."""
        T, th0 = self.period, self.theta0
        k = math.floor((v - th0) / T)
        best = math.inf
        for kk in (k - 1, k, k + 1, k + 2):
            for o in self.offsets:
                b = th0 + kk * T + o
                if v < b < best:
                    best = b
        return best

    def is_entry(self, b: float) -> bool:
        """Whether break ``b`` is a carriage entering the stroke (offset 0)."""
        x = (b - self.theta0) / self.period
        return abs(x - round(x)) * self.period <= 1e-9 * max(1.0, abs(b))

    # torques -----------------------------------------------------------------------------
    def torque(self, Theta: npt.ArrayLike) -> FloatArray:
        """Master-shaft load torque at Θ, N m (vectorised; membership by Θ itself)."""
        th = np.asarray(Theta, dtype=float)
        return _stroke_torque(self.params, self.delivery, self.path, self.schedule, th) * self.ratio

    def _torque_piece_vec(self, Theta: FloatArray, mid: float) -> FloatArray:
        k = math.floor((mid - self.theta0) / self.period)
        a_mid = self.schedule.v_A * (mid - self.theta0 - k * self.period)
        a0 = self.schedule.v_A * (np.asarray(Theta, dtype=float) - self.theta0 - k * self.period)
        return self._sum(a0, np.full(a0.shape, a_mid))

    def _sum(self, a0: FloatArray, a_member: FloatArray) -> FloatArray:
        sch = self.schedule
        total = np.zeros(a0.shape)
        for m in range(self.n_over):
            on = (a_member + m * sch.pitch >= 0.0) & (a_member + m * sch.pitch <= sch.S)
            if np.any(on):
                a = np.clip(a0 + m * sch.pitch, 0.0, sch.S)
                u = self.path.position(np.where(on, a, 0.0))
                total += np.where(on, stroke_state(self.params, self.delivery, u).M_1, 0.0)
        return total * self.ratio

    def torque_piece(self, theta: float, piece: tuple[float, float]) -> float:
        """Scalar load torque (N m) on the piece ``(lo, hi)`` of the break grid.

        Which carriages are on the stroke is decided at the piece's middle; their
        stroke positions follow ``theta`` (clipped to the stroke), so the torque is the
        piece's smooth formula, extended continuously a little past its ends.
        """
        lo, hi = piece
        mid = 0.5 * (lo + hi) if math.isfinite(hi) else lo + 0.5 * self.period
        sch = self.schedule
        k = math.floor((mid - self.theta0) / self.period)
        base = self.theta0 + k * self.period
        a_mid = sch.v_A * (mid - base)
        a0 = sch.v_A * (theta - base)
        total = 0.0
        for m in range(self.n_over):
            am = a_mid + m * sch.pitch
            if 0.0 <= am <= sch.S:
                a = min(max(a0 + m * sch.pitch, 0.0), sch.S)
                pt = evaluate_stroke_point(
                    self.delivery, self.path.position1(a), return_section=self.params.return_section
                )
                total += pt.m_1
        return total * self._scale


_LOADS: dict[tuple[object, ...], MasterLoad] = {}


def master_load(scene: SceneView, omega_nom: float | None = None) -> MasterLoad:
    """The scene's :class:`MasterLoad` (cached per parameters).

    ``omega_nom`` defaults to the scene's ``motor_dynamics.omega_nom``; without
    ``motor_dynamics`` it must be given.
    """
    if omega_nom is None:
        md = scene.effect('motor_dynamics')
        if md is None:
            raise ParameterError(
                'effects',
                'motor_dynamics',
                'master_load_torque needs omega_nom: give it or list motor_dynamics in the scene',
            )
        omega_nom = md.omega_nom
    key = (
        _params(scene),
        scene.machine('delivery'),
        scene.machine('delivery_chain'),
        scene.machine('knife'),
        float(omega_nom),
    )
    load = _LOADS.get(key)
    if load is None:
        if len(_LOADS) >= 32:
            _LOADS.clear()
        load = _LOADS[key] = MasterLoad(scene, float(omega_nom))
    return load
