"""L, streamed: the leaf layup advanced window by window from a carried state.

:class:`LayupStream` computes the layup's exact events (a leaf enters its chute, leaves
the exit, lands or spills; damage, stick and slip, faults), joint states, the
``chute_speed`` constraint and the summary figures, for ever, in bounded memory. As
:class:`folder_line.core.line.folder_stream.FolderStream`, :meth:`LayupStream.compute`
``(c)`` does the work whose result lies at or before ``c`` and :meth:`LayupStream.emit`
``(t)`` hands out the events up to ``t``, sorted.

Stream: leaf slot j enters at ``t_j = phase + j interval + jitter interval U_j`` (one
draw per slot from the seed's stream ``layup.leaves``), chute ``j mod 2``, id j; with
``faults`` a missing slot does not enter, a double one enters twice, a late one
``late_delay`` later. Exit: with ``chute_belts`` after the belt has carried it the
chute's length (belt phase, :class:`folder_line.core.mechanisms.belt.BeltPhase`); with
``guide_friction`` (no belts) when the integrator of
:class:`folder_line.core.effects.guide_friction.GuideSlider` finds it; with neither at its
entry (the paper's picture). Flight (``leaf_flight``): a closed form in line time from the
exit, final once it left. The events' crank cycle is read off the drive at the event.

Carried between windows (:class:`LayupState`): the next slot, the random streams, the
slots not yet due, the leaves in the chutes (and the slider's state), the leaves in the
air, the belt, the events found and not handed out, and the running figures.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from folder_line.core.effects import chute_belts, faults, guide_friction, leaf_damage, leaf_flight
from folder_line.core.line.constraints import chute_speed_series
from folder_line.core.line.folder_stream import due_bound
from folder_line.core.line.layup_figures import (
    ExtremeSpeed,
    GuideFrictionFigures,
    Landing,
    LandingHistogram,
    LayupFigures,
    LeafStats,
    PhaseSpeeds,
    SwingSpeed,
)
from folder_line.core.line.layup_kinematics import EXTREME_WINDOW, PHASE_BINS, LayupKinematics
from folder_line.core.line.running import BinnedSum, RunningStats
from folder_line.core.line.tuning import Tuning, belt_steps
from folder_line.core.mechanisms.belt import BeltPhase, BeltStream
from folder_line.core.mechanisms.drive import Drive
from folder_line.core.mechanisms.layup import LayupParams
from folder_line.core.mechanisms.layup_angles import TAU
from folder_line.core.mechanisms.layup_reach import sweep, swing_extremes
from folder_line.core.numerics import rng as rng_mod
from folder_line.core.types.events import (
    ConstraintSeries,
    JointSamples,
    empty_events,
    event_kind,
    make_events,
    stack_samples,
)
from folder_line.errors import ParameterError

if TYPE_CHECKING:
    from folder_line.core.line.scene import Scene

__all__ = ['FLIGHT_DTYPE', 'LayupState', 'LayupStream']

#: leaves whose flight is kept after they landed (what a view of the last ones needs)
HISTORY = 256

#: a leaf in a chute: id, chute, entry time and belt phase at its exit (NaN until known)
_CHUTE_DTYPE = np.dtype([('id', 'i8'), ('chute', 'i8'), ('t_in', 'f8'), ('b_x', 'f8')])
#: a slot drawn whose entry has not come
_SLOT_DTYPE = np.dtype(
    [('j', 'i8'), ('t', 'f8'), ('missing', '?'), ('double', '?'), ('delay', 'f8'), ('fault_done', '?')]
)
#: a leaf in the air (or landed, kept as history): its exit state and its landing
FLIGHT_DTYPE = np.dtype(
    [
        ('id', 'i8'),
        ('t_exit', 'f8'),
        ('x0', 'f8'),
        ('y0', 'f8'),
        ('vx', 'f8'),
        ('vy', 'f8'),
        ('t_land', 'f8'),
        ('x_land', 'f8'),
        ('inside', '?'),
    ]
)
#: what the summary needs of an exit beyond its event: crank angle and speed along the chute
_EXIT_DTYPE = np.dtype([('t', 'f8'), ('id', 'i8'), ('phi', 'f8'), ('along', 'f8')])

_ENTER, _EXIT = event_kind('leaf_enter'), event_kind('leaf_exit')
_LANDED, _SPILLED = event_kind('leaf_landed'), event_kind('leaf_spilled')


@dataclass
class _Figures:
    """The running figures of the layup's summary (of the events handed out)."""

    entered: int = 0
    exited: int = 0
    landed: int = 0
    spilled: int = 0
    spilled_left: int = 0
    spilled_right: int = 0
    damaged: int = 0
    sticks: int = 0
    slips: int = 0
    speed: RunningStats = field(default_factory=RunningStats)
    along: RunningStats = field(default_factory=RunningStats)
    landing_x: RunningStats = field(default_factory=RunningStats)
    extremes: list[RunningStats] = field(default_factory=lambda: [RunningStats(), RunningStats()])
    by_phase: BinnedSum = field(default_factory=lambda: BinnedSum(PHASE_BINS))
    histogram: np.ndarray | None = None


@dataclass
class LayupState:
    """What the layup carries from one window to the next (module docstring); copied whole by a checkpoint."""

    rng_leaves: np.random.Generator
    rng_faults: np.random.Generator | None
    slowdowns: faults.SlowdownStream | None
    belt: BeltStream | None
    slider: guide_friction.GuideSlider | None
    computed: float = -math.inf
    emitted: float = -math.inf
    slot_next: int = 0
    slots: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=_SLOT_DTYPE))
    entering: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=[('id', 'i8'), ('t', 'f8')]))
    chutes: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=_CHUTE_DTYPE))
    flights: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=FLIGHT_DTYPE))
    history: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=FLIGHT_DTYPE))
    found: list[np.ndarray] = field(default_factory=list)  # events found, not handed out
    exits: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=_EXIT_DTYPE))
    figures: _Figures = field(default_factory=_Figures)


class LayupStream:
    """The layup part of the line, streamed (see the module docstring).

    Parameters
    ----------
    scene : Scene
        Validated scene with a ``layup`` machine (and ``container`` for ``leaf_flight``).
    drive : Drive
        The master drive (replaced with :meth:`set_drive` when the commands change).
    tunings : iterable of Tuning
        The operator's changes; here the chute belt speed ``layup.v_tr``.
    judge : bool
        Judge the leaves and keep the running summary (False: the events alone).

    Raises
    ------
    ParameterError
        ``layup.v_tr <= 0`` with belts; ``container.y_floor`` not below the exits with
        ``leaf_flight``; a guide-friction entry point beyond a chute, or a chute pointing
        upward, with ``guide_friction``.

    Attributes
    ----------
    kinematics : LayupKinematics
    units : dict of str to tuple of str
    state : LayupState
    """

    def __init__(self, scene: Scene, drive: Drive, tunings: Iterable[Tuning] = (), *, judge: bool = True) -> None:
        lp: LayupParams = scene.machine('layup')
        self.scene = scene
        self.judge = judge
        self.params = lp
        self.drive = drive
        self.kinematics = LayupKinematics(lp, drive)
        self.belts_on = scene.has('chute_belts')
        self.friction_on = scene.has('guide_friction') and not self.belts_on
        self.flight_on = scene.has('leaf_flight')
        self.damage_on = scene.has('leaf_damage')
        self.faults_on = scene.has('faults')
        sw = sweep(lp)
        seed = scene.seed
        self.v_tr = chute_belts.check_belt_speed(lp.v_tr) if self.belts_on else 0.0
        fp = scene.effect_params('faults') if self.faults_on else None
        self.fault_params = fp
        slow = None
        if fp is not None and self.belts_on:
            slow = faults.SlowdownStream(fp, 60.0 / lp.n_kr, rng_mod.stream(seed, 'layup.belt_slowdowns'))
        belt = BeltStream(drive, slow, belt_steps(tunings, 'layup.v_tr', self.v_tr)) if self.belts_on else None
        slider = None
        if self.friction_on:
            gp = scene.effect_params('guide_friction')
            guide_friction.check_geometry(gp, min(lp.l3, lp.l5), min(-sw.yC[1] / lp.l3, -sw.yE[1] / lp.l5))
            slider = guide_friction.GuideSlider(gp, self._kin_vec, self._kin_one)
        if self.flight_on:
            cont = scene.machine('container')
            lowest = min(sw.yC[0], sw.yE[0])
            if not cont.y_floor < lowest:
                raise ParameterError(
                    'container.y_floor', cont.y_floor, f'must be below the lowest chute exit (y = {lowest!r} m)'
                )
            self.container = cont
            self.flight_params: leaf_flight.Params = scene.effect_params('leaf_flight')
        self.lookahead = float(scene.effect_params('guide_friction').h) if self.friction_on else 0.0
        self.state = LayupState(
            rng_mod.stream(seed, 'layup.leaves'),
            rng_mod.stream(seed, 'layup.faults') if fp is not None else None,
            slow,
            belt,
            slider,
        )
        self._extremes = swing_extremes(lp)
        grid = self.kinematics.model.arrays(
            np.concatenate([np.arange(4096) * (TAU / 4096), [e.phi for e in self._extremes]]), accelerations=False
        )
        self._swing = np.abs(np.concatenate([grid.vC, grid.vE]))
        self.units: dict[str, tuple[str, ...]] = {'drive': ('layup_crank', 'transporter3', 'transporter4')}
        if self.belts_on:
            self.units['belts'] = ('chute_belts',)

    # ------------------------------------------------------------------ kinematics for the slider

    def _kin_vec(self, t: np.ndarray, ch: np.ndarray) -> guide_friction.ChuteState[npt.NDArray[np.float64]]:
        q = self.kinematics.chute(t, ch)
        return guide_friction.ChuteState(q['sin'], q['cos'], q['omega'], q['eps'])

    def _kin_one(self, t: float, ch: int) -> guide_friction.ChuteState[float]:
        return guide_friction.ChuteState(*self.kinematics.chute_scalar(t, ch))

    # ------------------------------------------------------------------ commands

    @property
    def belt(self) -> BeltPhase | None:
        """The chute belts' phase (:class:`folder_line.core.mechanisms.belt.BeltPhase`), or None without belts."""
        return None if self.state.belt is None else self.state.belt.phase

    @property
    def profile(self) -> chute_belts.BeltProfile | None:
        """The chute belts' speed and phase, or None without belts."""
        return None if self.state.belt is None else chute_belts.BeltProfile(self.v_tr, self.state.belt.phase)

    def set_drive(self, drive: Drive) -> None:
        """The drive under new commands (the same as the old one up to the time computed)."""
        self.drive = drive
        self.kinematics.drive = drive
        if self.state.belt is not None:
            self.state.belt.phase.drive = drive

    def set_tunings(self, tunings: Iterable[Tuning]) -> None:
        """The operator's tunings (those effective up to the time computed unchanged)."""
        if self.state.belt is not None:
            self.state.belt.set_steps(belt_steps(tunings, 'layup.v_tr', self.v_tr))

    def restore(self, state: LayupState) -> None:
        """Continue from ``state`` (a copy taken by a checkpoint), on the current drive."""
        self.state = state
        if state.belt is not None:
            state.belt.phase.drive = self.drive
        if state.slider is not None:
            state.slider.kin, state.slider.kin1 = self._kin_vec, self._kin_one

    # ------------------------------------------------------------------ work

    def _found(self, *tables: np.ndarray) -> None:
        st = self.state
        tables = tuple(tb for tb in tables if tb.size)
        if tables:
            st.found.extend(tables)

    def compute(self, c: float) -> None:
        """Do every piece of work whose result lies at or before line time ``c`` (s)."""
        st = self.state
        if c <= st.computed:
            return
        if st.slowdowns is not None:
            st.slowdowns.advance(c)
            for t, start in st.slowdowns.take_events():
                if start:
                    self._found(make_events('belt_slowdown_start', [t], value=st.slowdowns.params.slowdown_factor))
                else:
                    self._found(make_events('belt_slowdown_end', [t]))
        if st.belt is not None:
            st.belt.advance(c)
        self._draw(c)
        self._slots_due(c)
        self._enter(c)
        self._exit(c)
        self._land(c)
        st.computed = c

    def _draw(self, c: float) -> None:
        """Draw the slots that may enter by ``c`` (one uniform each, and with faults three)."""
        st = self.state
        sp = self.scene.sheets
        half = 0.5 * sp.jitter * sp.interval
        if sp.phase - half > c:
            return
        last = math.floor((c - sp.phase + half) / sp.interval)
        n = last + 1 - st.slot_next
        if n <= 0:
            return
        j = np.arange(st.slot_next, last + 1, dtype=np.int64)
        st.slot_next = last + 1
        u = st.rng_leaves.random(n) - 0.5
        t = sp.phase + j * sp.interval + sp.jitter * sp.interval * u
        slots = np.zeros(n, dtype=_SLOT_DTYPE)
        slots['j'], slots['t'] = j, t
        if st.rng_faults is not None:
            sf = faults.draw_sheet_faults(self.fault_params, n, st.rng_faults)  # type: ignore[arg-type]
            slots['missing'], slots['double'], slots['delay'] = sf.missing, sf.double, sf.delay
        keep = slots['t'] >= 0.0  # a slot before the line starts never enters
        st.slots = np.concatenate((st.slots, slots[keep]))

    def _slots_due(self, c: float) -> None:
        """Slots whose nominal time has come: their faults, and their leaves queued to enter."""
        st = self.state
        sl = st.slots
        due = sl['t'] <= c
        if not due.any():
            return
        now, st.slots = sl[due], sl[~due]
        t, j = now['t'], now['j']
        if self.faults_on:
            cyc = self.kinematics.cycle(t)
            late = now['delay'] > 0.0
            self._found(
                make_events('fault_missing', t[now['missing']], sheet=j[now['missing']], cycle=cyc[now['missing']]),
                make_events('fault_double', t[now['double']], sheet=j[now['double']], cycle=cyc[now['double']]),
                make_events('fault_late', t[late], sheet=j[late], cycle=cyc[late], value=now['delay'][late]),
            )
        present = ~now['missing']
        dbl = present & now['double']
        ids = np.concatenate([j[present], j[dbl]])
        t_in = np.concatenate([(t + now['delay'])[present], (t + now['delay'])[dbl]])
        new = np.zeros(ids.size, dtype=st.entering.dtype)
        new['id'], new['t'] = ids, t_in
        both = np.concatenate((st.entering, new))
        st.entering = both[np.lexsort((both['id'], both['t']))]

    def _enter(self, c: float) -> None:
        st = self.state
        ent = st.entering
        n = int(np.searchsorted(ent['t'], c, side='right'))
        if n == 0:
            return
        now, st.entering = ent[:n], ent[n:]
        ids, t_in = now['id'], now['t']
        chute = (ids % 2).astype(np.int64)
        self._found(make_events('leaf_enter', t_in, sheet=ids, cycle=self.kinematics.cycle(t_in)))
        lp = self.params
        length = np.where(chute == 1, lp.l5, lp.l3)
        if self.belts_on:
            assert st.belt is not None
            ph = st.belt.phase
            new = np.zeros(n, dtype=_CHUTE_DTYPE)
            new['id'], new['chute'], new['t_in'] = ids, chute, t_in
            with np.errstate(over='ignore'):  # a subnormal v_tr: the travel overflows to inf, the leaf never exits
                new['b_x'] = ph.at(t_in) + length / self.v_tr
            st.chutes = np.concatenate((st.chutes, new))
        elif st.slider is not None:
            st.slider.add(ids, t_in, chute, length)
        else:  # the paper's picture: dropped at the exit at its entry time, with the swing speed only
            self._exited(ids, chute, t_in, np.zeros(n))

    def _exit(self, c: float) -> None:
        st = self.state
        if self.belts_on and st.chutes.size:
            assert st.belt is not None
            ph = st.belt.phase
            ch = st.chutes
            b_c = float(ph.at(np.array([c]))[0])
            wait = np.flatnonzero(ch['b_x'] <= due_bound(b_c))
            if wait.size:
                t = np.asarray(self.drive.time_of(ph.theta_of(ch['b_x'][wait])), dtype=float)
                due = t <= c
                rows = wait[due]
                if rows.size:
                    t_x = t[due]
                    along = self.v_tr * np.asarray(self.drive.rate(t_x), dtype=float) * ph.factor(t_x)
                    self._exited(ch['id'][rows], ch['chute'][rows], t_x, along)
                    keep = np.ones(ch.size, dtype=bool)
                    keep[rows] = False
                    st.chutes = ch[keep]
        elif st.slider is not None:
            found = st.slider.advance(c)
            if found.exit_id.size:
                order = np.lexsort((found.exit_id, found.exit_t))
                ids = found.exit_id[order]
                self._exited(ids, (ids % 2).astype(np.int64), found.exit_t[order], found.exit_v[order])
            kin = self.kinematics
            if found.stick_t.size:
                self._found(
                    make_events('leaf_stick', found.stick_t, sheet=found.stick_id, cycle=kin.cycle(found.stick_t))
                )
            if found.slip_t.size:
                self._found(make_events('leaf_slip', found.slip_t, sheet=found.slip_id, cycle=kin.cycle(found.slip_t)))

    def _exited(self, ids: np.ndarray, chute: np.ndarray, t_x: np.ndarray, u: np.ndarray) -> None:
        """Leaves leaving their chute exits at ``t_x`` with speed ``u`` along the chute: their events and flights."""
        st, kin = self.state, self.kinematics
        q = kin.chute(t_x, chute)
        vp = q['v_perp']
        speed = chute_belts.absolute_speed(vp, u) if self.belts_on else np.sqrt(vp * vp + u * u)
        # t̂ = (sin, −cos), n̂ = (cos, sin)
        vx = u * q['sin'] + vp * q['cos']
        vy = -u * q['cos'] + vp * q['sin']
        cyc = kin.cycle(t_x)
        self._found(make_events('leaf_exit', t_x, sheet=ids, cycle=cyc, value=speed))
        ex = np.zeros(ids.size, dtype=_EXIT_DTYPE)
        ex['t'], ex['id'], ex['phi'], ex['along'] = t_x, ids, q['phi'], u
        st.exits = np.concatenate((st.exits, ex))
        if self.damage_on:
            bad = leaf_damage.damaged(self.scene.effect_params('leaf_damage'), speed)
            if bad.any():
                self._found(make_events('leaf_damaged', t_x[bad], sheet=ids[bad], cycle=cyc[bad], value=speed[bad]))
        if self.flight_on:
            cont = self.container
            t_f, x_land = leaf_flight.landing(self.flight_params, q['x'], q['y'], vx, vy, cont.y_floor)
            fl = np.zeros(ids.size, dtype=FLIGHT_DTYPE)
            fl['id'], fl['t_exit'], fl['x0'], fl['y0'], fl['vx'], fl['vy'] = ids, t_x, q['x'], q['y'], vx, vy
            fl['t_land'], fl['x_land'] = t_x + t_f, x_land
            fl['inside'] = (x_land >= cont.x_left) & (x_land <= cont.x_right)
            st.flights = np.concatenate((st.flights, fl))

    def _land(self, c: float) -> None:
        st = self.state
        fl = st.flights
        if fl.size == 0:
            return
        down = fl['t_land'] <= c
        if not down.any():
            return
        now = fl[down]
        cyc = self.kinematics.cycle(now['t_land'])
        i = now['inside']
        self._found(
            make_events('leaf_landed', now['t_land'][i], sheet=now['id'][i], cycle=cyc[i], value=now['x_land'][i]),
            make_events('leaf_spilled', now['t_land'][~i], sheet=now['id'][~i], cycle=cyc[~i], value=now['x_land'][~i]),
        )
        st.flights = fl[~down]
        st.history = np.concatenate((st.history, now))

    def prune(self, t_keep: float) -> None:
        """Forget what no query from ``t_keep`` (s) on needs: the leaves landed before it, but the last
        :data:`HISTORY`; the belt's intervals that ended before it."""
        st = self.state
        h = st.history
        if h.size > HISTORY:
            before = np.flatnonzero(h['t_land'] < t_keep)
            keep = np.ones(h.size, dtype=bool)
            keep[before[:-HISTORY]] = False  # the last HISTORY landed before t_keep stay
            st.history = h[keep]
        if st.belt is not None:
            st.belt.phase.prune(t_keep)

    # ------------------------------------------------------------------ hand out

    def emit(self, t: float) -> tuple[np.ndarray, list[ConstraintSeries]]:
        """The events found with times at or before ``t`` (s), sorted; and the ``chute_speed`` rows of their exits."""
        st = self.state
        if t > st.computed:
            raise ValueError(f'LayupStream.emit({t!r}): computed only to {st.computed!r} s')
        f = np.concatenate(st.found) if len(st.found) > 1 else (st.found[0] if st.found else empty_events())
        m = f['t'] <= t
        out, rest = f[m], f[~m]
        st.found = [rest] if rest.size else []
        if out.size:
            out = out[np.lexsort((out['sheet'], out['kind'], out['t']))]
        ex = st.exits
        em = ex['t'] <= t
        exits, st.exits = ex[em], ex[~em]
        if exits.size:
            exits = exits[np.lexsort((exits['id'], exits['t']))]
        st.emitted = max(st.emitted, t)
        if not self.judge:
            return out, []
        self._tally(out, exits)
        xr = out[out['kind'] == _EXIT]
        series = chute_speed_series(self.scene, xr['sheet'], xr['t'], xr['value'])
        return out, [] if series is None else [series]

    def _tally(self, out: np.ndarray, exits: np.ndarray) -> None:
        fg = self.state.figures
        kinds = out['kind']
        fg.entered += int(np.count_nonzero(kinds == _ENTER))
        fg.damaged += int(np.count_nonzero(kinds == event_kind('leaf_damaged')))
        fg.sticks += int(np.count_nonzero(kinds == event_kind('leaf_stick')))
        fg.slips += int(np.count_nonzero(kinds == event_kind('leaf_slip')))
        speed = out['value'][kinds == _EXIT]
        fg.exited += int(speed.size)
        if speed.size:
            fg.speed.add(speed)
            phi = exits['phi']
            fg.along.add(exits['along'])
            for e, acc in zip(self._extremes, fg.extremes, strict=True):
                d = np.abs(np.remainder(phi - e.phi + math.pi, TAU) - math.pi)
                acc.add(speed[d <= EXTREME_WINDOW])
            edges = np.linspace(0.0, TAU, PHASE_BINS + 1)
            b = np.clip(np.searchsorted(edges, phi, side='right') - 1, 0, PHASE_BINS - 1)
            fg.by_phase.add(b, speed)
        if self.flight_on:
            cont = self.container
            xl = out['value'][kinds == _LANDED]
            xs = out['value'][kinds == _SPILLED]
            fg.landed += int(xl.size)
            fg.spilled += int(xs.size)
            fg.spilled_left += int(np.count_nonzero(xs < cont.x_left))
            fg.spilled_right += int(np.count_nonzero(xs > cont.x_right))
            fg.landing_x.add(xl)
            h = leaf_flight.histogram(xl, cont.x_left, cont.x_right, cont.bins)
            fg.histogram = h.counts if fg.histogram is None else fg.histogram + h.counts

    # ------------------------------------------------------------------ figures

    def summary(self, theta_end: float) -> LayupFigures:
        """The layup's figures as of the events handed out (``theta_end``: Θ then, nominal s)."""
        fg = self.state.figures
        at_ext = {
            e.kind: ExtremeSpeed(e.phi, math.degrees(EXTREME_WINDOW), LeafStats.of(acc))
            for e, acc in zip(self._extremes, fg.extremes, strict=True)
        }
        edges = np.linspace(0.0, TAU, PHASE_BINS + 1)
        landing = None
        if self.flight_on:
            cont = self.container
            counts = np.zeros(cont.bins, dtype=np.int64) if fg.histogram is None else fg.histogram
            hist = LandingHistogram.of(leaf_flight.histogram_of_counts(counts, cont.x_left, cont.x_right))
            landing = Landing(hist, LeafStats.of(fg.landing_x), fg.spilled_left, fg.spilled_right)
        friction = None
        if self.friction_on:
            assert self.state.slider is not None
            friction = GuideFrictionFigures(int(self.state.slider.steps), fg.sticks, fg.slips, LeafStats.of(fg.along))
        return LayupFigures(
            crank_cycles=math.floor(theta_end * self.kinematics.turns_rate),
            leaves=fg.entered,
            leaves_exited=fg.exited,
            leaves_landed=fg.landed,
            leaves_spilled=fg.spilled,
            leaves_damaged=fg.damaged,
            min_exit_speed=fg.speed.low if fg.speed.count else None,
            max_exit_speed=fg.speed.high if fg.speed.count else None,
            mean_exit_speed=fg.speed.mean,
            exit_speed_at_extremes=at_ext,
            exit_speed_by_phase=PhaseSpeeds([float(math.degrees(x)) for x in edges], fg.by_phase.means()),
            swing_speed=SwingSpeed(float(self._swing.min()), float(self._swing.max())),
            landing=landing,
            guide_friction=friction,
        )

    # ------------------------------------------------------------------ joint states

    def sample_unit(self, unit: str, t: npt.ArrayLike, theta: np.ndarray, lam: np.ndarray) -> JointSamples:
        """Joint states of one unit (``drive``; ``belts`` with belts) at ``t``."""
        t = np.asarray(t, dtype=float).reshape(-1)
        kin = self.kinematics
        if unit == 'drive':
            phi = kin.wrap(theta * kin.turns_rate)
            st = kin.model.arrays(phi, accelerations=False)  # θ, ω do not depend on the accelerations
            return stack_samples(
                'drive',
                ['layup_crank', 'transporter3', 'transporter4'],
                t,
                [phi, st.theta3, st.theta5],
                [kin.omega * lam, st.omega3 * lam, st.omega5 * lam],
            )
        if unit == 'belts' and self.state.belt is not None:
            ph = self.state.belt.phase
            return stack_samples(
                'belts', ['chute_belts'], t, [self.v_tr * ph.at(t, theta)], [self.v_tr * lam * ph.factor(t)]
            )
        raise KeyError(f'unit {unit!r} has no layup joints; units: {", ".join(self.units)}')

    # ------------------------------------------------------------------ a view of the leaves

    def flights_view(self) -> np.ndarray:
        """The leaves in the air and the last :data:`HISTORY` that landed (FLIGHT_DTYPE, by exit time)."""
        st = self.state
        both = np.concatenate((st.history, st.flights))
        return both[np.argsort(both['t_exit'], kind='stable')]
