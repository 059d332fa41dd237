"""``guide_friction`` — a leaf slides down a swinging chute against Coulomb friction (L, no belts).

Paper 000 (its results recomputed in docs/machines.md, section L): at the swing extremes the exit speeds
v_C, v_E vanish, "leaves lose speed, stay longer on the guides O2C, O3E, are braked
by friction, and the container edges fill unevenly". This effect models that leaf
on the guide (ours: docs/scenes.md, "Effects").

Equation
--------
The chute turns about its pivot by the angle θ' **from the downward vertical**
(θ' = θ3 + π/2, resp. θ5 + π/2), with ω = dθ'/dt and ε = dω/dt (:class:`ChuteState`); the
leaf is a point at distance s from the pivot along the chute. Per unit mass, with the walls'
push N along the chute's normal (either sign: the chute is a channel)::

    N  = ε s + 2 ω ṡ + g sin θ'                                    (normal push)
    s̈ = g cos θ' + ω² s − μ |ε s + 2 ω ṡ + g sin θ'| sign(ṡ)      (sliding)

The chutes point downward over their whole swing (cos θ' > 0), so ṡ >= 0 throughout. A leaf
slides (ṡ > 0: :func:`acceleration`) or is stuck (ṡ = 0) while ``σ <= 0`` (:func:`switching`),
with the events ``leaf_stick`` and ``leaf_slip``. All leaves advance in lockstep by fixed-step
RK4 (:class:`GuideSlider`, :func:`slide`). The frame and the derivation, the stick–slip rules,
the integrator (events on the steps' Hermite interpolants, steps cut at the kinks of ``|N|``,
the scan of a stuck leaf) and its limits, its accuracy and cost, what the model shows and the
suggested parameters: docs/machines.md, "Leaves sliding on the guides".
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Generic, NamedTuple, TypeAlias, TypeVar

import numpy as np
import numpy.typing as npt

from folder_line.core.numerics.arrays import FloatArray, IntArray
from folder_line.core.numerics.constants import G
from folder_line.core.numerics.hermite import hermite, hermite_level
from folder_line.core.numerics.roots import brent, brentq
from folder_line.core.numerics.validate import check_fields, non_negative, within
from folder_line.errors import ParameterError

__all__ = ['ChuteState', 'Params', 'SlideResult', 'acceleration', 'check_geometry', 'normal', 'slide', 'switching']

#: |N| (m/s²) at which a step end counts as on the zero of N
_KINK_NTOL = 1e-11
#: Illinois iterations locating a zero of N
_KINK_MAXITER = 12
#: samples per block when scanning a stuck leaf's switching function
_SCAN_BLOCK = 64
#: bisection passes of the exit interpolant (step fraction in [0, 1] to 2**-55)
_EXIT_BISECTIONS = 55

#: float (one leaf) or float64 array (n leaves): the kinematics and the state share it
_F = TypeVar('_F', float, FloatArray)


@dataclass(frozen=True)
class Params:
    """Parameters of ``guide_friction``.

    Attributes
    ----------
    mu : float
        Coulomb friction coefficient between leaf and guide (>= 0; same for static
        and kinetic friction). Suggested 0.5.
    s0 : float
        Entry point: distance from the chute's pivot, m (>= 0; must be shorter than
        both chutes, checked by the simulator). Suggested 0.0.
    v0 : float
        Entry speed along the chute, m/s (>= 0). Suggested 1.0.
    h : float
        RK4 step, s, in (0, 0.05]. Suggested 0.002.
    """

    mu: float
    s0: float
    v0: float
    h: float

    def __post_init__(self) -> None:
        check_fields(
            self,
            'effects.guide_friction',
            mu=within(0.0, 100.0),
            s0=non_negative,
            v0=within(0.0, 1e3),
            h=within(0.0, 0.05, lo_open=True),
        )


class ChuteState(NamedTuple, Generic[_F]):
    """Kinematics of each leaf's chute at given times (arrays, or floats for one leaf).

    Fields: ``sin``, ``cos`` — sin θ', cos θ' of the chute angle from the downward
    vertical; ``omega`` — dθ'/dt, rad/s; ``eps`` — d²θ'/dt², rad/s².
    """

    sin: _F
    cos: _F
    omega: _F
    eps: _F


#: kin(t, chute) -> ChuteState: vectorised chute kinematics (chute 0: transporter 3, 1: transporter 4)
KinFn: TypeAlias = Callable[[FloatArray, IntArray], ChuteState[FloatArray]]
#: kin1(t, chute) -> ChuteState of floats: the same for one leaf (fast scalar path)
Kin1Fn: TypeAlias = Callable[[float, int], ChuteState[float]]


@dataclass(frozen=True, eq=False)
class SlideResult:
    """Outcome of :func:`slide` for n leaves.

    Attributes
    ----------
    exited : ndarray of bool, shape (n,)
        The leaf reached the exit by ``t_end``.
    t_exit : ndarray, shape (n,)
        Exit time, s (where ``exited``; the entry time elsewhere).
    v_exit : ndarray, shape (n,)
        Speed along the chute at the exit, m/s (where ``exited``; 0 elsewhere).
    stick_t, slip_t : ndarray
        Times of the stick and slip events (<= t_end), s.
    stick_leaf, slip_leaf : ndarray of int64
        Index (into the input arrays) of the leaf of each event.
    steps : int
        RK4 iterations of the lockstep loop.
    """

    exited: np.ndarray
    t_exit: np.ndarray
    v_exit: np.ndarray
    stick_t: np.ndarray
    stick_leaf: np.ndarray
    slip_t: np.ndarray
    slip_leaf: np.ndarray
    steps: int = field(default=0)


def normal(s: _F, v: _F, k: ChuteState[_F]) -> _F:
    """Wall push per unit mass ``N = ε s + 2 ω ṡ + g sin θ'``, m/s²."""
    return k.eps * s + 2.0 * k.omega * v + G * k.sin


def acceleration(params: Params, s: _F, v: _F, k: ChuteState[_F]) -> _F:
    """``s̈ = g cos θ' + ω² s − μ |N|`` while sliding outward (ṡ >= 0), m/s²."""
    return G * k.cos + k.omega * k.omega * s - params.mu * abs(normal(s, v, k))


def switching(params: Params, s: _F, k: ChuteState[_F]) -> _F:
    """``σ = g cos θ' + ω² s − μ |ε s + g sin θ'|`` of a leaf at rest: it slips where σ > 0, m/s²."""
    return G * k.cos + k.omega * k.omega * s - params.mu * abs(k.eps * s + G * k.sin)


def check_geometry(params: Params, l_min: float, cos_max_up: float) -> None:
    """Reject chutes the model cannot handle.

    Parameters
    ----------
    params : Params
        The effect's parameters.
    l_min : float
        The shorter chute, m: ``s0`` must be shorter.
    cos_max_up : float
        Smallest cos θ' over the swing of both chutes: must be > 0 (chutes point down).

    Raises
    ------
    ParameterError
        ``effects.guide_friction.s0`` not shorter than the chutes, or a chute that
        points upward somewhere in its swing (a leaf could slide back out).
    """
    if not params.s0 < l_min:
        raise ParameterError(
            'effects.guide_friction.s0', params.s0, f'must be shorter than the shorter chute ({l_min!r} m)'
        )
    if not cos_max_up > 0.0:
        raise ParameterError(
            'effects.guide_friction',
            'layup geometry',
            f'a chute points upward in its swing (cos of the angle from the downward vertical '
            f'reaches {cos_max_up:.6g}); the guide-friction model needs both chutes to point down',
        )


def _rk4(
    params: Params,
    kin: KinFn,
    t: np.ndarray,
    s: np.ndarray,
    v: np.ndarray,
    a: np.ndarray,
    ch: np.ndarray,
    hh: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One RK4 step of length hh per leaf: (s, ṡ, s̈, N) at t + hh."""
    half = 0.5 * hh
    km = kin(t + half, ch)
    s2 = s + half * v
    v2 = v + half * a
    a2 = acceleration(params, s2, v2, km)
    s3 = s + half * v2
    v3 = v + half * a2
    a3 = acceleration(params, s3, v3, km)
    ke = kin(t + hh, ch)
    s4 = s + hh * v3
    v4 = v + hh * a3
    a4 = acceleration(params, s4, v4, ke)
    sixth = hh / 6.0
    s1 = s + sixth * (v + 2.0 * v2 + 2.0 * v3 + v4)
    v1 = v + sixth * (a + 2.0 * a2 + 2.0 * a3 + a4)
    return s1, v1, acceleration(params, s1, v1, ke), normal(s1, v1, ke)


class _Active:
    """Compact per-leaf state of the sliding leaves."""

    __slots__ = ('a', 'ch', 'fresh', 'ids', 'length', 'n', 'pending', 's', 't', 'v')

    def __init__(
        self,
        ids: np.ndarray,
        t: np.ndarray,
        s: np.ndarray,
        v: np.ndarray,
        a: np.ndarray,
        n: np.ndarray,
        ch: np.ndarray,
        length: np.ndarray,
        fresh: np.ndarray,
        pending: np.ndarray,
    ) -> None:
        self.ids, self.t, self.s, self.v, self.a, self.n = ids, t, s, v, a, n
        self.ch, self.length, self.fresh, self.pending = ch, length, fresh, pending

    def take(self, m: np.ndarray) -> _Active:
        return _Active(
            *(getattr(self, k)[m] for k in ('ids', 't', 's', 'v', 'a', 'n', 'ch', 'length', 'fresh', 'pending'))
        )

    @staticmethod
    def concat(parts: list[_Active]) -> _Active:
        return _Active(
            *(
                np.concatenate([getattr(p, k) for p in parts])
                for k in ('ids', 't', 's', 'v', 'a', 'n', 'ch', 'length', 'fresh', 'pending')
            )
        )

    @property
    def size(self) -> int:
        return int(self.ids.size)


def _split_at_kink(
    params: Params,
    kin: KinFn,
    act: _Active,
    cross: np.ndarray,
    hh: np.ndarray,
    s1: np.ndarray,
    v1: np.ndarray,
    a1: np.ndarray,
    n1: np.ndarray,
) -> None:
    """Shorten the steps across which N changes sign so that they end on its zero (in place).

    Illinois (modified regula falsi) iterations on the step length, each a full RK4
    sub-step, until |N| at the end is below ``_KINK_NTOL`` or the bracket is a few ulp
    wide.
    """
    rows = np.flatnonzero(cross)
    na, nb = act.n[rows], n1[rows].copy()
    ha, hb = np.zeros(rows.size), hh[rows].copy()
    t, s, v, a, ch = act.t[rows], act.s[rows], act.v[rows], act.a[rows], act.ch[rows]
    best = hb.copy()
    out = (s1[rows], v1[rows], a1[rows], n1[rows])
    side = np.zeros(rows.size)  # Illinois: which end was kept last (-1 a, +1 b)
    live = np.ones(rows.size, dtype=bool)
    for _ in range(_KINK_MAXITER):
        hc = hb - nb * (hb - ha) / (nb - na)
        hc = np.where((hc > ha) & (hc < hb), hc, 0.5 * (ha + hb))
        r = _rk4(params, kin, t[live], s[live], v[live], a[live], ch[live], hc[live])
        nc = np.zeros(rows.size)
        nc[live] = r[3]
        for k, arr in enumerate(out):
            arr[live] = r[k]
        best[live] = hc[live]
        conv = live & ((np.abs(nc) <= _KINK_NTOL) | (hb - ha <= 4.0 * np.spacing(t + hb)))
        same_a = live & (nc * na > 0.0)
        same_b = live & ~same_a
        # replace the end with the sign of nc; halve the other end's value if it was kept twice (Illinois)
        nb_keep = same_a & (side == -1.0)
        na_keep = same_b & (side == 1.0)
        ha = np.where(same_a, hc, ha)
        na = np.where(same_a, nc, na)
        hb = np.where(same_b, hc, hb)
        nb = np.where(same_b, nc, nb)
        nb = np.where(nb_keep, 0.5 * nb, nb)
        na = np.where(na_keep, 0.5 * na, na)
        side = np.where(same_a, -1.0, np.where(same_b, 1.0, side))
        live &= ~conv
        if not live.any():
            break
    hh[rows] = best
    s1[rows], v1[rows], a1[rows], n1[rows] = out


def _exit_fraction(
    s0: np.ndarray, v0: np.ndarray, s1: np.ndarray, v1: np.ndarray, hh: np.ndarray, length: np.ndarray
) -> np.ndarray:
    """Step fraction where the Hermite interpolant of s reaches ``length`` (s0 < length <= s1): bisection."""
    return hermite_level(s0, v0, s1, v1, hh, length, _EXIT_BISECTIONS)


def _slip_time(params: Params, kin1: Kin1Fn, s: float, ch: int, lo: float, hi: float) -> float:
    """Root of σ in [lo, hi] (σ(lo) <= 0 < σ(hi) on the vectorised samples), by Brent's method."""

    def sigma(t: float) -> float:
        return float(switching(params, s, kin1(t, ch)))

    f_lo, f_hi = sigma(lo), sigma(hi)
    if f_lo > 0.0:  # the scalar and vector kinematics differ in the last bits at a zero
        return lo
    if not f_hi > 0.0:
        return hi
    return brent(sigma, lo, hi).root


def slide(
    params: Params,
    kin: KinFn,
    kin1: Kin1Fn,
    t_enter: npt.ArrayLike,
    chute: npt.ArrayLike,
    length: npt.ArrayLike,
    t_end: float,
) -> SlideResult:
    """Integrate every leaf from its entry to the exit (or to ``t_end``), with stick–slip.

    :class:`GuideSlider` run once to ``t_end`` (plus one step, so that a slip before
    ``t_end`` is confirmed), keeping what happens by ``t_end``.

    Parameters
    ----------
    params : Params
        The effect's parameters.
    kin : callable ``kin(t, chute) -> ChuteState``
        Vectorised chute kinematics at the times ``t`` (s) for the chutes ``chute``
        (0: transporter 3, 1: transporter 4).
    kin1 : callable ``kin1(t, chute) -> ChuteState``
        The same for one leaf, floats (used by the root-finding of slip times).
    t_enter : array_like, shape (n,)
        Entry times, s.
    chute : array_like of int, shape (n,)
        Chute of each leaf.
    length : array_like, shape (n,)
        Chute length of each leaf (l3 or l5), m (> s0).
    t_end : float
        End of the run, s: leaves still on a chute then have not exited.

    Returns
    -------
    SlideResult
    """
    t_enter = np.asarray(t_enter, dtype=float)
    n = t_enter.size
    slider = GuideSlider(params, kin, kin1)
    slider.add(np.arange(n, dtype=np.int64), t_enter, np.asarray(chute, dtype=np.int64), length)
    found = slider.advance(t_end + params.h)
    exited = np.zeros(n, dtype=bool)
    t_exit = t_enter.copy()
    v_exit = np.zeros(n)
    ok = found.exit_t <= t_end
    exited[found.exit_id[ok]] = True
    t_exit[found.exit_id[ok]] = found.exit_t[ok]
    v_exit[found.exit_id[ok]] = found.exit_v[ok]
    kst, ksl = found.stick_t <= t_end, found.slip_t <= t_end
    return SlideResult(
        exited,
        t_exit,
        v_exit,
        found.stick_t[kst],
        found.stick_id[kst],
        found.slip_t[ksl],
        found.slip_id[ksl],
        slider.steps,
    )


@dataclass(frozen=True, eq=False)
class Found:
    """What :meth:`GuideSlider.advance` found: exits (id, time s, speed along the chute m/s), sticks and
    slips (id, time s), each in the order found."""

    exit_id: IntArray
    exit_t: FloatArray
    exit_v: FloatArray
    stick_id: IntArray
    stick_t: FloatArray
    slip_id: IntArray
    slip_t: FloatArray


class GuideSlider:
    """The leaves on the guides, advanced window by window (the integrator of :func:`slide`, streamed).

    A piece of work is done only when it ends at or before the time advanced to: an RK4
    step of a sliding leaf from ``t`` when ``t + h`` is reached, a stuck leaf's switching
    function at its scan times ``t_stick + k h`` up to it. A leaf's steps are the same
    whatever the windows, so the events are too. A slip is reported once the leaf's
    first step after it moves (a grazing slip whose first step does not move is dropped
    and the leaf scanned on); advanced one step ``h`` past a time, every event up to that
    time is found.

    Parameters
    ----------
    params : Params
    kin, kin1 : callable
        The chute kinematics, vectorised and scalar (:func:`slide`).

    Attributes
    ----------
    steps : int
        RK4 steps taken, summed over the leaves.
    """

    def __init__(self, params: Params, kin: KinFn, kin1: Kin1Fn) -> None:
        self.params = params
        self.kin = kin
        self.kin1 = kin1
        self.steps = 0
        z, zi = np.zeros(0), np.zeros(0, dtype=np.int64)
        self.act = _Active(zi, z, z, z, z, z, zi, z, np.zeros(0, dtype=bool), z)
        # stuck leaves: id, s, chute, length, scan origin t0, next scan index k (samples at t0 + k h)
        self.stuck = (zi, z, zi, z, z, zi)
        self._found: list[tuple[str, np.ndarray, np.ndarray, np.ndarray]] = []

    @property
    def leaves(self) -> int:
        """Leaves on the guides (sliding or stuck)."""
        return self.act.size + int(self.stuck[0].size)

    def earliest(self) -> float:
        """The earliest time at which work is pending (a step's start, a scan time), s (inf if none)."""
        t = [float(self.act.t.min())] if self.act.size else []
        if self.stuck[0].size:
            t.append(float((self.stuck[4] + self.stuck[5] * self.params.h).min()))
        return min(t, default=math.inf)

    def add(self, ids: npt.ArrayLike, t_enter: npt.ArrayLike, chute: npt.ArrayLike, length: npt.ArrayLike) -> None:
        """Leaves entering their chutes at ``t_enter`` (s; at most the time advanced to next)."""
        p = self.params
        ids = np.asarray(ids, dtype=np.int64)
        t_enter = np.asarray(t_enter, dtype=float)
        chute = np.asarray(chute, dtype=np.int64)
        length = np.broadcast_to(np.asarray(length, dtype=float), t_enter.shape).copy()
        n = t_enter.size
        if n == 0:
            return
        s = np.full(n, p.s0)
        v = np.full(n, p.v0)
        k0 = self.kin(t_enter, chute)
        a, nrm = acceleration(p, s, v, k0), normal(s, v, k0)
        keep = np.ones(n, dtype=bool)
        if p.v0 == 0.0:
            at_rest = a <= 0.0  # σ(t_enter) <= 0: stuck from the entry
            self._found.append(('stick', ids[at_rest], t_enter[at_rest], np.zeros(int(at_rest.sum()))))
            self._stick(ids[at_rest], s[at_rest], chute[at_rest], length[at_rest], t_enter[at_rest])
            keep = ~at_rest
        fresh = np.full(n, p.v0 == 0.0)
        new = _Active(ids, t_enter.copy(), s, v, a, nrm, chute, length, fresh, np.full(n, -1.0)).take(keep)
        self.act = _Active.concat([self.act, new]) if self.act.size else new

    def _stick(self, ids: np.ndarray, s: np.ndarray, ch: np.ndarray, length: np.ndarray, t0: np.ndarray) -> None:
        """Leaves stuck at ``t0``: scanned from there on (sample 0 included: the vectorised kinematics may
        see σ > 0 where the scalar ones decided on a stick)."""
        if ids.size == 0:
            return
        add = (ids, s, ch, length, t0, np.zeros(ids.size, dtype=np.int64))
        self.stuck = tuple(np.concatenate((a, b)) for a, b in zip(self.stuck, add, strict=True))  # type: ignore[assignment]

    def advance(self, c: float) -> Found:
        """Do every step and scan that ends at or before ``c`` (s); what was found on the way."""
        while True:
            moved = self._scan(c)
            rows = np.flatnonzero(self.act.t + self.params.h <= c)
            if rows.size:
                self._step(rows)
            elif not moved:
                break
        return self._take()

    def _take(self) -> Found:
        def pick(kind: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            parts = [x for x in self._found if x[0] == kind]
            if not parts:
                return np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0)
            return (
                np.concatenate([x[1] for x in parts]).astype(np.int64),
                np.concatenate([x[2] for x in parts]).astype(float),
                np.concatenate([x[3] for x in parts]).astype(float),
            )

        ex, st, sl = pick('exit'), pick('stick'), pick('slip')
        self._found = []
        return Found(ex[0], ex[1], ex[2], st[0], st[1], sl[0], sl[1])

    def _step(self, rows: np.ndarray) -> None:
        """One lockstep RK4 step of the sliding leaves ``rows`` (docs/machines.md, "Leaves sliding on the guides")."""
        p = self.params
        whole = self.act
        act = whole.take(rows)
        rest = np.ones(whole.size, dtype=bool)
        rest[rows] = False
        waiting = whole.take(rest)
        self.steps += act.size
        hh = np.full(act.size, p.h)
        s1, v1, a1, n1 = _rk4(p, self.kin, act.t, act.s, act.v, act.a, act.ch, hh)
        # split steps across a sign change of N (kink of |N|)
        cross = (act.n * n1 < 0.0) & (np.abs(act.n) > _KINK_NTOL) & (np.abs(n1) > _KINK_NTOL)
        if cross.any():
            _split_at_kink(p, self.kin, act, cross, hh, s1, v1, a1, n1)
        t1 = act.t + hh
        halted = v1 <= 0.0
        failed = halted & act.fresh  # did not get moving after a slip / from rest
        stop = halted & ~act.fresh
        out_exit = (s1 >= act.length) & ~failed
        done = out_exit | halted
        th_exit = self._exits(act, hh, s1, v1, a1, out_exit, stop)
        new_stuck, restart = self._stops(act, hh, s1, v1, a1, stop, th_exit)
        for row in np.flatnonzero(failed).tolist():
            if act.pending[row] < 0.0:  # stuck from its entry / after a grazing stop
                self._found.append(('stick', act.ids[row : row + 1], act.t[row : row + 1], np.zeros(1)))
            new_stuck.append((row, float(act.s[row]), float(t1[row])))
        # confirmed slips: leaves that got moving after their pending slip
        conf = act.fresh & ~failed & (act.pending >= 0.0)
        if conf.any():
            self._found.append(('slip', act.ids[conf], act.pending[conf], np.zeros(int(conf.sum()))))
        if new_stuck:
            rr = np.array([x[0] for x in new_stuck], dtype=np.int64)
            sv = np.array([x[1] for x in new_stuck])
            tv = np.array([x[2] for x in new_stuck])
            self._stick(act.ids[rr], sv, act.ch[rr], act.length[rr], tv)
        nxt = _Active(
            act.ids, t1, s1, v1, a1, n1, act.ch, act.length, np.zeros(act.size, dtype=bool), np.full(act.size, -1.0)
        )
        parts = [waiting, nxt.take(~done)]
        if restart:
            rr = np.array([x[0] for x in restart], dtype=np.int64)
            tr = np.array([x[1] for x in restart])
            sr = np.array([x[2] for x in restart])
            parts.append(self._from_rest(act.ids[rr], tr, sr, act.ch[rr], act.length[rr], np.full(rr.size, -1.0)))
        self.act = _Active.concat(parts)

    def _exits(
        self,
        act: _Active,
        hh: np.ndarray,
        s1: np.ndarray,
        v1: np.ndarray,
        a1: np.ndarray,
        out_exit: np.ndarray,
        stop: np.ndarray,
    ) -> dict[int, float]:
        """Record the exits of the step (leaves ``act`` stepped by ``hh`` to ``s1, v1, a1``) of the leaves
        ``out_exit`` that do not also stop in it (``stop``); for those that do, their exit's step
        fraction by row (:meth:`_stops` decides which comes first)."""
        if not out_exit.any():
            return {}
        er = np.flatnonzero(out_exit)
        th = _exit_fraction(act.s[er], act.v[er], s1[er], v1[er], hh[er], act.length[er])
        tx = act.t[er] + th * hh[er]
        vx = hermite(th, act.v[er], act.a[er], v1[er], a1[er], hh[er])
        ok = ~stop[er]
        self._found.append(('exit', act.ids[er[ok]], tx[ok], vx[ok]))
        return dict(zip(er[stop[er]].tolist(), th[stop[er]].tolist(), strict=True))

    def _stops(
        self,
        act: _Active,
        hh: np.ndarray,
        s1: np.ndarray,
        v1: np.ndarray,
        a1: np.ndarray,
        stop: np.ndarray,
        th_exit: dict[int, float],
    ) -> tuple[list[tuple[int, float, float]], list[tuple[int, float, float]]]:
        """The leaves whose speed reaches 0 in the step (``stop``; the step as for :meth:`_exits`): each
        exits first (``th_exit``), sticks (recorded), or slides on from rest (a grazing stop).

        Returns
        -------
        tuple of list
            The new stuck leaves ``(row, s m, scan from s)`` and the restarts ``(row, t s, s m)``.
        """
        p, kin1 = self.params, self.kin1
        new_stuck: list[tuple[int, float, float]] = []  # (row, s, scan from)
        restart: list[tuple[int, float, float]] = []  # (row, t, s): grazing stop, slide on from rest
        for row in np.flatnonzero(stop).tolist():
            y0, d0, y1, d1, hr = (float(act.v[row]), float(act.a[row]), float(v1[row]), float(a1[row]), float(hh[row]))

            def dv(x: float, y0: float = y0, d0: float = d0, y1: float = y1, d1: float = d1, hr: float = hr) -> float:
                return hermite(x, y0, d0, y1, d1, hr)  # speed along the step: zero at the stop

            th_stop = brentq(dv, 0.0, 1.0)
            t0 = float(act.t[row])
            leaf = np.array([act.ids[row]], dtype=np.int64)
            if row in th_exit and th_exit[row] <= th_stop:
                self._found.append(
                    (
                        'exit',
                        leaf,
                        np.array([t0 + th_exit[row] * hr]),
                        np.array([hermite(th_exit[row], y0, d0, y1, d1, hr)]),
                    )
                )
                continue
            t_stop = t0 + th_stop * hr
            s_stop = hermite(th_stop, float(act.s[row]), y0, float(s1[row]), y1, hr)
            ch = int(act.ch[row])
            if float(switching(p, s_stop, kin1(t_stop, ch))) <= 0.0:
                self._found.append(('stick', leaf, np.array([t_stop]), np.zeros(1)))
                new_stuck.append((row, s_stop, t_stop))
            else:
                restart.append((row, t_stop, s_stop))
        return new_stuck, restart

    def _from_rest(
        self,
        ids: np.ndarray,
        t: np.ndarray,
        s: np.ndarray,
        ch: np.ndarray,
        length: np.ndarray,
        pending: np.ndarray,
    ) -> _Active:
        """Leaves starting to slide from rest at times ``t`` (s) and places ``s`` (m): fresh, with their
        pending slip times ``pending`` (s; -1 for none)."""
        p = self.params
        k = self.kin(t, ch)
        z = np.zeros(ids.size)
        return _Active(
            ids, t, s, z, acceleration(p, s, z, k), normal(s, z, k), ch, length, np.ones(ids.size, dtype=bool), pending
        )

    def _scan(self, c: float) -> bool:
        """Scan the stuck leaves' switching function at their scan times up to ``c``, in blocks of
        :data:`_SCAN_BLOCK`; the leaves that slip become fresh sliding leaves with a pending slip.
        True if any sample was taken."""
        p, kin = self.params, self.kin
        ids, s, ch, length, t0, k_next = self.stuck
        if ids.size == 0:
            return False
        h = p.h
        # samples k_next .. k_last with t0 + k h <= c
        k_last = np.floor((c - t0) / h).astype(np.int64)
        k_last = np.where(t0 + k_last * h > c, k_last - 1, k_last)
        k_last = np.minimum(k_last, k_next + _SCAN_BLOCK - 1)
        rows = np.flatnonzero(k_last >= k_next)
        if rows.size == 0:
            return False
        width = int((k_last[rows] - k_next[rows]).max()) + 1
        kk = np.minimum(k_next[rows, None] + np.arange(width)[None, :], k_last[rows, None])  # past c: repeated
        valid = (k_next[rows, None] + np.arange(width)[None, :]) <= k_last[rows, None]
        grid = t0[rows, None] + kk * h
        ks = kin(grid.ravel(), np.repeat(ch[rows], width))
        sig = switching(p, np.repeat(s[rows], width), ks).reshape(grid.shape)
        pos = (sig > 0.0) & valid
        slip = np.full(ids.size, -1.0)
        for j in np.flatnonzero(pos.any(axis=1)).tolist():
            r = int(rows[j])
            i = int(np.argmax(pos[j]))
            if kk[j, i] == 0:  # slips where its scan starts (after a failed start)
                slip[r] = float(grid[j, i])
                continue
            lo = float(t0[r] + (kk[j, 0] - 1) * h) if i == 0 else float(grid[j, i - 1])  # the sample before
            slip[r] = _slip_time(p, self.kin1, float(s[r]), int(ch[r]), lo, float(grid[j, i]))
        k_next = k_next.copy()
        k_next[rows] = k_last[rows] + 1
        ok = slip >= 0.0
        self.stuck = tuple(a[~ok] for a in (ids, s, ch, length, t0, k_next))  # type: ignore[assignment]
        if ok.any():
            rs = np.flatnonzero(ok)
            tr = slip[rs]
            resumed = self._from_rest(ids[rs], tr, s[rs], ch[rs], length[rs], tr.copy())
            self.act = _Active.concat([self.act, resumed]) if self.act.size else resumed
        return True
