"""``stop_bounce`` — restitution at the front stops, settle time and rebound (F).

Source: ours (docs/scenes.md, "Effects", *stop_bounce (F)*); docs/machines.md section F
(paper 001): "bounce of the signature off the front stops must be minimal (lowest
impact force); it is damped mainly by fixed, pre-tensioned polymer strings over the
signature". The paper gives no model; this one is ours.

Model
-----
The signature hits the stops at speed ``V`` and rebounds at ``e V`` (coefficient of
restitution ``e`` in [0, 1)). Moving away from the stops it is braked at ``a_f``
(friction of the table and the strings; the feed belt under it pulls it back at the
same rate), so it travels::

    rebound distance   x_n = (e^n V)² / (2 a_f)

stops, and is driven back onto the stops, arriving at the speed it left with,
``e^n V``, after ``2 e^n V / a_f``. The next rebound is at ``e^{n+1} V``, and so on.
An impact slower than ``v_rest`` does not rebound (the strings hold the signature):
the signature is settled. So the n-th bounce (n = 1, 2, ...) happens iff the impact
before it, at ``e^{n-1} V``, is at least ``v_rest`` (and ``e > 0``), and the number of
bounces is, in closed form::

    N = 0                                   if e = 0 or V < v_rest
    N = 1 + floor(ln(v_rest / V) / ln e)    otherwise

(corrected by one where rounding of the logarithms puts ``e^{N-1} V`` on the wrong
side of ``v_rest``). The settle time after the first impact is the finite geometric
sum::

    t_settle = sum_{n=1..N} 2 e^n V / a_f = (2 V / a_f) e (1 - e^N) / (1 - e)

and the n-th bounce starts at ``(2 V / a_f) e (1 - e^{n-1}) / (1 - e)`` after the
first impact.

Constraints (evaluated by :mod:`folder_line.core.line.constraints`):
``settled_before_knife`` = knife contact − settled (s) and ``rebound`` = ``tolerance``
− first rebound distance (m), the fold tolerance at the stops.

Events: one ``bounce`` per bounce (value: its rebound distance) up to
:data:`MAX_BOUNCE_EVENTS` per signature — past that the bounces are sub-micrometre
and only counted (the settle time always includes all ``N``) — then ``settled``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from folder_line.core.limits import BOUNCE_DECELERATION, REST_SPEED
from folder_line.core.numerics.validate import check_fields, positive, within
from folder_line.errors import ParameterError

__all__ = [
    'MAX_BOUNCE_EVENTS',
    'BounceSchedule',
    'Params',
    'bounce_count',
    'bounce_schedule',
    'first_rebound',
    'settle_time',
]

#: at most this many ``bounce`` events per signature (the count and the settle time are exact)
MAX_BOUNCE_EVENTS = 16


@dataclass(frozen=True)
class Params:
    """Impact at the front stops.

    Attributes
    ----------
    e : float
        Coefficient of restitution, dimensionless, in [0, 1).
    a_f : float
        Deceleration of the rebounding signature (table, strings, belt), m/s², in [1, 1e6]
        (:data:`folder_line.core.limits.BOUNCE_DECELERATION`).
    tolerance : float
        Largest admissible rebound distance (fold tolerance), m (> 0).
    v_rest : float
        Impacts slower than this do not rebound, m/s, in [1e-6, 100]
        (:data:`folder_line.core.limits.REST_SPEED`).
    """

    e: float
    a_f: float
    tolerance: float
    v_rest: float

    def __post_init__(self) -> None:
        check_fields(
            self,
            'effects.stop_bounce',
            e=within(0.0, 1.0, hi_open=True),
            a_f=BOUNCE_DECELERATION.check,
            tolerance=positive,
            v_rest=REST_SPEED.check,
        )


def _speeds(V: npt.ArrayLike) -> np.ndarray:
    v = np.asarray(V, dtype=float)
    if not (np.all(np.isfinite(v)) and np.all(v >= 0.0)):
        raise ParameterError('V', V, 'impact speed must be finite and >= 0 (m/s)')
    return v


def _restitution(params: Params, v: np.ndarray, e: npt.ArrayLike | None) -> float | np.ndarray:
    """``params.e`` (None: one restitution for every impact), else ``e`` checked: one per impact speed, in [0, 1)."""
    if e is None:
        return params.e
    ea = np.asarray(e, dtype=float)
    if ea.shape != v.shape or not (np.all(ea >= 0.0) and np.all(ea < 1.0)):
        raise ParameterError('e', e, 'needs one restitution in [0, 1) per impact speed')
    return ea


def _count(e: float | np.ndarray, v_rest: float, v: np.ndarray) -> np.ndarray:
    """N per impact at speeds ``v`` with restitution ``e`` (a float, or an array shaped like ``v``), checked."""
    bouncing = (v >= v_rest) & (e > 0.0)
    if not np.any(bouncing):
        return np.zeros(v.shape, dtype=np.int64)
    ratio = np.where(bouncing, v_rest / np.where(bouncing, v, 1.0), 1.0)  # in (0, 1]
    if isinstance(e, np.ndarray):
        ee: float | np.ndarray = np.where(bouncing, e, 0.5)  # a placeholder in (0, 1) where e = 0: no log(0)
        log_e: float | np.ndarray = np.log(ee)
    else:  # one e > 0 for all: one logarithm
        ee, log_e = e, math.log(e)
    k = np.floor(np.log(ratio) / log_e)  # >= 0
    k = np.clip(k, 0.0, 1e15)  # int64-safe; e -> 1 with v_rest -> 0 is unphysical anyway
    # fix the rounding of the logarithms: want e^k V >= v_rest > e^(k+1) V
    k = np.where(ee**k * v < v_rest, k - 1.0, k)
    k = np.where(ee ** (k + 1.0) * v >= v_rest, k + 1.0, k)
    return np.where(bouncing, k.astype(np.int64) + 1, 0)


def _settle(e: float | np.ndarray, a_f: float, v: np.ndarray, count: np.ndarray) -> np.ndarray:
    """``(2 V / a_f) e (1 - e^N) / (1 - e)`` per impact (0 where N = 0), s."""
    return np.where(count > 0, (2.0 * v / a_f) * e * (1.0 - e ** count.astype(float)) / (1.0 - e), 0.0)


def bounce_count(params: Params, V: npt.ArrayLike, e: npt.ArrayLike | None = None) -> np.ndarray:
    """Number of bounces N after an impact at ``V`` (closed form via logarithms).

    Parameters
    ----------
    params : Params
        Restitution.
    V : array_like
        Impact speed, m/s (>= 0).
    e : array_like, optional
        A restitution per impact, shaped like ``V``, in [0, 1) (``property_scatter``); None:
        ``params.e`` for all.

    Returns
    -------
    ndarray of int64
        N >= 0, shaped like ``V``: the largest N with ``e^{N-1} V >= v_rest`` (0 if
        ``e = 0`` or ``V < v_rest``).
    """
    v = _speeds(V)
    return _count(_restitution(params, v, e), params.v_rest, v)


def first_rebound(params: Params, V: npt.ArrayLike) -> np.ndarray:
    """Rebound distance of the first bounce, ``(e V)² / (2 a_f)`` (0 if none), m."""
    v = _speeds(V)
    n = bounce_count(params, v)
    ev = params.e * v
    return np.where(n > 0, ev * ev / (2.0 * params.a_f), 0.0)


def settle_time(params: Params, V: npt.ArrayLike) -> np.ndarray:
    """Time from the first impact until the signature rests at the stops, s.

    ``(2 V / a_f) e (1 - e^N) / (1 - e)`` with N from :func:`bounce_count` (0 if N = 0).
    """
    v = _speeds(V)
    return _settle(params.e, params.a_f, v, bounce_count(params, v))


@dataclass(frozen=True, eq=False)
class BounceSchedule:
    """The bounces of many impacts, flattened (one row per emitted bounce).

    Attributes
    ----------
    index : ndarray of int64
        Which impact (index into the ``V`` given) each row belongs to.
    n : ndarray of int64
        Bounce number, 1-based.
    dt : ndarray
        Start of the bounce after the first impact, s.
    rebound : ndarray
        Its rebound distance ``(e^n V)² / (2 a_f)``, m.
    count : ndarray of int64
        N per impact (all bounces, also those not emitted).
    settle : ndarray
        Settle time per impact, s.
    """

    index: np.ndarray
    n: np.ndarray
    dt: np.ndarray
    rebound: np.ndarray
    count: np.ndarray
    settle: np.ndarray


def bounce_schedule(
    params: Params, V: npt.ArrayLike, max_events: int = MAX_BOUNCE_EVENTS, e: npt.ArrayLike | None = None
) -> BounceSchedule:
    """Every bounce (up to ``max_events`` per impact) of impacts at speeds ``V``, vectorised.

    Parameters
    ----------
    params : Params
        Restitution.
    V : array_like, shape (M,)
        Impact speeds, m/s.
    max_events : int
        Most bounce rows per impact (>= 0).
    e : array_like, shape (M,), optional
        A restitution per impact, in [0, 1) (``property_scatter``); None: ``params.e`` for all.

    Returns
    -------
    BounceSchedule
    """
    v = _speeds(V).ravel()
    ee = _restitution(params, v, None if e is None else np.asarray(e, dtype=float).ravel())
    count = _count(ee, params.v_rest, v)
    af = params.a_f
    settle = _settle(ee, af, v, count)
    emitted = np.minimum(count, max_events)
    index = np.repeat(np.arange(v.size, dtype=np.int64), emitted)
    starts = np.cumsum(emitted) - emitted
    n = np.arange(index.size, dtype=np.int64) - np.repeat(starts, emitted) + 1
    vi = v[index]
    ei = ee[index] if isinstance(ee, np.ndarray) else ee
    nf = n.astype(float)
    dt = (2.0 * vi / af) * ei * (1.0 - ei ** (nf - 1.0)) / (1.0 - ei)
    speed = ei**nf * vi
    return BounceSchedule(index, n, dt, speed * speed / (2.0 * af), count, settle)
