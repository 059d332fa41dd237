"""``folder-line analyze RUN_DIR|BAG [--out DIR] [--csv]``: the analysis of a recorded run, written.

:func:`analyze` reads a run's bag (:func:`folder_line.analysis.recording.read_recording`),
judges it (:func:`folder_line.analysis.replay.evaluate`), replays the supervisor
(:func:`folder_line.analysis.supervisor_replay.replay_transitions`) and writes to ``--out``
(default ``RUN_DIR/analysis``)

``report.md``
    the run's numbers -- cycles, sheets counted, per-constraint minimum margins, the
    violations (cycle, constraint, margin), whether the recorded events are the line
    model's (:func:`folder_line.analysis.event_check.compare_events`), the supervisor's state
    transitions (replayed, and whether they agree with the recorded ones), the messages
    recorded and lost -- and the figures;
the figures
    those of :data:`folder_line.analysis.figures.FIGURES` the scene has
    (:func:`folder_line.analysis.figures.draw_figures`);
``csv/<topic>.csv`` (``--csv``)
    every message of every topic of the bag, one row each
    (:mod:`folder_line.analysis.csv_export`).

The numbers of ``report.md`` are those of ``simulate(scene, t_end, commands=...)`` for a
run of ``t_end`` s: the recorded events are judged by the line's own constraint code.
:func:`print_analysis` prints the headline numbers, as ``folder-line analyze`` does.

Memory: the recording holds the events and a bounded sample of the joint states
(:func:`folder_line.analysis.recording.read_recording`); the judging, the comparison with
the line model and the figures go through the run window by window of line time and keep
running figures only (:mod:`folder_line.analysis.replay`, :mod:`folder_line.analysis.streaming`),
so what ``analyze`` holds besides the recording does not grow with the run's line time (but
for the list of violations, which the report lists in full).
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import IO, cast

import numpy as np

from folder_line.analysis.csv_export import CsvCollector
from folder_line.analysis.event_check import EventCheck, compare_events
from folder_line.analysis.figure_data import GANTT_CYCLES
from folder_line.analysis.figures import FIGURES, draw_figures
from folder_line.analysis.recording import Recording, read_recording
from folder_line.analysis.replay import Evaluation, evaluate
from folder_line.analysis.summary import AnalysisSummary
from folder_line.analysis.supervisor_replay import (
    StateTransition,
    recorded_transitions,
    replay_transitions,
    transitions_agree,
)
from folder_line.bag.gaps import describe_gaps
from folder_line.bag.metadata import files_text
from folder_line.core.line.margin_text import MARGIN_MEANINGS, margin_at, margin_text
from folder_line.core.supervision.records import Violation as SupervisorViolation
from folder_line.errors import FolderLineError, ParameterError
from folder_line.files.atomic import claim_output_dir, write_text_atomic
from folder_line.interfaces import NS_PER_S

__all__ = ['AnalysisResult', 'analyze', 'print_analysis']


@dataclass(frozen=True, eq=False)
class AnalysisResult:
    """What :func:`analyze` wrote and computed.

    Attributes
    ----------
    out : Path
        The output directory.
    report : Path
        ``report.md``.
    figures : dict of str to Path
        Figure file name -> path, for the figures the scene has.
    csv : dict of str to Path
        Topic -> its CSV (empty without ``csv=True``).
    summary : AnalysisSummary
        The numbers of the report.
    recording : Recording
    evaluation : Evaluation
        The recorded events judged (:func:`folder_line.analysis.replay.evaluate`): every
        constraint's running figures, the violations.
    events_check : EventCheck
        The recorded events against the line model's.
    """

    out: Path
    report: Path
    figures: dict[str, Path]
    csv: dict[str, Path]
    summary: AnalysisSummary
    recording: Recording
    evaluation: Evaluation
    events_check: EventCheck


def _margin(name: str, value: float, unit: str) -> str:
    """A margin in report.md: its unit of the text, to the ns or the nm (6 decimals of ms, mm)."""
    return margin_text(value, unit, name, precision=6)


def _report_lines(
    rec: Recording,
    ev: Evaluation,
    check: EventCheck,
    summary: AnalysisSummary,
    figures: Mapping[str, Path],
    csv_files: Mapping[str, Path],
) -> list[str]:
    """The lines of ``report.md``, section by section."""
    return [
        *_head_lines(rec, check, summary),
        *_model_lines(check),
        *_constraint_lines(summary),
        *_violation_lines(ev, summary),
        *_transition_lines(summary),
        *_message_lines(rec, summary),
        *_file_lines(figures, csv_files),
    ]


def _head_lines(rec: Recording, check: EventCheck, summary: AnalysisSummary) -> list[str]:
    """The title, the run's description and the summary table."""
    scene = rec.scene
    bag = rec.bag
    lines = [
        f'# Analysis of the run: scene `{scene.name}`',
        '',
        f'- bag: `{bag.path}` ({files_text(len(bag.files))}, {bag.message_count} messages)',
        f'- effects: {", ".join(scene.effects) or "none"}; seed {scene.seed}',
        f'- line time reached: {rec.t_end:.9g} s'
        + (f'; window analysed: {summary.t_from:.9g} .. {rec.t_end:.9g} s' if summary.t_from else '')
        + '; drive commands and tunings recorded: '
        + (', '.join(f'{c.kind} at {c.t:.9g} s' for c in rec.commands) or 'none'),
        (
            "- numbers: the recorded events judged by the line's constraint code "
            '(`folder_line.core.line.constraints`), as `simulate(scene, line time reached)` judges its own'
        ),
        *(
            [
                f'- **a repaired bag with {describe_gaps(rec.gaps)}** of line time whose messages may be lost: '
                f'{rec.unjudged.text() or "no cycle"} not judged (nor counted below), the supervisor replayed '
                f'up to {rec.gaps[0].first_ns / NS_PER_S:.9g} s'
            ]
            if rec.gaps
            else []
        ),
        '',
        '## Summary',
        '',
        '| quantity | value |',
        '|---|---|',
        f'| cycles | {summary.cycles} |',
        f'| sheets counted | {summary.sheets_counted} |',
        (
            f'| sheets counted by sheet_counter (last /line/sheet_counter/count) | '
            f'{"-" if rec.sheet_count is None else rec.sheet_count} |'
        ),
        f'| events | {int(rec.events.size)} |',
        f'| violations | {summary.violations.count} |',
        f"| recorded events equal to the line model's | {'yes' if check.agree else 'no'} |",
    ]
    if rec.bad_events:
        lines.append(f'| /line/events messages that are not events | {rec.bad_events} |')
    return lines


def _model_lines(check: EventCheck) -> list[str]:
    """The section on the recorded events against the line model, with the first differences."""
    lines = ['', '## The recorded events and the line model', '']
    lines.append(
        'The streamed line model under the recorded drive commands and tunings, replayed window by window '
        f'({check.windows} window{"" if check.windows == 1 else "s"}) and compared with the recorded events of each '
        f'window: {check.text()}.'
    )
    if check.differences:
        lines += ['', '| t, s | kind | sheet | cycle | recorded value | model value |', '|---|---|---|---|---|---|']
        lines += [
            f'| {d.t:.9f} | {d.kind} | {d.sheet} | {d.cycle} | '
            f'{"-" if d.recorded is None else repr(d.recorded)} | '
            f'{"-" if d.model is None else repr(d.model)} |'
            for d in check.differences
        ]
        more = check.values_differ + check.recorded_only + check.model_only - len(check.differences)
        if more > 0:
            lines += ['', f'... and {more} more.']
    return lines


def _constraint_lines(summary: AnalysisSummary) -> list[str]:
    """The events counted by kind and every constraint's smallest margin, with what the margins mean."""
    lines = ['', '## Events', '', '| kind | count |', '|---|---|']
    lines += [f'| {k} | {n} |' for k, n in summary.events.items()]
    lines += [
        '',
        '## Constraints',
        '',
        'Margins >= 0 pass; times in ms, lengths in mm, speeds in m/s (the CSV and JSON keep SI units).',
        '',
        '| constraint | evaluations | smallest margin | at | violations |',
        '|---|---|---|---|---|',
    ]
    for name, m in summary.min_margin.items():
        lines.append(
            f'| {name} | {m.evaluations} | {_margin(name, m.margin, m.unit)} | {margin_at(name, m.cycle)} '
            f'| {m.violations} |'
        )
    if not summary.min_margin:
        lines.append('| (none evaluated) | | | | |')
    else:
        lines += ['', 'What the margins mean:', '']
        lines += [f'- `{name}`: {MARGIN_MEANINGS[name]}' for name in summary.min_margin if name in MARGIN_MEANINGS]
    return lines


def _violation_lines(ev: Evaluation, summary: AnalysisSummary) -> list[str]:
    """Every violated row, with its decision time."""
    lines = ['', '## Violations', '']
    viol = summary.violations.first
    if viol:
        decided = {(v.constraint, v.cycle): v.t for v in ev.violations}
        lines += ['| cycle or leaf | constraint | margin | decided at t, s |', '|---|---|---|---|']
        lines += [
            f'| {margin_at(v.constraint, v.cycle)} | {v.constraint} | '
            f'{_margin(v.constraint, v.margin, v.unit)} | '
            f'{decided.get((v.constraint, v.cycle), float("nan")):.9g} |'
            for v in viol
        ]
    else:
        lines.append('No constraint was violated.')
    return lines


def _transition_lines(summary: AnalysisSummary) -> list[str]:
    """The supervisor's state transitions, the recorded states and the violations as the replay decided them."""
    lines = ['', '## State transitions', '', f'Source: {summary.transitions_source}.', '']
    recorded = summary.recorded_transitions
    shown: dict[str, float] = {}
    for tr in recorded:
        shown.setdefault(tr.target, tr.t)
    if summary.transitions:
        lines += ['| t, s | from | to | cause | first recorded on /line/supervisor/state, s |', '|---|---|---|---|---|']
        lines += [
            f'| {tr.t:.9g} | {tr.source or "(first state)"} | {tr.target} | {tr.cause or ""} | {shown[tr.target]:.9g} |'
            if tr.target in shown
            else f'| {tr.t:.9g} | {tr.source or "(first state)"} | {tr.target} | {tr.cause or ""} | - |'
            for tr in summary.transitions
        ]
    else:
        lines.append('No state transition.')
    lines += [
        '',
        'Recorded states: ' + (' -> '.join(f'{tr.target} ({tr.t:.3f} s)' for tr in recorded) or 'none') + '.',
    ]
    replayed = summary.replay_violations
    if replayed:
        lines += [
            '',
            '### Violations as the supervisor decided them (replay, causal)',
            '',
            '| t, s | cycle or leaf | constraint | margin | action | state |',
            '|---|---|---|---|---|---|',
        ]
        lines += [
            f'| {v.t:.9g} | {margin_at(v.constraint, v.cycle)} | {v.constraint} | '
            f'{_margin(v.constraint, v.margin, v.unit)} | {v.action} | {v.state} |'
            for v in replayed
        ]
    return lines


def _message_lines(rec: Recording, summary: AnalysisSummary) -> list[str]:
    """The messages recorded, published and lost per topic."""
    lines = ['', '## Messages', '']
    published = rec.bag.published
    lost = summary.lost
    lines += ['| topic | type | recorded | published | lost |', '|---|---|---|---|---|']
    for topic, info in rec.bag.topics.items():
        pub = '-' if published is None else published.get(topic, '-')
        ls = '-' if lost is None else lost.get(topic, '-')
        lines.append(f'| {topic} | {info.type} | {info.count} | {pub} | {ls} |')
    if rec.run is not None and rec.run.get('loss_accounting'):
        lines += ['', f'Loss accounting (run.json): {rec.run["loss_accounting"]}.']
    elif rec.run is None:
        lines += ['', 'No run.json: lost messages unknown.']
    return lines


def _file_lines(figures: Mapping[str, Path], csv_files: Mapping[str, Path]) -> list[str]:
    """The CSV files written and the figures, drawn or not."""
    lines: list[str] = []
    if csv_files:
        lines += [
            '',
            '## CSV',
            '',
            f'One file per topic in `csv/` ({len(csv_files)} files): '
            + ', '.join(f'`{p.name}`' for p in csv_files.values())
            + '.',
        ]
    lines += ['', '## Figures', '']
    for name, path in figures.items():
        lines += [f'**{name}**: {FIGURES[name]}.', '', f'![{path.stem}]({path.name})', '']
    missing = [n for n in FIGURES if n not in figures]
    if missing:
        lines.append('Not drawn (the scene has no such part): ' + ', '.join(missing) + '.')
    return lines


def analyze(
    path: str | os.PathLike[str],
    out: str | os.PathLike[str] | None = None,
    csv: bool = False,
    *,
    gantt_cycles: int = GANTT_CYCLES,
    t_from: float | None = None,
    t_to: float | None = None,
    before_writing: Callable[[Recording], None] | None = None,
) -> AnalysisResult:
    """Analyse a recorded run: figures, ``report.md`` and, with ``csv``, one CSV per topic.

    Parameters
    ----------
    path : path-like
        A run directory (``run.json``, ``bag/``) or a bag directory.
    out : path-like, optional
        Output directory; default ``<run directory>/analysis`` (the bag's parent
        directory when a bag is given).
    csv : bool
        Also write ``csv/<topic>.csv`` for every topic of the bag.
    gantt_cycles : int
        Cycles in the cyclogram (>= 1).
    t_from, t_to : float, optional
        The window of line time analysed, s (``--from``, ``--to``): the bag is read up to
        ``t_to`` only (the run as if it ended there: its numbers are those of
        ``simulate(scene, t_to)``), and the report's numbers, the figures and the CSVs
        cover ``[t_from, t_to]``; every event before ``t_from`` is still judged, since a
        cycle needs those before it.
    before_writing : callable, optional
        Called with the recording once it is read, before anything is written (``analyze --animate``
        checks its window there: a refusal leaves nothing behind).

    Returns
    -------
    AnalysisResult

    Raises
    ------
    ParameterError, BagError
        A bad path, a bag that cannot be read or holds no valid scene.
    """
    if not (isinstance(gantt_cycles, int) and gantt_cycles >= 1):
        raise ParameterError('gantt_cycles', gantt_cycles, 'must be a whole number >= 1')
    if t_from is not None and t_to is not None and t_to <= t_from:
        raise ParameterError('--to', t_to, f'must be after --from ({t_from:g} s)')
    start = 0.0 if t_from is None else t_from
    collector = CsvCollector() if csv else None
    start_ns = round(start * NS_PER_S)

    def collect(topic: str, t_ns: int, msg: object) -> None:
        if collector is not None and t_ns >= start_ns:
            collector(topic, t_ns, msg)

    try:
        rec = read_recording(path, collect if collector is not None else None, t_to=t_to, t_from=start)
        if start >= rec.t_end and start > 0.0:
            raise ParameterError('--from', start, f'at or after the line time the bag reaches ({rec.t_end:.9g} s)')
        if before_writing is not None:
            before_writing(rec)
        out_dir = Path(rec.bag.path).parent / 'analysis' if out is None else Path(out)
        with claim_output_dir(out_dir, '--out', files=('report.md', *FIGURES), dirs=('csv',) if csv else ()):
            return _write_analysis(rec, out_dir, collector, gantt_cycles, start)
    finally:
        if collector is not None:
            collector.close()


def _window(rec: Recording, t_from: float) -> Recording:
    """``rec`` with its events from ``t_from`` on (what the figures show; the joint
    states were read from ``t_from`` on): views of its tables (sorted by time), no copy."""
    if t_from <= 0.0:
        return rec
    i = int(np.searchsorted(rec.event_ns, round(t_from * NS_PER_S), side='left'))
    return dataclasses.replace(rec, events=rec.events[i:], event_ns=rec.event_ns[i:])


def _write_analysis(
    rec: Recording, out_dir: Path, collector: CsvCollector | None, gantt_cycles: int, t_from: float = 0.0
) -> AnalysisResult:
    """The evaluation, plots, CSVs and report of :func:`analyze`, into the claimed ``out_dir``."""
    if collector is not None:  # every CSV target is checked before anything is written
        collector.check(out_dir / 'csv', list(rec.bag.topics), '--out')
    ev = evaluate(rec, t_from, keep_cycles=gantt_cycles)
    check = compare_events(rec, t_from)
    summary = _summary(rec, ev, check, t_from)
    figures = draw_figures(_window(rec, t_from), ev, out_dir, gantt_cycles)
    csv_files = collector.write(out_dir / 'csv', list(rec.bag.topics)) if collector is not None else {}
    report = write_text_atomic(
        out_dir / 'report.md', '\n'.join(_report_lines(rec, ev, check, summary, figures, csv_files)) + '\n'
    )
    return AnalysisResult(
        out=out_dir,
        report=report,
        figures=figures,
        csv=csv_files,
        summary=summary,
        recording=rec,
        evaluation=ev,
        events_check=check,
    )


def _summary(rec: Recording, ev: Evaluation, check: EventCheck, t_from: float) -> AnalysisSummary:
    """The numbers of the report: the recorded events judged (``ev``), the run's, the supervisor replayed."""
    recorded = recorded_transitions(rec.states)
    transitions, matches, violations, source = _replayed(rec, recorded)
    judged = ev.summary
    return AnalysisSummary(
        **{f.name: getattr(judged, f.name) for f in dataclasses.fields(judged)},
        t_end=rec.t_end,
        t_from=t_from,
        sheet_counter=rec.sheet_count,
        messages={t: s.count for t, s in rec.bag.topics.items()},
        lost=None if rec.run is None else cast('dict[str, int] | None', rec.run.get('lost')),  # as run writes it
        events_check=check,
        recorded_transitions=recorded,
        gaps=list(rec.gaps),
        unjudged=rec.unjudged.text(),
        transitions=transitions,
        replay_matches=matches,
        replay_violations=violations,
        transitions_source=source,
    )


def _replayed(
    rec: Recording, recorded: list[StateTransition]
) -> tuple[list[StateTransition], bool | None, list[SupervisorViolation] | None, str]:
    """The supervisor's transitions of the report (replayed, or ``recorded`` if the replay fails), whether they
    agree with ``recorded``, the violations as the replay decided them and where the transitions come from
    (:class:`~folder_line.analysis.summary.AnalysisSummary`'s ``transitions`` .. ``transitions_source``)."""
    if rec.gaps:  # the replay stops at the first gap: compared with what was recorded before it
        recorded = [t for t in recorded if t.t * NS_PER_S < rec.gaps[0].first_ns]
    try:
        replayed, sup = replay_transitions(rec)
    except (FolderLineError, ValueError, TypeError) as exc:  # a stream the logic rejects: say so, keep the record
        return (
            recorded,
            None,
            None,
            'the states published on /line/supervisor/state (the replay through '
            f'folder_line.core.supervision.offline.replay failed: {type(exc).__name__}: {exc})',
        )
    matches = transitions_agree(replayed, recorded)
    source = (
        'the recorded events, NaN/inf values, lost participants and operator commands replayed in lockstep '
        'through '
        'folder_line.core.supervision.offline.replay (decision times'
        + (f'; up to the first gap, at {rec.gaps[0].first_ns / NS_PER_S:.3f} s' if rec.gaps else '')
        + '); '
        + (
            'they agree with the states recorded on /line/supervisor/state'
            if matches
            else 'they do NOT agree with the states recorded on /line/supervisor/state: '
            + ' -> '.join(t.target for t in recorded)
        )
    )
    return replayed, matches, list(sup.violations), source


def print_analysis(result: AnalysisResult, stream: IO[str]) -> None:
    """What ``folder-line analyze`` prints: the headline numbers, whether the recorded events are the line
    model's, and the files written."""
    s = result.summary
    judged = ' judged' if s.gaps else ''
    print(
        f'scene {s.scene}: {s.t_end:.3f} s of line time, {s.cycles} cycles{judged}, '
        f'{s.sheets_counted} sheets counted, {s.violations.count} violations',
        file=stream,
    )
    for name, m in s.min_margin.items():
        print(
            f'  {name:<24} min margin {margin_text(m.margin, m.unit, name)}, at {margin_at(name, m.cycle)}, '
            f'{m.violations} of {m.evaluations} violated',
            file=stream,
        )
    if s.gaps:
        print(
            f'repaired bag with {describe_gaps(s.gaps)}: {s.unjudged or "no cycle"} not judged (events may be lost '
            f'there); states replayed up to {s.gaps[0].first_ns / NS_PER_S:.3f} s',
            file=stream,
        )
    if s.transitions:
        print('states: ' + ' -> '.join(t.target for t in s.transitions), file=stream)
    print(f'against the line model: {s.events_check.text()}', file=stream)
    print(f'wrote {result.report}', file=stream)
    for path in result.figures.values():
        print(f'wrote {path}', file=stream)
    if result.csv:
        print(f'wrote {len(result.csv)} CSV files to {result.out / "csv"}', file=stream)
