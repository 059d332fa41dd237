"""The recorded events against the line model, window by window (:func:`compare_events`).

:func:`compare_events` advances the streamed line
(:class:`folder_line.core.line.stream.LineStream`, under every recorded command and tuning at
once) window by window (:data:`~folder_line.analysis.streaming.WINDOW`) and compares its events
with the recorded ones of the same window: the time to the ns (as a node publishes it), the kind,
the sheet, the cycle and the value (:class:`EventCheck`). With ``t_from`` the stream is first
fast-forwarded to ``t_from`` in windows of :data:`~folder_line.core.line.model.WINDOW` s, keeping nothing.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from folder_line.analysis.gap_cycles import without_unjudged
from folder_line.analysis.recording import Recording
from folder_line.analysis.streaming import WINDOW, window_ends
from folder_line.core.line.model import WINDOW as FAST_FORWARD
from folder_line.core.line.stream import LineStream
from folder_line.core.types.events import EVENT_KINDS
from folder_line.errors import FolderLineError
from folder_line.files.json_types import JsonObject
from folder_line.interfaces import NS_PER_S

__all__ = ['MAX_DIFFERENCES', 'EventCheck', 'EventDifference', 'compare_events']

#: the differences between the recorded events and the model's listed at most
MAX_DIFFERENCES = 10
#: an event this close (ns) before a window's end may round into the next window: compared there too
_CARRY_NS = 1000


@dataclass(frozen=True)
class EventDifference:
    """A recorded event the line model has not, or with another value (or the model's the recording has not).

    Attributes
    ----------
    t : float
        The event's time, s (its ns).
    kind : str
    sheet, cycle : int
    recorded, model : float or None
        The event's value on each side; None where the event is missing.
    """

    t: float
    kind: str
    sheet: int
    cycle: int
    recorded: float | None
    model: float | None

    def as_json(self) -> JsonObject:
        """``{'t', 'kind', 'sheet', 'cycle', 'recorded', 'model'}``."""
        return {
            't': self.t,
            'kind': self.kind,
            'sheet': self.sheet,
            'cycle': self.cycle,
            'recorded': self.recorded,
            'model': self.model,
        }


@dataclass
class EventCheck:
    """The recorded events against the line model's (:func:`compare_events`).

    Attributes
    ----------
    t_from, t_end : float
        The span compared, s (from ``t_from`` -- its ns -- to ``t_end``).
    recorded, model : int
        Events compared, of the recording and of the model.
    matched : int
        Recorded events with a model event of the same time (ns), kind, sheet and cycle.
    values_differ : int
        Of those, the ones whose value differs.
    largest_difference : float
        The largest ``|recorded - model| / max(|recorded|, |model|)`` of a value that differs
        (0 if none).
    recorded_only, model_only : int
        Events with no counterpart on the other side.
    differences : list of EventDifference
        The first :data:`MAX_DIFFERENCES` differences.
    windows : int
        Windows of the model compared.
    error : str or None
        Why the model could not be replayed (None if it was).
    """

    t_from: float
    t_end: float
    recorded: int = 0
    model: int = 0
    matched: int = 0
    values_differ: int = 0
    largest_difference: float = 0.0
    recorded_only: int = 0
    model_only: int = 0
    differences: list[EventDifference] = field(default_factory=list)
    windows: int = 0
    error: str | None = None

    @property
    def agree(self) -> bool:
        """Every recorded event is the model's, value bit for bit, and none is missing."""
        return self.error is None and self.values_differ == 0 and self.recorded_only == 0 and self.model_only == 0

    def as_json(self) -> JsonObject:
        """JSON-ready, with :meth:`text` as ``text``."""
        return {
            'agree': self.agree,
            'text': self.text(),
            't_from': self.t_from,
            't_end': self.t_end,
            'recorded': self.recorded,
            'model': self.model,
            'matched': self.matched,
            'values_differ': self.values_differ,
            'largest_difference': self.largest_difference,
            'recorded_only': self.recorded_only,
            'model_only': self.model_only,
            'differences': [d.as_json() for d in self.differences],
            'windows': self.windows,
            'error': self.error,
        }

    def text(self) -> str:
        """The outcome in one sentence."""
        if self.error is not None:
            return f'the line model could not be replayed: {self.error}'
        span = f'{self.recorded} recorded events from {self.t_from:.9g} to {self.t_end:.9g} s'
        if self.agree:
            return f"{span}: every one is the line model's (time to the ns, kind, sheet, cycle, value bit for bit)"
        parts = []
        if self.values_differ:
            parts.append(
                f'{self.values_differ} with another value (largest relative difference {self.largest_difference:.3g})'
            )
        if self.recorded_only:
            parts.append(f'{self.recorded_only} not in the model')
        if self.model_only:
            parts.append(f'{self.model_only} of the model not recorded')
        return f'{span}, {self.model} of the model: ' + '; '.join(parts)


_KEY = np.dtype([('ns', 'i8'), ('kind', 'i2'), ('sheet', 'i8'), ('cycle', 'i8'), ('value', 'f8')])


def _keys(ns: np.ndarray, events: np.ndarray) -> np.ndarray:
    out = np.zeros(events.size, dtype=_KEY)
    out['ns'] = ns
    for name in ('kind', 'sheet', 'cycle', 'value'):
        out[name] = events[name]
    return out


def _sorted(rows: np.ndarray) -> np.ndarray:
    out: np.ndarray = rows[np.lexsort((rows['value'], rows['cycle'], rows['sheet'], rows['kind'], rows['ns']))]
    return out


class _Comparison:
    """Recorded and model events matched window by window (an event within :data:`_CARRY_NS` of a window's
    end unmatched there is tried again in the next window: its ns may round across the cut)."""

    def __init__(self, check: EventCheck) -> None:
        self.check = check
        self.rec_carry = np.zeros(0, dtype=_KEY)
        self.mod_carry = np.zeros(0, dtype=_KEY)

    def _differ(self, row: np.void, recorded: float | None, model: float | None) -> None:
        ck = self.check
        if len(ck.differences) < MAX_DIFFERENCES:
            ck.differences.append(
                EventDifference(
                    int(row['ns']) / NS_PER_S,
                    EVENT_KINDS[int(row['kind'])],
                    int(row['sheet']),
                    int(row['cycle']),
                    recorded,
                    model,
                )
            )

    def window(self, recorded: np.ndarray, model: np.ndarray, end_ns: int | None) -> None:
        """Match a window's events (``end_ns`` its end; None: the last window, nothing carried on)."""
        ck = self.check
        ck.recorded += recorded.size
        ck.model += model.size
        r = _sorted(np.concatenate((self.rec_carry, recorded)))
        m = _sorted(np.concatenate((self.mod_carry, model)))
        a, b, r_only, m_only = _pair(r, m)
        self._values(a, b)
        if end_ns is None:
            self.rec_carry, self.mod_carry = np.zeros(0, dtype=_KEY), np.zeros(0, dtype=_KEY)
        else:
            near_r, near_m = r_only['ns'] > end_ns - _CARRY_NS, m_only['ns'] > end_ns - _CARRY_NS
            self.rec_carry, self.mod_carry = r_only[near_r], m_only[near_m]
            r_only, m_only = r_only[~near_r], m_only[~near_m]
        ck.recorded_only += r_only.size
        ck.model_only += m_only.size
        for row in r_only:
            self._differ(row, float(row['value']), None)
        for row in m_only:
            self._differ(row, None, float(row['value']))

    def _values(self, a: np.ndarray, b: np.ndarray) -> None:
        """Count the matched pairs ``a[i]``, ``b[i]`` and those whose values differ."""
        ck = self.check
        same = a['value'] == b['value']
        ck.matched += a.size
        diff = np.flatnonzero(~same)
        ck.values_differ += diff.size
        if diff.size:
            va, vb = a['value'][diff], b['value'][diff]
            scale = np.maximum(np.abs(va), np.abs(vb))
            rel = np.abs(va - vb) / np.where(scale > 0.0, scale, 1.0)
            ck.largest_difference = max(ck.largest_difference, float(rel.max()))
            for i in diff[: MAX_DIFFERENCES - len(ck.differences)].tolist():
                self._differ(a[i], float(a['value'][i]), float(b['value'][i]))


def _pair(r: np.ndarray, m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Recorded events ``r`` and model events ``m`` (both :func:`_sorted`) paired by time (ns), kind, sheet
    and cycle.

    Returns
    -------
    a, b, r_only, m_only : ndarray
        The paired rows of each side (``a[i]`` with ``b[i]``), and the rows with no counterpart.
    """
    key = ['ns', 'kind', 'sheet', 'cycle']
    if r.size == m.size and all(np.array_equal(r[k], m[k]) for k in key):
        return r, m, np.zeros(0, dtype=_KEY), np.zeros(0, dtype=_KEY)
    pool: dict[tuple[int, int, int, int], list[int]] = {}  # some differ: pair them by key
    for j, row in enumerate(m[key].tolist()):
        pool.setdefault(row, []).append(j)
    ri, mi, lone = [], [], []
    for i, row in enumerate(r[key].tolist()):
        js = pool.get(row)
        if js:
            ri.append(i)
            mi.append(js.pop(0))
        else:
            lone.append(i)
    used = np.zeros(m.size, dtype=bool)
    used[mi] = True
    return r[ri], m[mi], r[lone], m[~used]


def _model_ns(events: np.ndarray) -> np.ndarray:
    """A model event's time as a node publishes it (``time_ref``: rounded to the ns, not before 0)."""
    return np.maximum(0, np.round(events['t'] * NS_PER_S).astype(np.int64))


def compare_events(
    rec: Recording, t_from: float = 0.0, *, window: float = WINDOW, fast_forward: float = FAST_FORWARD
) -> EventCheck:
    """The recorded events against the streamed line's, window by window (see the module docstring).

    Parameters
    ----------
    rec : Recording
    t_from : float, optional
        Compare from this line time on, s (``analyze --from``): the line is fast-forwarded there first.
    window : float, optional
        Line time per window compared, s (> 0). The result does not depend on it.
    fast_forward : float, optional
        Line time per window of the fast-forward, s (> 0).

    Returns
    -------
    EventCheck
        With ``error`` set if the line model cannot be built under the recorded commands.
    """
    check = EventCheck(t_from, rec.t_end)
    try:
        stream = LineStream(rec.scene, rec.commands)
    except (FolderLineError, ValueError) as exc:
        check.error = f'{type(exc).__name__}: {exc}'
        return check
    cmp = _Comparison(check)
    from_ns = round(t_from * NS_PER_S)
    pending = np.zeros(0, dtype=_KEY)  # the model's events at t_from (to the ns) from the fast-forward
    start = max(t_from, 0.0)
    if t_from > 0.0:  # fast-forward: nothing kept but the last window's events at t_from
        for cut in window_ends(0.0, t_from, fast_forward):
            w = stream.advance(cut)
        ns = _model_ns(w.events)
        keep = (ns >= from_ns) & without_unjudged(w.events, rec.unjudged)
        pending = _keys(ns[keep], w.events[keep])
    events, event_ns = rec.events, rec.event_ns
    lo = int(np.searchsorted(event_ns, from_ns, side='left'))
    cuts = window_ends(start, rec.t_end, window) if rec.t_end >= start else []
    for n, cut in enumerate(cuts, start=1):
        w = stream.advance(cut)
        last = n == len(cuts)
        end_ns = round(cut * NS_PER_S)
        hi = events.size if last else int(np.searchsorted(event_ns, end_ns, side='right'))
        judged = without_unjudged(w.events, rec.unjudged)  # a gap's cycles are not in the recording either
        model = np.concatenate((pending, _keys(_model_ns(w.events[judged]), w.events[judged])))
        pending = np.zeros(0, dtype=_KEY)
        cmp.window(_keys(event_ns[lo:hi], events[lo:hi]), model, None if last else end_ns)
        lo = hi
        check.windows += 1
    if pending.size:  # no window after the fast-forward
        cmp.window(_keys(event_ns[lo:], events[lo:]), pending, None)
    return check
