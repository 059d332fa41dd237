"""F with D, streamed: the folder and its delivery advanced window by window from a carried state.

:class:`FolderStream` computes the folder's exact events (the timeline of
:mod:`folder_line.core.line.folder_sim`: hand-over, arrival at the front stops, bounces, knife contact and
exit, release on the pile, faults), its joint states and its per-cycle constraints,
for ever, in memory that does not grow with line time. Two calls drive it:

* :meth:`FolderStream.compute` ``(c)`` does every piece of work whose result lies at or
  before line time ``c``: a signature is drawn when its slot's nominal hand-over phase is
  reached, its hand-over, arrival, release are found when their time is at or before
  ``c`` (each a closed form in the master phase mapped by ``drive.time_of``, or in line
  time), its bounces and settling (line time, final once it arrived) are scheduled at
  its arrival. Nothing computed depends on the drive after ``c``.
* :meth:`FolderStream.emit` ``(t)`` hands out the events found with times at or before
  ``t`` (``t <= c``), sorted, updates the running summary and judges every machine cycle
  whose signatures are all settled (:func:`folder_line.core.line.constraints.folder_evaluation`
  on that cycle's rows, in cycle order).

Carried between windows (:class:`~folder_line.core.line.folder_state.FolderState`): the next slot and
sheet id, the positions of the random streams, the signatures in the machine
(:data:`~folder_line.core.line.folder_state.SHEET_DTYPE`),
the slots whose nominal time has not come, the knife's next contact and exit, the belt
(slow-downs and speed steps), the events found and not yet handed out, the rows of the
cycles not yet judged and the running counts. Every event is computed by the same
elementwise operations whatever the windows, so a run cut into windows gives the
events, rows and summary of one window, bit for bit.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from folder_line.core.effects import (
    arrival_jitter,
    faults,
    feed_slip,
    length_scatter,
    property_scatter,
    stop_bounce,
)
from folder_line.core.line import folder_joints, folder_steps
from folder_line.core.line.constraints import FOLDER_CONSTRAINTS, folder_evaluation
from folder_line.core.line.delivery_plan import DeliveryPlan
from folder_line.core.line.folder_figures import FaultCounts, FolderFigures
from folder_line.core.line.folder_state import _SLOT_DTYPE, SHEET_DTYPE, FolderState
from folder_line.core.line.tuning import Tuning, belt_steps
from folder_line.core.mechanisms import knife as knf
from folder_line.core.mechanisms.belt import BeltPhase, BeltStream
from folder_line.core.mechanisms.drive import Drive
from folder_line.core.numerics.rng import stream
from folder_line.core.types.events import (
    ConstraintSeries,
    JointSamples,
    empty_events,
    event_kind,
    make_events,
)

if TYPE_CHECKING:
    from folder_line.core.line.scene import Scene

__all__ = ['FolderStream', 'due_bound']

#: smallest speed factor used to freeze the slip speeds at a hand-over (a drive at a standstill)
_LAMBDA_FLOOR = 1e-9
#: signatures kept after they left the machine (what a view of the last ones needs)
HISTORY = 32

_K = {k: event_kind(k) for k in ('knife_contact', 'sheet_handover', 'at_stops', 'settled', 'bounce')}
#: the kinds a cycle is judged on (the release is judged on its own row)
_JUDGED_KINDS = np.array(list(_K.values()), dtype=np.int16)
_RELEASE = event_kind('released_on_pile')


def due_bound(theta: float) -> float:
    """The largest phase whose time can be at or before that of ``theta`` (rounding of ``time_of``), nominal s."""
    return theta + max(1e-9, 1e-12 * abs(theta))


def _nan(n: int) -> np.ndarray:
    return np.full(n, math.nan)


class FolderStream:
    """The folder (and its delivery) streamed (see the module docstring).

    Parameters
    ----------
    scene : Scene
        Must have ``knife``, ``cyclogram`` and ``feed_transporter``; ``delivery`` and
        ``delivery_chain`` optional; effects ``feed_slip``, ``stop_bounce``, ``faults``,
        ``chain_friction``, ``arrival_jitter``, ``length_scatter``, ``property_scatter`` run
        only if listed.
    drive : Drive
        Master drive (replaced with :meth:`set_drive` when the commands change).
    tunings : iterable of Tuning
        The operator's changes; here the feed belt speed ``feed_transporter.V_tr``.
    judge : bool
        Judge the cycles and keep the running summary (False: the events alone, as a
        machine node that publishes them needs; no rows, and :meth:`summary` counts nothing).

    Attributes
    ----------
    timing : CycleTiming
    plan : DeliveryPlan or None
    V_tr : float
        The scene's feed belt speed, m/s.
    knife : KnifeParams
    units : dict of str to tuple of str
        Unit (``drive``, ``belts``, ``feed``) -> its joint names.
    state : FolderState
    """

    def __init__(self, scene: Scene, drive: Drive, tunings: Iterable[Tuning] = (), *, judge: bool = True) -> None:
        s = folder_steps.setup(scene, drive, math.inf)
        self.scene = scene
        self.judge = judge
        self.drive = drive
        self.setup = s
        self.timing = s.timing
        self.V_tr = s.V_tr
        self.plan: DeliveryPlan | None = s.plan
        self.knife: knf.KnifeParams = scene.machine('knife')
        self.with_torque = scene.has('chain_friction') and s.plan is not None
        self.torque_params = scene.effect_params('chain_friction') if self.with_torque else None
        self.units: dict[str, tuple[str, ...]] = {
            'drive': ('knife_crank', 'knife'),
            'belts': ('first_transporter',),
            'feed': ('feed_belt', 'chain', 'carriage') if s.plan is not None else ('feed_belt',),
        }
        seed = scene.seed
        slow = None
        rng_faults = None
        if s.faults is not None:
            rng_faults = stream(seed, 'folder.faults')
            slow = faults.SlowdownStream(s.faults, s.timing.T, stream(seed, 'folder.slowdowns'))
        jitter = stream(seed, arrival_jitter.STREAM) if s.jitter is not None else None
        length = stream(seed, length_scatter.STREAM) if s.length is not None else None
        sc = s.scatter
        e_rng = stream(seed, 'folder.property_scatter.e') if sc and s.bounce and sc.e_sigma != 0.0 else None
        mu_rng = stream(seed, 'folder.property_scatter.mu') if sc and s.slip and sc.mu_sigma != 0.0 else None
        belt = BeltStream(drive, slow, belt_steps(tunings, 'feed_transporter.V_tr', s.V_tr))
        self.state = FolderState(belt, slow, rng_faults, jitter, length, e_rng, mu_rng)
        # each constraint with nothing judged: the name, unit and description of its series
        self.empty_rows = {
            c.name: c for c in folder_evaluation(empty_events(), self.timing, scene, drive, plan=self.plan).constraints
        }

    # ------------------------------------------------------------------ commands

    @property
    def belt(self) -> BeltPhase:
        """The feed belt's phase (:class:`folder_line.core.mechanisms.belt.BeltPhase`)."""
        return self.state.belt.phase

    def set_drive(self, drive: Drive) -> None:
        """The drive under new commands (the same as the old one up to the time computed)."""
        self.drive = drive
        self.state.belt.phase.drive = drive

    def set_tunings(self, tunings: Iterable[Tuning]) -> None:
        """The operator's tunings (those effective up to the time computed unchanged)."""
        self.state.belt.set_steps(belt_steps(tunings, 'feed_transporter.V_tr', self.V_tr))

    def restore(self, state: FolderState) -> None:
        """Continue from ``state`` (a copy taken by a checkpoint), on the current drive."""
        self.state = state
        state.belt.phase.drive = self.drive

    # ------------------------------------------------------------------ work

    def _time_of(self, theta: np.ndarray) -> np.ndarray:
        if theta.size == 0:
            return np.zeros(0)
        return np.asarray(self.drive.time_of(theta), dtype=float)

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
        s = self.setup
        theta_c = float(np.asarray(self.drive.theta(np.array([c])), dtype=float)[0])
        bound = due_bound(theta_c)
        if st.slowdowns is not None:
            st.slowdowns.advance(c)
            for t, start in st.slowdowns.take_events():
                if start:
                    self._found(make_events('belt_slowdown_start', [t], value=s.faults.slowdown_factor))  # type: ignore[union-attr]
                else:
                    self._found(make_events('belt_slowdown_end', [t]))
        st.belt.advance(c)
        self._draw_slots(bound)
        self._slot_events(c)
        self._hand_over(c, bound)
        self._slip_ride(c)
        self._arrive(c, theta_c)
        self._knife(c, bound)
        self._release(c, bound)
        st.computed = c

    def _draw_slots(self, bound: float) -> None:
        """Draw the slots whose nominal hand-over phase is reached, and their signatures."""
        st, s = self.state, self.setup
        T, first = s.timing.T, s.timing.knife.t_out + s.phase
        if first > bound:
            return
        last = math.floor((bound - first) / T) + 1
        k = np.arange(st.slot_next, last + 1, dtype=np.int64)
        k = k[k * T + first <= bound]
        if k.size == 0:
            return
        st.slot_next = int(k[-1]) + 1
        theta_nom = k * T + first
        missing, double, delay = self._slot_faults(k.size)
        mult = np.where(missing, 0, np.where(double, 2, 1))
        # a slot before the line starts (a knife whose exit phase t_out + phase is negative) feeds nothing
        mult = np.where(theta_nom + delay < 0.0, 0, mult)
        n = int(mult.sum())
        ids = np.arange(st.sheet_next, st.sheet_next + n, dtype=np.int64)
        first_id = np.full(k.size, -1, dtype=np.int64)
        fed = mult > 0
        first_id[fed] = ids[(np.cumsum(mult) - mult)[fed]]
        st.sheet_next += n
        if self.judge:  # what a cycle waits for before it is judged
            self._cycles_to(int(k[-1]) + 1)
            st.expected[k - st.judged_next] = mult
        if s.faults is not None:
            slots = np.zeros(k.size, dtype=_SLOT_DTYPE)
            slots['k'], slots['theta'], slots['missing'], slots['double'] = k, theta_nom, missing, double
            slots['delay'], slots['first_id'] = delay, first_id
            st.slots = np.concatenate((st.slots, slots))
        if n == 0:
            return
        st.sheets = np.concatenate(
            (st.sheets, self._new_sheets(ids, np.repeat(k, mult), np.repeat(theta_nom + delay, mult)))
        )

    def _slot_faults(self, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The faults of ``n`` new slots: missing, double (bool) and the delay of a late one (s; 0 without faults)."""
        st, s = self.state, self.setup
        if st.rng_faults is None:
            return np.zeros(n, dtype=bool), np.zeros(n, dtype=bool), np.zeros(n)
        sf = faults.draw_sheet_faults(s.faults, n, st.rng_faults)  # type: ignore[arg-type]
        return sf.missing, sf.double, np.asarray(sf.delay, dtype=float)

    def _new_sheets(self, ids: np.ndarray, cycle: np.ndarray, theta_h: np.ndarray) -> np.ndarray:
        """The signatures ``ids`` of the slots ``cycle``, handed over at the phases ``theta_h`` (nominal s),
        with their draws: travel to the stops (m), friction and restitution (SHEET_DTYPE rows, times NaN)."""
        st, s = self.state, self.setup
        n = ids.size
        new = np.zeros(n, dtype=SHEET_DTYPE)
        for name in ('t_h', 'b_h', 't_m', 'rest', 'b_a', 't_a', 'v', 't_s', 'settle', 't_c', 't_x', 't_r', 'mu', 'e'):
            new[name] = _nan(n)
        new['id'] = ids
        new['cycle'] = cycle
        new['theta_h'] = theta_h
        new['fate'] = np.where(new['cycle'] < st.kc_next, 0, -1)  # its cycle's knife came first: jammed
        L = np.full(n, s.timing.L_feed)
        if s.jitter is not None and st.rng_jitter is not None:
            L = L + arrival_jitter.offsets_from(s.jitter, st.rng_jitter, n)
        if s.length is not None and st.rng_length is not None:
            L = L - length_scatter.excess_from(s.length, st.rng_length, n)
        new['L'] = L
        if s.scatter is not None and s.slip is not None and st.rng_mu is not None:
            new['mu'] = property_scatter.friction_from(s.scatter, s.slip.mu, st.rng_mu, n)
        if s.scatter is not None and s.bounce is not None and st.rng_e is not None:
            new['e'] = property_scatter.restitution_from(s.scatter, s.bounce.e, st.rng_e, n)
        return new

    def _slot_events(self, c: float) -> None:
        """The faults of the slots whose nominal time has come."""
        st = self.state
        if st.slots.size == 0:
            return
        t_nom = self._time_of(st.slots['theta'])
        due = t_nom <= c
        if not due.any():
            return
        n = int(np.argmin(due)) if not due.all() else due.size  # in slot order, so a prefix
        sl, t = st.slots[:n], t_nom[:n]
        st.slots = st.slots[n:]
        ok = t >= 0.0  # a slot before the line starts has no fault either
        for kind, mask in (
            ('fault_missing', sl['missing']),
            ('fault_double', sl['double']),
            ('fault_late', sl['delay'] > 0.0),
        ):
            m = mask & ok
            value = sl['delay'][m] if kind == 'fault_late' else 0.0
            self._found(make_events(kind, t[m], sheet=sl['first_id'][m], cycle=sl['k'][m], value=value))

    def _hand_over(self, c: float, bound: float) -> None:
        st, s = self.state, self.setup
        sh = st.sheets
        wait = np.flatnonzero(np.isnan(sh['t_h']) & (sh['theta_h'] <= bound))
        if wait.size == 0:
            return
        t = self._time_of(sh['theta_h'][wait])
        rows = wait[t <= c]
        if rows.size == 0:
            return
        t_h = t[t <= c]
        sh['t_h'][rows] = t_h
        self._found(make_events('sheet_handover', t_h, sheet=sh['id'][rows], cycle=sh['cycle'][rows]))
        belt = st.belt.phase
        L = sh['L'][rows]
        if s.slip is None:
            theta_h = sh['theta_h'][rows]
            b_h = theta_h if belt.plain else belt.at(t_h, theta_h)
            sh['b_h'][rows] = b_h
            sh['b_a'][rows] = b_h + L / s.V_tr
            return
        sh['b_h'][rows] = belt.at(t_h)  # where the belt is (what a view of the belt draws from)
        lam = np.maximum(np.asarray(self.drive.rate(t_h), dtype=float), _LAMBDA_FLOOR)
        f_h = belt.factor(t_h)
        mu = sh['mu'][rows]
        sa = feed_slip.arrival(s.slip, lam * s.timing.V_d, lam * f_h * s.V_tr, L, None if np.isnan(mu).all() else mu)
        slide = ~sa.reached
        # slides all the way to the stops: a closed form in line time, final at the hand-over
        sr = rows[slide]
        sh['t_a'][sr] = t_h[slide] + sa.t[slide]
        sh['v'][sr] = sa.v_impact[slide]
        self._arrived(sr)
        ride = rows[~slide]
        sh['t_m'][ride] = t_h[~slide] + sa.t_slip[~slide]
        sh['rest'][ride] = L[~slide] - sa.d_slip[~slide]

    def _slip_ride(self, c: float) -> None:
        """With feed_slip: the belt phase at the arrival of the signatures that reached the belt speed."""
        st, s = self.state, self.setup
        sh = st.sheets
        rows = np.flatnonzero(~np.isnan(sh['t_m']) & np.isnan(sh['b_a']) & (sh['t_m'] <= c))
        if rows.size:
            sh['b_a'][rows] = st.belt.phase.at(sh['t_m'][rows]) + sh['rest'][rows] / s.V_tr

    def _arrive(self, c: float, theta_c: float) -> None:
        st, s = self.state, self.setup
        sh = st.sheets
        belt = st.belt.phase
        b_c = float(belt.at(np.array([c]), np.array([theta_c]))[0])
        wait = np.flatnonzero(np.isnan(sh['t_a']) & (sh['b_a'] <= due_bound(b_c)))
        if wait.size == 0:
            return
        t = self._time_of(belt.theta_of(sh['b_a'][wait]))
        rows = wait[t <= c]
        if rows.size == 0:
            return
        t_a = t[t <= c]
        sh['t_a'][rows] = t_a
        sh['v'][rows] = s.V_tr * np.asarray(self.drive.rate(t_a), dtype=float) * belt.factor(t_a)
        self._arrived(rows)

    def _arrived(self, rows: np.ndarray) -> None:
        """At the stops: the event, and the bounces and the settling (line time, final now)."""
        if rows.size == 0:
            return
        st, s = self.state, self.setup
        sh = st.sheets
        ids, cyc, t_a, v = sh['id'][rows], sh['cycle'][rows], sh['t_a'][rows], sh['v'][rows]
        self._found(make_events('at_stops', t_a, sheet=ids, cycle=cyc, value=v))
        if s.bounce is None:
            sh['t_s'][rows] = t_a
            sh['settle'][rows] = 0.0
            return
        e = sh['e'][rows]
        sched = stop_bounce.bounce_schedule(s.bounce, v, e=None if np.isnan(e).all() else e)
        sh['t_s'][rows] = t_a + sched.settle
        sh['settle'][rows] = sched.settle
        sh['bounces'][rows] = sched.count
        self._found(
            make_events(
                'bounce',
                t_a[sched.index] + sched.dt,
                sheet=ids[sched.index],
                cycle=cyc[sched.index],
                value=sched.rebound,
            ),
            make_events('settled', t_a + sched.settle, sheet=ids, cycle=cyc),
        )

    def _knife(self, c: float, bound: float) -> None:
        """Knife contacts (the fates of their cycles' signatures) and exits, and cycle 0's start."""
        st, s = self.state, self.setup
        T, t_in, t_out = s.timing.T, s.timing.knife.t_in, s.timing.knife.t_out
        if not st.start0_found and t_out <= bound:
            t0 = float(self._time_of(np.array([t_out]))[0])
            if t0 <= c:
                st.start0_found, st.start0_t = True, t0
        k_c, t_c = self._cursor(st.kc_next, T + t_in, T, bound, c)
        if k_c.size:
            st.kc_next = int(k_c[-1]) + 1
            self._found(make_events('knife_contact', t_c, cycle=k_c))
            sh = st.sheets
            pos = np.searchsorted(k_c, sh['cycle'])
            hit = (pos < k_c.size) & (k_c[np.minimum(pos, k_c.size - 1)] == sh['cycle'])
            rows = np.flatnonzero(hit & (sh['fate'] < 0))
            tc = t_c[pos[rows]]
            sh['t_c'][np.flatnonzero(hit)] = t_c[pos[hit]]
            folded = ~np.isnan(sh['t_a'][rows]) & (sh['t_a'][rows] <= tc)
            sh['fate'][rows] = folded.astype(np.int8)
        k_x, t_x = self._cursor(st.kx_next, T + t_out, T, bound, c)
        if k_x.size:
            st.kx_next = int(k_x[-1]) + 1
            self._found(make_events('knife_exit', t_x, cycle=k_x))
            if self.judge:  # where the cycles still to be judged start
                if st.exit_t.size == 0:
                    st.exit_base = int(k_x[0])
                st.exit_t = np.concatenate((st.exit_t, t_x))
            sh = st.sheets
            pos = np.searchsorted(k_x, sh['cycle'])
            hit = (pos < k_x.size) & (k_x[np.minimum(pos, k_x.size - 1)] == sh['cycle'])
            sh['t_x'][hit] = t_x[pos[hit]]

    def _cursor(self, k0: int, first: float, step: float, bound: float, c: float) -> tuple[np.ndarray, np.ndarray]:
        """Indices k >= k0 with ``k step + first`` due by ``c``, and their times (a prefix: times increase)."""
        if k0 * step + first > bound:
            return np.zeros(0, dtype=np.int64), np.zeros(0)
        last = math.floor((bound - first) / step) + 1
        k = np.arange(k0, last + 1, dtype=np.int64)
        k = k[k * step + first <= bound]
        t = self._time_of(k * step + first)
        n = int(np.count_nonzero(t <= c))
        return k[:n], t[:n]

    def _release(self, c: float, bound: float) -> None:
        st, plan = self.state, self.plan
        if plan is None:
            return
        sh = st.sheets
        wait = np.flatnonzero((sh['fate'] == 1) & np.isnan(sh['t_r']))
        if wait.size == 0:
            return
        th = plan.release_phase(sh['cycle'][wait])
        near = th <= bound
        wait, th = wait[near], th[near]
        t = self._time_of(th)
        rows = wait[t <= c]
        if rows.size:
            sh['t_r'][rows] = t[t <= c]
            self._found(make_events('released_on_pile', sh['t_r'][rows], sheet=sh['id'][rows], cycle=sh['cycle'][rows]))

    # ------------------------------------------------------------------ hand out

    def emit(self, t: float) -> tuple[np.ndarray, list[ConstraintSeries]]:
        """The events found with times at or before ``t`` (s, at most the time computed), sorted by time,
        kind, sheet; and the constraint rows of the cycles (and releases) judged with them.

        Returns
        -------
        events : ndarray of EVENT_DTYPE
        rows : list of ConstraintSeries
            One per constraint of the folder, in :data:`FOLDER_CONSTRAINTS` order (empty series where
            nothing was judged).
        """
        st = self.state
        if t > st.computed:
            raise ValueError(f'FolderStream.emit({t!r}): computed only to {st.computed!r} s')
        f = np.concatenate(st.found) if len(st.found) > 1 else (st.found[0] if st.found else empty_events())
        out_mask = f['t'] <= t
        out = f[out_mask]
        rest = f[~out_mask]
        st.found = [rest] if rest.size else []
        if out.size:
            out = out[np.lexsort((out['sheet'], out['kind'], out['t']))]
            st.t_last = max(st.t_last, float(out['t'][-1]))
        st.emitted = max(st.emitted, t)
        if out.size == 0 or not self.judge:  # nothing (to be) judged
            if out.size:
                self._retire(t)
            return out, [] if not self.judge else [self.empty_rows[name] for name in self.constraint_names]
        self._tally(out, t)
        rows = self._judge(out, final=False)
        self._retire(t)
        return out, rows

    def _tally(self, out: np.ndarray, t: float) -> None:
        st = self.state
        cnt = st.counts
        kinds = out['kind']
        cnt.fed += int(np.count_nonzero(kinds == _K['sheet_handover']))
        cnt.at_stops += int(np.count_nonzero(kinds == _K['at_stops']))
        cnt.released += int(np.count_nonzero(kinds == _RELEASE))
        cnt.slowdowns += int(np.count_nonzero(kinds == event_kind('belt_slowdown_start')))
        cnt.missing += int(np.count_nonzero(kinds == event_kind('fault_missing')))
        cnt.double += int(np.count_nonzero(kinds == event_kind('fault_double')))
        cnt.late += int(np.count_nonzero(kinds == event_kind('fault_late')))
        if st.start0_found and st.start0_t <= t and cnt.started == 0:
            cnt.started = 1
        cnt.started += int(np.count_nonzero(kinds == event_kind('knife_exit')))
        contacts = out['cycle'][kinds == _K['knife_contact']]
        cnt.contacts += int(contacts.size)
        sh = st.sheets
        if contacts.size:
            mine = np.isin(sh['cycle'], contacts)
            cnt.folded += int(np.count_nonzero(mine & (sh['fate'] == 1)))
            cnt.jammed += int(np.count_nonzero(mine & (sh['fate'] == 0)))
        arrived = out['sheet'][kinds == _K['at_stops']]
        if arrived.size and self.setup.bounce is not None:
            m = np.isin(sh['id'], arrived)
            if m.any():
                cnt.bounces_max = max(cnt.bounces_max, int(sh['bounces'][m].max()))
                cnt.settle_max = max(cnt.settle_max, float(sh['settle'][m].max()))

    def _judge(self, out: np.ndarray, final: bool) -> list[ConstraintSeries]:
        """Rows of the cycles complete with ``out`` handed out (all of the pending ones if ``final``)."""
        st = self.state
        judged = out[np.isin(out['kind'], _JUDGED_KINDS)]
        if judged.size:
            st.rows = np.concatenate((st.rows, judged))
            last_kind = _K['settled'] if self.setup.bounce is not None else _K['at_stops']
            done_cyc = judged['cycle'][judged['kind'] == last_kind]
            contact_cyc = judged['cycle'][judged['kind'] == _K['knife_contact']]
            self._cycles_to(int(max(done_cyc.max(initial=-1), contact_cyc.max(initial=-1))) + 1)
            np.add.at(st.settled, done_cyc[done_cyc >= st.judged_next] - st.judged_next, 1)
            st.contacted[contact_cyc[contact_cyc >= st.judged_next] - st.judged_next] = True
        # a cycle is complete once its knife contact is out, its slot drawn and its signatures settled
        ready = st.contacted & (final | ((st.expected >= 0) & (st.settled >= st.expected)))
        k = st.judged_next + (int(np.argmin(ready)) if not ready.all() else ready.size)
        parts: list[ConstraintSeries] = []
        if k > st.judged_next:
            done = (st.rows['cycle'] >= st.judged_next) & (st.rows['cycle'] < k)
            ev = folder_evaluation(
                st.rows[done], self.timing, self.scene, self.drive, plan=self.plan, t_end=st.t_last
            ).constraints
            parts = [c for c in ev if c.name != 'release_at_min_speed']
            st.rows = st.rows[~done]
            n = k - st.judged_next
            st.expected, st.settled, st.contacted = st.expected[n:], st.settled[n:], st.contacted[n:]
            drop = min(max(0, (k - 1) - st.exit_base), st.exit_t.size)  # keep the exit that starts cycle k
            st.exit_t, st.exit_base = st.exit_t[drop:], st.exit_base + drop
            st.judged_next = k
        rel = out[out['kind'] == _RELEASE]
        release = None
        if self.plan is not None and rel.size:
            release = next(
                c
                for c in folder_evaluation(rel, self.timing, self.scene, self.drive, plan=self.plan).constraints
                if c.name == 'release_at_min_speed'
            )
        by_name = {c.name: c for c in parts}
        if release is not None:
            by_name['release_at_min_speed'] = release
        return [by_name.get(name) or self.empty_rows[name] for name in self.constraint_names]

    @property
    def constraint_names(self) -> tuple[str, ...]:
        """The constraints this scene's folder is judged on, in :data:`FOLDER_CONSTRAINTS` order."""
        names = ['feed_window', 'settled_before_knife', 'one_per_cycle']
        if self.setup.bounce is not None:
            names.append('rebound')
        if self.plan is not None:
            names.append('release_at_min_speed')
        return tuple(n for n in FOLDER_CONSTRAINTS if n in names)

    def finish(self) -> list[ConstraintSeries]:
        """The rows of every cycle whose knife contact was handed out but that was not judged yet (a
        signature still on its way at the end: judged as the batch judges it, on the events so far)."""
        return self._judge(empty_events(), final=True)

    def _retire(self, t: float) -> None:
        """Drop the signatures whose every event is handed out (the last few kept as history)."""
        st = self.state
        sh = st.sheets
        contact_out = ~np.isnan(sh['t_c']) & (sh['t_c'] <= t)
        settled_out = ~np.isnan(sh['t_s']) & (sh['t_s'] <= t)
        if self.plan is not None:
            gone = (~np.isnan(sh['t_r']) & (sh['t_r'] <= t)) | ((sh['fate'] == 0) & contact_out & settled_out)
        else:
            gone = (sh['fate'] >= 0) & contact_out & settled_out
        if gone.any():
            st.history = np.concatenate((st.history, sh[gone]))
            st.sheets = sh[~gone]

    def earliest_needed(self) -> float:
        """The earliest line time whose drive a cycle still to be judged reads (its start, where its feed
        deadline may lie), s."""
        st = self.state
        if not self.judge:
            return math.inf
        if st.judged_next == 0:
            return 0.0
        i = (st.judged_next - 1) - st.exit_base
        return float(st.exit_t[i]) if 0 <= i < st.exit_t.size else math.inf

    def _cycles_to(self, end: int) -> None:
        """Make the per-cycle arrays reach cycle ``end - 1`` (a cycle not drawn yet expects -1)."""
        st = self.state
        n = end - st.judged_next - st.expected.size
        if n > 0:
            st.expected = np.concatenate((st.expected, np.full(n, -1, dtype=np.int64)))
            st.settled = np.concatenate((st.settled, np.zeros(n, dtype=np.int64)))
            st.contacted = np.concatenate((st.contacted, np.zeros(n, dtype=bool)))

    def prune(self, t_keep: float) -> None:
        """Forget what no query from ``t_keep`` (s) on needs: the signatures that left the machine before it,
        but the last :data:`HISTORY`; the belt's intervals that ended before it."""
        st = self.state
        h = st.history
        if h.size > HISTORY:
            end = np.fmax(np.fmax(h['t_r'], h['t_s']), np.fmax(h['t_c'], h['t_x']))
            before = np.flatnonzero(end < t_keep)
            keep = np.ones(h.size, dtype=bool)
            keep[before[:-HISTORY]] = False  # the last HISTORY that left before t_keep stay
            st.history = h[keep]
        st.belt.phase.prune(t_keep)

    # ------------------------------------------------------------------ figures

    def summary(self) -> FolderFigures:
        """The figures of the folder as of the events handed out (the ``simulate`` summary's ``folder``)."""
        st, s = self.state, self.setup
        cnt = st.counts
        counted = cnt.released if self.plan is not None else cnt.folded
        static = folder_steps.static_summary(s)
        in_machine = cnt.fed - counted
        bounce = static.stop_bounce
        if bounce is not None:
            bounce = replace(bounce, bounces_max=cnt.bounces_max, settle_time_max=cnt.settle_max)
        fault_counts = None
        if s.faults is not None:
            fault_counts = FaultCounts(missing=cnt.missing, double=cnt.double, late=cnt.late, slowdowns=cnt.slowdowns)
        return replace(
            static,
            cycles=cnt.contacts,
            cycles_started=cnt.started,
            sheets_fed=cnt.fed,
            sheets_at_stops=cnt.at_stops,
            sheets_folded=cnt.folded,
            sheets_jammed=cnt.jammed,
            sheets_counted=counted,
            sheets_in_machine=in_machine,
            sheets_balance_ok=bool(cnt.fed == counted + in_machine and in_machine >= 0),
            stop_bounce=bounce,
            faults=fault_counts,
        )

    # ------------------------------------------------------------------ joint states

    def sample_unit(self, unit: str, t: npt.ArrayLike, theta: np.ndarray, lam: np.ndarray) -> JointSamples:
        """Joint states of one unit (``drive``, ``belts``, ``feed``) at ``t`` (in the window the belt knows)."""
        t = np.asarray(t, dtype=float).reshape(-1)
        if unit == 'drive':
            return folder_joints.drive_samples(self.timing, self.knife, t, theta, lam, self.with_torque)
        if unit == 'belts':
            return folder_joints.belts_samples(self.timing, t, theta, lam, self.with_torque)
        if unit == 'feed':
            belt = self.state.belt.phase
            return folder_joints.feed_samples(self.scene, self.plan, self.V_tr, belt, self.torque_params, t, theta, lam)
        raise KeyError(f'unit {unit!r} has no folder joints; units: {", ".join(self.units)}')

    # ------------------------------------------------------------------ a view of the signatures

    def sheets_view(self) -> np.ndarray:
        """The signatures in the machine and the last :data:`HISTORY` that left it (SHEET_DTYPE rows, by id;
        each time NaN until found)."""
        st = self.state
        both = np.concatenate((st.history, st.sheets))
        return both[np.argsort(both['id'], kind='stable')]
