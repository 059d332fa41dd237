"""Cycle evaluation: the constraints the supervisor judges, each at its own decision time.

The events fed are kept until judged, and :meth:`CycleEvaluation.due` turns those due by a
watermark into decisions (:class:`Due`), in time order:

* a folder cycle at its ``knife_contact``, on the events up to that instant: the *same*
  code as the batch simulator, :func:`folder_line.core.line.constraints.folder_evaluation`
  with ``causal=True`` (each cycle sees only the rows up to its own knife contact, so the
  batching of the feed does not matter);
* ``release_at_min_speed`` at the ``released_on_pile`` time;
* the layup's ``chute_speed`` at each ``leaf_exit``
  (:func:`folder_line.core.line.constraints.evaluate_layup_constraints`).

A supervisor that starts watching a line already running judges the folder cycles whose
start it saw: from the first knife event fed, cycle 0 if it is cycle 0's knife contact,
else the cycle after the one that event belongs to (the ones before started unseen, and
their signatures' events may never come).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from folder_line.core.line.constraints import evaluate_layup_constraints, folder_evaluation
from folder_line.core.line.delivery_plan import DeliveryPlan, delivery_plan
from folder_line.core.line.scene import Scene
from folder_line.core.mechanisms.cyclogram import CycleTiming, cycle_timing
from folder_line.core.mechanisms.drive import Drive
from folder_line.core.types.events import EVENT_DTYPE, append_events, event_kind, kind_table, kinds_in

__all__ = ['CycleEvaluation', 'Due']

_FOLDER_KINDS = kind_table(('sheet_handover', 'at_stops', 'bounce', 'settled', 'knife_contact'))
_CONTACT = event_kind('knife_contact')
_EXIT = event_kind('knife_exit')
_RELEASE = event_kind('released_on_pile')
_LEAF_EXIT = event_kind('leaf_exit')


@dataclass(frozen=True)
class Due:
    """A decision due at ``t``: one evaluated cycle (or release, or leaf exit)."""

    t: float
    order: int
    cycle: int
    margins: tuple[tuple[str, str, float], ...]  # (name, unit, margin)
    signatures: int = 1
    source: str = 'folder'  # 'folder', 'release', 'layup'


class CycleEvaluation:
    """The events not yet judged, and the evaluations they give.

    Parameters
    ----------
    scene : Scene
        The line's scene (the folder's cycle timing and delivery plan are derived once).

    Attributes
    ----------
    timing : CycleTiming or None
        The folder's cycle (None without the folder).
    plan : DeliveryPlan or None
        The delivery's figures (None without the delivery).
    folder_done : int
        The last folder cycle judged.
    """

    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        self.timing: CycleTiming | None = None
        self.plan: DeliveryPlan | None = None
        if scene.has_folder:
            self.timing = cycle_timing(scene.machine('cyclogram'), scene.machine('knife'))
            self.plan = delivery_plan(scene, self.timing)
        self._folder = np.zeros(0, dtype=EVENT_DTYPE)
        self._releases = np.zeros(0, dtype=EVENT_DTYPE)
        self._exits = np.zeros(0, dtype=EVENT_DTYPE)
        self.folder_done = -1  # last folder cycle judged
        self.first_cycle: int | None = None  # the first folder cycle whose start was seen
        self._release_done = -math.inf  # last release time judged
        self._exit_done = -math.inf  # last leaf exit time judged
        self._next: float | None = None  # the earliest time an evaluation may be due, s (None: not known)
        self._judged = False  # an evaluation was taken since the last commit
        # evaluations made ahead (:meth:`preview`): folder cycle -> its Due, (t, cycle) -> release margins
        self._ahead_drive: Drive | None = None
        self._ahead: dict[int, Due] = {}
        self._ahead_releases: dict[tuple[float, int], Due] = {}

    def add(self, rows: np.ndarray) -> None:
        """Keep the rows (finite, of EVENT_DTYPE) that a later evaluation needs."""
        kind = rows['kind']
        if self.first_cycle is None:
            knife = rows[(kind == _CONTACT) | (kind == _EXIT)]
            if knife.size:
                first = knife[np.lexsort((knife['kind'], knife['t']))][0]
                c = int(first['cycle'])
                self.first_cycle = 0 if first['kind'] == _CONTACT and c == 0 else c + 1
                self.folder_done = max(self.folder_done, self.first_cycle - 1)
                self._judged = True  # the rows of cycles before it go at the next commit
        f = rows[kinds_in(kind, _FOLDER_KINDS) & (rows['cycle'] > self.folder_done)]
        if f.size:
            self._folder = append_events(self._folder, f)
        r = rows[kind == _RELEASE]
        if r.size:
            self._releases = append_events(self._releases, r)
        x = rows[kind == _LEAF_EXIT]
        if x.size:
            self._exits = append_events(self._exits, x)
        if self._next is not None:  # the new candidates only move it earlier
            self._next = min(self._next, self._earliest_of(f, r, x))

    def _earliest_of(self, f: np.ndarray, r: np.ndarray, x: np.ndarray) -> float:
        """The earliest time among the knife contacts ``f``, releases ``r`` and leaf exits ``x`` not yet
        judged (inf if none)."""
        out = math.inf
        contact = f['t'][(f['kind'] == _CONTACT) & (f['cycle'] > self.folder_done)]
        for t in (contact, r['t'][r['t'] > self._release_done], x['t'][x['t'] > self._exit_done]):
            if t.size:
                out = min(out, float(t.min()))
        return out

    def next_due(self) -> float:
        """The earliest time an evaluation may be due (s; inf if none): :meth:`due` before it gives none."""
        if self._next is None:
            self._next = self._earliest_of(self._folder, self._releases, self._exits)
        return self._next

    def preview(self, rows: np.ndarray, drive: Drive) -> None:
        """Evaluate ahead the cycles and releases of ``rows`` (finite, of EVENT_DTYPE), events that
        will be fed, under ``drive``.

        :meth:`due` then takes their evaluations from here, as long as the drive it is given is
        ``drive`` (a new command makes a new drive: it evaluates again). Each cycle is judged on
        the rows up to its own knife contact (``causal``), so evaluating many cycles at once, on
        more rows, gives each one's margins as evaluating it alone does.
        """
        self._ahead_drive = drive
        self._ahead = {}
        self._ahead_releases = {}
        if self.timing is None:
            return
        kind = rows['kind']
        if self.first_cycle is not None:
            f = rows[kinds_in(kind, _FOLDER_KINDS) & (rows['cycle'] > self.folder_done)]
            fb = np.concatenate([self._folder[self._folder['cycle'] > self.folder_done], f])
            contacts = fb['cycle'][fb['kind'] == _CONTACT]
            if contacts.size:
                sub = fb[fb['cycle'] <= contacts.max()]
                for it in self._folder_items(sub, drive):
                    self._ahead[it.cycle] = it
        r = rows[(kind == _RELEASE) & (rows['t'] > self._release_done)]
        if r.size:
            # a release is judged with the others of its cycle due at the same time (the smallest
            # margin): only a cycle's single release is evaluated ahead
            known = self._releases['cycle'][self._releases['t'] > self._release_done]
            cycles, counts = np.unique(np.concatenate([known, r['cycle']]), return_counts=True)
            single = r[np.isin(r['cycle'], cycles[counts == 1])]
            if single.size:
                for it in self._release_items(single, drive):
                    self._ahead_releases[(it.t, it.cycle)] = it

    def _folder_items(self, sub: np.ndarray, drive: Drive) -> list[Due]:
        """The folder cycles' evaluations of the rows ``sub``."""
        assert self.timing is not None
        ev = folder_evaluation(sub, self.timing, self.scene, drive, plan=self.plan, causal=True)
        per: dict[int, list[tuple[str, str, float]]] = {int(c): [] for c in ev.cycle}
        for s in ev.constraints:
            if s.name == 'release_at_min_speed':
                continue
            for c, m in zip(s.cycle.tolist(), s.margin.tolist(), strict=True):
                per[int(c)].append((s.name, s.unit, float(m)))
        return [
            Due(float(tc), 0, int(c), tuple(per[int(c)]), int(n), 'folder')
            for c, tc, n in zip(ev.cycle.tolist(), ev.t.tolist(), ev.signatures.tolist(), strict=True)
        ]

    def _release_items(self, rows: np.ndarray, drive: Drive) -> list[Due]:
        """The evaluations of the releases ``rows``."""
        assert self.timing is not None
        ev = folder_evaluation(rows, self.timing, self.scene, drive, plan=self.plan, causal=True)
        return [
            Due(float(tr), 1, int(c), ((s.name, s.unit, float(m)),), 1, 'release')
            for s in ev.constraints
            if s.name == 'release_at_min_speed'
            for c, m, tr in zip(s.cycle.tolist(), s.margin.tolist(), s.t.tolist(), strict=True)
        ]

    def due(self, W: float, drive_before: Callable[[], Drive]) -> list[Due]:
        """The evaluations due by ``W`` that are not yet taken, in time order.

        ``drive_before()`` gives the drive that is right before ``W``; it is called (a
        line model may have to be built) only if a folder cycle or a release is due.
        """
        if self.next_due() > W:
            return []
        items, drive = self._folder_due(W, drive_before)
        items += self._releases_due(W, drive, drive_before)
        items += self._exits_due(W)
        items.sort(key=lambda it: (it.t, it.order, it.cycle))
        return items

    def _folder_due(self, W: float, drive_before: Callable[[], Drive]) -> tuple[list[Due], Drive | None]:
        """The folder cycles whose knife contact is due by ``W`` (s), and the drive if it was needed."""
        fb = self._folder
        if self.timing is None or not fb.size or self.first_cycle is None:
            return [], None
        contact = (fb['kind'] == _CONTACT) & (fb['t'] <= W) & (fb['cycle'] > self.folder_done)
        if not contact.any():
            return [], None
        drive = drive_before()
        last = int(fb['cycle'][contact].max())
        ahead = [self._ahead.get(c) for c in range(self.folder_done + 1, last + 1)]
        if drive is self._ahead_drive and None not in ahead:
            return [it for it in ahead if it is not None], drive
        sub = fb[(fb['cycle'] > self.folder_done) & (fb['cycle'] <= last) & ((fb['kind'] != _CONTACT) | contact)]
        return self._folder_items(sub, drive), drive

    def _releases_due(self, W: float, drive: Drive | None, drive_before: Callable[[], Drive]) -> list[Due]:
        """The releases due by ``W`` (s); ``drive``: the drive before ``W`` if already at hand."""
        rb = self._releases
        if self.timing is None or not rb.size:
            return []
        due = (rb['t'] <= W) & (rb['t'] > self._release_done)
        if not due.any():
            return []
        drive = drive_before() if drive is None else drive
        keys = list(zip(rb['t'][due].tolist(), rb['cycle'][due].tolist(), strict=True))
        known = [self._ahead_releases.get(k) for k in keys]
        if drive is self._ahead_drive and None not in known:
            return [it for it in known if it is not None]
        return self._release_items(rb[due], drive)

    def _exits_due(self, W: float) -> list[Due]:
        """The leaf exits due by ``W`` (s)."""
        xb = self._exits
        items: list[Due] = []
        if xb.size:
            due = (xb['t'] <= W) & (xb['t'] > self._exit_done)
            if due.any():
                for s in evaluate_layup_constraints(xb[due], self.scene):
                    for c, m, tx in zip(s.cycle.tolist(), s.margin.tolist(), s.t.tolist(), strict=True):
                        items.append(Due(float(tx), 2, int(c), ((s.name, s.unit, float(m)),), 1, 'layup'))
        return items

    def taken(self, it: Due) -> None:
        """The evaluation ``it`` was taken: its rows are judged."""
        self._next = None
        self._judged = True
        if it.source == 'folder':
            self.folder_done = max(self.folder_done, it.cycle)
        elif it.source == 'release':
            self._release_done = max(self._release_done, it.t)
        else:
            self._exit_done = max(self._exit_done, it.t)

    def commit(self) -> None:
        """Drop the buffered rows of what has been judged."""
        if not self._judged:
            return
        self._judged = False
        fb = self._folder
        if fb.size:
            self._folder = fb[fb['cycle'] > self.folder_done]
        rb = self._releases
        if rb.size:
            self._releases = rb[rb['t'] > self._release_done]
        xb = self._exits
        if xb.size:
            self._exits = xb[xb['t'] > self._exit_done]
