"""The master drive: the map between line time t and master phase Θ.

Every shaft and belt of the line is geared to the master drive. The drive turns at
a speed factor λ(t) = dΘ/dt of its nominal speed (λ = 1 in steady running), so a
machine whose nominal shaft speed is ω turns through ω·Θ(t) rad by time t, and a
belt of nominal speed V has advanced V·Θ(t) m. Kinematic events therefore sit at
fixed Θ whatever the drive does, and :meth:`Drive.time_of` turns them into exact
times. Θ is in "nominal seconds".

Profiles: :class:`ConstantDrive` (λ = 1, Θ = t: costs nothing),
:class:`RampDrive` (linear spin-up), and the ``motor_dynamics`` effect's ODE drive
(:mod:`folder_line.core.effects.motor_dynamics`).

Supervisor commands
-------------------
A :class:`Command` carries an effective time ``t`` (s) and a kind: ``hold`` and
``stop`` take the master drive down to standstill from ``t``, ``unhold`` and ``start``
bring it back to nominal speed from ``t`` (hold/stop differ only in the supervisor's
state, not in the physics). A command that does not change whether the drive is
*running* (a second ``hold`` while held, ``stop`` after ``hold``) changes nothing.
:func:`commanded_drive` turns the scene's profile and the commands into a drive:

* no effective command: the profile's own drive (:func:`build_drive`), unchanged;
* else the profile's drive up to the first effective command's time ``t_1``, then a
  :class:`PiecewiseLinearDrive` built by a **ramp generator** from the state
  ``(Θ(t_1), λ(t_1))``: λ moves towards its target (1 running, 0 held) at the rate
  ``1/t_up`` upwards and ``1/t_brake`` downwards, and stays there; a command arriving
  mid-ramp continues from the current λ. ``t_up = t_ramp`` for the ``ramp`` profile;
  for ``constant`` it is ``max(t_ramp, t_brake)`` (:attr:`DriveSpec.t_restart`): an
  instantaneous restart would make λ jump, which no drive does.

The generator is causal: the knots before a command's time do not depend on it, and
each segment is evaluated from its own start knot, so adding a later command leaves
Θ, λ and every event before its time unchanged, bit for bit (the line's nodes may
learn of a command late, but before it is effective, and still agree on the past).
While held, λ = 0 and Θ stands still: every kinematic event keeps its master phase
and only moves in time. With ``motor_dynamics`` the motor is switched off (brake) and
on again instead (:func:`folder_line.core.effects.motor_dynamics.build_drive`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from folder_line.core.numerics.arrays import FloatArray
from folder_line.core.numerics.validate import among, check_fields, non_negative, positive
from folder_line.errors import ParameterError

__all__ = [
    'COMMAND_KINDS',
    'DRIVE_PROFILES',
    'Command',
    'ConstantDrive',
    'Drive',
    'DriveSpec',
    'PiecewiseLinearDrive',
    'RampDrive',
    'SplicedDrive',
    'build_drive',
    'check_commands',
    'commanded_drive',
    'ramp_generator',
    'running_switches',
    'target_rate',
    'theta_rate',
]


DRIVE_PROFILES = ('constant', 'ramp')
#: supervisor command kinds: the first two stop the drive, the last two run it
COMMAND_KINDS = ('hold', 'stop', 'unhold', 'start')
_RUNNING = {'hold': False, 'stop': False, 'unhold': True, 'start': True}


@runtime_checkable
class Drive(Protocol):
    """What the simulator needs from the master drive (all vectorised over arrays)."""

    def theta(self, t: npt.ArrayLike) -> np.ndarray:
        """Master phase Θ(t), nominal s, for t in [0, duration]."""
        ...

    def rate(self, t: npt.ArrayLike) -> np.ndarray:
        """Speed factor λ(t) = dΘ/dt, dimensionless (1 = nominal)."""
        ...

    def rate_dot(self, t: npt.ArrayLike) -> np.ndarray:
        """dλ/dt, 1/s."""
        ...

    def time_of(self, theta: npt.ArrayLike) -> np.ndarray:
        """Inverse of Θ(t): the earliest t with Θ(t) = theta, s. ``theta`` must lie in
        [Θ(0), Θ(duration)]; callers drop events beyond :meth:`theta` of the duration."""
        ...


@dataclass(frozen=True)
class DriveSpec:
    """The scene's ``drive`` section.

    Attributes
    ----------
    profile : {'constant', 'ramp'}
        ``constant``: nominal speed from t = 0. ``ramp``: λ rises linearly from 0 to 1
        over ``t_ramp`` s, then stays at 1. Ignored when the scene lists
        ``motor_dynamics`` (the motor's ODE sets λ).
    t_ramp : float
        Ramp time, s (>= 0; > 0 for ``ramp``; ignored for ``constant`` except as a lower
        bound of the restart ramp, :attr:`t_restart`).
    t_brake : float
        Time to ramp the drive down from full speed to standstill on a supervisor
        ``hold``/``stop``, s (> 0; default 0.5). Ignored with ``motor_dynamics``
        (its ``T_brake`` decides).
    """

    profile: str
    t_ramp: float = 0.0
    t_brake: float = 0.5

    def __post_init__(self) -> None:
        check_fields(self, 'drive', profile=among(DRIVE_PROFILES), t_ramp=non_negative, t_brake=positive)
        if self.profile == 'ramp' and self.t_ramp <= 0.0:
            raise ParameterError('drive.t_ramp', self.t_ramp, 'must be > 0 for profile ramp')

    @property
    def t_restart(self) -> float:
        """Time to ramp up from standstill to full speed after ``unhold``/``start``, s:
        ``t_ramp`` for the ``ramp`` profile, ``max(t_ramp, t_brake)`` for ``constant``
        (which has no ramp of its own; an instantaneous restart would make λ jump)."""
        return self.t_ramp if self.profile == 'ramp' else max(self.t_ramp, self.t_brake)


class ConstantDrive:
    """λ = 1: Θ = t."""

    def theta(self, t: npt.ArrayLike) -> np.ndarray:
        return np.array(t, dtype=float)

    def rate(self, t: npt.ArrayLike) -> np.ndarray:
        return np.ones_like(np.asarray(t, dtype=float))

    def rate_dot(self, t: npt.ArrayLike) -> np.ndarray:
        return np.zeros_like(np.asarray(t, dtype=float))

    def time_of(self, theta: npt.ArrayLike) -> np.ndarray:
        return np.array(theta, dtype=float)


class RampDrive:
    """λ = t / t_ramp for t < t_ramp, then 1: Θ = t²/(2 t_ramp), then t − t_ramp/2.

    Parameters
    ----------
    t_ramp : float
        Ramp time, s (> 0).
    """

    def __init__(self, t_ramp: float) -> None:
        self.t_ramp = float(t_ramp)

    def theta(self, t: npt.ArrayLike) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        tr = self.t_ramp
        return np.where(t < tr, t * t / (2.0 * tr), t - 0.5 * tr)

    def rate(self, t: npt.ArrayLike) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        return np.minimum(t / self.t_ramp, 1.0)

    def rate_dot(self, t: npt.ArrayLike) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        return np.where(t < self.t_ramp, 1.0 / self.t_ramp, 0.0)

    def time_of(self, theta: npt.ArrayLike) -> np.ndarray:
        th = np.asarray(theta, dtype=float)
        tr = self.t_ramp
        return np.where(th < 0.5 * tr, np.sqrt(2.0 * tr * np.maximum(th, 0.0)), th + 0.5 * tr)


def build_drive(spec: DriveSpec) -> ConstantDrive | RampDrive:
    """The drive of a scene without ``motor_dynamics``."""
    if spec.profile == 'ramp':
        return RampDrive(spec.t_ramp)
    return ConstantDrive()


def theta_rate(drive: Drive, t: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """``(drive.theta(t), drive.rate(t))``, in one pass where the drive offers ``theta_rate``."""
    f = getattr(drive, 'theta_rate', None)
    if f is not None:
        th, lam = f(t)
        return np.asarray(th, dtype=float), np.asarray(lam, dtype=float)
    return np.asarray(drive.theta(t), dtype=float), np.asarray(drive.rate(t), dtype=float)


# --------------------------------------------------------------------------- supervisor commands


@dataclass(frozen=True)
class Command:
    """A supervisor command to the master drive.

    Attributes
    ----------
    t : float
        Effective time, s (finite, >= 0): the drive starts to react at ``t``.
    kind : {'hold', 'stop', 'unhold', 'start'}
        ``hold``/``stop``: down to standstill; ``unhold``/``start``: back to nominal speed.
    """

    t: float
    kind: str

    def __post_init__(self) -> None:
        check_fields(self, 'command', t=non_negative, kind=among(COMMAND_KINDS))

    @property
    def running(self) -> bool:
        """Whether the drive runs after this command (``unhold``, ``start``)."""
        return _RUNNING[self.kind]


def check_commands(
    commands: Iterable[Any], kinds: tuple[type, ...] = (), what: str = 'a folder_line.core.mechanisms.drive.Command'
) -> tuple[Any, ...]:
    """Commands as a tuple, checked: each a :class:`Command` (or one of ``kinds``, described as ``what``),
    sorted by ``t`` (ties allowed).

    Raises
    ------
    ParameterError
        Something else, or a command earlier than the one before it.
    """
    out = tuple(commands)
    allowed = kinds or (Command,)
    for i, c in enumerate(out):
        if not isinstance(c, allowed):
            raise ParameterError(f'commands[{i}]', c, f'must be {what}')
        t: float = out[i].t
        if i and t < out[i - 1].t:
            raise ParameterError(
                f'commands[{i}].t',
                t,
                f'commands must be sorted by effective time; the one before is at {out[i - 1].t!r} s',
            )
    return out


def running_switches(commands: Iterable[Command], running: bool = True) -> list[tuple[float, bool]]:
    """The commands that change whether the drive runs: ``(t, running after t)`` in order.

    Parameters
    ----------
    commands : iterable of Command
        Sorted by time (:func:`check_commands`).
    running : bool
        The state before the first command (the line starts running).

    Returns
    -------
    list of (float, bool)
        Redundant commands (a ``hold`` while held, ``stop`` after ``hold``, ...) dropped.
    """
    out: list[tuple[float, bool]] = []
    for c in check_commands(commands):
        if c.running != running:
            running = c.running
            out.append((c.t, running))
    return out


# --------------------------------------------------------------------------- piecewise linear speed


class PiecewiseLinearDrive:
    """λ piecewise linear in t, Θ piecewise quadratic: exact evaluation and inverse.

    On segment i, ``t_i <= t < t_{i+1}`` (the last one unbounded), with ``τ = t − t_i``::

        λ(t) = λ_i + a_i τ ,    Θ(t) = Θ_i + τ (λ_i + a_i τ / 2) ,    dλ/dt = a_i

    Each segment is evaluated from its own start knot (so splitting a segment at a
    later time leaves the values before the split unchanged, bit for bit). The
    inverse on a segment is the root of ``a τ²/2 + λ_i τ − Δ = 0``, ``Δ = θ − Θ_i``,
    in the cancellation-free form ``τ = 2Δ / (λ_i + sqrt(λ_i² + 2 a_i Δ))``
    (``λ_i >= 0``, so the denominator adds two non-negative terms).

    Parameters
    ----------
    t, theta, lam, acc : array_like, shape (n,)
        Knots: start time (s, strictly increasing), Θ (nominal s, non-decreasing),
        λ (>= 0) and the segment's dλ/dt (1/s).
    target : array_like, shape (n,), optional
        The speed each segment heads for (:meth:`target_rate`; 1 running, 0 held if omitted). The caller keeps the knots
        consistent (Θ and λ at knot i+1 those of segment i at t_{i+1}); λ must stay
        >= 0 on every segment (it is clipped at 0 against rounding).

    Notes
    -----
    Times before ``t[0]`` are clipped to it. ``time_of`` of a phase the drive never
    reaches (beyond the last knot with λ = 0 and no acceleration) is ``inf``.
    """

    def __init__(
        self,
        t: npt.ArrayLike,
        theta: npt.ArrayLike,
        lam: npt.ArrayLike,
        acc: npt.ArrayLike,
        target: npt.ArrayLike | None = None,
    ) -> None:
        self.target = None if target is None else np.array(target, dtype=np.float64).ravel()
        self.t = np.array(t, dtype=np.float64).ravel()
        self.theta0 = np.array(theta, dtype=np.float64).ravel()
        self.lam0 = np.array(lam, dtype=np.float64).ravel()
        self.acc = np.array(acc, dtype=np.float64).ravel()
        n = self.t.size
        if n < 1 or not (self.theta0.size == self.lam0.size == self.acc.size == n):
            raise ValueError('PiecewiseLinearDrive: t, theta, lam and acc need the same length >= 1')
        if not (
            np.all(np.isfinite(self.t))
            and np.all(np.isfinite(self.theta0))
            and np.all(np.isfinite(self.lam0))
            and np.all(np.isfinite(self.acc))
        ):
            raise ValueError('PiecewiseLinearDrive: knots must be finite')
        if np.any(np.diff(self.t) <= 0.0) or np.any(np.diff(self.theta0) < 0.0) or np.any(self.lam0 < 0.0):
            raise ValueError('PiecewiseLinearDrive: t must increase, theta must not decrease, lam must be >= 0')
        self.length: FloatArray = np.append(np.diff(self.t), math.inf)  # segment durations (last: unbounded)

    def _segment(self, t: FloatArray) -> tuple[npt.NDArray[np.intp], FloatArray]:
        i = np.clip(np.searchsorted(self.t, t, side='right') - 1, 0, self.t.size - 1)
        return i, np.maximum(t - self.t[i], 0.0)

    def theta(self, t: npt.ArrayLike) -> np.ndarray:
        """Θ(t), nominal s."""
        i, tau = self._segment(np.asarray(t, dtype=np.float64))
        return self.theta0[i] + tau * (self.lam0[i] + 0.5 * self.acc[i] * tau)

    def rate(self, t: npt.ArrayLike) -> np.ndarray:
        """λ(t) (clipped at 0 against rounding at the end of a ramp down)."""
        i, tau = self._segment(np.asarray(t, dtype=np.float64))
        return np.maximum(self.lam0[i] + self.acc[i] * tau, 0.0)

    def rate_dot(self, t: npt.ArrayLike) -> np.ndarray:
        """dλ/dt, 1/s (right-continuous at the knots)."""
        i, _ = self._segment(np.asarray(t, dtype=np.float64))
        return self.acc[i].copy()

    def target_rate(self, t: npt.ArrayLike) -> np.ndarray:
        """The running speed λ heads for at ``t`` (the press speed setting; 1 unless given), 0 while held."""
        i, _ = self._segment(np.asarray(t, dtype=np.float64))
        if self.target is None:
            return np.ones(np.shape(i))
        return self.target[i].copy()

    def theta_rate(self, t: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """``(Θ(t), λ(t))`` in one pass (the same values as :meth:`theta` and :meth:`rate`)."""
        i, tau = self._segment(np.asarray(t, dtype=np.float64))
        lam, acc = self.lam0[i], self.acc[i]
        return self.theta0[i] + tau * (lam + 0.5 * acc * tau), np.maximum(lam + acc * tau, 0.0)

    def time_of(self, theta: npt.ArrayLike) -> np.ndarray:
        """Earliest t with Θ(t) = theta, s (``t[0]`` for theta <= Θ(t[0]); ``inf`` if never reached)."""
        th = np.asarray(theta, dtype=np.float64)
        if not np.all(np.isfinite(th)):
            raise ParameterError('theta', theta, 'must be finite')
        # the last knot with Θ_i < θ: a segment with Θ_i < θ <= Θ_{i+1}, never a plateau
        i = np.searchsorted(self.theta0, th, side='left') - 1
        low = i < 0
        i = np.clip(i, 0, self.t.size - 1)
        d = np.where(low, 0.0, th - self.theta0[i])
        lam, acc = self.lam0[i], self.acc[i]
        root = np.sqrt(np.maximum(lam * lam + 2.0 * acc * d, 0.0))
        den = lam + root
        ok = den > 0.0
        tau = np.where(ok, 2.0 * d / np.where(ok, den, 1.0), np.where(d > 0.0, math.inf, 0.0))
        return self.t[i] + np.minimum(tau, self.length[i])


class SplicedDrive:
    """One drive up to ``t_switch``, another from then on (Θ and λ continuous there).

    Parameters
    ----------
    head, tail : Drive
        ``head`` for t < t_switch, ``tail`` for t >= t_switch (its Θ(t_switch) must
        be the head's: :func:`commanded_drive` builds it so).
    t_switch : float
        Switch time, s.
    """

    def __init__(self, head: Drive, tail: Drive, t_switch: float) -> None:
        self.head = head
        self.tail = tail
        self.t_switch = float(t_switch)
        self.theta_switch = float(np.asarray(tail.theta(np.array(self.t_switch))))

    def _pick(
        self, f_head: Callable[[np.ndarray], np.ndarray], f_tail: Callable[[np.ndarray], np.ndarray], t: npt.ArrayLike
    ) -> np.ndarray:
        tt = np.asarray(t, dtype=float)
        ts = self.t_switch
        if tt.size == 1:  # one node tick: one side only
            return np.asarray((f_head if float(tt.reshape(-1)[0]) < ts else f_tail)(tt))
        return np.where(tt < ts, f_head(np.minimum(tt, ts)), f_tail(np.maximum(tt, ts)))

    def theta(self, t: npt.ArrayLike) -> np.ndarray:
        return self._pick(self.head.theta, self.tail.theta, t)

    def rate(self, t: npt.ArrayLike) -> np.ndarray:
        return self._pick(self.head.rate, self.tail.rate, t)

    def rate_dot(self, t: npt.ArrayLike) -> np.ndarray:
        return self._pick(self.head.rate_dot, self.tail.rate_dot, t)

    def target_rate(self, t: npt.ArrayLike) -> np.ndarray:
        return self._pick(lambda x: target_rate(self.head, x), lambda x: target_rate(self.tail, x), t)

    def theta_rate(self, t: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """``(Θ(t), λ(t))``, the same values as :meth:`theta` and :meth:`rate`."""
        tt = np.asarray(t, dtype=float)
        if tt.size == 1:
            return theta_rate(self.head if float(tt.reshape(-1)[0]) < self.t_switch else self.tail, tt)
        return self.theta(tt), self.rate(tt)

    def time_of(self, theta: npt.ArrayLike) -> np.ndarray:
        th = np.asarray(theta, dtype=float)
        if not np.all(np.isfinite(th)):
            raise ParameterError('theta', theta, 'must be finite')
        ths = self.theta_switch
        head = th <= ths
        return np.where(head, self.head.time_of(np.minimum(th, ths)), self.tail.time_of(np.maximum(th, ths)))


def ramp_generator(
    t0: float,
    theta0: float,
    lam0: float,
    running: bool,
    switches: Iterable[tuple[float, bool]],
    t_up: float,
    t_down: float,
    speeds: Iterable[tuple[float, float]] = (),
) -> PiecewiseLinearDrive:
    """Knots of λ moving towards its target at fixed rates, from a state at ``t0``.

    Parameters
    ----------
    t0, theta0, lam0 : float
        Start time (s), Θ there (nominal s) and λ there (>= 0).
    running : bool
        Target at ``t0``: the speed setting if running, else 0.
    switches : iterable of (float, bool)
        ``(t, running)`` target changes at times >= t0, in order
        (:func:`running_switches`).
    t_up, t_down : float
        Time for a full ramp up (0 -> 1) and down (1 -> 0), s (> 0): the rates are
        ``1/t_up`` and ``1/t_down``.
    speeds : iterable of (float, float)
        ``(t, s)``: from ``t`` on (>= t0, in order) the running speed is ``s`` times
        nominal (an operator's tuning of the press speed); 1 before the first.

    Returns
    -------
    PiecewiseLinearDrive
        Knots at ``t0``, at every switch, and where λ reaches its target, with each
        segment's target (:meth:`PiecewiseLinearDrive.target_rate`).
    """
    a_up, a_down = 1.0 / t_up, 1.0 / t_down
    changes = sorted(
        [(float(t), 0, bool(run), 0.0) for t, run in switches] + [(float(t), 1, True, float(v)) for t, v in speeds],
        key=lambda c: c[0],
    )  # stable: at equal times a run switch before a speed change, each in its own order
    speed = 1.0
    hi = max([1.0] + [c[3] for c in changes if c[1] == 1])
    lam0 = min(max(float(lam0), 0.0), hi)
    ramp = _Ramp(a_up, a_down, hi, float(t0), float(theta0), lam0, speed if running else 0.0)
    for t, what, run, value in changes:
        if t < ramp.ts[-1]:
            raise ParameterError('commands', t, f'a switch at {t!r} s is before the generator start {ramp.ts[-1]!r} s')
        ramp.reach_before(t)
        if what == 0:
            if run == running:
                continue
            running = run
        else:
            speed = value
        ramp.head_for(t, speed if running else 0.0)
    ramp.reach_before(math.inf)
    return PiecewiseLinearDrive(ramp.ts, ramp.ths, ramp.lams, ramp.accs, ramp.targets)


class _Ramp:
    """The knots of :func:`ramp_generator` so far: times ``ts`` (s), Θ ``ths`` (nominal s), λ ``lams``, and each
    segment's slope ``accs`` (1/s) and target ``targets``; λ ramps up at ``a_up`` and down at ``a_down`` (1/s)
    and stays in ``[0, hi]``."""

    def __init__(
        self, a_up: float, a_down: float, hi: float, t0: float, theta0: float, lam0: float, target: float
    ) -> None:
        self.a_up, self.a_down, self.hi = a_up, a_down, hi
        self.ts, self.ths, self.lams, self.accs = [t0], [theta0], [lam0], [0.0]
        self.targets = [target]
        self.accs[0] = self.acc_for(lam0, target)

    def acc_for(self, lam: float, target: float) -> float:
        """The slope of λ from ``lam`` towards ``target``, 1/s."""
        return self.a_up if lam < target else (-self.a_down if lam > target else 0.0)

    def knot(self, t: float, lam: float | None, acc_next: float, target: float) -> None:
        """Close the current segment at t (Θ, λ from its own formula, or λ given) and open the next."""
        ts, ths, lams, accs = self.ts, self.ths, self.lams, self.accs
        tau = t - ts[-1]
        theta = ths[-1] + tau * (lams[-1] + 0.5 * accs[-1] * tau)
        lam_t = min(max(lams[-1] + accs[-1] * tau, 0.0), self.hi) if lam is None else lam
        ts.append(t)
        ths.append(theta)
        lams.append(lam_t)
        accs.append(acc_next)
        self.targets.append(target)

    def reach_before(self, t_limit: float) -> None:
        """Add the knot where λ reaches its target, if that is before t_limit."""
        a = self.accs[-1]
        if a == 0.0:
            return
        target = self.targets[-1]
        t_r = self.ts[-1] + (target - self.lams[-1]) / a
        if t_r < t_limit and t_r > self.ts[-1]:
            self.knot(t_r, target, 0.0, target)

    def head_for(self, t: float, target: float) -> None:
        """From ``t`` (s, at or after the last knot) on, λ heads for ``target``."""
        if target == self.targets[-1]:
            return
        if t > self.ts[-1]:
            tau = t - self.ts[-1]
            lam_t = min(max(self.lams[-1] + self.accs[-1] * tau, 0.0), self.hi)
            self.knot(t, lam_t, self.acc_for(lam_t, target), target)
        else:  # a switch at the current knot: only the segment's slope (and target) change
            self.accs[-1] = self.acc_for(self.lams[-1], target)
            self.targets[-1] = target


def target_rate(drive: Drive, t: npt.ArrayLike) -> np.ndarray:
    """The running speed ``drive`` heads for at ``t`` (its ``target_rate``; 1 for a drive without settings)."""
    f = getattr(drive, 'target_rate', None)
    if f is None:
        return np.ones(np.shape(np.asarray(t, dtype=float)))
    return np.asarray(f(t), dtype=float)


def commanded_drive(
    spec: DriveSpec, commands: Iterable[Command] = (), speeds: Iterable[tuple[float, float]] = ()
) -> Drive:
    """The drive of a scene without ``motor_dynamics`` under supervisor commands and press speed settings.

    Parameters
    ----------
    spec : DriveSpec
        The scene's profile (``t_ramp``, ``t_brake``).
    commands : iterable of Command
        Sorted by ``t`` (ParameterError otherwise); duplicates are idempotent.
    speeds : iterable of (float, float)
        ``(t, s)``, sorted: the running speed is ``s`` times nominal from ``t`` on (an
        operator's tuning of the press speed, :mod:`folder_line.core.line.tuning`).

    Returns
    -------
    Drive
        :func:`build_drive` of the spec if no command or setting changes anything
        (identical to it); else a :class:`SplicedDrive`: the profile's drive up to
        the first effective command or setting, then the ramp generator
        (:func:`ramp_generator`, module docstring) from its state there.
    """
    base = build_drive(spec)
    switches = running_switches(commands)
    settings = [(float(t), float(v)) for t, v in speeds]
    while settings and settings[0][1] == 1.0:  # nominal until the first change: the profile's own drive
        settings.pop(0)
    if not switches and not settings:
        return base
    t1 = min(([switches[0][0]] if switches else []) + ([settings[0][0]] if settings else []))
    ta = np.array(t1)
    tail = ramp_generator(
        t1, float(base.theta(ta)), float(base.rate(ta)), True, switches, spec.t_restart, spec.t_brake, settings
    )
    return SplicedDrive(base, tail, t1)
