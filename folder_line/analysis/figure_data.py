"""What the figures of a recorded run show, as arrays: the numbers drawn, with no plotting.

Each function takes a :class:`~folder_line.analysis.recording.Recording` (and its
:class:`~folder_line.analysis.replay.Evaluation`) and returns the recorded samples of one
figure of :mod:`folder_line.analysis.figures` set against the model: the layup's exit
speeds (:func:`exit_speed_data`) and its leaves' (:func:`leaf_exit_data`), the delivery's
efficiency along the stroke (:func:`efficiency_data`), the folder's first cycles operation by
operation (:func:`cycle_rows`) and the leaves' landing positions (:func:`landing_data`).

None of them holds more than a bounded part of a long run: the joint states are the
recording's bounded sample; what is taken from the recorded events is gathered in slices of
the event table (:func:`folder_line.analysis.streaming.event_chunks`), counted over every
event, and the points drawn one per event (the leaves' exits and landings) are kept to
:data:`LEAF_POINTS`, thinned by a hash of their times (:class:`folder_line.analysis.streaming.Thinned`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from folder_line.analysis.recording import Recording
from folder_line.analysis.replay import CYCLES_KEPT, Evaluation
from folder_line.analysis.streaming import CHUNK, Thinned, event_chunks
from folder_line.core.effects import leaf_flight
from folder_line.core.line.constraints import FOLDER_CONSTRAINTS
from folder_line.core.mechanisms import delivery
from folder_line.core.mechanisms.drive import target_rate
from folder_line.core.supervision.settings import CHECK_PERIOD, SPEED_REACHED
from folder_line.core.types.events import event_kind
from folder_line.files.json_types import JsonObject
from folder_line.interfaces import NODE_OF_UNIT, NS_PER_S

__all__ = [
    'GANTT_CYCLES',
    'LEAF_POINTS',
    'CycleRow',
    'ExitCount',
    'Landings',
    'LeafExits',
    'SheetTimes',
    'at_speed_time',
    'cycle_rows',
    'efficiency_data',
    'exit_speed_data',
    'landing_data',
    'leaf_exit_data',
    'off_speed',
]

#: cycles shown in the Gantt chart by default (the margins :func:`~folder_line.analysis.replay.evaluate` keeps)
GANTT_CYCLES = CYCLES_KEPT
#: leaves drawn at most in a figure that draws one point per leaf (every leaf is counted)
LEAF_POINTS = 5000

#: the supervisor's state of a line running at speed
_AT_SPEED_STATE = 'EXECUTE'


@dataclass(frozen=True)
class SheetTimes:
    """A signature's operations in a cycle of the cyclogram, s (None where not recorded).

    Attributes
    ----------
    sheet : int
    handover : float
        Handed over to the folder.
    at_stops, settled : float or None
        At the stops; settled there (``at_stops`` without ``stop_bounce``).
    release : float or None
        Released on the pile.
    """

    sheet: int
    handover: float
    at_stops: float | None
    settled: float | None
    release: float | None

    def as_json(self) -> JsonObject:
        """``{'sheet', 'handover', 'at_stops', 'settled', 'release'}``."""
        return {
            'sheet': self.sheet,
            'handover': self.handover,
            'at_stops': self.at_stops,
            'settled': self.settled,
            'release': self.release,
        }


@dataclass(frozen=True)
class CycleRow:
    """A folder cycle of the cyclogram: its operations' times and its margins.

    Attributes
    ----------
    cycle : int
    start : float
        The knife exit that opens the cycle's feed window, s.
    contact : float
        Its knife's contact, s.
    exit : float or None
        Its knife's exit, s (None if not recorded).
    deadline : float
        End of the allowed feed time, s.
    sheets : list of SheetTimes
        Its signatures.
    margins : dict of str to float
        Folder constraint -> margin of the cycle (SI units), in the line's order.
    """

    cycle: int
    start: float
    contact: float
    exit: float | None
    deadline: float
    sheets: list[SheetTimes]
    margins: dict[str, float]

    def as_json(self) -> JsonObject:
        """``{'cycle', 'start', 'contact', 'exit', 'deadline', 'sheets', 'margins'}``."""
        return {
            'cycle': self.cycle,
            'start': self.start,
            'contact': self.contact,
            'exit': self.exit,
            'deadline': self.deadline,
            'sheets': [s.as_json() for s in self.sheets],
            'margins': dict(self.margins),
        }


@dataclass(frozen=True)
class ExitCount:
    """The exits of a chute's leaves, counted.

    Attributes
    ----------
    count : int
        Every exit.
    off_speed : int
        Those where the line was not at speed (the start-up, holds and stops; :func:`off_speed`).
    start_up : int
        Of those, the ones before the drive first reached speed.
    """

    count: int = 0
    off_speed: int = 0
    start_up: int = 0


@dataclass(frozen=True, eq=False)
class LeafExits:
    """The leaves' exits from the chutes (:func:`leaf_exit_data`): every one counted, some drawn.

    Attributes
    ----------
    tally : dict of str to ExitCount
        ``'C'`` and ``'E'`` (the exits of odd and even leaves) -> their exits counted.
    t : ndarray
        The exits drawn, s.
    deg : ndarray
        Their crank angles, degrees in [0, 360).
    value : ndarray
        Their absolute exit speeds, m/s.
    at_e, off : ndarray of bool
        At E (an even leaf); off speed.
    fraction : float
        Of the exits drawn (1: every one).
    """

    tally: dict[str, ExitCount]
    t: np.ndarray
    deg: np.ndarray
    value: np.ndarray
    at_e: np.ndarray
    off: np.ndarray
    fraction: float


@dataclass(frozen=True, eq=False)
class Landings:
    """The leaves' landing positions (:func:`landing_data`): the histogram of every one, some drawn.

    Attributes
    ----------
    x : ndarray
        The landing positions drawn, m.
    spilled : ndarray
        The positions drawn of the leaves spilled over a wall, m.
    landed, spilled_count : int
        Every leaf landed, spilled.
    fraction : float
        Of the leaves drawn (1: every one).
    edges : ndarray
        The histogram's bin edges across the container, m.
    counts : ndarray
        Leaves landed per bin.
    cv : float or None
        std/mean of the counts (None if no leaf landed).
    x_left, x_right : float
        The container's walls, m.
    """

    x: np.ndarray
    spilled: np.ndarray
    landed: int
    spilled_count: int
    fraction: float
    edges: np.ndarray
    counts: np.ndarray
    cv: float | None
    x_left: float
    x_right: float


def at_speed_time(rec: Recording, ev: Evaluation) -> float:
    """Line time at which the drive first reached speed, s: the samples before it are the start-up.

    The time of the first ``EXECUTE`` recorded on ``/line/supervisor/state`` (the supervisor
    leaves STARTING when the drive's speed factor reaches ``speed_reached``); ``inf`` if
    states were recorded but never ``EXECUTE``. Without recorded states, the first point of
    the check grid (:data:`~folder_line.core.supervision.settings.CHECK_PERIOD`) where the
    model drive ``ev.drive`` turns at :data:`~folder_line.core.supervision.settings.SPEED_REACHED`
    of the speed it heads for (nominal, or the press speed set) or more (0 for a drive at speed from the start).

    Parameters
    ----------
    rec : Recording
    ev : Evaluation
        ``rec`` judged (its ``drive``: the scene's drive under the recorded commands).

    Returns
    -------
    float
        s, in [0, inf].
    """
    if rec.states:
        return next((t_ns / NS_PER_S for t_ns, state in rec.states if state == _AT_SPEED_STATE), math.inf)
    n = math.ceil((rec.t_end + CHECK_PERIOD) / CHECK_PERIOD)  # the points of np.arange(0, t_end + step, step)
    for i in range(0, n, CHUNK):  # a slice of the grid at a time: an hour is 720 000 points
        grid = np.arange(i, min(i + CHUNK, n), dtype=float) * CHECK_PERIOD
        fast = np.flatnonzero(
            np.asarray(ev.drive.rate(grid), dtype=float) >= SPEED_REACHED * target_rate(ev.drive, grid)
        )
        if fast.size:
            return float(grid[fast[0]])
    return math.inf


def off_speed(rec: Recording, ev: Evaluation, t: np.ndarray) -> np.ndarray:
    """Which line times ``t`` fall where the line was not running at speed: the start-up, and the
    ramps and standstills of holds, stops and suspends after it.

    With recorded states: the times before the first ``EXECUTE`` (:func:`at_speed_time`)
    and those in any later state but ``EXECUTE``. Without: where the model drive ``ev.drive``
    turns below :data:`~folder_line.core.supervision.settings.SPEED_REACHED` of its nominal speed.
    """
    t = np.asarray(t, dtype=float)
    if not rec.states:  # below the speed the drive heads for (the press speed set; nominal unless tuned)
        return np.asarray(ev.drive.rate(t), dtype=float) < SPEED_REACHED * target_rate(ev.drive, t)
    stamps = np.array([t_ns / NS_PER_S for t_ns, _ in rec.states])
    running = np.array([state == _AT_SPEED_STATE for _, state in rec.states])
    i = np.searchsorted(stamps, t, side='right') - 1  # the state shown at t
    return np.asarray((i < 0) | ~running[np.clip(i, 0, None)], dtype=bool)


def exit_speed_data(rec: Recording) -> dict[str, np.ndarray] | None:
    """The layup's exit speeds from the recorded crank_drive (and belt) joint states, or None.

    Returns
    -------
    dict or None
        ``t`` (s), ``phi`` (crank angle in [0, 2π), rad), ``vC = ω3 l3``, ``vE = ω5 l5``
        (m/s, signed), ``v_belt`` (recorded chute belt speed at the same stamps, m/s;
        0 without belts), ``vaC``, ``vaE`` (``sqrt(v² + v_belt²)``, m/s). None if the
        scene has no layup or nothing of it was recorded.
    """
    scene = rec.scene
    crank = rec.joints.get(NODE_OF_UNIT['drive'])
    if not scene.has_layup or crank is None or 'layup_crank' not in crank.names or crank.t.size == 0:
        return None
    lp = scene.machine('layup')
    t = crank.t
    phi = np.mod(crank.column('layup_crank'), 2.0 * math.pi)
    w3, w5 = crank.column('transporter3', 'velocity'), crank.column('transporter4', 'velocity')
    keep = np.ones(t.size, dtype=bool)
    v_belt = np.zeros(t.size)
    belts = rec.joints.get(NODE_OF_UNIT['belts'])
    if scene.has('chute_belts'):
        if belts is None or 'chute_belts' not in belts.names or belts.t.size == 0:
            keep[:] = False
        else:  # the belt's sample of the same tick
            i = np.minimum(np.searchsorted(belts.t, t), belts.t.size - 1)
            keep = belts.t[i] == t
            v_belt = np.where(keep, belts.column('chute_belts', 'velocity')[i], 0.0)
    vC, vE = w3 * lp.l3, w5 * lp.l5
    data = {
        't': t,
        'phi': phi,
        'vC': vC,
        'vE': vE,
        'v_belt': v_belt,
        'vaC': np.sqrt(vC * vC + v_belt * v_belt),
        'vaE': np.sqrt(vE * vE + v_belt * v_belt),
    }
    return {k: v[keep] for k, v in data.items()}


def efficiency_data(rec: Recording, ev: Evaluation) -> dict[str, np.ndarray] | None:
    """η, K_v and the sprocket torque at the recorded carriage positions, or None without a delivery.

    The stroke position ``u`` of each sample is the recorded carriage displacement
    ``x = u x_max + l (1 - cos α(u))`` inverted (x is increasing in u); samples with
    no carriage on the stroke (position and speed 0) are left out.

    Returns
    -------
    dict or None
        ``t`` (s), ``x`` (m), ``u``, ``eta`` (model at u), ``K_v_model``, ``K_v``
        (recorded carriage speed / chain speed; NaN-free: 0 where the chain stood),
        ``torque`` (recorded sprocket torque, N m; empty without efforts).
    """
    plan = ev.plan
    ft = rec.joints.get(NODE_OF_UNIT['feed'])
    if plan is None or ft is None or 'carriage' not in ft.names or ft.t.size == 0:
        return None
    x = ft.column('carriage')
    v = ft.column('carriage', 'velocity')
    v_chain = ft.column('chain', 'velocity')
    on = (x > 0.0) | (v > 0.0)
    u_grid = np.linspace(0.0, 2.0, 20001)
    st = delivery.evaluate_stroke(plan.params, u_grid, return_section='geometric')
    x_grid = u_grid * plan.chain.x_max + plan.rod * (1.0 - np.cos(st.alpha))
    u = np.interp(x[on], x_grid, u_grid)
    at = delivery.evaluate_stroke(plan.params, u, return_section='geometric')
    moving = v_chain[on] > 0.0
    kv = np.divide(v[on], v_chain[on], out=np.zeros(u.size), where=moving)
    torque = np.zeros(0)
    if ft.effort is not None and rec.scene.has('chain_friction'):
        torque = ft.column('chain', 'effort')[on]
    return {
        't': ft.t[on],
        'x': x[on],
        'u': u,
        'eta': at.eta,
        'K_v_model': at.K_v,
        'K_v': kv,
        'moving': moving,
        'torque': torque,
    }


_CYCLE_KINDS = np.array(
    [
        event_kind(k)
        for k in ('knife_contact', 'knife_exit', 'sheet_handover', 'at_stops', 'settled', 'released_on_pile')
    ],
    dtype=np.int16,
)


def _cycle_events(rec: Recording, cycles: np.ndarray) -> np.ndarray:
    """The recorded rows of ``cycles`` the cyclogram reads (knife, signatures), in table order: one scan of
    the table in slices."""
    parts = [
        part[np.isin(part['kind'], _CYCLE_KINDS) & np.isin(part['cycle'], cycles)]
        for part, _ in event_chunks(rec.events, rec.event_ns)
    ]
    return np.concatenate(parts) if parts else rec.events[:0]


def cycle_rows(rec: Recording, ev: Evaluation, n: int = GANTT_CYCLES) -> list[CycleRow]:
    """The first ``n`` judged folder cycles (and the first violated one with its neighbours): the
    operations' times and the margins.

    Parameters
    ----------
    rec : Recording
        The recording (its events from the start of the span shown).
    ev : Evaluation
        ``rec`` judged, keeping the margins of at least ``n`` cycles (``keep_cycles``).
    n : int
        Cycles shown from the first.

    Returns
    -------
    list of CycleRow
        Per cycle, ascending.

    Raises
    ------
    ValueError
        ``n`` is more than the cycles whose margins ``ev`` kept, and more were judged.
    """
    timing = ev.timing
    if timing is None:
        return []
    if n > ev.keep_cycles and len(ev.first_cycles) == ev.keep_cycles:
        raise ValueError(f'cycle_rows: the evaluation kept the margins of {ev.keep_cycles} cycles, not {n}')
    cycles = np.array(ev.first_cycles[:n], dtype=np.int64)
    if ev.first_violated is not None and ev.first_violated not in cycles:  # the first violated, between its neighbours
        cycles = np.union1d(cycles, np.array(ev.around_violated, dtype=np.int64))
    if cycles.size == 0:
        return []
    drive = ev.drive
    th_start = cycles * timing.T + timing.knife.t_out
    # to the ns, as the recorded event times (a cycle starts at the knife exit of the cycle before)
    t_start = np.round(np.asarray(drive.time_of(th_start), dtype=float) * NS_PER_S) / NS_PER_S
    rows = _cycle_events(rec, cycles)

    def of(kind: str) -> np.ndarray:
        out: np.ndarray = rows[rows['kind'] == event_kind(kind)]
        return out

    def first_time(table: np.ndarray, key: str, value: int) -> float | None:
        hit = table[table[key] == value]
        return float(hit['t'][0]) if hit.size else None

    contact, exits, hand = of('knife_contact'), of('knife_exit'), of('sheet_handover')
    stops, settled, release = of('at_stops'), of('settled'), of('released_on_pile')
    bouncing = rec.scene.has('stop_bounce')
    out: list[CycleRow] = []
    for k, t0 in zip(cycles.tolist(), t_start.tolist(), strict=True):
        tc = first_time(contact, 'cycle', k)
        if tc is None:  # a neighbour decided before the span shown
            continue
        th_dead = float(np.asarray(drive.theta(np.asarray(tc)))) - (timing.T - timing.t_knife - timing.t_allowed)
        sheets = []
        for s in hand[hand['cycle'] == k]:
            sid = int(s['sheet'])
            t_a = first_time(stops, 'sheet', sid)
            sheets.append(
                SheetTimes(
                    sid,
                    float(s['t']),
                    t_a,
                    first_time(settled, 'sheet', sid) if bouncing else t_a,
                    first_time(release, 'sheet', sid),
                )
            )
        margins = ev.cycle_margins.get(k, {})
        out.append(
            CycleRow(
                cycle=k,
                start=t0,
                contact=tc,
                exit=first_time(exits, 'cycle', k),
                deadline=float(np.asarray(drive.time_of(np.asarray(th_dead)))),
                sheets=sheets,
                margins={name: margins[name] for name in FOLDER_CONSTRAINTS if name in margins},
            )
        )
    return out


def leaf_exit_data(rec: Recording, ev: Evaluation, cap: int = LEAF_POINTS) -> LeafExits | None:
    """The leaves' exits from the chutes (``leaf_exit`` events), counted, and at most ``cap`` of them to draw.

    Parameters
    ----------
    rec : Recording
    ev : Evaluation
        ``rec`` judged (its drive: the crank angle at each exit; what is off speed: :func:`off_speed`).
    cap : int
        Exits kept to draw at most (a pseudo-random choice by a hash of their times beyond it).

    Returns
    -------
    LeafExits or None
        None if no leaf left a chute.
    """
    kind = event_kind('leaf_exit')
    if not rec.scene.has_layup:
        return None
    lp = rec.scene.machine('layup')
    t_speed = at_speed_time(rec, ev)
    dtype = np.dtype([('t', 'f8'), ('deg', 'f8'), ('value', 'f8'), ('at_e', '?'), ('off', '?')])
    kept = Thinned(cap, dtype)
    tally = {name: ExitCount() for name in ('C', 'E')}
    for part, ns in event_chunks(rec.events, rec.event_ns):
        mine = part['kind'] == kind
        exits = part[mine]
        if not exits.size:
            continue
        turns = (lp.n_kr / 60.0) * np.asarray(ev.drive.theta(exits['t']), dtype=float)
        rows = np.zeros(exits.size, dtype=dtype)
        rows['t'], rows['value'] = exits['t'], exits['value']
        rows['deg'] = np.degrees(np.mod(2.0 * math.pi * turns, 2.0 * math.pi))
        rows['at_e'] = exits['sheet'] % 2 == 1
        rows['off'] = off_speed(rec, ev, exits['t'])
        start_up = exits['t'] < t_speed
        for name, at_e in (('C', False), ('E', True)):
            m = rows['at_e'] == at_e
            was = tally[name]
            tally[name] = ExitCount(
                was.count + int(np.count_nonzero(m)),
                was.off_speed + int(np.count_nonzero(m & rows['off'])),
                was.start_up + int(np.count_nonzero(m & rows['off'] & start_up)),
            )
        kept.add(ns[mine], rows)
    if kept.seen == 0:
        return None
    r = kept.rows
    return LeafExits(tally, r['t'], r['deg'], r['value'], r['at_e'], r['off'], kept.fraction)


def landing_data(rec: Recording, cap: int = LEAF_POINTS) -> Landings | None:
    """The leaves' landing positions, or None without ``leaf_flight``.

    The histogram is the simulator's (:func:`folder_line.core.effects.leaf_flight.histogram`: the
    container's equal bins), added up over slices of the events (exact); the landing positions
    drawn one by one are at most ``cap`` (a pseudo-random choice by a hash of their times beyond it).

    Returns
    -------
    Landings or None
    """
    scene = rec.scene
    if not scene.has('leaf_flight') or 'container' not in scene.machines:
        return None
    cont = scene.machine('container')
    landed_kind, spilled_kind = event_kind('leaf_landed'), event_kind('leaf_spilled')
    counts = np.zeros(int(cont.bins), dtype=np.int64)
    landed = Thinned(cap, np.dtype(float))
    spilled = Thinned(cap, np.dtype(float))
    for part, ns in event_chunks(rec.events, rec.event_ns):
        m = part['kind'] == landed_kind
        x = part['value'][m]
        counts += leaf_flight.histogram(x, cont.x_left, cont.x_right, cont.bins).counts
        landed.add(ns[m], x)
        s = part['kind'] == spilled_kind
        spilled.add(ns[s], part['value'][s])
    hist = leaf_flight.histogram_of_counts(counts, cont.x_left, cont.x_right)
    return Landings(
        x=landed.rows,
        spilled=spilled.rows,
        landed=landed.seen,
        spilled_count=spilled.seen,
        fraction=min(landed.fraction, spilled.fraction),
        edges=np.asarray(hist.edges),
        counts=np.asarray(hist.counts),
        cv=hist.cv,
        x_left=float(cont.x_left),
        x_right=float(cont.x_right),
    )
