"""``folder-line run`` end to end over DDS: the run, its honest exit, SIGTERM, a second line, hostile inputs.

The runs that must be stopped or disturbed mid-run are started as a process
(``python -m folder_line.cli.main run``, :mod:`_line_runs`) with this test's ROS domain; the
test waits for their progress output, never for a time. Every assertion holds whatever
the load: in lockstep, what the line publishes does not depend on it.
"""

from __future__ import annotations

import json
import math
import os
import signal
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest
from _ros_env import DOMAIN_ID
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import JointState, TimeReference
from std_msgs.msg import String

from folder_line.cli.main import main
from folder_line.config.run_config import SCENE_FILE
from folder_line.config.scenes import load_scene
from folder_line.core.line.model import simulate
from folder_line.core.line.scene import Scene
from folder_line.interfaces import (
    COMMANDS_TOPIC,
    EVENTS_TOPIC,
    MACHINE_NODES,
    NS_PER_S,
    PARTICIPANTS_TOPIC,
    progress_topic,
    tick_done_topic,
)
from folder_line.ros.lockstep import ACK_QOS, LINE_QOS, PARTICIPANTS_QOS, TICK_QOS
from folder_line.ros.run import OTHER_LINE_WAIT
from folder_line.ros.time_msg import ns_to_time_msg
from folder_line.ros.topics import COMMANDS_QOS, joint_states_topic

from ._line_runs import (
    assert_bag_is_model,
    line_processes,
    read_bag_mcap,
    start_run,
    statuses,
    tagged,
    wait_for_line_time,
)

if TYPE_CHECKING:
    from .conftest import Ros

RATE = 200.0  # the nodes' default, Hz of sim time
TICK_TOPICS = (
    '/clock',
    '/line/supervisor/state',
    '/line/sheet_counter/count',
    '/line/sheet_counter/rate',
    *(joint_states_topic(n) for n in ('crank_drive', 'belt_conveyor', 'feed_transporter', 'sheet_counter')),
)


def test_run_in_process(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    duration, rtf = 2.0, 1.0  # (capfd: the EventsExecutor enables faulthandler, which needs a real stderr)
    assert main(['run', '--duration', str(duration), '--rtf', str(rtf), '--out', str(tmp_path)]) == 0
    out = capfd.readouterr().out
    assert 'sheets counted' in out and f'wrote {tmp_path / "run.json"}' in out
    assert 'lost messages: 0 on every topic' in out
    summary = json.loads((tmp_path / 'run.json').read_text())
    assert summary['mode'] == 'in-process' and summary['clock'] == 'lockstep' and not summary['interrupted']
    assert summary['outcome']['ok'] and summary['supervisor_state'] == 'EXECUTE'
    assert summary['sim_time_reached_s'] == duration
    assert 0.0 < summary['rtf_achieved'] <= rtf * 1.001  # a ceiling, whatever the load
    messages = summary['messages']
    for topic in TICK_TOPICS:  # every tick, none skipped: 0, 5 ms, ..., duration
        assert messages[topic] == RATE * duration + 1, (topic, messages[topic])
    assert messages['/diagnostics'] == int(duration) + 1 and messages['/line/participants'] == 1
    batch = simulate(load_scene('folder'), duration, sample_rate=0.0).summary()
    assert summary['sheets_counted'] == batch.sheets_counted == summary['expected_from_simulate']['sheets_counted']
    assert summary['sheets_counted'] > 0
    assert summary['events_received'] == batch.events
    assert messages[EVENTS_TOPIC] == sum(batch.events.values())
    assert summary['published'] == summary['bag']['messages'] and set(summary['lost'].values()) == {0}
    assert_bag_is_model(read_bag_mcap(tmp_path / 'bag'), 'folder', duration, RATE)


def test_an_in_process_run_parses_the_scene_once(
    tmp_path: Path, capfd: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """``run`` parses the scene once and writes it merged to ``<out>/scene.yaml``; the five nodes get
    that path and share the parsed scene (before: every node parsed it twice, 7 parses in all)."""
    parses: list[str] = []
    build = Scene.__init__

    def counted(self: Scene, *args: Any, **kwargs: Any) -> None:
        build(self, *args, **kwargs)
        parses.append(self.name)  # every parse ends in one Scene

    monkeypatch.setattr(Scene, '__init__', counted)
    argv = ['run', '--duration', '0.5', '--rtf', 'max', '--set', 'seed=3', '--set', 'feed_transporter.V_tr=9.4']
    assert main([*argv, '--out', str(tmp_path)]) == 0
    capfd.readouterr()
    assert parses == ['folder']
    assert json.loads((tmp_path / 'run.json').read_text())['outcome']['ok']
    monkeypatch.undo()
    written = load_scene(tmp_path / SCENE_FILE)  # the merged scene: nothing left to override
    assert written == load_scene('folder', {'seed': 3, 'feed_transporter.V_tr': 9.4})
    assert written.seed == 3 and written.machine('feed_transporter').V_tr == 9.4


@pytest.mark.parametrize(
    ('item', 'line'),
    [
        ('feed_transporter.V_tr=-1', 'folder-line: error: feed_transporter.V_tr=-1: must be in [0.001, 1000] m/s'),
        ('V_tr', "folder-line: error: --set='V_tr': must be KEY=VALUE, e.g. feed_transporter.V_tr=5.833"),
    ],
)
def test_run_refuses_a_bad_set_with_one_line(
    tmp_path: Path, capfd: pytest.CaptureFixture[str], item: str, line: str
) -> None:
    out = tmp_path / 'out'
    assert main(['run', '--duration', '1', '--set', item, '--out', str(out)]) == 2
    captured = capfd.readouterr()
    assert captured.err == line + '\n'
    assert not out.exists()  # nothing started, nothing written


@pytest.mark.parametrize('processes', [False, True], ids=['in-process', 'processes'])
def test_sigterm_closes_the_bag_writes_run_json_and_ends_every_node(
    node_env: dict[str, str], tmp_path: Path, processes: bool
) -> None:
    out = tmp_path / 'out'
    run = start_run(node_env, out, '--duration', '60', '--rtf', '1', *(['--processes'] if processes else []))
    try:
        wait_for_line_time(run, 0.3)
        nodes = tagged(run.tag)
        assert len(nodes) == (7 if processes else 1), nodes  # run (+ line_clock and the five machine nodes)
        run.proc.send_signal(signal.SIGTERM)
        code = run.wait(timeout=120)
    finally:
        run.stop()
    assert code == 1, run.text()  # interrupted is not success
    [line] = run.error_lines()
    assert line.startswith('folder-line: run failed: interrupted (SIGTERM) at '), line
    summary = json.loads((out / 'run.json').read_text())
    assert summary['interrupted'] == 'SIGTERM' and not summary['outcome']['ok']
    assert 0.3 <= summary['sim_time_reached_s'] < 60.0
    assert (out / 'bag' / 'metadata.yaml').is_file()
    records = read_bag_mcap(out / 'bag')  # every segment finished
    n_clock = len(records[('/clock', '')])
    assert n_clock == summary['messages']['/clock'] == summary['bag']['messages']['/clock'] >= 0.3 * RATE
    for node in ('crank_drive', 'belt_conveyor', 'feed_transporter', 'sheet_counter'):
        # lockstep: every tick was recorded whole before the next; only the last one may be cut by the
        # interruption, or its /clock still be on its way to the recorder
        assert abs(len(records[(joint_states_topic(node), node)]) - n_clock) <= 1, node
    if processes:
        assert set(summary['exit_codes']) == {*MACHINE_NODES, 'line_clock'}
    assert tagged(run.tag) == {}  # nothing of the run is left
    assert line_processes(out, DOMAIN_ID, run.started) == {}


def test_a_second_line_on_the_same_domain_is_refused(
    node_env: dict[str, str], tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    # 4 s at rtf 0.5: at least 8 s of wall time (a ceiling, whatever the load), more than the second run's
    # search for another line (run.OTHER_LINE_WAIT)
    first = start_run(node_env, tmp_path / 'first', '--duration', '4', '--rtf', '0.5')
    try:
        wait_for_line_time(first, 0.0)  # its line_clock is up
        second = tmp_path / 'second'
        assert main(['run', '--duration', '1', '--out', str(second)]) == 2
        err = capfd.readouterr().err
        assert err.count('\n') == 1, err
        assert err.startswith('folder-line: error: another line is running: a line with this FOLDER_LINE_KEY '), err
        assert 'own FOLDER_LINE_KEY (unset it, and run makes one)' in err  # a line with another key may run beside
        assert f'ROS_DOMAIN_ID={DOMAIN_ID}' in err
        assert not second.exists()  # refused before anything was written
        assert OTHER_LINE_WAIT < 4.0 / 0.5
        assert first.wait(timeout=120) == 0, first.text()
    finally:
        first.stop()
    summary = json.loads((tmp_path / 'first' / 'run.json').read_text())
    assert summary['outcome']['ok'] and not summary['interrupted'] and summary['sim_time_reached_s'] == 4.0


@pytest.mark.parametrize('processes', [False, True], ids=['in-process', 'processes'])
def test_a_foreign_clock_is_refused_and_the_run_goes_on(
    ros: Ros, node_env: dict[str, str], tmp_path: Path, processes: bool
) -> None:
    """A stray ``/clock`` (``ros2 topic pub /clock ...``): a jump far ahead, then back; sim time goes on
    from the line's own clock, the run ends EXECUTE with exit 0 and every tick of the grid in the bag."""
    out = tmp_path / 'out'
    duration = 3.0
    run = start_run(node_env, out, '--duration', str(duration), '--rtf', '1', *(['--processes'] if processes else []))
    try:
        wait_for_line_time(run, 0.5)
        stray = ros.node('stray_clock').create_publisher(ClockMsg, '/clock', 10)
        assert ros.spin_until(lambda: stray.get_subscription_count() >= 1, timeout=20.0)  # line_clock's
        for stamp in (99999 * NS_PER_S, 1):
            stray.publish(ClockMsg(clock=ns_to_time_msg(stamp)))
            ros.spin_for(0.3)
        code = run.wait(timeout=120)
    finally:
        run.stop()
    assert code == 0, run.text()
    summary = json.loads((out / 'run.json').read_text())
    assert summary['outcome']['ok'] and summary['supervisor_state'] == 'EXECUTE', summary['outcome']
    assert summary['sim_time_reached_s'] == duration and not summary['interrupted']
    ticks = [r.log_ns for r in read_bag_mcap(out / 'bag', ['/clock'])[('/clock', '')]]
    assert ticks == [k * NS_PER_S // int(RATE) for k in range(int(duration * RATE) + 1)]  # the grid, no stray stamp
    logs = run.text() + ''.join(p.read_text() for p in (out / 'logs').glob('*.log')) if processes else run.text()
    refusals = [line for line in logs.splitlines() if 'refused a foreign /clock message from /stray_clock' in line]
    assert len(refusals) == 1, logs[-3000:]  # named once, however many messages it sent
    assert tagged(run.tag) == {}


def _hostile(ros: Ros) -> list[tuple[object, object]]:
    """(publisher, message) pairs: malformed, foreign or unknown inputs on every topic the nodes subscribe to
    (not ``/clock``: its only publisher is the protocol's owner)."""
    node = ros.node('fuzzer')
    pairs: list[tuple[object, object]] = []

    def ref(frame: str, source: str, sec: int = 0) -> TimeReference:
        msg = TimeReference(source=source)
        msg.header.frame_id = frame
        msg.header.stamp = msg.time_ref = ns_to_time_msg(sec * 1_000_000_000)
        return msg

    commands = node.create_publisher(TimeReference, COMMANDS_TOPIC, COMMANDS_QOS)
    pairs += [
        (commands, ref('fuzz', 'hold', 1)),
        (commands, ref('fuzz', 'stop', 1)),
        (commands, ref('supervisor', 'jump', 1)),
        (commands, ref('supervisor', '', 1)),
        (commands, ref('supervisor', 'hold ' + 'x' * 500, 1)),
    ]
    events = node.create_publisher(TimeReference, EVENTS_TOPIC, LINE_QOS)
    pairs += [
        (events, ref('fuzz', 'knife_contact sheet=1 cycle=1 value=0.0', 1)),  # not the owner's
        (events, ref('fuzz', 'garbage')),
        (events, ref('fuzz', '')),
        (events, ref('fuzz', 'é' * 300)),
        (events, ref('fuzz', 'knife_contact sheet=x cycle=1 value=nan')),
        (events, ref('fuzz', 'no_such_kind sheet=1 cycle=1 value=1.0')),
        (events, ref('crank_drive', 'garbage')),  # a participant's name on a malformed event
        (events, ref('crank_drive', 'settled sheet=1 cycle=1 value=0.0', 1)),
    ]  # not crank_drive's kind
    for producer in (*MACHINE_NODES, 'line_recorder'):
        for done in (
            node.create_publisher(TimeReference, tick_done_topic(producer), TICK_QOS),
            node.create_publisher(TimeReference, progress_topic(producer), ACK_QOS),
        ):
            pairs += [
                (done, ref(producer, 'garbage', 2)),
                (done, ref(producer, 'messages=-1 events=0 commands=0', 2)),
                (done, ref(producer, 'messages=1 events=1 commands=1 extra=1', 2)),
                (done, ref(producer, f'messages={2**64} events=0 commands=0', 2)),
                (done, ref('fuzz', 'messages=0 events=0 commands=0', 2)),
            ]
    participants = node.create_publisher(String, PARTICIPANTS_TOPIC, PARTICIPANTS_QOS)
    pairs += [
        (participants, String(data='garbage')),
        (participants, String(data='clock=fast end=1 participants=x')),
        (participants, String(data='clock=lockstep end=none participants=crank_drive')),  # a second line's
        (participants, String(data='x' * 5000)),
    ]
    for name in ('crank_drive', 'belt_conveyor', 'feed_transporter', 'sheet_counter'):
        joints = node.create_publisher(JointState, joint_states_topic(name), LINE_QOS)
        nan = JointState(name=['fuzz'], position=[math.nan], velocity=[math.inf], effort=[])
        nan.header.frame_id = 'fuzz'  # NaN from the node itself aborts the line; from anyone else it is rejected
        pairs += [(joints, JointState(name=['fuzz'], position=[1.0, 2.0], velocity=[], effort=[3.0])), (joints, nan)]
    return pairs


def test_hostile_inputs_are_rejected_and_the_line_runs_on(ros: Ros, node_env: dict[str, str], tmp_path: Path) -> None:
    duration = 3.0
    out = tmp_path / 'out'
    run = start_run(node_env, out, '--duration', str(duration), '--rtf', '1')
    rounds = 0
    try:
        wait_for_line_time(run, 0.0)  # past its search for another line: the fuzzer would be one
        pairs = _hostile(ros)
        while run.proc.poll() is None:  # until the run ends: every round while it runs
            for publisher, msg in pairs:
                publisher.publish(msg)  # type: ignore[attr-defined]
            rounds += 1
            ros.spin_for(0.05)
        code = run.wait(timeout=120)
    finally:
        run.stop()
    assert rounds > 0
    assert code == 0, run.text()  # no node exited, the line ended as the scene expects
    summary = json.loads((out / 'run.json').read_text())
    assert summary['outcome']['ok'] and summary['sim_time_reached_s'] == duration, summary['outcome']
    records = read_bag_mcap(out / 'bag')
    assert len(records[(EVENTS_TOPIC, 'fuzz')]) > 0  # the recorder records what it hears, hostile too
    # what the line published is the model: the hostile inputs changed nothing
    assert_bag_is_model(records, 'folder', duration, RATE, rejected=True)
    inputs = statuses(records, 'folder_line/supervisor/inputs')
    assert inputs
    _, rejected, status = inputs[-1]
    assert status.level == 1 and status.message.endswith('inputs rejected'), status.message  # WARN
    for kind in ('command', 'event', 'tick_done', 'announcement', 'joint_states'):
        assert int(rejected.get(kind, '0')) > 0, (kind, rejected)


def test_a_run_that_fills_the_disk_ends_in_one_line_and_leaves_a_partial_bag(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    """The recorder's write fails (ENOSPC on a 64 KiB tmpfs): the run stops, prints one error line naming
    the bag file and the OS reason (no FATAL callback dump from the executor), exits 2, and the bag is
    left as far as it got, marked partial and repairable."""
    import subprocess

    if os.geteuid() != 0:
        pytest.skip('mounting a tmpfs needs root')
    disk = tmp_path / 'small'
    disk.mkdir()
    mount = subprocess.run(
        ['mount', '-t', 'tmpfs', '-o', 'size=64k', 'tmpfs', str(disk)], capture_output=True, text=True, check=False
    )
    if mount.returncode != 0:
        pytest.skip(f'cannot mount a tmpfs here: {mount.stderr.strip()}')
    try:
        out = disk / 'run'
        assert main(['run', '--duration', '2', '--rtf', 'max', '--out', str(out)]) == 2
        err = [line for line in capfd.readouterr().err.splitlines() if not line.startswith('[INFO]')]
        assert err == [f"folder-line: error: --out: '{out / 'bag' / 'bag_0.mcap'}': No space left on device"], err
        from folder_line.bag.reader import read_bag

        assert read_bag(out / 'bag').custom['folder_line.complete'] == 'false'
        assert not (out / 'run.json').exists()
    finally:
        subprocess.run(['umount', '-l', str(disk)], check=False)
