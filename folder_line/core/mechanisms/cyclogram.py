"""F: cycle timing of the second-fold apparatus — feed versus knife (paper 001, Figs. 1-2).

What the paper says (paper 001, read from its scan; docs/machines.md, section F)
--------------------------------------------------------------------------------
* Reference press ДАВР-62: folding cylinder ``D_fc = 267.38 mm``, ``n_c = 25000``
  rev/h, ``omega_c = 43.6 1/s``; printing speed ``V_d = omega_c R_fc`` ("5.829"
  and later "5.729 m/s" in the paper; ``43.633 * 0.13369 = 5.833 m/s``, used here).
* One signature of ``L_a = 420 mm`` per knife-crank turn: the crank turns twice as
  fast as the cylinder, ``omega_k = 87.266 1/s`` (50000 rev/h), so
  ``T = 2 pi / omega_k = 0.072 s`` and the web advances ``L_c = V_d T`` per cycle
  (eq. 4; ``= pi R_fc = 0.4200 m``, i.e. exactly ``L_a``).
* Cyclogram (Figs. 1-2): A feed to the front stops, Б alignment (for the 2nd fold
  only the settling at the fixed stops, no side lay), В loop by the knife and feed
  into the folding rollers, Г pull-through; the next signature is fed while the
  previous one is still being folded. For knife folders with side alignment the
  paper takes ``z = t_u + t_b + t_zs = 0.25 T`` for the time at the stops (eq. 3).
* "...при центральному механізмі при частоті обертання валу кривошипа 50000
  об/год на фальцювання зошита і вихід ножа з-під стола потрібно 0,03 с. Отже,
  час на подачу зошита (з врахуванням зменшення тривалості подачі на 10%)
  складає 0,025 с." — folding plus the knife's exit from under the table takes
  0.03 s; hence the feed time, shortened by 10 % as a reserve, is 0.025 s.
  (The paper also says this is "24 % of the cycle": 0.03/0.072 is 41.7 %, so the
  0.03 s is taken as the reference.)
* eq. (5) ``V_tr = L / t = 0.230 / 0.025`` ("≈ 9.02", arithmetically 9.2 m/s);
  eq. (6) ``V_tr / V_d ≈ 1.6``: the second transporter must feed 1.6 times faster
  than the printing speed.

The timing model (ours, reproducing those numbers)
--------------------------------------------------
Time ``t`` runs with the knife crank, ``phi(t) = omega_k t``, period
``T = 2 pi / omega_k``. In every cycle:

1. **Knife window** ``[t_in, t_out]``: the knife occupies the table while
   ``s(phi) >= s_clear`` (:func:`folder_line.core.mechanisms.knife.window`, exact ends by
   root finding). Its duration ``t_knife`` stands for the paper's 0.03 s; the
   default knife geometry (``r_k = 0.04, L_k = 0.16, e = 0, s_clear = 0.1656`` m)
   gives ``t_knife = 0.030010 s`` at 50000 rev/h.
2. **Feed window** ``[t_out, t_in + T - t_dwell]``: the next signature may move
   onto the table only after the knife has left it, and must be at rest at the
   front stops a dwell ``t_dwell = dwell_frac * T`` before the knife comes down
   again at ``t_in + T`` (operation Б: settle against the stops under the
   strings). The paper's ``z = 0.25 T`` includes side alignment, which the 2nd
   fold does not have, so ``dwell_frac = 0.2`` by default (our assumption; it is
   what makes the paper's 0.025 s come out). Duration
   ``t_fw = T - t_knife - t_dwell = 0.072 - 0.03001 - 0.0144 = 0.02759 s``.
3. **Dwell** ``[t_in + T - t_dwell, t_in + T]``.

With the reserve ``reserve`` (paper: 10 %) the feed may use only
``t_allowed = (1 - reserve) t_fw = 0.02483 s`` (paper: 0.025 s). The signature
travels ``L_feed = 0.230 m`` on the second transporter at ``V_tr`` in
``t_feed = L_feed / V_tr`` (eq. 1 with the feed travel), so

* feed margin ``= t_allowed - t_feed`` (s; >= 0 passes);
* ``V_tr,min = L_feed / ((1 - reserve) t_fw) = 9.263 m/s = 1.588 V_d``: the paper's
  9.2 m/s and factor 1.6 come out of the knife kinematics.

At ``V_tr = V_d`` (no speed-up) ``t_feed = 0.03943 s`` and the margin is
``-0.01460 s``: the signature arrives after the knife has come down.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from folder_line.core.limits import CYLINDER_SPEED, MACHINE_LENGTH
from folder_line.core.mechanisms.knife import KnifeParams, KnifeWindow, window
from folder_line.core.numerics.validate import check_fields, in_range, positive, within
from folder_line.errors import ParameterError

__all__ = [
    'KNIFE_PER_CYLINDER',
    'CycleTiming',
    'CyclogramParams',
    'FeedCheck',
    'Phase',
    'check_feed',
    'cycle_timing',
    'cyclogram',
    'feed_margin',
    'feed_time',
    'min_feed_speed',
]

TWO_PI = 2.0 * math.pi

#: knife crank turns per folding-cylinder turn: one signature per half cylinder turn (paper 001), so
#: ``knife.n_k = 2 cyclogram.n_c``; a scene with another pair is refused
#: (:func:`folder_line.core.line.scene.parse_scene`), ``press.n_c`` sets both
KNIFE_PER_CYLINDER = 2.0


@dataclass(frozen=True)
class CyclogramParams:
    """Validated timing parameters of the second-fold apparatus.

    Parameters
    ----------
    D_fc : float
        Folding cylinder diameter, m; in [1e-4, 100] (:data:`folder_line.core.limits.MACHINE_LENGTH`;
        paper 0.26738).
    n_c : float
        Folding cylinder speed, rev/h; > 0 (paper 25000).
    L_feed : float
        Travel of the signature on the 2nd transporter to the front stops, m; in [1e-4, 100]
        (paper 0.230).
    L_a : float
        Cut-sheet (signature) length, m; in [1e-4, 100] (paper 0.420).
    reserve : float
        Time reserve: the feed may use only ``(1 - reserve)`` of the feed window;
        dimensionless, in [0, 1) (paper 0.10).
    dwell_frac : float
        Rest at the front stops before knife contact, as a fraction of the cycle
        T; dimensionless, in [0, 1) (default 0.2).

    Raises
    ------
    ParameterError
        A value out of range; the message names the field and the value.
    """

    D_fc: float
    n_c: float
    L_feed: float
    L_a: float
    reserve: float
    dwell_frac: float

    def __post_init__(self) -> None:
        check_fields(
            self,
            'cyclogram',
            D_fc=MACHINE_LENGTH.check,
            n_c=CYLINDER_SPEED.check,
            L_feed=MACHINE_LENGTH.check,
            L_a=MACHINE_LENGTH.check,
            reserve=within(0.0, 1.0, hi_open=True),
            dwell_frac=within(0.0, 1.0, hi_open=True),
        )

    @property
    def omega_c(self) -> float:
        """Folding cylinder angular speed ``2 pi n_c / 3600``, rad/s."""
        return TWO_PI * self.n_c / 3600.0

    @property
    def V_d(self) -> float:
        """Printing (cylinder surface) speed ``omega_c D_fc / 2``, m/s."""
        return self.omega_c * self.D_fc / 2.0


@dataclass(frozen=True)
class Phase:
    """One stretch of the cycle timeline.

    Attributes
    ----------
    name : str
        ``'knife'`` (knife over/through the table), ``'feed'`` (feed window) or
        ``'dwell'`` (signature at rest at the front stops).
    t_start, t_end : float
        Times, s, on the knife clock (``phi = omega_k t``, t = 0 at phi = 0).
    phi_start, phi_end : float
        The same as knife crank angles, rad.
    duration : float
        ``t_end - t_start``, s.
    """

    name: str
    t_start: float
    t_end: float
    phi_start: float
    phi_end: float
    duration: float


@dataclass(frozen=True)
class CycleTiming:
    """Timing of one cycle, independent of the transporter speed.

    Attributes
    ----------
    omega_c : float
        Folding cylinder angular speed, rad/s.
    V_d : float
        Printing speed ``omega_c D_fc / 2``, m/s.
    omega_k : float
        Knife crank angular speed, rad/s.
    T : float
        Cycle ``2 pi / omega_k``, s.
    speed_ratio : float
        ``n_k / n_c`` (2 in the paper: one signature per half cylinder turn).
    L_c : float
        Web advance per cycle ``V_d T``, m (eq. 4).
    L_a : float
        Cut-sheet length, m.
    L_c_error : float
        ``L_c - L_a``, m: consistency of the cylinder and the knife (0 ideally).
    knife : KnifeWindow
        The knife's table-occupation window.
    t_knife : float
        ``knife.duration``, s.
    t_dwell : float
        ``dwell_frac T``, s.
    t_fw : float
        Feed window ``T - t_knife - t_dwell``, s.
    reserve : float
        Reserve fraction.
    t_allowed : float
        ``(1 - reserve) t_fw``: time the feed may use, s.
    L_feed : float
        Feed travel, m.
    V_tr_min : float
        ``L_feed / t_allowed``: slowest transporter that passes, m/s.
    ratio_min : float
        ``V_tr_min / V_d``.
    timeline : tuple of Phase
        ``knife [t_in, t_out]``, ``feed [t_out, t_in + T - t_dwell]``,
        ``dwell [t_in + T - t_dwell, t_in + T]``: one full cycle from knife entry.
    """

    omega_c: float
    V_d: float
    omega_k: float
    T: float
    speed_ratio: float
    L_c: float
    L_a: float
    L_c_error: float
    knife: KnifeWindow
    t_knife: float
    t_dwell: float
    t_fw: float
    reserve: float
    t_allowed: float
    L_feed: float
    V_tr_min: float
    ratio_min: float
    timeline: tuple[Phase, ...]

    def min_feed_speed(self, reserve: float | None = None) -> float:
        """Slowest transporter speed that feeds in time, m/s.

        Parameters
        ----------
        reserve : float, optional
            Reserve fraction in [0, 1), dimensionless; default the configured one.

        Returns
        -------
        float
            ``L_feed / ((1 - reserve) t_fw)``, m/s.
        """
        return min_feed_speed(self, reserve)

    def feed_margin(self, V_tr: ArrayLike) -> float | NDArray[np.float64]:
        """Feed margin ``t_allowed - L_feed / V_tr``, s (see :func:`feed_margin`)."""
        return feed_margin(self, V_tr)


@dataclass(frozen=True)
class FeedCheck:
    """The cycle checked at one transporter speed.

    Attributes
    ----------
    timing : CycleTiming
        The cycle.
    V_tr : float
        2nd-transporter speed, m/s.
    ratio : float
        ``V_tr / V_d``.
    t_feed : float
        ``L_feed / V_tr``, s.
    margin : float
        ``t_allowed - t_feed``, s; >= 0 passes.
    passes : bool
        ``margin >= 0``.
    t_arrival : float
        ``t_out + t_feed``: the signature reaches the stops, s (knife clock).
    t_rest : float
        ``t_in + T - t_arrival``: actual rest at the stops before the knife, s
        (``t_dwell + reserve t_fw + margin``; negative if it arrives late).
    """

    timing: CycleTiming
    V_tr: float
    ratio: float
    t_feed: float
    margin: float
    passes: bool
    t_arrival: float
    t_rest: float


def cycle_timing(params: CyclogramParams, knife: KnifeParams) -> CycleTiming:
    """Timing of the cycle from the cylinder, the feed geometry and the knife kinematics.

    Parameters
    ----------
    params : CyclogramParams
        Cylinder, feed travel, sheet length, reserve and dwell.
    knife : KnifeParams
        The knife crank-slider (its speed ``n_k`` sets the cycle T).

    Returns
    -------
    CycleTiming
        All times in s on the knife clock.

    Raises
    ------
    ParameterError
        The knife window and the dwell leave no feed window (``t_fw <= 0``).
    """
    V_d = params.V_d
    w_k = knife.omega_k
    T = TWO_PI / w_k
    kw = window(knife)
    t_dwell = params.dwell_frac * T
    t_fw = T - kw.duration - t_dwell
    if not t_fw > 0.0:
        raise ParameterError(
            'cyclogram.dwell_frac',
            params.dwell_frac,
            f'the knife window {kw.duration!r} s plus the dwell {t_dwell!r} s fill the whole '
            f'cycle T = {T!r} s: no time is left to feed the signature',
        )
    t_allowed = (1.0 - params.reserve) * t_fw
    V_min = params.L_feed / t_allowed
    L_c = V_d * T
    t0 = kw.t_in
    marks = (('knife', t0, kw.t_out), ('feed', kw.t_out, t0 + T - t_dwell), ('dwell', t0 + T - t_dwell, t0 + T))
    timeline = tuple(Phase(n, a, b, w_k * a, w_k * b, b - a) for n, a, b in marks)
    return CycleTiming(
        omega_c=params.omega_c,
        V_d=V_d,
        omega_k=w_k,
        T=T,
        speed_ratio=knife.n_k / params.n_c,
        L_c=L_c,
        L_a=params.L_a,
        L_c_error=L_c - params.L_a,
        knife=kw,
        t_knife=kw.duration,
        t_dwell=t_dwell,
        t_fw=t_fw,
        reserve=params.reserve,
        t_allowed=t_allowed,
        L_feed=params.L_feed,
        V_tr_min=V_min,
        ratio_min=V_min / V_d,
        timeline=timeline,
    )


def _speeds(V_tr: ArrayLike) -> float | NDArray[np.float64]:
    if isinstance(V_tr, (bool, float, int)):
        return positive('V_tr', V_tr)
    v = np.asarray(V_tr, dtype=float)
    if not np.all(np.isfinite(v)):
        raise ParameterError('V_tr', V_tr, 'transporter speed must be finite (m/s)')
    if not np.all(v > 0.0):
        raise ParameterError('V_tr', V_tr, 'transporter speed must be > 0 (m/s)')
    return v


def feed_time(timing: CycleTiming, V_tr: ArrayLike) -> float | NDArray[np.float64]:
    """Time to feed the signature to the stops, ``L_feed / V_tr``.

    Parameters
    ----------
    timing : CycleTiming
        The cycle (for ``L_feed``).
    V_tr : float or array_like of float
        2nd-transporter speed(s), m/s; finite, > 0.

    Returns
    -------
    float or ndarray
        s; an array of ``V_tr``'s shape for array input.
    """
    return timing.L_feed / _speeds(V_tr)


def feed_margin(timing: CycleTiming, V_tr: ArrayLike) -> float | NDArray[np.float64]:
    """Feed margin ``(1 - reserve) t_fw - L_feed / V_tr`` (vectorised over ``V_tr``).

    Parameters
    ----------
    timing : CycleTiming
        The cycle.
    V_tr : float or array_like of float
        2nd-transporter speed(s), m/s; finite, > 0.

    Returns
    -------
    float or ndarray
        s; >= 0 passes.
    """
    return timing.t_allowed - feed_time(timing, V_tr)


def min_feed_speed(timing: CycleTiming, reserve: float | None = None) -> float:
    """Slowest 2nd-transporter speed that feeds within the reserved feed window.

    Parameters
    ----------
    timing : CycleTiming
        The cycle.
    reserve : float, optional
        Reserve fraction in [0, 1), dimensionless; default ``timing.reserve``.

    Returns
    -------
    float
        ``L_feed / ((1 - reserve) t_fw)``, m/s.
    """
    res = timing.reserve if reserve is None else in_range('reserve', reserve, 0.0, 1.0, hi_open=True)
    return timing.L_feed / ((1.0 - res) * timing.t_fw)


def check_feed(timing: CycleTiming, V_tr: float) -> FeedCheck:
    """The cycle checked at one transporter speed.

    Parameters
    ----------
    timing : CycleTiming
        The cycle, from :func:`cycle_timing`.
    V_tr : float
        2nd-transporter speed, m/s; finite, > 0.

    Returns
    -------
    FeedCheck
        Feed time, margin, arrival and rest at the stops.

    Raises
    ------
    ParameterError
        ``V_tr`` not finite or not > 0.
    """
    v = positive('V_tr', V_tr)
    t_feed = timing.L_feed / v
    margin = timing.t_allowed - t_feed
    t_arrival = timing.knife.t_out + t_feed
    t_rest = timing.knife.t_in + timing.T - t_arrival
    return FeedCheck(timing, v, v / timing.V_d, t_feed, margin, bool(margin >= 0.0), t_arrival, t_rest)


def cyclogram(params: CyclogramParams, knife: KnifeParams, V_tr: float) -> FeedCheck:
    """:func:`cycle_timing` then :func:`check_feed` in one call.

    Parameters
    ----------
    params : CyclogramParams
        Cylinder, feed travel, sheet length, reserve and dwell.
    knife : KnifeParams
        The knife crank-slider.
    V_tr : float
        2nd-transporter speed, m/s; finite, > 0.

    Returns
    -------
    FeedCheck
        The checked cycle; ``.timing`` holds the speed-independent part.
    """
    return check_feed(cycle_timing(params, knife), V_tr)
