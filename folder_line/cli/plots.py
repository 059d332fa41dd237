"""``folder-line simulate --plots DIR``: analyze's figures of the simulated line, streamed in bounded memory.

The figures are those ``analyze`` draws of a recorded run (:data:`folder_line.analysis.figures.FIGURES`,
with the papers' model curves of :mod:`folder_line.analysis.figures`), drawn from the line as it is
streamed window by window (:class:`folder_line.core.line.stream.LineStream`, :data:`PLOT_WINDOW` s
at a time, :data:`KEEP` s of it kept): what is kept for them does not grow with the line time.
What each keeps, and so what it shows:

``exit_speeds.png``, ``efficiency.png`` (joint states)
    a pseudo-random sample of the ticks of the run's 200 Hz grid
    (:data:`folder_line.config.run_config.RATE`): a tick is drawn if the splitmix64 hash of its
    stamp in ns (:func:`folder_line.analysis.streaming.stamp_priority`, as ``analyze`` thins a
    recording's) falls in the lowest ``1 / 2**L`` of its range, ``L`` the least that keeps about
    :data:`JOINT_SAMPLES` of the span's ticks (every tick of a short span). The hash has no
    pattern in time, so the sample does not alias with the machines' periods. The belt speed's
    extremes are over every tick. The leaves' exits: their counts exact, at most
    :data:`LEAF_SAMPLES` of each exit drawn (a pseudo-random sample by the hash of the leaf).
``cyclogram.png``
    the first :data:`folder_line.analysis.figure_data.GANTT_CYCLES` cycles judged at the knife,
    and the first violated one with its neighbours: their events are taken from the last
    windows while they are still held (:class:`_Cyclogram`).
``margins.png``
    exact counts of every constraint's margins in bins of a streamed histogram
    (:class:`StreamedHistogram`): a grid of power-of-two widths aligned on 0 (on -0.5 for whole
    sheets), whose width doubles, pairs of bins merged, whenever the margins seen would need
    more than :data:`MARGIN_BINS` bins; the smallest margin exact. A count axis on a log scale
    where a bin holds under 1 % of the tallest (it would not show), one bar about the value where
    the margins are equal to rounding (said on the figure).
``landing.png``
    exact counts in the container's bins (:func:`folder_line.core.effects.leaf_flight.histogram_of_counts`,
    the summary's), the spilled leaves counted (at most :data:`LEAF_SAMPLES` of them marked); the
    marks of single landings: at most :data:`LANDING_MARKS`, a pseudo-random sample by the hash
    of the leaf (more would be one black band).

The line is the one the summary printed with it describes: the scene under its ``--tune``
changes, from ``--from`` on if given; with ``--bag`` the line of that bag (under the commands its
supervisor issued). The drive is at speed where it turns at
:data:`folder_line.core.supervision.settings.SPEED_REACHED` of the speed it heads for (no
supervisor state is recorded here: ``analyze`` of a bag takes the supervisor's ``EXECUTE``).
The figures are drawn by :mod:`folder_line.cli.plot_drawing`.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from folder_line.analysis.figure_data import GANTT_CYCLES, CycleRow, SheetTimes
from folder_line.analysis.figures import FIGURES
from folder_line.analysis.streaming import stamp_priority
from folder_line.cli import summary as summary_cli
from folder_line.cli.plot_drawing import draw
from folder_line.config.run_config import RATE
from folder_line.core.line.constraints import FOLDER_CONSTRAINTS
from folder_line.core.line.line_summary import LineSummary, WindowSummary
from folder_line.core.line.scene import Scene
from folder_line.core.line.stream import LineStream, Window
from folder_line.core.line.tuning import LineCommand
from folder_line.core.mechanisms.cyclogram import cycle_timing
from folder_line.core.mechanisms.drive import target_rate
from folder_line.core.supervision.settings import CHECK_PERIOD, SPEED_REACHED
from folder_line.core.types.events import ConstraintSeries, JointSamples, event_kind
from folder_line.errors import OutputError
from folder_line.files.atomic import check_output_dir, claim_output_dir
from folder_line.interfaces import NS_PER_S

__all__ = [
    'JOINT_SAMPLES',
    'KEEP',
    'LEAF_SAMPLES',
    'MARGIN_BINS',
    'OPTION',
    'PLOT_WINDOW',
    'FigureData',
    'StreamedHistogram',
    'TickGrid',
    'check_plots',
    'collect',
    'write_figures',
]

#: the option naming the folder
OPTION = '--plots'
#: line time per window of the streamed run, s
PLOT_WINDOW = 60.0
#: line time before each window the stream keeps, s: a cycle judged late is drawn from the events and
#: the drive of the windows before
KEEP = 2.0 * PLOT_WINDOW
#: ticks of the 200 Hz grid drawn, about (the largest power-of-two fraction of the span's ticks at most this)
JOINT_SAMPLES = 5000
#: leaves drawn one by one at most, per exit (exit speeds) and spilled (landing)
LEAF_SAMPLES = 2000
#: landings marked one by one at most under the landing histogram (more would be one black band)
LANDING_MARKS = 400
#: most bins of a margin histogram (at least half as many once the margins spread: the width doubles)
MARGIN_BINS = 48
#: line time after a cycle's knife contact when its operations are taken from the windows held, s
SETTLE = 10.0
_STEP_NS = round(NS_PER_S / RATE)


def check_plots(path: str) -> None:
    """Refuse a ``--plots`` folder before any work: not a folder, or holding something other than the figures."""
    check_output_dir(path, OPTION, files=tuple(FIGURES))


# --------------------------------------------------------------------------- streamed collections


class StreamedHistogram:
    """Exact counts of a stream of margins in bins whose width doubles as their range grows.

    The bins are ``[origin + i w, origin + (i + 1) w)`` with ``w`` a power of two and ``origin`` 0
    (-0.5 for whole numbers: one bin per number while ``w`` is 1), so 0 is always an edge and no
    bin holds both a violation (< 0) and a pass. When the values seen would need more than
    ``max_bins`` bins, ``w`` doubles and pairs of bins merge: every count stays exact, for the bins
    of the final width. Memory: ``max_bins`` counts, whatever the number of values.

    Parameters
    ----------
    whole : bool
        The values are whole numbers (``sheets``).
    max_bins : int
        Most bins held (>= 2).

    Attributes
    ----------
    width : float
        Bin width, the values' unit (0 before any value).
    count, violated : int
        Values added; those < 0.
    low, high : float
        Smallest and largest value (``inf``, ``-inf`` before any).
    """

    def __init__(self, whole: bool = False, max_bins: int = MARGIN_BINS) -> None:
        self.origin = -0.5 if whole else 0.0
        self.max_bins = max(int(max_bins), 2)
        self.width = 1.0 if whole else 0.0
        self.first = 0  # the index of the first bin held
        self.passed = np.zeros(0, dtype=np.int64)
        self.failed = np.zeros(0, dtype=np.int64)
        self.count = self.violated = 0
        self.low, self.high = math.inf, -math.inf

    def _index(self, x: np.ndarray) -> np.ndarray:
        return np.floor((x - self.origin) / self.width).astype(np.int64)

    def add(self, values: np.ndarray) -> None:
        """Count ``values`` (finite floats, the margins' unit)."""
        x = np.asarray(values, dtype=float).reshape(-1)
        if x.size == 0:
            return
        lo, hi = float(x.min()), float(x.max())
        if self.width == 0.0:  # the least power of two that puts the first values' spread in the bins
            spread = hi - lo
            scale = spread / self.max_bins if spread > 0.0 else max(abs(lo), abs(hi)) * 2.0**-30
            self.width = 2.0 ** math.ceil(math.log2(scale)) if scale > 0.0 else 2.0**-40
        self.low, self.high = min(self.low, lo), max(self.high, hi)
        while True:
            i_lo, i_hi = self._index(np.array([self.low, self.high]))
            if i_hi - i_lo < self.max_bins:
                break
            self._double()
        i_lo, i_hi = int(i_lo), int(i_hi)
        if self.passed.size == 0:
            self.first = i_lo
        start = min(self.first, i_lo)
        size = max(self.first + self.passed.size, i_hi + 1) - start
        if start != self.first or size != self.passed.size:
            self.passed = _moved(self.passed, self.first - start, size)
            self.failed = _moved(self.failed, self.first - start, size)
            self.first = start
        i = self._index(x) - self.first
        bad = x < 0.0
        self.passed += np.bincount(i[~bad], minlength=size)
        self.failed += np.bincount(i[bad], minlength=size)
        self.count += int(x.size)
        self.violated += int(np.count_nonzero(bad))

    def _double(self) -> None:
        """Twice the width: bin ``i`` goes to ``floor(i / 2)``."""
        self.width *= 2.0
        if self.passed.size == 0:
            return
        old = np.arange(self.first, self.first + self.passed.size)
        new = old // 2
        first = int(new[0])
        size = int(new[-1]) - first + 1
        self.passed = np.bincount(new - first, weights=self.passed, minlength=size).astype(np.int64)
        self.failed = np.bincount(new - first, weights=self.failed, minlength=size).astype(np.int64)
        self.first = first

    @property
    def edges(self) -> np.ndarray:
        """The edges of the bins held, the values' unit."""
        return self.origin + self.width * np.arange(self.first, self.first + self.passed.size + 1)


def _moved(counts: np.ndarray, at: int, size: int) -> np.ndarray:
    out = np.zeros(size, dtype=np.int64)
    out[at : at + counts.size] = counts
    return out


class _Sample:
    """At most ``cap`` rows of a stream, a uniform pseudo-random choice: the rows with the smallest keys."""

    def __init__(self, cap: int) -> None:
        self.cap = cap
        self.keys = np.zeros(0, dtype=np.uint64)
        self.rows: dict[str, np.ndarray] = {}
        self.count = 0

    def add(self, keys: np.ndarray, **columns: np.ndarray) -> None:
        self.count += int(keys.size)
        if keys.size == 0:
            return
        self.keys = np.concatenate((self.keys, keys))
        for name, col in columns.items():
            self.rows[name] = np.concatenate((self.rows[name], col)) if name in self.rows else np.asarray(col)
        if self.keys.size > 2 * self.cap:
            self._cut()

    def _cut(self) -> None:
        keep = np.sort(np.argsort(self.keys, kind='stable')[: self.cap])
        self.keys = self.keys[keep]
        self.rows = {k: v[keep] for k, v in self.rows.items()}

    def done(self) -> dict[str, np.ndarray]:
        if self.keys.size > self.cap:
            self._cut()
        return self.rows

    def column(self, name: str) -> np.ndarray:
        return self.done().get(name, np.zeros(0))


@dataclass
class TickGrid:
    """The ticks of the 200 Hz grid in ``[start, end]`` drawn: those whose hash is in the lowest ``1 / 2**level``."""

    start: float
    end: float
    cap: int

    def __post_init__(self) -> None:
        self.k0 = -(-round(self.start * NS_PER_S) // _STEP_NS)
        self.k1 = round(self.end * NS_PER_S) // _STEP_NS
        self.total = max(self.k1 - self.k0 + 1, 0)
        self.level = max(0, math.ceil(math.log2(self.total / self.cap))) if self.total > self.cap else 0

    def between(self, t0: float, t1: float) -> tuple[np.ndarray, np.ndarray]:
        """All ticks of the window ``(t0, t1]`` (from ``start`` on), and those drawn: line times, s."""
        lo = self.k0 if not math.isfinite(t0) or t0 <= self.start else round(t0 * NS_PER_S) // _STEP_NS + 1
        hi = min(self.k1, round(t1 * NS_PER_S) // _STEP_NS)
        stamps = np.arange(max(lo, self.k0), hi + 1, dtype=np.int64) * _STEP_NS
        drawn = stamps if self.level == 0 else stamps[(stamp_priority(stamps) >> np.uint64(64 - self.level)) == 0]
        return stamps / NS_PER_S, drawn / NS_PER_S

    def text(self, drawn: int) -> str:
        """``'4001 ticks of the 200 Hz grid, all drawn'``, or how many are drawn and how."""
        grid = f'{self.total} ticks of the {RATE:g} Hz grid'
        if self.level == 0:
            return f'{grid}, all drawn' if drawn == self.total else f'{grid}, {drawn} drawn'
        return f'{grid}, {drawn} drawn (a pseudo-random 1/{2**self.level})'


def _column(js: JointSamples, name: str, quantity: str = 'position') -> np.ndarray:
    data = getattr(js, quantity)
    out: np.ndarray = data[:, js.names.index(name)]
    return out


class _Cyclogram:
    """The folder's first cycles and the first violated one, from the events of the windows still held.

    Per window the events of the cyclogram's kinds are held for :data:`KEEP` s; a cycle wanted
    (one of the first ``n`` judged at the knife whose feed began in the span, at ``start`` or later,
    or the first violated one after them with its neighbours) is taken from them :data:`SETTLE` s
    after its knife contact, while the stream still holds the drive there; its sheets' releases on
    the pile and its margins are taken as they come.
    """

    _KINDS = ('sheet_handover', 'at_stops', 'settled', 'knife_contact', 'knife_exit', 'released_on_pile')

    def __init__(self, scene: Scene, n: int, start: float) -> None:
        self.scene = scene
        self.n = n
        self.start = start
        self.timing = cycle_timing(scene.machine('cyclogram'), scene.machine('knife'))
        self.kinds = np.array([event_kind(k) for k in self._KINDS])
        self.k = {name: event_kind(name) for name in self._KINDS}
        self.held: list[tuple[float, np.ndarray]] = []  # (window end, its events of the kinds)
        self.first: list[int] = []  # the first n cycles judged at the knife
        self.contact: dict[int, float] = {}  # cycle -> its knife contact, for the cycles wanted
        self.rows: dict[int, CycleRow] = {}  # cycle -> its row, once taken (releases and margins added when done)
        self.release: dict[int, float] = {}  # sheet -> released on the pile, for the sheets of the rows
        self.margins: dict[int, dict[str, float]] = {}  # cycle -> constraint -> margin, for the cycles wanted
        self.held_rows: list[tuple[float, list[ConstraintSeries]]] = []
        self.bad: int | None = None  # the first violated cycle (of those judged at the knife in the span)
        self.cycles = 0  # knife contacts in the span

    @property
    def wanted(self) -> list[int]:
        out = list(self.first)
        if self.bad is not None and self.first and self.bad >= self.first[0]:
            out += [c for c in (self.bad - 1, self.bad, self.bad + 1) if c not in out]
        return sorted(out)

    def _held_events(self) -> np.ndarray:
        return np.concatenate([ev for _, ev in self.held]) if self.held else np.zeros(0)

    def window(self, stream: LineStream, w: Window) -> None:
        ev = w.events[np.isin(w.events['kind'], self.kinds)]
        self.held = [(t, e) for t, e in self.held if t > w.t1 - KEEP] + [(w.t1, ev)]
        folder_rows = [r for r in w.constraints if r.name in FOLDER_CONSTRAINTS and r.margin.size]
        self.held_rows = [(t, r) for t, r in self.held_rows if t > w.t1 - KEEP] + [(w.t1, folder_rows)]
        contacts = ev[ev['kind'] == self.k['knife_contact']]
        self.cycles += int(contacts.size)
        timing = self.timing
        for c in contacts['cycle'].tolist():
            if len(self.first) < self.n:  # a cycle whose feed began before the span is not the span's
                began = float(np.asarray(stream.drive.time_of(np.asarray([c * timing.T + timing.knife.t_out])))[0])
                if self.start <= 0.0 or began >= self.start:
                    self.first.append(int(c))
        self._rows_judged(folder_rows)
        wanted = self.wanted
        for row in contacts[np.isin(contacts['cycle'], wanted)]:
            self.contact.setdefault(int(row['cycle']), float(row['t']))
        rel = ev[ev['kind'] == self.k['released_on_pile']]
        for row in rel:
            if int(row['sheet']) in self.release and math.isnan(self.release[int(row['sheet'])]):
                self.release[int(row['sheet'])] = float(row['t'])
        for c in wanted:
            if c not in self.rows and c in self.contact and w.t1 >= self.contact[c] + SETTLE:
                self._take(stream, c)

    def _rows_judged(self, rows: list[ConstraintSeries]) -> None:
        """Note the margins of the cycles wanted and the first violated cycle (from the span's first cycle on)."""
        if not self.first:
            return
        bad = [int(r.cycle[i]) for r in rows for i in np.flatnonzero(r.margin < 0.0) if r.cycle[i] >= self.first[0]]
        if bad and (self.bad is None or min(bad) < self.bad):
            self.bad = min(bad)
            for c in self.wanted:  # a neighbour before it: from the held events and rows
                hit = self._held_events()
                hit = hit[(hit['kind'] == self.k['knife_contact']) & (hit['cycle'] == c)] if hit.size else hit
                if hit.size:
                    self.contact.setdefault(c, float(hit['t'][0]))
            for _, held in self.held_rows:
                self._margins_of(held)
            return
        self._margins_of(rows)

    def _margins_of(self, rows: list[ConstraintSeries]) -> None:
        wanted = set(self.wanted)
        for r in rows:
            for c, m in zip(r.cycle.tolist(), r.margin.tolist(), strict=True):
                if c in wanted:
                    self.margins.setdefault(c, {})[r.name] = m

    def finish(self, stream: LineStream, rows: list[ConstraintSeries]) -> None:
        folder_rows = [r for r in rows if r.name in FOLDER_CONSTRAINTS and r.margin.size]
        self._rows_judged(folder_rows)
        for c in self.wanted:
            if c not in self.rows and c in self.contact:
                self._take(stream, c)

    def _take(self, stream: LineStream, k: int) -> None:
        """Cycle ``k``'s row from the held events (its operations' times) and the drive (its start, deadline)."""
        ev = self._held_events()
        timing, drive = self.timing, stream.drive

        def first_time(kind: str, key: str, value: int) -> float | None:
            hit = ev[(ev['kind'] == self.k[kind]) & (ev[key] == value)]
            return float(hit['t'][0]) if hit.size else None

        tc = self.contact[k]
        th_start = k * timing.T + timing.knife.t_out
        t0 = float(np.round(np.asarray(drive.time_of(np.asarray([th_start])), dtype=float)[0] * NS_PER_S) / NS_PER_S)
        th_dead = float(np.asarray(drive.theta(np.asarray([tc])), dtype=float)[0]) - (
            timing.T - timing.t_knife - timing.t_allowed
        )
        bouncing = self.scene.has('stop_bounce')
        sheets = []
        hand = ev[(ev['kind'] == self.k['sheet_handover']) & (ev['cycle'] == k)]
        for s in hand:
            sid = int(s['sheet'])
            t_a = first_time('at_stops', 'sheet', sid)
            rel = first_time('released_on_pile', 'sheet', sid)
            self.release[sid] = math.nan if rel is None else rel
            settled = first_time('settled', 'sheet', sid) if bouncing else t_a
            sheets.append(SheetTimes(sid, float(s['t']), t_a, settled, None))
        exit_ = first_time('knife_exit', 'cycle', k)
        deadline = float(np.asarray(drive.time_of(np.asarray([th_dead])), dtype=float)[0])
        self.rows[k] = CycleRow(k, t0, tc, exit_, deadline, sheets, {})

    def done(self) -> list[CycleRow]:
        """The rows drawn, by cycle: with each sheet's release (None if not released in the span) and the margins."""
        out = []
        for c in self.wanted:
            if c not in self.rows:
                continue
            row = self.rows[c]
            sheets = [
                replace(s, release=None if math.isnan(self.release.get(s.sheet, math.nan)) else self.release[s.sheet])
                for s in row.sheets
            ]
            out.append(replace(row, sheets=sheets, margins=dict(self.margins.get(c, {}))))
        return out


class FigureData:
    """What the figures of a streamed run keep (bounded), as a :class:`folder_line.cli.summary.Observer`.

    Parameters
    ----------
    scene : Scene
    start, end : float
        The span drawn, line time from 0, s.
    """

    def __init__(self, scene: Scene, start: float, end: float) -> None:
        self.scene, self.start, self.end = scene, start, end
        self.ticks = TickGrid(start, end, JOINT_SAMPLES)
        self.layup = scene.has_layup
        self.belts = scene.has('chute_belts')
        self.delivery = scene.has_delivery
        self.flight = scene.has('leaf_flight') and 'container' in scene.machines
        self.joints: dict[str, list[np.ndarray]] = {}
        self.belt_low, self.belt_high = math.inf, -math.inf
        self.t_speed: float | None = None  # the first time on the check grid the drive is at speed (from start)
        # per exit, the leaves at speed and those off speed (start-up, holds) sampled apart: the few off speed all drawn
        self.exits = {(e, off): _Sample(LEAF_SAMPLES) for e in ('C', 'E') for off in (False, True)}
        self.exit_counts = {e: {'all': 0, 'early': 0, 'start_up': 0} for e in ('C', 'E')}
        self.margins: dict[str, StreamedHistogram] = {}
        self.units: dict[str, str] = {}
        self.cyclogram = _Cyclogram(scene, GANTT_CYCLES, start) if scene.has_folder else None
        cont = scene.machine('container') if self.flight else None
        self.container = cont
        self.landed = np.zeros(cont.bins if cont is not None else 0, dtype=np.int64)
        self.landed_x = _Sample(LANDING_MARKS)
        self.spilled_x = _Sample(LEAF_SAMPLES)

    # ------------------------------------------------------------------ the stream's windows

    def window(self, stream: LineStream, w: Window) -> None:
        if not self.margins:
            for name, tl in stream.tallies.constraints.items():
                self.margins[name] = StreamedHistogram(whole=tl.unit == 'sheets')
                self.units[name] = tl.unit
        for rows in w.constraints:
            self.margins[rows.name].add(rows.margin)
        self._speed(stream, w)
        every, drawn = self.ticks.between(w.t0, w.t1)
        if self.layup or self.delivery:
            self._joints(stream, every, drawn)
        ev = w.events
        if self.layup:
            self._exits(stream, ev[ev['kind'] == event_kind('leaf_exit')])
        if self.container is not None:
            cont = self.container
            x = ev['value'][ev['kind'] == event_kind('leaf_landed')]
            self.landed += np.histogram(x, bins=cont.bins, range=(cont.x_left, cont.x_right))[0]
            landed = ev[ev['kind'] == event_kind('leaf_landed')]
            self.landed_x.add(stamp_priority(landed['sheet']), x=landed['value'])
            spilled = ev[ev['kind'] == event_kind('leaf_spilled')]
            self.spilled_x.add(stamp_priority(spilled['sheet']), x=spilled['value'])
        if self.cyclogram is not None:
            self.cyclogram.window(stream, w)

    def finish(self, stream: LineStream, rows: list[ConstraintSeries]) -> None:
        for r in rows:
            self.margins[r.name].add(r.margin)
        if self.cyclogram is not None:
            self.cyclogram.finish(stream, rows)

    def off_speed(self, stream: LineStream, t: np.ndarray) -> np.ndarray:
        """Which line times ``t`` (in the last window) the drive turns below speed at: start-up, holds, stops."""
        drive = stream.drive
        out: np.ndarray = np.asarray(drive.rate(t), dtype=float) < SPEED_REACHED * target_rate(drive, t)
        return out

    def _speed(self, stream: LineStream, w: Window) -> None:
        if self.t_speed is not None:
            return
        lo = self.start if not math.isfinite(w.t0) or w.t0 <= self.start else w.t0
        k0 = math.ceil(lo / CHECK_PERIOD - 1e-9)
        grid = np.arange(k0, math.floor(w.t1 / CHECK_PERIOD + 1e-9) + 1) * CHECK_PERIOD
        grid = grid[(grid >= lo) & (grid <= w.t1)]
        if grid.size:
            fast = np.flatnonzero(~self.off_speed(stream, grid))
            if fast.size:
                self.t_speed = float(grid[fast[0]])

    def _joints(self, stream: LineStream, every: np.ndarray, t: np.ndarray) -> None:
        if self.belts and every.size:  # the belt's extremes over every tick
            v = _column(stream.sample('belts', every), 'chute_belts', 'velocity')
            self.belt_low, self.belt_high = min(self.belt_low, float(v.min())), max(self.belt_high, float(v.max()))
        if t.size == 0:
            return
        cols: dict[str, np.ndarray] = {'t': t, 'off': self.off_speed(stream, t)}
        if self.layup:
            crank = stream.sample('drive', t)
            cols['phi'] = np.mod(_column(crank, 'layup_crank'), 2.0 * math.pi)
            cols['w3'] = _column(crank, 'transporter3', 'velocity')
            cols['w5'] = _column(crank, 'transporter4', 'velocity')
            cols['v_belt'] = _column(stream.sample('belts', t), 'chute_belts', 'velocity') if self.belts else 0.0 * t
        if self.delivery:
            ft = stream.sample('feed', t)
            cols['x'] = _column(ft, 'carriage')
            cols['v'] = _column(ft, 'carriage', 'velocity')
            cols['v_chain'] = _column(ft, 'chain', 'velocity')
            if ft.effort is not None and self.scene.has('chain_friction'):
                cols['torque'] = _column(ft, 'chain', 'effort')
        for name, col in cols.items():
            self.joints.setdefault(name, []).append(np.asarray(col))

    def _exits(self, stream: LineStream, exits: np.ndarray) -> None:
        exits = exits[exits['t'] >= self.start]
        if exits.size == 0:
            return
        lp = self.scene.machine('layup')
        turns = (lp.n_kr / 60.0) * np.asarray(stream.drive.theta(exits['t']), dtype=float)
        deg = np.degrees(np.mod(2.0 * math.pi * turns, 2.0 * math.pi))
        early = self.off_speed(stream, exits['t'])
        start_up = exits['t'] < (math.inf if self.t_speed is None else self.t_speed)
        for at_e, name in ((False, 'C'), (True, 'E')):
            mine = (exits['sheet'] % 2 == 1) == at_e
            n = self.exit_counts[name]
            n['all'] += int(np.count_nonzero(mine))
            n['early'] += int(np.count_nonzero(mine & early))
            n['start_up'] += int(np.count_nonzero(mine & early & start_up))
            rows = exits[mine]
            for off in (False, True):
                pick = early[mine] == off
                self.exits[name, off].add(
                    stamp_priority(rows['sheet'][pick]), deg=deg[mine][pick], v=rows['value'][pick]
                )

    def joint(self, name: str) -> np.ndarray:
        """A column of the ticks drawn (``t``, ``off``, ``phi``, ``w3``, ...), in time order."""
        parts = self.joints.get(name, [])
        return np.concatenate(parts) if parts else np.zeros(0)


def collect(
    scene: Scene,
    duration: float,
    *,
    start: float | None = None,
    commands: Sequence[LineCommand] = (),
    progress: Callable[[float], None] | None = None,
) -> tuple[FigureData, LineSummary | WindowSummary]:
    """Stream the line over ``duration`` s (from ``start`` on: ``--from``) keeping the figures' data.

    Returns
    -------
    (FigureData, LineSummary or WindowSummary)
        The figures' data and the run's summary (:func:`folder_line.cli.summary.line_summary`'s:
        ``simulate(...).summary()`` bit for bit, or the window's with ``start``).
    """
    t0 = 0.0 if start is None else start
    data = FigureData(scene, t0, t0 + duration)
    result = summary_cli.line_summary(
        scene,
        duration,
        start=start,
        commands=commands,
        progress=progress,
        window=PLOT_WINDOW,
        keep=KEEP,
        observers=(data,),
    )
    return data, result


def write_figures(path: str, data: FigureData) -> dict[str, Path]:
    """Draw the figures of ``data`` into the folder ``path`` (claimed while drawing); print each file written.

    Returns
    -------
    dict of str to Path
        Figure name -> file written.

    Raises
    ------
    folder_line.errors.OutputError
        The folder cannot be claimed.
    """
    with claim_output_dir(path, OPTION, files=tuple(FIGURES)) as out:
        before = {p.name for p in out.iterdir()}
        try:
            figures = draw(data, out)
        except OSError as exc:  # a full disk part way: the figures this call added go, the option is named
            for name in FIGURES:
                if name not in before:
                    (out / name).unlink(missing_ok=True)
            raise (exc.with_option(OPTION) if isinstance(exc, OutputError) else exc) from None
    for written in figures.values():
        print(f'wrote {written}', file=sys.stdout)
    return figures
