"""The summary of a ``folder-line run`` (``run.json``), its verdict and its human-readable form.

:class:`RunSummary` holds what :func:`folder_line.ros.run.run_line` found: the run's
figures, what the recorder received, the simulation's figures of the same span
(:class:`ExpectedFromSimulate`) and the bag's account (:class:`BagAccount`).
:meth:`RunSummary.as_json` is the ``run.json`` document; :func:`outcome` says whether
the run ended as the scene expects (:class:`Outcome`); :func:`print_run_summary`
prints the end of ``folder-line run``.

This module does not load rclpy.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import IO, Literal

from folder_line.bag.metadata import files_text
from folder_line.core.line.tuning import Tuning
from folder_line.files.json_types import JsonObject

__all__ = ['BagAccount', 'ExpectedFromSimulate', 'Outcome', 'RunSummary', 'outcome', 'print_run_summary']


@dataclass(frozen=True)
class ExpectedFromSimulate:
    """What ``simulate`` finds over the span the line ran, with the operator's tunings.

    Attributes
    ----------
    sheets_counted : int
        Sheets the counter counts.
    events : dict of str to int
        Events per kind (the kinds that occur).
    violations : int
        Constraint violations.
    """

    sheets_counted: int
    events: dict[str, int]
    violations: int

    def as_json(self) -> JsonObject:
        """The ``expected_from_simulate`` object of ``run.json``."""
        return {'sheets_counted': self.sheets_counted, 'events': dict(self.events), 'violations': self.violations}


@dataclass(frozen=True)
class BagAccount:
    """The run's bag and its loss accounting.

    Attributes
    ----------
    path : str
        The bag directory.
    files : int
        Its ``.mcap`` files.
    messages : dict of str to int
        Messages recorded per topic, by topic.
    published : dict of str to int or None
        Messages published per recorded topic; None when the publishers run in other processes.
    lost : dict of str to int or None
        Per recorded topic, published - recorded - ``after_last_tick``; None with ``published``.
    after_last_tick : dict of str to int
        Per topic (non-zero only), messages of ticks after the last one recorded (a stopped line): not lost.
    loss_accounting : str
        How ``published`` and ``lost`` were counted, in words.
    """

    path: str
    files: int
    messages: dict[str, int]
    published: dict[str, int] | None
    lost: dict[str, int] | None
    after_last_tick: dict[str, int]
    loss_accounting: str

    def as_json(self) -> JsonObject:
        """Its keys of ``run.json``: ``bag``, ``published``, ``lost``, ``after_last_tick``, ``loss_accounting``."""
        return {
            'bag': {'path': self.path, 'files': self.files, 'messages': dict(self.messages)},
            'published': None if self.published is None else dict(self.published),
            'lost': None if self.lost is None else dict(self.lost),
            'after_last_tick': dict(self.after_last_tick),
            'loss_accounting': self.loss_accounting,
        }


@dataclass(frozen=True)
class Outcome:
    """Whether a run ended as the scene expects (:func:`outcome`).

    Attributes
    ----------
    ok : bool
        The run succeeded.
    expected_state : str or None
        The supervisor state ``simulate`` expects at the end (EXECUTE), None when it expects violations.
    state : str
        The supervisor state the line ended in ('' if none was received).
    message : str
        One line: what happened, or why the run failed.
    """

    ok: bool
    expected_state: str | None
    state: str
    message: str

    def as_json(self) -> JsonObject:
        """The ``outcome`` object of ``run.json``."""
        return {'ok': self.ok, 'expected_state': self.expected_state, 'state': self.state, 'message': self.message}


@dataclass(frozen=True)
class RunSummary:
    """The summary of a run, written to ``run.json`` (:meth:`as_json`).

    Attributes
    ----------
    scene : str
        The scene's name.
    duration_s : float
        Line time asked for, s.
    sim_time_reached_s : float
        Line time reached, s.
    wall_time_s : float
        Wall time of the run, s.
    rtf_requested : float or 'max'
        The real-time factor ceiling; 'max': none.
    rtf_achieved : float
        Line time over wall time.
    mode : str
        'in-process' or 'processes'.
    clock : str
        'lockstep' or 'wall'.
    interrupted : str or None
        Why the run stopped early (signals, reasons, comma-separated); None: it did not (``false`` in ``run.json``).
    lost_participants : dict of str to float
        Participant -> line time it was declared lost, s.
    cause : str or None
        The first violation that changed the supervisor's state: constraint, cycle, time, action, node.
    messages : dict of str to int
        Messages received per topic, by topic.
    events_received : dict of str to int
        Events received per kind, by kind.
    sheets_counted : int
        The sheet counter's last count.
    supervisor_state : str
        The supervisor's last state ('' if none was received).
    tunings : tuple of Tuning
        The operator's tunings the supervisor accepted, by effective time.
    expected_from_simulate : ExpectedFromSimulate
        ``simulate``'s figures of the span run.
    bag : BagAccount or None
        The bag and its loss accounting (None: no bag; its keys are left out of ``run.json``).
    partition : str or None
        The line's DDS partition; None: an open line (the user's own profiles file).
    exit_codes : dict of str to int or None
        With node processes: node -> exit code; None in-process (left out of ``run.json``).
    """

    scene: str
    duration_s: float
    sim_time_reached_s: float
    wall_time_s: float
    rtf_requested: float | Literal['max']
    rtf_achieved: float
    mode: str
    clock: str
    interrupted: str | None
    lost_participants: dict[str, float]
    cause: str | None
    messages: dict[str, int]
    events_received: dict[str, int]
    sheets_counted: int
    supervisor_state: str
    tunings: tuple[Tuning, ...]
    expected_from_simulate: ExpectedFromSimulate
    bag: BagAccount | None = None
    partition: str | None = None
    exit_codes: dict[str, int] | None = None

    @property
    def outcome(self) -> Outcome:
        """Whether the run ended as the scene expects: the module's :func:`outcome` of this summary."""
        return outcome(self)  # the module's function: a method's body does not see the class's names

    def as_json(self) -> JsonObject:
        """The ``run.json`` document: keys in the order written, ``outcome`` last."""
        doc: JsonObject = {
            'scene': self.scene,
            'duration_s': self.duration_s,
            'sim_time_reached_s': self.sim_time_reached_s,
            'wall_time_s': self.wall_time_s,
            'rtf_requested': self.rtf_requested,
            'rtf_achieved': self.rtf_achieved,
            'mode': self.mode,
            'clock': self.clock,
            'interrupted': False if self.interrupted is None else self.interrupted,
            'lost_participants': dict(self.lost_participants),
            'cause': self.cause,
            'messages': dict(self.messages),
            'events_received': dict(self.events_received),
            'sheets_counted': self.sheets_counted,
            'supervisor_state': self.supervisor_state,
            'tunings': [{'t': tu.t, 'key': tu.key, 'value': tu.value} for tu in self.tunings],
            'expected_from_simulate': self.expected_from_simulate.as_json(),
        }
        if self.bag is not None:
            doc.update(self.bag.as_json())
        doc['partition'] = self.partition
        if self.exit_codes is not None:
            doc['exit_codes'] = dict(self.exit_codes)
        doc['outcome'] = self.outcome.as_json()
        return doc


def outcome(summary: RunSummary) -> Outcome:
    """Whether the run ended as the scene expects, and if not, one line that says why.

    ``ok`` only when sim time reached ``duration``, the run was not interrupted, no
    participant was lost and the supervisor ended in the state ``simulate`` expects
    (EXECUTE: the scenes start the line and nothing stops it unless a constraint is
    violated, which ``simulate`` reports as a violation).
    """
    expected = 'EXECUTE' if summary.expected_from_simulate.violations == 0 else None
    problems = [f'participant {node} lost at {t:.6f} s' for node, t in summary.lost_participants.items()]
    reached = summary.sim_time_reached_s
    if summary.interrupted:
        problems.append(f'interrupted ({summary.interrupted}) at {reached:.6f} s')
    elif reached < summary.duration_s:
        problems.append(f'sim time stopped at {reached:.6f} s of {summary.duration_s:g} s')
    state, cause = summary.supervisor_state, summary.cause
    if expected is not None and state != expected:
        what = f'line ended {state or "with no supervisor state"}'
        if cause:
            what += f': {cause}'
        problems.insert(0, what)
    elif expected is None and state == 'EXECUTE':
        problems.append('simulate expects violations, yet the line ended in EXECUTE')
    if problems:
        return Outcome(False, expected, state, '; '.join(problems))
    message = (
        f'line ended {state} as the scene expects'
        + (" with the operator's tunings" if summary.tunings else '')
        + (f': {cause}' if cause else '')
    )
    return Outcome(True, expected, state, message)


def print_run_summary(summary: RunSummary, out_dir: Path, stream: IO[str]) -> None:
    """Print the human-readable end of ``folder-line run`` (``out_dir``: where ``run.json`` was written)."""
    print(
        f'scene {summary.scene}: {summary.sim_time_reached_s:.3f} s of line time in '
        f'{summary.wall_time_s:.1f} s ({summary.mode}, {summary.clock} clock, rtf achieved '
        f'{summary.rtf_achieved:.2f}, ceiling {summary.rtf_requested})',
        file=stream,
    )
    tunings = summary.tunings
    print(
        f'supervisor: {summary.supervisor_state}   sheets counted: {summary.sheets_counted} '
        f'(simulate{" with the same tunings" if tunings else ""}: '
        f'{summary.expected_from_simulate.sheets_counted})',
        file=stream,
    )
    for tu in tunings:  # as simulate --tune takes them
        print(
            f'tuned: {tu.key} = {tu.value!r} from {tu.t:.9f} s (simulate --tune {tu.t!r}:{tu.key}={tu.value!r})',
            file=stream,
        )
    print('messages received per topic:', file=stream)
    for topic, n in summary.messages.items():
        print(f'  {topic:<40} {n}', file=stream)
    bag = summary.bag
    if bag is not None:
        if bag.lost is None:
            print(f'lost messages: unknown ({bag.loss_accounting})', file=stream)
        elif any(bag.lost.values()):
            print('lost messages: ' + ', '.join(f'{t} {n}' for t, n in bag.lost.items() if n), file=stream)
        else:
            print('lost messages: 0 on every topic', file=stream)
        print(f'wrote {bag.path} ({files_text(bag.files)})', file=stream)
    print(f'wrote {out_dir / "run.json"}', file=stream)
