"""The summary of a run (:class:`LineSummary`) and of a window of one (:class:`WindowSummary`), and
what they share with ``analyze``'s judged numbers (:class:`SpanSummary`).

:meth:`folder_line.core.line.stream.LineStream.summary` makes a :class:`LineSummary` of the
events and constraint rows handed out; the ``simulate`` verb prints it and writes its
``as_json()`` (``--json``), whose numbers are the metrics
(:func:`folder_line.core.line.metrics.flatten_metrics`). ``simulate --from`` makes a
:class:`WindowSummary`. ``as_json()`` gives the JSON document, keys in the order written, an
optional key present only where the run has it.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

from folder_line.core.line.folder_figures import FolderFigures
from folder_line.core.line.layup_figures import LandingHistogram, LayupFigures

__all__ = [
    'JudgedFigures',
    'LineSummary',
    'MarginFigures',
    'SpanSummary',
    'TuningRecord',
    'ViolationRecord',
    'Violations',
    'WindowSummary',
]


@dataclass(frozen=True)
class ViolationRecord:
    """A violated row: its ``cycle`` (or leaf), the ``constraint``, its ``margin`` in the constraint's ``unit``."""

    cycle: int
    constraint: str
    margin: float
    unit: str

    def as_json(self) -> dict[str, object]:
        """``{'cycle', 'constraint', 'margin', 'unit'}``."""
        return asdict(self)


@dataclass(frozen=True)
class Violations:
    """The violated rows: how many, and the first ones listed (by cycle, then constraint)."""

    count: int
    first: list[ViolationRecord]

    def as_json(self) -> dict[str, object]:
        """``{'count', 'first'}``."""
        return {'count': self.count, 'first': [v.as_json() for v in self.first]}


@dataclass(frozen=True)
class MarginFigures:
    """A constraint's smallest margin (in its ``unit``), the first ``cycle`` (or leaf) with it, its rows
    judged (``evaluations``) and violated."""

    margin: float
    unit: str
    cycle: int
    evaluations: int
    violations: int

    def as_json(self) -> dict[str, object]:
        """``{'margin', 'unit', 'cycle', 'evaluations', 'violations'}``."""
        return asdict(self)


@dataclass(frozen=True)
class JudgedFigures:
    """The constraint rows and events of a run or a window: ``violations``, ``min_margin`` (constraint ->
    its smallest margin; constraints with rows only), ``events`` (kind -> count; kinds that occurred only)."""

    violations: Violations
    min_margin: dict[str, MarginFigures]
    events: dict[str, int]

    @property
    def min_margin_s(self) -> dict[str, float]:
        """The smallest margins of the constraints judged in seconds, s."""
        return _in_seconds(self.min_margin)

    def as_json(self) -> dict[str, object]:
        """``violations``, ``min_margin_s``, ``min_margin``, ``events``."""
        return {
            'violations': self.violations.as_json(),
            'min_margin_s': self.min_margin_s,
            'min_margin': {k: v.as_json() for k, v in self.min_margin.items()},
            'events': dict(self.events),
        }


@dataclass(frozen=True)
class TuningRecord:
    """An operator's tuning of a run (``simulate --tune``): from line time ``t`` (s) ``key`` = ``value`` (``unit``)."""

    t: float
    key: str
    value: float
    unit: str

    def as_json(self) -> dict[str, object]:
        """``{'t', 'key', 'value', 'unit'}``."""
        return asdict(self)


def _in_seconds(min_margin: dict[str, MarginFigures]) -> dict[str, float]:
    """Constraint -> smallest margin of those judged in seconds, s."""
    return {k: v.margin for k, v in min_margin.items() if v.unit == 's'}


@dataclass(frozen=True)
class SpanSummary:
    """What is judged of a span of line time: its scene, its counts, its constraint rows and events (the
    part of the ``simulate`` summary that does not depend on the parts; ``analyze``'s judged numbers).

    Attributes
    ----------
    scene : str
    duration_s : float
        Line time of the span, s.
    seed : int
    effects : list of str
    cycles : int
        Folder cycles (knife contacts), else crank cycles of the layup.
    sheets_counted : int
        Folder sheets counted, else leaves landed.
    violations : Violations
    min_margin : dict of str to MarginFigures
    events : dict of str to int
    """

    scene: str
    duration_s: float
    seed: int
    effects: list[str]
    cycles: int
    sheets_counted: int
    violations: Violations
    min_margin: dict[str, MarginFigures]
    events: dict[str, int]

    @property
    def min_margin_s(self) -> dict[str, float]:
        """The smallest margins of the constraints judged in seconds, s."""
        return _in_seconds(self.min_margin)

    @property
    def judged(self) -> JudgedFigures:
        """The violations, the smallest margins and the events."""
        return JudgedFigures(self.violations, self.min_margin, self.events)

    def as_json(self) -> dict[str, object]:
        """The fields in order, with ``min_margin_s`` after ``violations``."""
        return {
            'scene': self.scene,
            'duration_s': self.duration_s,
            'seed': self.seed,
            'effects': list(self.effects),
            'cycles': self.cycles,
            'sheets_counted': self.sheets_counted,
            **self.judged.as_json(),
        }


@dataclass(frozen=True)
class LineSummary(SpanSummary):
    """The summary of a run from line time 0 (the ``simulate`` verb's): :class:`SpanSummary`'s fields and
    the parts' figures.

    Attributes
    ----------
    folder : FolderFigures or None
    layup : LayupFigures or None
    tunings : list of TuningRecord or None
        The operator's tunings (``simulate --tune``; None: none given).
    """

    folder: FolderFigures | None = None
    layup: LayupFigures | None = None
    tunings: list[TuningRecord] | None = None

    def as_json(self) -> dict[str, object]:
        """The JSON document (``simulate --json``): :meth:`SpanSummary.as_json`, then ``v_tr_over_v_d``
        and the folder's figures, the layup's, and its ``landing_cv`` and ``landing_histogram`` with
        ``leaf_flight``."""
        out = super().as_json()
        if self.folder is not None:
            out['v_tr_over_v_d'] = self.folder.v_tr_over_v_d
            out['folder'] = self.folder.as_json()
        if self.layup is not None:
            out['layup'] = self.layup.as_json()
            if self.layup.landing is not None:
                out['landing_cv'] = self.layup.landing.histogram.cv
                out['landing_histogram'] = self.layup.landing.histogram.as_json()
        if self.tunings is not None:
            out['tunings'] = [tu.as_json() for tu in self.tunings]
        return out


@dataclass(frozen=True)
class WindowSummary(SpanSummary):
    """The summary of the window ``(from_s, to_s]`` of a run from 0 (``simulate --from``): what the line
    handed out in it (:class:`SpanSummary`'s fields, in the window), without the parts' figures.

    Attributes
    ----------
    from_s, to_s : float
        The window, line time s.
    landing : LandingHistogram or None
        The leaves landed in the window (with ``leaf_flight``).
    tunings : list of TuningRecord or None
    """

    from_s: float = 0.0
    to_s: float = 0.0
    landing: LandingHistogram | None = None
    tunings: list[TuningRecord] | None = None

    def as_json(self) -> dict[str, object]:
        """The JSON document (``simulate --from --json``): ``from_s`` and ``to_s`` after ``scene``."""
        span = super().as_json()
        out: dict[str, object] = {'scene': span.pop('scene'), 'from_s': self.from_s, 'to_s': self.to_s, **span}
        if self.landing is not None:
            out['landing_cv'] = self.landing.cv
            out['landing_histogram'] = self.landing.as_json()
        if self.tunings is not None:
            out['tunings'] = [tu.as_json() for tu in self.tunings]
        return out
