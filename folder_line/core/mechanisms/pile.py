"""The sheet counter's joint: the delivery's pile table, or the floor of the layup container.

The counted sheets lie on a table that a lift lowers by one sheet thickness per sheet,
so that the top of the stack stays where the sheets arrive (the delivery height for
the pile, the floor height ``container.y_floor`` for the leaves). That table is the one
joint of unit ``counter``: prismatic, vertical, m, 0 at t = 0 and negative
downward.

* Scenes with the delivery D (``scene.has_delivery``): joint ``pile_table``, lowered per
  ``released_on_pile`` event (one folded signature released by the carriage).
* Other scenes: joint ``container_floor``, lowered per ``leaf_landed`` event (a leaf
  landed between the container walls; only ``leaf_flight`` lands leaves, so without it
  the floor stays at 0).

These are exactly the events the node counts (:func:`counted_event`). Model (ours; the
papers say nothing about the pile): after each counted sheet, at its event time t_i,
the lift lowers the table by the thickness h (``sheets.thickness``) at constant speed
over the settle time τ (:data:`T_LOWER`):

    z(t) = −h Σ_i r((t − t_i) / τ),      r(s) = min(max(s, 0), 1)            m
    ż(t) = −(h / τ) #{i : t_i ≤ t < t_i + τ}                                m/s

so z is continuous, non-increasing, and exactly ``−h n`` once the n-th sheet's lowering
has ended (t ≥ t_n + τ, before the next sheet). Sheets closer together than τ (a double
sheet, two leaves landing at once) overlap and add their speeds. ż is the right
derivative of z (the table moves from t_i on and is at rest again at t_i + τ), so a
forward difference of z over a step without a kink inside equals ż. Both depend on
the event times up to t only: a model built for a longer horizon gives the same
values. No effort is computed.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from folder_line.core.numerics.validate import check_fields, positive
from folder_line.core.types.events import EVENT_KINDS, JointSamples, stack_samples

__all__ = ['T_LOWER', 'UNIT', 'PileStream', 'PileTable', 'SteppedPile', 'counted_event', 'pile_table']

#: the unit that owns the table (:data:`folder_line.core.line.stream.UNITS`)
UNIT = 'counter'
#: settle time τ over which the lift lowers the table by one sheet thickness, s (ours: well
#: inside the folder's cycle of 0.072 s, so between two signatures the table rests)
T_LOWER = 0.02


def counted_event(has_delivery: bool) -> str:
    """Event kind the sheet counter counts: ``released_on_pile`` with the delivery, else ``leaf_landed``."""
    return 'released_on_pile' if has_delivery else 'leaf_landed'


@dataclass(frozen=True, eq=False)
class PileTable:
    """The table under the counted sheets (see the module docstring for the model).

    Parameters
    ----------
    joint : str
        Joint name, ``'pile_table'`` or ``'container_floor'``.
    times : array_like, shape (M,)
        Event times of the counted sheets, s, sorted ascending (one per sheet; equal
        times are several sheets).
    thickness : float
        Thickness h of one sheet on the stack, m (> 0).
    t_lower : float
        Settle time τ of one lowering, s (> 0).

    Attributes
    ----------
    units : dict of str to tuple of str
        ``{'counter': (joint,)}``, as the line's parts give theirs.
    """

    joint: str
    times: np.ndarray
    thickness: float
    t_lower: float = T_LOWER
    units: dict[str, tuple[str, ...]] = field(init=False)
    _ends: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        times = np.array(self.times, dtype=float).reshape(-1)
        if not np.all(np.isfinite(times)):
            raise ValueError(f'PileTable: times must be finite, got {times[~np.isfinite(times)][:3]!r}')
        if times.size > 1 and np.any(np.diff(times) < 0.0):
            raise ValueError('PileTable: times must be sorted ascending')
        times.setflags(write=False)
        object.__setattr__(self, 'times', times)
        check_fields(self, '', thickness=positive, t_lower=positive)
        ends = times + self.t_lower  # non-decreasing, as the times are
        ends.setflags(write=False)
        object.__setattr__(self, '_ends', ends)
        object.__setattr__(self, 'units', {UNIT: (self.joint,)})

    @property
    def speed(self) -> float:
        """Lowering speed of one sheet's lowering, h / τ, m/s."""
        return self.thickness / self.t_lower

    def state(self, t: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Table height z and velocity ż at line times ``t``.

        Parameters
        ----------
        t : array_like, shape (N,)
            Line times, s (finite).

        Returns
        -------
        z : ndarray, shape (N,)
            Height, m (<= 0): −h × (sheets lowered so far, fractions for those still
            lowering).
        zdot : ndarray, shape (N,)
            Velocity, m/s (<= 0): −(h/τ) × (sheets lowering at t).
        """
        tt = np.asarray(t, dtype=float).reshape(-1)
        if not np.all(np.isfinite(tt)):
            raise ValueError('PileTable.state: t must be finite')
        started = np.searchsorted(self.times, tt, side='right')  # t_i <= t
        done = np.searchsorted(self._ends, tt, side='right')  # t_i + τ <= t: fully lowered
        active = started - done  # lowering at t: indices done .. started - 1
        lowered = done.astype(float)
        for j in range(int(active.max()) if active.size else 0):
            on = active > j
            i = done[on] + j
            lowered[on] += np.clip((tt[on] - self.times[i]) / self.t_lower, 0.0, 1.0)
        return -self.thickness * lowered + 0.0, -self.speed * active.astype(float) + 0.0  # + 0: no -0.0

    def sample_unit(
        self, unit: str, t: npt.ArrayLike, theta: np.ndarray | None = None, lam: np.ndarray | None = None
    ) -> JointSamples:
        """Joint states of ``counter`` at ``t`` (``theta`` and ``lam`` unused: the lift is not
        geared to the master drive), as the line's parts give theirs."""
        return _counter_samples(self, unit, t)


@dataclass(frozen=True, eq=False)
class SteppedPile:
    """A table whose lowering time changed during the run (an operator's tuning of ``pile.t_lower``).

    Each sheet is lowered over the time in force at its event: the sheets of each span
    between two changes form a :class:`PileTable` of their own, and the table's height
    and speed are the sums over the spans (each span's lowering is linear in its sheets).

    Parameters
    ----------
    tables : tuple of PileTable
        One per span, in time order, all of the same joint and thickness.
    """

    tables: tuple[PileTable, ...]
    units: dict[str, tuple[str, ...]] = field(init=False)
    thickness: float = field(init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, 'units', dict(self.tables[0].units))
        object.__setattr__(self, 'thickness', self.tables[0].thickness)

    def state(self, t: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Table height z and velocity ż at line times ``t`` (:meth:`PileTable.state`)."""
        parts = [table.state(t) for table in self.tables]
        return sum((z for z, _ in parts[1:]), parts[0][0]), sum((v for _, v in parts[1:]), parts[0][1])

    def sample_unit(
        self, unit: str, t: npt.ArrayLike, theta: np.ndarray | None = None, lam: np.ndarray | None = None
    ) -> JointSamples:
        """Joint states of ``counter`` at ``t`` (:meth:`PileTable.sample_unit`)."""
        return _counter_samples(self, unit, t)


def _counter_samples(table: PileTable | SteppedPile, unit: str, t: npt.ArrayLike) -> JointSamples:
    """Joint states of ``counter`` at ``t``: the table's height and speed (:meth:`PileTable.state`)."""
    if unit != UNIT:
        raise KeyError(f'unit {unit!r} has no table joint; units: {UNIT}')
    tt = np.asarray(t, dtype=float).reshape(-1)
    z, zdot = table.state(tt)
    return stack_samples(UNIT, table.units[UNIT], tt, [z], [zdot])


def pile_table(
    has_delivery: bool,
    events: np.ndarray,
    thickness: float,
    t_lower: float = T_LOWER,
    steps: list[tuple[float, float]] | None = None,
) -> PileTable | SteppedPile:
    """The sheet counter's table for a line's sorted event table.

    Parameters
    ----------
    has_delivery : bool
        The scene has the delivery D: ``pile_table`` under ``released_on_pile``; else
        ``container_floor`` under ``leaf_landed``.
    events : ndarray of EVENT_DTYPE
        All events of the line, sorted by time.
    thickness : float
        Sheet thickness, m (``scene.sheets.thickness``).
    t_lower : float
        Settle time of one lowering, s.
    steps : list of (float, float), optional
        ``(t, τ)`` from ``t`` on, sorted, the first at 0 (an operator's tunings of
        ``pile.t_lower``, :func:`folder_line.core.line.tuning.values_from`): a
        :class:`SteppedPile` then, each sheet lowered over the τ in force at its event.
    """
    kind = EVENT_KINDS.index(counted_event(has_delivery))
    times = events['t'][events['kind'] == kind]
    joint = 'pile_table' if has_delivery else 'container_floor'
    if not steps or (len(steps) == 1 and steps[0][1] == t_lower):
        return PileTable(joint, times, thickness, t_lower if not steps else steps[0][1])
    starts = [t for t, _ in steps]
    cuts = np.searchsorted(times, starts[1:], side='left')  # a sheet at a change's time takes the new τ
    spans = np.split(times, cuts)
    return SteppedPile(
        tuple(PileTable(joint, span, thickness, tau) for span, (_, tau) in zip(spans, steps, strict=True))
    )


class PileStream:
    """The table of :class:`PileTable`, fed the counted sheets as the line runs, in bounded memory.

    Each sheet is lowered over the lowering time in force at its count (an operator may
    change it, :mod:`folder_line.core.line.tuning`). The sheets whose lowering has ended
    before the earliest time still asked for are only counted.

    Parameters
    ----------
    has_delivery : bool
        ``pile_table`` (delivery) or ``container_floor`` (layup).
    thickness : float
        Sheet thickness h, m (> 0).
    steps : list of (float, float)
        ``(t, τ)`` from ``t`` on, sorted, the first at 0
        (:func:`folder_line.core.line.tuning.values_from`).

    Attributes
    ----------
    units : dict of str to tuple of str
        ``{'counter': (joint,)}``.
    """

    def __init__(self, has_delivery: bool, thickness: float, steps: list[tuple[float, float]]) -> None:
        self.joint = 'pile_table' if has_delivery else 'container_floor'
        self.thickness = positive('sheets.thickness', thickness)
        self.units: dict[str, tuple[str, ...]] = {UNIT: (self.joint,)}
        self.steps = list(steps)
        self.counted = 0  # sheets counted, in all
        self.lowered = 0  # sheets whose lowering ended before the kept ones
        self._t = np.zeros(0)  # the kept sheets' count times, s (ascending)
        self._tau = np.zeros(0)  # and their lowering times, s

    def set_steps(self, steps: list[tuple[float, float]]) -> None:
        """New lowering times (an operator's tuning; those already in force unchanged)."""
        self.steps = list(steps)

    def add(self, times: npt.ArrayLike) -> None:
        """Sheets counted at ``times`` (s, ascending, after those added before)."""
        t = np.asarray(times, dtype=float).reshape(-1)
        if t.size == 0:
            return
        starts = np.array([s for s, _ in self.steps])
        taus = np.array([v for _, v in self.steps])
        tau = taus[np.clip(np.searchsorted(starts, t, side='right') - 1, 0, None)]
        self._t = np.concatenate((self._t, t))
        self._tau = np.concatenate((self._tau, tau))
        self.counted += t.size

    def prune(self, t_keep: float) -> None:
        """Forget the sheets whose lowering ended at or before ``t_keep`` (s): the state at later times is
        unchanged."""
        ended = self._t + self._tau <= t_keep
        n = int(np.argmin(ended)) if not ended.all() else ended.size  # a prefix, as the ends are nearly ordered
        if n:
            self.lowered += n
            self._t, self._tau = self._t[n:], self._tau[n:]

    @property
    def kept(self) -> int:
        """How many counted sheets' count times are kept (those whose table step may still be running)."""
        return int(self._t.size)

    def count(self, t: npt.ArrayLike) -> np.ndarray:
        """Sheets counted at or before line times ``t``."""
        tt = np.asarray(t, dtype=float)
        return (self.counted - self._t.size) + np.searchsorted(self._t, tt, side='right')

    def state(self, t: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Table height z and velocity ż at line times ``t`` (m, m/s; see :class:`PileTable`), for times
        not before the last :meth:`prune`. The sheets still lowering are added in the order counted, so the
        values do not depend on which sheets are kept."""
        tt = np.asarray(t, dtype=float).reshape(-1)
        if not np.all(np.isfinite(tt)):
            raise ValueError('PileStream.state: t must be finite')
        ti, tau = self._t, self._tau
        ends = ti + tau
        done = self.lowered + np.searchsorted(np.sort(ends), tt, side='right')
        lowered = done.astype(float)
        speed = np.zeros(tt.shape)
        if ti.size:
            started = np.searchsorted(ti, tt, side='right')
            lo = np.searchsorted(ti, tt - float(tau.max()), side='left')
            for j in range(int((started - lo).max()) if tt.size else 0):
                i = lo + j
                ic = np.minimum(i, ti.size - 1)
                on = (i < started) & (ends[ic] > tt)
                lowered = np.where(on, lowered + np.clip((tt - ti[ic]) / tau[ic], 0.0, 1.0), lowered)
                speed = np.where(on, speed + self.thickness / tau[ic], speed)
        return -self.thickness * lowered + 0.0, -speed + 0.0

    def sample_unit(
        self, unit: str, t: npt.ArrayLike, theta: np.ndarray | None = None, lam: np.ndarray | None = None
    ) -> JointSamples:
        """Joint states of ``counter`` at ``t`` (the lift is not geared to the master drive)."""
        if unit != UNIT:
            raise KeyError(f'unit {unit!r} has no table joint; units: {UNIT}')
        tt = np.asarray(t, dtype=float).reshape(-1)
        z, zdot = self.state(tt)
        return stack_samples(UNIT, self.units[UNIT], tt, [z], [zdot])
