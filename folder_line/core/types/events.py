"""Exact line events and sampled joint states: the simulator's two outputs.

Events are rows of one structured array, sorted by time. Their times come from
closed forms or root-finding, never from the sampling grid.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any, Generic, TypeVar

import numpy as np
import numpy.typing as npt

__all__ = [
    'EVENT_DTYPE',
    'EVENT_KINDS',
    'ConstraintSeries',
    'JointSamples',
    'LinePart',
    'SubResult',
    'append_events',
    'empty_events',
    'event_kind',
    'kind_table',
    'kinds_in',
    'make_events',
    'merge_events',
    'stack_samples',
]

#: Every event kind; an event's ``kind`` field is the index in this tuple.
#: ``value`` holds, per kind: the speed (m/s) for ``at_stops`` and ``leaf_exit``,
#: the rebound distance (m) for ``bounce``, the landing x (m) for ``leaf_landed``
#: and ``leaf_spilled``, the exit speed (m/s) for ``leaf_damaged``, the delay (s)
#: for ``fault_late``, the speed factor for ``belt_slowdown_start``; 0 otherwise.
EVENT_KINDS: tuple[str, ...] = (
    'sheet_handover',  # F: signature taken over by the 2nd (feed) transporter
    'at_stops',  # F: signature reaches the front stops
    'bounce',  # F: rebound off the front stops (stop_bounce)
    'settled',  # F: signature at rest at the front stops
    'knife_contact',  # F: knife edge reaches the signature (knife window opens)
    'knife_exit',  # F: knife leaves the table (window closes)
    'released_on_pile',  # D: carriage releases the sheet onto the pile
    'leaf_enter',  # L: leaf enters a chute
    'leaf_exit',  # L: leaf leaves a chute exit
    'leaf_landed',  # L: leaf lands on the container floor (value: x)
    'leaf_spilled',  # L: leaf lands outside the container walls (value: x)
    'leaf_damaged',  # L: leaf left a chute at or above the damage speed
    'leaf_stick',  # L: leaf sticks on the guide (guide_friction)
    'leaf_slip',  # L: leaf starts sliding again (guide_friction)
    'fault_missing',  # faults: a sheet is missing from the stream
    'fault_double',  # faults: two sheets arrive together
    'fault_late',  # faults: a sheet is delayed (value: delay, s)
    'belt_slowdown_start',  # faults: a belt slows down (value: speed factor)
    'belt_slowdown_end',  # faults: the belt is back at speed
)

_KIND_INDEX = {name: i for i, name in enumerate(EVENT_KINDS)}

#: t: time, s; kind: index into EVENT_KINDS; sheet: sheet/leaf id (-1 if none);
#: cycle: machine cycle index (-1 if none); value: see EVENT_KINDS
EVENT_DTYPE = np.dtype([('t', 'f8'), ('kind', 'i2'), ('sheet', 'i8'), ('cycle', 'i8'), ('value', 'f8')])


def event_kind(name: str) -> int:
    """Index of an event kind by name (KeyError names the kinds if unknown)."""
    try:
        return _KIND_INDEX[name]
    except KeyError:
        msg = f'event kind {name!r} unknown; known: {", ".join(EVENT_KINDS)}'
        raise KeyError(msg) from None


def kind_table(names: Iterable[str]) -> np.ndarray:
    """A lookup table for :func:`kinds_in`: True at the index of each kind in ``names`` (one entry per
    16-bit value, so that any ``kind`` field indexes it)."""
    table = np.zeros(1 << 16, dtype=bool)
    table[[event_kind(n) for n in names]] = True
    return table


def kinds_in(kind: np.ndarray, table: np.ndarray) -> np.ndarray:
    """Which of the event kinds ``kind`` (ints) the ``table`` (:func:`kind_table`) holds; a value that
    is no kind's index is not held. The same as ``np.isin`` on the table's kinds, without its sort."""
    k = np.asarray(kind)
    if k.dtype == np.int16:  # EVENT_DTYPE's: a negative kind reads as 32768 and up, held by no table
        held: np.ndarray = table[k.view(np.uint16)]
        return held
    known = (k >= 0) & (k < table.size)
    return table[np.where(known, k, 0)] & known


def append_events(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The rows of ``a`` then those of ``b`` (both of EVENT_DTYPE): ``np.concatenate`` without its
    promotion of the structured type, which costs more than the copy for the few rows of a tick."""
    out = np.empty(a.size + b.size, dtype=EVENT_DTYPE)
    out[: a.size] = a
    out[a.size :] = b
    return out


def empty_events() -> np.ndarray:
    """An event table with no rows."""
    return np.zeros(0, dtype=EVENT_DTYPE)


def make_events(
    kind: str, t: npt.ArrayLike, *, sheet: npt.ArrayLike = -1, cycle: npt.ArrayLike = -1, value: npt.ArrayLike = 0.0
) -> np.ndarray:
    """Rows of one kind; scalars broadcast against ``t``.

    Parameters
    ----------
    kind : str
        One of :data:`EVENT_KINDS`.
    t : array_like
        Event times, s; must be finite.
    sheet, cycle : array_like of int
        Sheet (or leaf) ids and cycle indices.
    value : array_like of float
        Kind-specific value (see :data:`EVENT_KINDS`); must be finite.
    """
    t = np.asarray(t, dtype=float).ravel()
    out = np.zeros(t.size, dtype=EVENT_DTYPE)
    out['t'] = t
    out['kind'] = event_kind(kind)
    out['sheet'] = np.broadcast_to(np.asarray(sheet, dtype=np.int64).ravel() if np.ndim(sheet) else sheet, t.shape)
    out['cycle'] = np.broadcast_to(np.asarray(cycle, dtype=np.int64).ravel() if np.ndim(cycle) else cycle, t.shape)
    out['value'] = np.broadcast_to(np.asarray(value, dtype=float).ravel() if np.ndim(value) else value, t.shape)
    if not (np.all(np.isfinite(out['t'])) and np.all(np.isfinite(out['value']))):
        msg = f'{kind} events: times and values must be finite'
        raise ValueError(msg)
    return out


def merge_events(tables: Iterable[np.ndarray]) -> np.ndarray:
    """Concatenate event tables and sort by time, then kind, then sheet (stable, deterministic)."""
    tables = [tb for tb in tables if tb.size]
    if not tables:
        return empty_events()
    allev = np.concatenate(tables)
    order = np.lexsort((allev['sheet'], allev['kind'], allev['t']))
    return allev[order]


@dataclass(frozen=True, eq=False)
class JointSamples:
    """Joint states of one machine unit sampled on a time grid (a JointState stream).

    Attributes
    ----------
    unit : str
        Machine unit, one of :data:`folder_line.core.line.stream.UNITS`, e.g. ``'drive'``.
    names : tuple of str
        Joint names, J of them.
    t : ndarray, shape (N,)
        Sample times, s.
    position, velocity : ndarray, shape (N, J)
        Positions (rad or m) and velocities (rad/s or m/s) per joint.
    effort : ndarray, shape (N, J), or None
        Efforts (N·m or N) where the scene computes them.
    """

    unit: str
    names: tuple[str, ...]
    t: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    effort: np.ndarray | None = None


@dataclass(frozen=True, eq=False)
class ConstraintSeries:
    """One cyclogram constraint evaluated every cycle (or every sheet/leaf).

    Attributes
    ----------
    name : str
        Constraint name, e.g. ``'feed_window'``.
    unit : str
        Unit of the margin: ``'s'``, ``'m'``, ``'m/s'`` or ``'sheets'``.
    cycle : ndarray of int64
        Cycle (or leaf) index of each evaluation.
    margin : ndarray of float64
        Margin per evaluation; negative means violated. Always finite.
    description : str
        What is checked, in words.
    t : ndarray of float64
        Line time at which each evaluation is decided, s (a folder cycle's knife
        contact, a release, a leaf's exit): what a live supervisor knows by then.
    """

    name: str
    unit: str
    cycle: np.ndarray
    margin: np.ndarray
    description: str = ''
    t: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def __post_init__(self) -> None:
        if self.t.shape != self.margin.shape:
            msg = f'constraint {self.name}: t has shape {self.t.shape}, margin {self.margin.shape}'
            raise ValueError(msg)

    def decided_by(self, t: float) -> np.ndarray:
        """Mask of the evaluations decided at or before line time ``t``."""
        return self.t <= t

    @property
    def violated(self) -> np.ndarray:
        """Boolean mask of the violated evaluations."""
        return self.margin < 0.0


def stack_samples(
    unit: str,
    names: Sequence[str],
    t: np.ndarray,
    positions: Sequence[np.ndarray],
    velocities: Sequence[np.ndarray],
    efforts: Sequence[np.ndarray] | None = None,
) -> JointSamples:
    """Build :class:`JointSamples` from per-joint columns."""
    pos = np.column_stack(positions) if positions else np.zeros((t.size, 0))
    vel = np.column_stack(velocities) if velocities else np.zeros((t.size, 0))
    eff = np.column_stack(efforts) if efforts is not None else None
    return JointSamples(unit, tuple(names), t, pos, vel, eff)


#: the figures of a part of the line (its summary: the folder's, the layup's)
FiguresT = TypeVar('FiguresT')


@dataclass(frozen=True, eq=False)
class SubResult(Generic[FiguresT]):
    """What one part of the line (L, or F with D) hands back to :func:`folder_line.core.line.model.simulate`.

    Attributes
    ----------
    events : ndarray of EVENT_DTYPE
        Exact events, any order (merged and sorted by the caller).
    samples : dict of str to JointSamples
        Unit (``drive``, ``belts``, ``feed``) -> joint states on the common sample
        grid; joints of the same unit from several parts are concatenated by the caller.
    constraints : list of ConstraintSeries
        Constraints evaluated per cycle (or per leaf).
    summary : FiguresT
        The figures of this part (``as_json()``: its block of the summary).
    """

    events: np.ndarray
    samples: dict[str, JointSamples]
    constraints: list[ConstraintSeries]
    summary: FiguresT


class LinePart(Generic[FiguresT]):
    """Base of one part of the line (:class:`~folder_line.core.line.folder_sim.FolderLine`,
    :class:`~folder_line.core.line.layup_sim.LayupLine`): built once, sampled anywhere.

    A subclass sets ``drive``, ``events``, ``constraints``, ``summary`` and ``units``
    (unit -> joint names) and implements :meth:`sample_unit`.
    """

    drive: Any
    events: np.ndarray
    constraints: list[ConstraintSeries]
    summary: FiguresT
    units: dict[str, tuple[str, ...]]

    def result(self, t_samples: npt.ArrayLike) -> SubResult[FiguresT]:
        """Events, samples on ``t_samples`` (none if empty), constraints and summary."""
        t = np.asarray(t_samples, dtype=float)
        samples = self.sample(t) if t.size else {}
        return SubResult(events=self.events, samples=samples, constraints=self.constraints, summary=self.summary)

    def sample(
        self, t: npt.ArrayLike, theta: np.ndarray | None = None, lam: np.ndarray | None = None
    ) -> dict[str, JointSamples]:
        """Joint states of every unit of this part at times ``t``.

        Parameters
        ----------
        t : array_like, shape (N,)
            Line times, s, in [0, duration].
        theta, lam : ndarray, optional
            ``drive.theta(t)`` and ``drive.rate(t)`` if already at hand.
        """
        t = np.asarray(t, dtype=float).reshape(-1)
        theta, lam = self._drive_state(t, theta, lam)
        return {unit: self.sample_unit(unit, t, theta, lam) for unit in self.units}

    def sample_unit(
        self, unit: str, t: npt.ArrayLike, theta: np.ndarray | None = None, lam: np.ndarray | None = None
    ) -> JointSamples:
        """Joint states of one unit at ``t`` (subclass)."""
        raise NotImplementedError

    def _drive_state(
        self, t: np.ndarray, theta: np.ndarray | None, lam: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray]:
        if theta is None:
            theta = np.asarray(self.drive.theta(t), dtype=float)
        if lam is None:
            lam = np.asarray(self.drive.rate(t), dtype=float)
        return theta, lam
