"""The numbers of a recorded run's analysis (:class:`AnalysisSummary`): what ``report.md`` and
``folder-line analyze`` tell of it.

The recorded events judged (:class:`~folder_line.core.line.line_summary.SpanSummary`), and the run's
own figures besides: the span read, the messages recorded and lost, the recorded events against the
line model, the supervisor's state transitions (recorded and replayed), the gaps of a repaired bag.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from folder_line.analysis.event_check import EventCheck
from folder_line.analysis.supervisor_replay import StateTransition
from folder_line.bag.gaps import Gap
from folder_line.core.line.line_summary import SpanSummary
from folder_line.core.supervision.records import Violation as SupervisorViolation
from folder_line.interfaces import NS_PER_S

__all__ = ['AnalysisSummary']


@dataclass(frozen=True)
class AnalysisSummary(SpanSummary):
    """The numbers of :func:`folder_line.analysis.report.analyze`: the recorded events judged, and the run's.

    Attributes
    ----------
    t_end : float
        The line time the bag reaches (up to ``--to``), s.
    t_from : float
        Start of the span analysed, s (0 without ``--from``).
    sheet_counter : int or None
        The last count published by the sheet counter (None if none was recorded).
    messages : dict of str to int
        Topic -> messages recorded.
    lost : dict of str to int or None
        Topic -> messages lost, as ``run.json`` has it (None without ``run.json`` or the figure).
    events_check : EventCheck
        The recorded events against the line model's.
    recorded_transitions : list of StateTransition
        The states recorded on ``/line/supervisor/state``.
    gaps : list of Gap
        A repaired bag's line time whose messages may be lost (empty for a whole bag).
    unjudged : str
        The cycles and leaves not judged for the gaps (``''`` if none).
    transitions : list of StateTransition
        The supervisor's transitions: the replayed ones, or the recorded ones if the replay failed.
    replay_matches : bool or None
        Whether the replayed transitions agree with the recorded ones (None if the replay failed).
    replay_violations : list of folder_line.core.supervision.records.Violation or None
        The violations as the replayed supervisor decided them (None if the replay failed).
    transitions_source : str
        Where :attr:`transitions` come from, and whether they agree with the recorded states.
    """

    t_end: float
    t_from: float
    sheet_counter: int | None
    messages: dict[str, int]
    lost: dict[str, int] | None
    events_check: EventCheck
    recorded_transitions: list[StateTransition]
    gaps: list[Gap]
    unjudged: str
    transitions: list[StateTransition]
    replay_matches: bool | None
    replay_violations: list[SupervisorViolation] | None
    transitions_source: str

    def as_json(self) -> dict[str, object]:
        """The judged numbers (:meth:`~folder_line.core.line.line_summary.SpanSummary.as_json`), then the
        run's; gaps in s as ``[first, last]``, ``replay_violations`` only if the replay ran."""
        out: dict[str, object] = {
            **super().as_json(),
            't_end': self.t_end,
            't_from': self.t_from,
            'sheet_counter': self.sheet_counter,
            'messages': dict(self.messages),
            'lost': None if self.lost is None else dict(self.lost),
            'events_check': self.events_check.as_json(),
            'recorded_transitions': [t.as_json() for t in self.recorded_transitions],
            'gaps': [[g.first_ns / NS_PER_S, g.last_ns / NS_PER_S] for g in self.gaps],
            'unjudged': self.unjudged,
            'transitions': [t.as_json() for t in self.transitions],
            'replay_matches': self.replay_matches,
        }
        if self.replay_violations is not None:
            out['replay_violations'] = [dataclasses.asdict(v) for v in self.replay_violations]
        out['transitions_source'] = self.transitions_source
        return out
