"""The sheet balance at a stop: :class:`Balance`, counted by :class:`SheetBalance`.

On entering HELD, SUSPENDED, STOPPED, ABORTED or COMPLETE, the sheets are counted from
the events up to that instant: fed (handed over) = delivered (released on the pile;
without a delivery: folded) + in the machine (on the feed belt, at the stops waiting for
the knife, jammed after it, or folded on the chain); for the layup, leaves entered =
landed (or exited, without ``leaf_flight``) + on the chutes + in the air.

The counts are kept as the events come (:class:`SheetBalance`): the sheets and leaves in
the machine, and counters of the ones delivered, so the memory does not grow with line
time. A supervisor that starts watching a line already running counts the sheets handed
over (and the leaves entered) from its first one on: the events of earlier ones are not
counted, and not held against the balance.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from folder_line.core.line.scene import Scene
from folder_line.core.types.events import event_kind, kind_table, kinds_in

__all__ = ['Balance', 'SheetBalance']

_BALANCE_KINDS = kind_table(
    (
        'sheet_handover',
        'at_stops',
        'knife_contact',
        'released_on_pile',
        'leaf_enter',
        'leaf_exit',
        'leaf_landed',
        'leaf_spilled',
    )
)

_HAND, _STOPS, _CONTACT, _RELEASE = (
    event_kind(k) for k in ('sheet_handover', 'at_stops', 'knife_contact', 'released_on_pile')
)
_ENTER, _EXIT, _LANDED, _SPILLED = (event_kind(k) for k in ('leaf_enter', 'leaf_exit', 'leaf_landed', 'leaf_spilled'))


@dataclass(frozen=True)
class Balance:
    """Sheets counted at a stop, from the events up to ``t``.

    Attributes
    ----------
    t : float
        Time of the transition into the stopped state, s.
    state : str
        That state.
    fed, delivered, in_machine : int
        Sheets (and leaves) fed, delivered, and still in the machine.
    detail : dict of str to int
        Where the ones in the machine are: ``on_feed``, ``at_stops``, ``jammed``,
        ``on_chain`` (folder), ``on_chutes``, ``in_air`` (layup); and ``folded``.
    ok : bool
        ``fed == delivered + in_machine`` and every delivered sheet was fed (no
        sheet lost, none counted twice); False when ``missing``.
    missing : str
        Empty, or why the balance cannot be judged: ``'events of <node> not received
        after <t> s'`` (a participant was lost: its counts stop there, the others' do not).
    """

    t: float
    state: str
    fed: int
    delivered: int
    in_machine: int
    detail: dict[str, int]
    ok: bool
    missing: str = ''


#: knife contacts kept before the oldest signature in the machine (for a late one handed over after its knife)
_CONTACTS_KEPT = 16


@dataclass
class _Signature:
    """A signature in the machine: its cycle, its arrival at the stops, and whether the knife folded it."""

    cycle: int
    t_a: float | None = None
    folded: bool = False


@dataclass
class _Counter:
    """The running counts of the folder and the layup (see :class:`SheetBalance`)."""

    first_sheet: int | None = None  # the first signature seen handed over
    fed: int = 0
    delivered: int = 0  # released (with the delivery), else folded
    folded: int = 0
    ok: bool = True
    sheets: dict[int, _Signature] = field(default_factory=dict)  # in the machine
    contacts: dict[int, float] = field(default_factory=dict)  # cycle -> knife contact (of cycles with sheets)
    first_leaf: int | None = None
    entered: int = 0
    exited: int = 0
    down: int = 0


class SheetBalance:
    """The events a balance counts, kept as running counts, and the balance at any time since the last commit.

    Parameters
    ----------
    scene : Scene
        The line's scene (which parts it has; ``leaf_flight``).
    with_delivery : bool
        The folder has the delivery: a sheet is delivered when released on the pile
        (else when folded).
    """

    def __init__(self, scene: Scene, with_delivery: bool) -> None:
        self.scene = scene
        self.with_delivery = with_delivery
        self.flight = scene.has('leaf_flight')
        self._rows: list[np.ndarray] = []  # fed, not yet counted
        self._t_first = math.inf  # the earliest time among them, s
        self._counter = _Counter()

    def add(self, rows: np.ndarray) -> None:
        """Keep the rows (finite, of EVENT_DTYPE) a balance counts."""
        b = rows[kinds_in(rows['kind'], _BALANCE_KINDS)]
        if b.size:
            self._rows.append(b)
            self._t_first = min(self._t_first, float(b['t'].min()))

    def commit(self, t: float) -> None:
        """Count the rows up to ``t`` (s) for good: no balance is asked for before ``t`` any more."""
        if not self._rows or t < self._t_first:
            return
        rows = np.concatenate(self._rows)
        done = rows['t'] <= t
        self._count(self._counter, rows[done])
        rest = rows[~done]
        self._rows = [rest] if rest.size else []
        self._t_first = float(rest['t'].min()) if rest.size else math.inf

    def at(self, t: float, state: str, lost_nodes: Sequence[str], blind_from: float) -> Balance:
        """The sheet balance from the events up to ``t`` (see :class:`Balance`; ``t`` not before the last commit).

        ``lost_nodes`` (lost from ``blind_from`` on, s): their events may be missing, so a
        balance at or after ``blind_from`` is not ``ok`` and says why.
        """
        c = self._counter
        if self._rows:
            rows = np.concatenate(self._rows)
            c = copy.deepcopy(c)
            self._count(c, rows[rows['t'] <= t])
        fed = delivered = in_machine = 0
        detail: dict[str, int] = {}
        ok = c.ok
        if self.scene.has_folder:
            waiting = on_feed = jammed = on_chain = 0
            for sig in c.sheets.values():
                t_c = c.contacts.get(sig.cycle)
                if sig.t_a is None:
                    on_feed += 1
                elif sig.folded:
                    on_chain += 1
                elif t_c is None:
                    waiting += 1
                else:
                    jammed += 1
            detail.update(
                {'on_feed': on_feed, 'at_stops': waiting, 'jammed': jammed, 'on_chain': on_chain, 'folded': c.folded}
            )
            fed += c.fed
            delivered += c.delivered
            in_machine += on_feed + waiting + jammed + on_chain
        if self.scene.has_layup:
            on_chutes = c.entered - c.exited
            in_air = c.exited - c.down if self.flight else 0
            ok &= on_chutes >= 0 and in_air >= 0
            detail.update({'on_chutes': on_chutes, 'in_air': in_air})
            fed += c.entered
            delivered += c.down if self.flight else c.exited
            in_machine += on_chutes + in_air
        ok &= fed == delivered + in_machine
        if lost_nodes and t >= blind_from:
            missing = f'events of {", ".join(lost_nodes)} not received after {blind_from:.6f} s'
            return Balance(float(t), state, fed, delivered, in_machine, detail, False, missing)
        return Balance(float(t), state, fed, delivered, in_machine, detail, bool(ok))

    def _count(self, c: _Counter, rows: np.ndarray) -> None:
        """Count ``rows`` (in time order) into ``c``."""
        rows = rows[np.lexsort((rows['sheet'], rows['kind'], rows['t']))]
        for t, kind, sheet, cycle in zip(
            rows['t'].tolist(), rows['kind'].tolist(), rows['sheet'].tolist(), rows['cycle'].tolist(), strict=True
        ):
            if kind == _HAND:
                _hand_over(c, sheet, cycle)
            elif kind == _STOPS:
                sig = c.sheets.get(sheet)
                if sig is not None and sig.t_a is None:
                    sig.t_a = t
            elif kind == _CONTACT:
                self._contact(c, cycle, t)
            elif kind == _RELEASE:
                _release(c, sheet)
            else:
                _leaf(c, kind, sheet)

    def _contact(self, c: _Counter, cycle: int, t: float) -> None:
        """The knife at ``t``: the signatures of ``cycle`` at the stops by then are folded."""
        c.contacts[cycle] = t
        for key, sig in list(c.sheets.items()):
            if sig.cycle == cycle and sig.t_a is not None and sig.t_a <= t and not sig.folded:
                sig.folded = True
                c.folded += 1
                if not self.with_delivery:
                    del c.sheets[key]
                    c.delivered += 1
        # forget the contacts no signature in the machine belongs to (the last few kept for a late one)
        low = min([sig.cycle for sig in c.sheets.values()] + [cycle - _CONTACTS_KEPT])
        for k in [k for k in c.contacts if k < low]:
            del c.contacts[k]


def _hand_over(c: _Counter, sheet: int, cycle: int) -> None:
    """A signature handed over: fed (a second hand-over of it, or one before the first, spoils the count)."""
    if c.first_sheet is None:
        c.first_sheet = sheet
    if sheet in c.sheets or sheet < c.first_sheet:
        c.ok = False  # counted twice
        return
    c.fed += 1
    c.sheets[sheet] = _Signature(cycle)


def _release(c: _Counter, sheet: int) -> None:
    """A signature released on the pile: delivered if it was folded (else the count is spoilt)."""
    sig = c.sheets.get(sheet)
    if sig is not None and sig.folded:
        del c.sheets[sheet]
        c.delivered += 1
    elif c.first_sheet is not None and sheet >= c.first_sheet:
        c.ok = False  # released, never folded (or twice)


def _leaf(c: _Counter, kind: int, sheet: int) -> None:
    """A leaf event of kind ``kind``: entered, exited, or down (landed or spilled)."""
    if kind == _ENTER:
        if c.first_leaf is None:
            c.first_leaf = sheet
        c.entered += int(sheet >= c.first_leaf)
    elif c.first_leaf is not None and sheet >= c.first_leaf:
        if kind == _EXIT:
            c.exited += 1
        else:  # landed or spilled
            c.down += 1
