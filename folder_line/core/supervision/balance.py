"""The sheet balance at a stop: :class:`Balance`, counted by :class:`SheetBalance`.

On entering HELD, SUSPENDED, STOPPED, ABORTED or COMPLETE, the sheets are counted from
the events up to that instant: fed (handed over) = delivered (released on the pile;
without a delivery: folded) + in the machine (on the feed belt, at the stops waiting for
the knife, jammed after it, or folded on the chain); for the layup, leaves entered =
landed (or exited, without ``leaf_flight``) + on the chutes + in the air.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from folder_line.core.line.events import EVENT_DTYPE, event_kind
from folder_line.core.line.scene import Scene

__all__ = ['Balance', 'SheetBalance']

_BALANCE_KINDS = np.array(
    [
        event_kind(k)
        for k in (
            'sheet_handover',
            'at_stops',
            'knife_contact',
            'released_on_pile',
            'leaf_enter',
            'leaf_exit',
            'leaf_landed',
            'leaf_spilled',
        )
    ],
    dtype=np.int16,
)

#: (fed, delivered, in the machine, where, consistent)
_Counts = tuple[int, int, int, dict[str, int], bool]


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


class SheetBalance:
    """The events a balance counts, and the balance at any time.

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
        self._rows: list[np.ndarray] = []

    def add(self, rows: np.ndarray) -> None:
        """Keep the rows (finite, of EVENT_DTYPE) a balance counts."""
        b = rows[np.isin(rows['kind'], _BALANCE_KINDS)]
        if b.size:
            self._rows.append(b)

    def at(self, t: float, state: str, lost_nodes: Sequence[str], blind_from: float) -> Balance:
        """The sheet balance from the events up to ``t`` (see :class:`Balance`).

        ``lost_nodes`` (lost from ``blind_from`` on, s): their events may be missing, so a
        balance at or after ``blind_from`` is not ``ok`` and says why.
        """
        rows = np.concatenate(self._rows) if self._rows else np.zeros(0, dtype=EVENT_DTYPE)
        rows = rows[rows['t'] <= t]
        kind = rows['kind']

        def of(name: str) -> np.ndarray:
            sel: np.ndarray = rows[kind == event_kind(name)]  # a field of a structured array is typed Any
            return sel

        fed = delivered = in_machine = 0
        detail: dict[str, int] = {}
        ok = True
        parts: list[_Counts] = []
        if self.scene.has_folder:
            parts.append(_folder_counts(of, self.with_delivery))
        if self.scene.has_layup:
            parts.append(_layup_counts(of, self.scene.has('leaf_flight')))
        for f, d, m, where, consistent in parts:
            ok &= consistent
            detail.update(where)
            fed += f
            delivered += d
            in_machine += m
        ok &= fed == delivered + in_machine
        if lost_nodes and t >= blind_from:
            missing = f'events of {", ".join(lost_nodes)} not received after {blind_from:.6f} s'
            return Balance(float(t), state, fed, delivered, in_machine, detail, False, missing)
        return Balance(float(t), state, fed, delivered, in_machine, detail, bool(ok))


def _folder_counts(of: Callable[[str], np.ndarray], with_delivery: bool) -> _Counts:
    """The folder's signatures: fed, delivered, in the machine (and where), consistent."""
    hand = of('sheet_handover')
    ids = hand['sheet']
    ok = np.unique(ids).size == ids.size
    stops = of('at_stops')
    contact = of('knife_contact')
    cc, first = np.unique(contact['cycle'], return_index=True)
    tc = contact['t'][first]
    arrived = np.isin(ids, stops['sheet'])
    t_stop = np.zeros(ids.size)
    if stops.size:
        order = np.argsort(stops['sheet'], kind='stable')
        ks, ts = stops['sheet'][order], stops['t'][order]
        pos = np.minimum(np.searchsorted(ks, ids), ks.size - 1)
        t_stop = np.where(arrived, ts[pos], 0.0)
    if cc.size:
        pos = np.minimum(np.searchsorted(cc, hand['cycle']), cc.size - 1)
        knifed = cc[pos] == hand['cycle']
        t_knife = np.where(knifed, tc[pos], np.inf)
    else:
        knifed = np.zeros(ids.size, dtype=bool)
        t_knife = np.full(ids.size, np.inf)
    folded = arrived & knifed & (t_stop <= t_knife)
    jammed = arrived & knifed & ~folded
    waiting = arrived & ~knifed
    on_feed = ~arrived
    if with_delivery:
        rel = of('released_on_pile')['sheet']
        ok &= bool(np.all(np.isin(rel, ids[folded]))) and np.unique(rel).size == rel.size
        delivered = int(rel.size)
        on_chain = int(np.count_nonzero(folded & ~np.isin(ids, rel)))
    else:
        delivered = int(np.count_nonzero(folded))
        on_chain = 0
    detail = {
        'on_feed': int(np.count_nonzero(on_feed)),
        'at_stops': int(np.count_nonzero(waiting)),
        'jammed': int(np.count_nonzero(jammed)),
        'on_chain': on_chain,
        'folded': int(np.count_nonzero(folded)),
    }
    in_machine = detail['on_feed'] + detail['at_stops'] + detail['jammed'] + on_chain
    return int(ids.size), delivered, in_machine, detail, bool(ok)


def _layup_counts(of: Callable[[str], np.ndarray], flight: bool) -> _Counts:
    """The layup's leaves: entered, down (landed or spilled; exited without ``flight``), in the machine."""
    entered = of('leaf_enter').size
    exited = of('leaf_exit').size
    if flight:
        down = of('leaf_landed').size + of('leaf_spilled').size
        in_air = exited - down
    else:
        down, in_air = exited, 0
    on_chutes = entered - exited
    ok = on_chutes >= 0 and in_air >= 0
    detail = {'on_chutes': int(on_chutes), 'in_air': int(in_air)}
    return int(entered), int(down), int(on_chutes + in_air), detail, bool(ok)
