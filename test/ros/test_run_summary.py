"""``run.json`` from :class:`RunSummary`: the document ``folder-line run`` has always written, key for key, in order."""

from __future__ import annotations

import io
import json
from dataclasses import replace
from pathlib import Path

from folder_line.core.line.tuning import Tuning
from folder_line.ros.run_summary import BagAccount, ExpectedFromSimulate, Outcome, RunSummary, print_run_summary

MESSAGES = {'/clock': 401, '/line/events': 248}
EVENTS = {'knife_contact': 24, 'sheet_counted': 26}


#: an in-process run of 2 s that ended as expected
RUN = RunSummary(
    scene='folder',
    duration_s=2.0,
    sim_time_reached_s=2.0,
    wall_time_s=1.5,
    rtf_requested='max',
    rtf_achieved=1.75,
    mode='in-process',
    clock='lockstep',
    interrupted=None,
    lost_participants={},
    cause=None,
    messages=MESSAGES,
    events_received=EVENTS,
    sheets_counted=26,
    supervisor_state='EXECUTE',
    tunings=(),
    expected_from_simulate=ExpectedFromSimulate(26, EVENTS, 0),
    bag=BagAccount('/out/bag', 1, MESSAGES, MESSAGES, dict.fromkeys(MESSAGES, 0), {}, 'in-process: counted'),
    partition='line_abc',
)


def summary(**changes: object) -> RunSummary:
    """:data:`RUN` with ``changes``."""
    return replace(RUN, **changes)


def head(**changes: object) -> dict[str, object]:
    """The keys of ``run.json`` before the bag's, as the summary was built before it was a dataclass."""
    return {
        'scene': 'folder',
        'duration_s': 2.0,
        'sim_time_reached_s': 2.0,
        'wall_time_s': 1.5,
        'rtf_requested': 'max',
        'rtf_achieved': 1.75,
        'mode': 'in-process',
        'clock': 'lockstep',
        'interrupted': False,
        'lost_participants': {},
        'cause': None,
        'messages': MESSAGES,
        'events_received': EVENTS,
        'sheets_counted': 26,
        'supervisor_state': 'EXECUTE',
        'tunings': [],
        'expected_from_simulate': {'sheets_counted': 26, 'events': EVENTS, 'violations': 0},
        **changes,
    }


def text(doc: object) -> str:
    """``doc`` as ``run.json`` holds it (key order included)."""
    return json.dumps(doc, indent=2, allow_nan=False)


def test_an_in_process_run_writes_every_key_in_order() -> None:
    tuned = summary(tunings=(Tuning(0.5, 'feed_transporter.V_tr', 9.0),), cause='c in cycle 3 at 1.000000 s -> slow')
    message = "line ended EXECUTE as the scene expects with the operator's tunings: c in cycle 3 at 1.000000 s -> slow"
    want = {
        **head(
            tunings=[{'t': 0.5, 'key': 'feed_transporter.V_tr', 'value': 9.0}],
            cause='c in cycle 3 at 1.000000 s -> slow',
        ),
        'bag': {'path': '/out/bag', 'files': 1, 'messages': MESSAGES},
        'published': MESSAGES,
        'lost': dict.fromkeys(MESSAGES, 0),
        'after_last_tick': {},
        'loss_accounting': 'in-process: counted',
        'partition': 'line_abc',
        'outcome': {
            'ok': True,
            'expected_state': 'EXECUTE',
            'state': 'EXECUTE',
            'message': message,
        },
    }
    assert text(tuned.as_json()) == text(want)
    assert tuned.outcome == Outcome(True, 'EXECUTE', 'EXECUTE', message)


def test_a_stopped_run_of_node_processes_says_why_it_failed() -> None:
    stopped = summary(
        rtf_requested=1.0,
        mode='processes',
        sim_time_reached_s=1.25,
        interrupted='SIGINT',
        lost_participants={'feed_transporter': 1.0},
        cause='lost:feed_transporter in cycle 12 at 1.000000 s -> abort (node feed_transporter)',
        supervisor_state='ABORTED',
        bag=None,
        partition=None,
        exit_codes={'line_clock': 0, 'feed_transporter': -9},
    )
    message = (
        'line ended ABORTED: lost:feed_transporter in cycle 12 at 1.000000 s -> abort (node feed_transporter); '
        'participant feed_transporter lost at 1.000000 s; interrupted (SIGINT) at 1.250000 s'
    )
    want = {
        **head(
            rtf_requested=1.0,
            mode='processes',
            sim_time_reached_s=1.25,
            interrupted='SIGINT',
            lost_participants={'feed_transporter': 1.0},
            cause='lost:feed_transporter in cycle 12 at 1.000000 s -> abort (node feed_transporter)',
            supervisor_state='ABORTED',
        ),
        'partition': None,
        'exit_codes': {'line_clock': 0, 'feed_transporter': -9},
        'outcome': {'ok': False, 'expected_state': 'EXECUTE', 'state': 'ABORTED', 'message': message},
    }
    assert text(stopped.as_json()) == text(want)


def test_the_outcome_follows_what_simulate_expects() -> None:
    short = summary(sim_time_reached_s=1.5, supervisor_state='')
    assert short.outcome == Outcome(
        False, 'EXECUTE', '', 'line ended with no supervisor state; sim time stopped at 1.500000 s of 2 s'
    )
    violations = ExpectedFromSimulate(26, EVENTS, 3)
    assert summary(expected_from_simulate=violations).outcome == Outcome(
        False, None, 'EXECUTE', 'simulate expects violations, yet the line ended in EXECUTE'
    )
    assert summary(expected_from_simulate=violations, supervisor_state='ABORTED').outcome.ok


def test_the_printed_summary() -> None:
    out = io.StringIO()
    print_run_summary(summary(tunings=(Tuning(0.5, 'feed_transporter.V_tr', 9.0),)), Path('/out'), out)
    assert out.getvalue().splitlines() == [
        'scene folder: 2.000 s of line time in 1.5 s (in-process, lockstep clock, rtf achieved 1.75, ceiling max)',
        'supervisor: EXECUTE   sheets counted: 26 (simulate with the same tunings: 26)',
        'tuned: feed_transporter.V_tr = 9.0 from 0.500000000 s (simulate --tune 0.5:feed_transporter.V_tr=9.0)',
        'messages received per topic:',
        f'  {"/clock":<40} 401',
        f'  {"/line/events":<40} 248',
        'lost messages: 0 on every topic',
        'wrote /out/bag (1 .mcap file)',
        'wrote /out/run.json',
    ]
