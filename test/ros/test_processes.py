"""``folder-line run --processes`` when one node process dies or stops mid-run.

The line runs as one process per node (``line_clock``, the five machine nodes; the
recorder in the ``run`` process). ``feed_transporter`` is killed (SIGKILL) or stopped
(SIGSTOP) once the line runs. In lockstep sim time then waits for it; after
``--lost-timeout`` s of wall time it is declared lost, named in ``run.json`` and by the
supervisor (violation ``lost:feed_transporter``, then ABORTED), the line runs on without
it to the end, and ``run`` exits non-zero with one line that names it. The bag is
complete and opens with the independent ``mcap`` reader. A stopped node is continued at
the end (SIGCONT) so that nothing is left behind.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
from pathlib import Path

import pytest
from _ros_env import DOMAIN_ID

from folder_line.interfaces import MACHINE_NODES

from ._line_runs import child_node, line_processes, read_bag_mcap, start_run, statuses, tagged, wait_for_line_time

VICTIM = 'feed_transporter'
DURATION = 4.0  # line time: the loss, the abort and the standstill after it (drive.t_brake 0.5 s)


@pytest.mark.parametrize('sig', [signal.SIGKILL, signal.SIGSTOP], ids=['SIGKILL', 'SIGSTOP'])
def test_a_lost_node_is_named_the_line_aborts_and_run_fails(
    node_env: dict[str, str], tmp_path: Path, sig: signal.Signals
) -> None:
    out = tmp_path / 'out'
    run = start_run(node_env, out, '--processes', '--duration', str(DURATION), '--rtf', '1', '--lost-timeout', '1')
    victim = None
    try:
        wait_for_line_time(run, 1.0)
        victim = child_node(run.pid, VICTIM)
        os.kill(victim, sig)
        code = run.wait(timeout=120)
    finally:
        if victim is not None and sig == signal.SIGSTOP:
            with contextlib.suppress(ProcessLookupError):
                os.kill(victim, signal.SIGCONT)
        run.stop()
    assert code == 1, run.text()
    [line] = run.error_lines()
    assert line.startswith('folder-line: run failed: line ended ABORTED: lost:feed_transporter in cycle '), line
    assert f'participant {VICTIM} lost at ' in line

    summary = json.loads((out / 'run.json').read_text())
    assert not summary['outcome']['ok'] and summary['outcome']['state'] == 'ABORTED'
    assert VICTIM in summary['outcome']['message']
    assert list(summary['lost_participants']) == [VICTIM]
    t_lost = summary['lost_participants'][VICTIM]
    assert 1.0 <= t_lost < DURATION
    assert summary['cause'].startswith('lost:feed_transporter in cycle ') and summary['cause'].endswith(
        f'-> abort (node {VICTIM})'
    )
    assert summary['supervisor_state'] == 'ABORTED'
    assert summary['sim_time_reached_s'] == DURATION  # the line ran on without it
    codes = summary['exit_codes']
    assert set(codes) == {*MACHINE_NODES, 'line_clock'}
    if sig == signal.SIGKILL:
        assert codes[VICTIM] == -signal.SIGKILL
    assert codes['line_clock'] == 3  # line_clock's own code for a lost participant
    assert codes['supervisor'] == 3  # it waited for the victim: its line did not end as expected
    assert all(codes[n] == 0 for n in MACHINE_NODES if n not in (VICTIM, 'supervisor')), codes

    # the bag: complete, readable by the independent reader, with the supervisor's verdict in it
    records = read_bag_mcap(out / 'bag')
    assert len(records[('/clock', '')]) == summary['messages']['/clock'] == round(DURATION * 200.0) + 1
    for node in ('crank_drive', 'belt_conveyor', 'sheet_counter'):  # the others published every tick
        assert len(records[(f'/line/{node}/joint_states', node)]) == round(DURATION * 200.0) + 1, node
    victim_states = records[(f'/line/{VICTIM}/joint_states', VICTIM)]
    assert 200 <= len(victim_states) < round(DURATION * 200.0) + 1
    [(_, violation, _)] = statuses(records, 'folder_line/supervisor/violation')
    assert violation['constraint'] == f'lost:{VICTIM}' and violation['action'] == 'abort'
    states = [r.msg.data for r in records[('/line/supervisor/state', '')]]
    assert states[-1] == 'ABORTED' and 'ABORTING' in states
    assert states[: states.index('ABORTING')][-1] == 'EXECUTE'
    assert [kv['node'] for _, kv, _ in statuses(records, 'folder_line/line_clock/lost')] == [VICTIM]
    inputs = statuses(records, 'folder_line/supervisor/inputs')
    assert inputs[-1][1].get('lost') == VICTIM

    assert tagged(run.tag) == {} and line_processes(out, DOMAIN_ID, run.started) == {}  # nothing left
