"""The pure half of ``folder-line monitor``: messages in, rates, latest values and the screen out (no ROS graph)."""

from __future__ import annotations

import ast
import math
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest
from _loaded import ros_modules_loaded
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from hypothesis import given, settings
from hypothesis import strategies as st
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState, TimeReference
from std_msgs.msg import Float64, String, UInt64

from folder_line.cli.main import main
from folder_line.cli.monitor import run_monitor
from folder_line.cli.monitor_view import LEVELS, MIN_HEIGHT, MIN_WIDTH, MonitorState, TopicStats
from folder_line.config.scenes import load_scene
from folder_line.core.line.margin_text import format_margin
from folder_line.core.line.model import LineModel
from folder_line.core.line.stream import LineStream
from folder_line.interfaces import (
    CLOCK_TOPIC,
    COMMANDS_TOPIC,
    DIAGNOSTICS_TOPIC,
    EVENT_KINDS,
    EVENTS_TOPIC,
    LANDING_TOPIC,
    SHEET_COUNT_TOPIC,
    SHEET_RATE_TOPIC,
    SUPERVISOR_STATE_TOPIC,
    event_source,
)
from folder_line.ros import monitor as ros_monitor
from folder_line.ros.nodes.supervisor import Supervisor
from folder_line.ros.recorder import LINE_TOPICS
from folder_line.ros.time_msg import ns_to_time_msg
from folder_line.ros.topics import joint_states_topic

CRANK = joint_states_topic('crank_drive')


def clock(ns: int) -> Clock:
    return Clock(clock=ns_to_time_msg(ns))


def event(kind: str, t_ns: int, sheet: int = -1, cycle: int = -1, value: float = 0.0, node: str = 'n') -> TimeReference:
    msg = TimeReference(time_ref=ns_to_time_msg(t_ns), source=event_source(kind, sheet, cycle, value))
    msg.header.frame_id = node
    return msg


def status(name: str, level: bytes, message: str, **values: str) -> DiagnosticStatus:
    return DiagnosticStatus(
        name=name, level=level, message=message, values=[KeyValue(key=k, value=v) for k, v in values.items()]
    )


def row(lines: list[str], first_word: str) -> list[str]:
    """The words of the one line that starts with ``first_word``."""
    found = [line.split() for line in lines if line.split()[:1] == [first_word]]
    assert len(found) == 1, (first_word, lines)
    return found[0]


# --------------------------------------------------------------------------- rates


def test_steady_rate_is_the_count_in_the_window_over_the_window() -> None:
    state = MonitorState([CLOCK_TOPIC], window=2.0)
    for k in range(601):  # 200 Hz over [0, 3] s of wall time
        state.ingest(CLOCK_TOPIC, clock(5_000_000 * k), k / 200)
    assert state.rate(CLOCK_TOPIC) == 200.0  # arrivals k = 201..600 in (1, 3]: 400 / 2 s
    assert state.topics[CLOCK_TOPIC].count == 601
    assert len(state.topics[CLOCK_TOPIC].arrivals) == 400  # nothing older than the window is kept


def test_rate_before_a_full_window_counts_intervals_since_the_first_message() -> None:
    state = MonitorState(window=2.0)
    for k in range(51):  # 100 Hz for 0.5 s only
        state.ingest(CRANK, JointState(), 10.0 + k / 100)
    assert state.rate(CRANK) == pytest.approx(100.0, rel=1e-12)  # 50 intervals in 0.5 s, not 51 / 2 s
    one = MonitorState()
    one.ingest(CRANK, JointState(), 3.0)
    assert one.rate(CRANK) is None and one.rate('/never') == 0.0  # one message: no rate yet, never: 0
    assert row(one.render(100), CRANK)[1:3] == ['-', '1']
    assert one.rate(CRANK, now=4.9) is None and one.rate(CRANK, now=5.0) == 0.0  # out of the window: 0
    one.ingest(CRANK, JointState(), 6.0)
    assert one.rate(CRANK, now=6.0) == 0.5  # 1 message in the last 2 s


def test_rate_falls_to_zero_within_a_window_after_the_publisher_stops() -> None:
    state = MonitorState(window=1.0)
    for k in range(300):  # 100 Hz over [0, 2.99] s
        state.ingest(SHEET_COUNT_TOPIC, UInt64(data=k), k / 100)
    assert state.rate(SHEET_COUNT_TOPIC, now=2.99) == pytest.approx(100.0)
    assert state.rate(SHEET_COUNT_TOPIC, now=3.49) == pytest.approx(50.0)  # half the window still has arrivals
    assert state.rate(SHEET_COUNT_TOPIC, now=4.0) == 0.0
    lines = state.render(120, None, now=4.0)
    assert row(lines, SHEET_COUNT_TOPIC)[1:3] == ['0.0', '300']  # rate 0, count kept, latest value kept
    assert 'no message for 1.0 s' in lines[1]


def test_history_delivered_at_once_counts_at_its_own_times() -> None:
    """A late joiner gets a transient-local history in one burst; stamped with their publishing times the
    messages give the publishing rate, and stamps older than the window do not count."""
    state = MonitorState(window=2.0)
    for k in range(601):  # 3 s of a 200 Hz state topic, all taken at once by a monitor that just joined
        state.ingest(SUPERVISOR_STATE_TOPIC, String(data='EXECUTE'), 100.0 + k / 200)
    assert state.rate(SUPERVISOR_STATE_TOPIC, now=103.0) == 200.0
    state.ingest(SUPERVISOR_STATE_TOPIC, String(data='EXECUTE'), 50.0)  # a stale stamp arriving late
    assert state.rate(SUPERVISOR_STATE_TOPIC, now=103.0) == 200.0
    assert state.topics[SUPERVISOR_STATE_TOPIC].count == 602 and state.topics[SUPERVISOR_STATE_TOPIC].first_wall == 50.0


@given(
    period=st.floats(min_value=1e-3, max_value=0.5),
    n=st.integers(min_value=2, max_value=3000),
    window=st.floats(min_value=0.1, max_value=5.0),
)
def test_rate_of_a_periodic_stream_is_within_one_message_per_window(period: float, n: int, window: float) -> None:
    stats = TopicStats()
    for k in range(n):
        stats.add(k * period, window)
    now = (n - 1) * period
    rate = stats.rate(now, window)
    assert rate is not None and math.isfinite(rate) and rate >= 0.0
    assert abs(rate - 1.0 / period) <= 1.0 / window + 1e-9 / period


def test_window_must_be_positive() -> None:
    for bad in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(ValueError, match='window='):
            MonitorState(window=bad)


# --------------------------------------------------------------------------- latest values


def test_every_line_topic_is_understood_with_its_message_class() -> None:
    state = MonitorState(LINE_TOPICS)
    for i, (topic, cls) in enumerate(LINE_TOPICS.items()):
        msg = cls()
        if cls is TimeReference and topic == EVENTS_TOPIC:
            msg = event('settled', 0)
        state.ingest(topic, msg, float(i))
    for topic, cls in LINE_TOPICS.items():  # a summary of the value, not the class name of an unknown topic
        assert state.topics[topic].latest not in ('-', cls.__name__), topic
    assert state.total == len(LINE_TOPICS)
    assert list(state.topics) == list(LINE_TOPICS)  # listed in the table's order


def test_sim_time_state_count_and_rtf() -> None:
    state = MonitorState(window=2.0)
    for k in range(401):  # 200 Hz of wall time at rtf 0.5
        state.ingest(CLOCK_TOPIC, clock(2_500_000 * k), 100.0 + k / 200)
    state.ingest(SUPERVISOR_STATE_TOPIC, String(data='STARTING'), 102.0)
    state.ingest(SHEET_COUNT_TOPIC, UInt64(data=68), 102.0)
    state.ingest(SHEET_RATE_TOPIC, Float64(data=13.6), 102.0)
    assert state.sim_time == 1.0 and state.rtf() == pytest.approx(0.5)
    head = state.render(140)[0]
    assert 'sim 1.000 s' in head and 'rtf 0.50' in head and 'supervisor STARTING |' in head
    assert 'sheets 68 (13.60/s)' in head  # the state found on joining has no 'since'
    state.ingest(CLOCK_TOPIC, clock(1_250_000_000), 102.1)
    state.ingest(SUPERVISOR_STATE_TOPIC, String(data='EXECUTE'), 102.1)
    assert 'supervisor EXECUTE since 1.25 s' in state.render(140)[0]
    state.ingest(CLOCK_TOPIC, clock(0), 102.2)  # a new line starts: its time, no rtf across the jump
    assert state.sim_time == 0.0 and state.rtf() is None


def test_joint_states_show_every_joint_with_position_velocity_effort() -> None:
    state = MonitorState(LINE_TOPICS)
    msg = JointState(
        name=['knife_crank', 'knife'], position=[5.48647, 0.185385], velocity=[87.2665, -2.93941], effort=[]
    )
    msg.header.stamp = ns_to_time_msg(5_031_000_000)
    state.ingest(CRANK, msg, 1.0)
    belt = JointState(name=['first_transporter'], position=[29.3467], velocity=[5.83333], effort=[12.5])
    state.ingest(joint_states_topic('belt_conveyor'), belt, 1.0)
    lines = state.render(120)
    assert row(lines, 'crank_drive/knife_crank') == ['crank_drive/knife_crank', '5.48647', '87.2665', '-', '5.031', 's']
    assert row(lines, 'crank_drive/knife')[1:3] == ['0.185385', '-2.93941']
    assert row(lines, 'belt_conveyor/first_transporter')[1:4] == ['29.3467', '5.83333', '12.5']
    assert row(lines, CRANK)[-5:] == ['2', 'joints', 'at', '5.031', 's']
    joints = [line.split()[0] for line in lines if '/' in line.split()[0] and not line.startswith('/')]
    assert joints == ['crank_drive/knife_crank', 'crank_drive/knife', 'belt_conveyor/first_transporter']


def test_latest_event_per_kind_with_its_time_in_kind_order() -> None:
    state = MonitorState()
    state.ingest(EVENTS_TOPIC, event('released_on_pile', 4_987_000_000, sheet=67, cycle=67, node='sheet_counter'), 1.0)
    state.ingest(EVENTS_TOPIC, event('bounce', 5_000_000_000, sheet=69, cycle=69, value=1.08e-7), 1.0)
    state.ingest(EVENTS_TOPIC, event('bounce', 5_013_000_000, sheet=69, cycle=69, value=2.5e-8), 1.1)
    state.ingest(EVENTS_TOPIC, event('knife_contact', 5_025_000_000, cycle=69, node='crank_drive'), 1.2)
    bogus = TimeReference(source='hello world')
    state.ingest(EVENTS_TOPIC, bogus, 1.3)  # not from the line: shown, not fatal
    lines = state.render(120)
    kinds = [line.split()[0] for line in lines[lines.index(next(x for x in lines if x.startswith('EVENT'))) + 1 :]]
    assert kinds == ['bounce', 'knife_contact', 'released_on_pile', 'hello']  # EVENT_KINDS order, unknown last
    assert EVENT_KINDS.index('bounce') < EVENT_KINDS.index('knife_contact') < EVENT_KINDS.index('released_on_pile')
    assert row(lines, 'bounce') == ['bounce', '2', '5.013', 's', '69', '69', '2.5e-08', 'n']
    assert row(lines, 'knife_contact')[4:6] == ['-', '69']  # sheet -1: none
    assert row(lines, 'released_on_pile')[-1] == 'sheet_counter'
    assert state.topics[EVENTS_TOPIC].latest == 'hello at 0.000 s'


def test_commands_keep_the_latest_eight() -> None:
    state = MonitorState()
    for k in range(10):
        state.ingest(COMMANDS_TOPIC, TimeReference(time_ref=ns_to_time_msg(k * NS), source=f'c{k}'), float(k))
    assert [c for c, _ in state.commands] == [f'c{k}' for k in range(2, 10)]
    assert state.render(300)[-1].startswith('DRIVE COMMANDS  c2 at 2.000 s, c3 at 3.000 s')


NS = 1_000_000_000

# --------------------------------------------------------------------------- constraints


def test_the_supervisors_own_diagnostics_render_as_one_row_per_constraint() -> None:
    scene = load_scene('folder')
    model = LineModel(scene, 10.0)  # the reference: one window, each row decided where it is decided
    fake = SimpleNamespace(
        scene=scene,
        stream=LineStream(scene),  # what the supervisor node judges on, advanced to each diagnostics stamp
        NODE_NAME='supervisor',
        rejected={},
        logic=SimpleNamespace(lost_nodes=[]),
        lockstep=SimpleNamespace(working=lambda stamp: None),
    )
    state = MonitorState()
    state.ingest(DIAGNOSTICS_TOPIC, Supervisor.diagnostics(fake, 0, 0.0), 1.0)  # nothing evaluated yet
    state.ingest(DIAGNOSTICS_TOPIC, Supervisor.diagnostics(fake, 5 * NS, 5.0), 2.0)
    lines = state.render(140)
    names = [c.name for c in model.constraints]
    assert names and list(state.constraints) == [f'folder_line/{n}' for n in names] + ['folder_line/supervisor/inputs']
    for c in model.constraints:
        decided = c.decided_by(5.0)
        words = row(lines, f'folder_line/{c.name}')
        smallest = format_margin(float(c.margin[decided].min()), c.unit, c.name, short=True)
        text = next(x for x in lines if x.startswith(f'folder_line/{c.name} '))
        assert words[1] == 'OK' and f' {smallest} ' in text, (text, smallest)  # in its own unit, as simulate
        assert f' 0/{int(decided.sum())} ' in text


def test_violations_and_smallest_margin() -> None:
    state = MonitorState()
    first = DiagnosticArray(
        status=[
            status('folder_line/feed_window', DiagnosticStatus.OK, 'no cycle evaluated yet', unit='s', evaluations='0'),
            status(
                'folder_line/rebound',
                DiagnosticStatus.ERROR,
                'violated in cycle 3',
                margin='-0.002',
                unit='m',
                cycle='3',
                min_margin='-0.002',
                violations='1',
                evaluations='4',
            ),
            status('custom/no_min', DiagnosticStatus.OK, 'ok', margin='0.5', unit='s'),
        ]
    )
    state.ingest(DIAGNOSTICS_TOPIC, first, 1.0)
    second = DiagnosticArray(
        status=[
            status(
                'folder_line/rebound',
                DiagnosticStatus.WARN,
                '1 violations so far',
                margin='0.001',
                unit='m',
                cycle='4',
                min_margin='-0.002',
                violations='1',
                evaluations='5',
            ),
            status('custom/no_min', DiagnosticStatus.OK, 'ok', margin='0.75', unit='s'),
        ]
    )
    state.ingest(DIAGNOSTICS_TOPIC, second, 2.0)
    styled = dict(state.render_styled(140))
    lines = list(styled)
    assert row(lines, 'folder_line/feed_window')[1:5] == ['OK', '-', '-', '-/0']
    rebound = next(x for x in lines if x.startswith('folder_line/rebound'))
    assert rebound.split()[1:7] == ['WARN', '+1.0000', 'mm', '-2.0000', 'mm', '1/5']  # each margin in its unit
    assert styled[rebound] == 'alert'
    assert row(lines, 'custom/no_min')[2:6] == [
        '+750.0000',
        'ms',
        '+500.0000',
        'ms',
    ]  # no min_margin: the smallest seen
    assert state.topics[DIAGNOSTICS_TOPIC].latest.endswith('1 WARN or ERROR')


# --------------------------------------------------------------------------- screen


def busy_state() -> MonitorState:
    state = MonitorState(LINE_TOPICS)
    for k in range(50):
        state.ingest(CLOCK_TOPIC, clock(k * 5_000_000), k / 200)
        js = JointState(
            name=[f'joint_with_a_rather_long_name_{j}' for j in range(4)],
            position=[1e9 * k] * 4,
            velocity=[-1.0] * 4,
            effort=[math.pi] * 4,
        )
        state.ingest(CRANK, js, k / 200)
        state.ingest(EVENTS_TOPIC, event(EVENT_KINDS[k % len(EVENT_KINDS)], k * NS, sheet=k, cycle=k), k / 200)
    state.ingest(SUPERVISOR_STATE_TOPIC, String(data='EXECUTE'), 0.3)
    state.ingest(LANDING_TOPIC, Float64(data=0.25), 0.3)
    return state


@settings(max_examples=60, deadline=None)
@given(width=st.integers(min_value=0, max_value=250), height=st.one_of(st.none(), st.integers(0, 80)))
def test_the_screen_always_fits(width: int, height: int | None) -> None:
    lines = busy_state().render(width, height)
    assert all(len(line) <= width for line in lines)
    if height is not None:
        assert len(lines) <= height
    if width >= MIN_WIDTH and (height is None or height >= MIN_HEIGHT):
        assert lines[0].startswith('folder-line monitor'[:width])
    else:
        shown = ''.join(lines)
        assert shown == 'terminal too small'[: len(shown)] or shown.startswith('terminal too small')
        assert shown or width == 0 or height == 0


def test_a_short_screen_says_what_it_hides() -> None:
    state = busy_state()
    full = state.render(120)
    short = state.render(120, 12)
    assert short[:11] == full[:11]
    assert short[11] == f'... {len(full) - 11} more lines: enlarge the terminal'
    assert state.render(30, 40) == ['terminal too small (30x40): ne', 'ed 40x6; q quits']


def test_before_any_message() -> None:
    lines = MonitorState(LINE_TOPICS).render(100, 30)
    assert 'supervisor ?' in lines[0] and 'waiting for the line' in lines[1]
    assert all(row(lines, topic)[1:] == ['0.0', '0', '-'] for topic in LINE_TOPICS)


# --------------------------------------------------------------------------- layering


def test_diagnostic_levels_are_those_of_the_message() -> None:
    names = ('OK', 'WARN', 'ERROR', 'STALE')
    assert {getattr(DiagnosticStatus, name)[0]: name for name in names} == LEVELS


def test_the_view_needs_no_ros_and_the_ros_side_no_cli() -> None:
    assert ros_modules_loaded('import folder_line.cli.monitor_view') == ('', [])
    tree = ast.parse(Path(ros_monitor.__file__).read_text(encoding='utf-8'))
    imported = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
    imported |= {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    assert not [m for m in imported if m and m.startswith('folder_line.cli')]


# --------------------------------------------------------------------------- command line


@pytest.mark.parametrize(
    'argv, text',
    [
        (['--rate', '0'], "--rate='0': must be in [0.1, 60] Hz"),
        (['--rate', 'fast'], "--rate='fast': must be a number"),
        (['--window', '-1'], "--window='-1': must be in [0.01, 600] s"),
    ],
)
def test_bad_options_exit_2_naming_the_value(argv: list[str], text: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(['monitor', *argv])
    assert exc.value.code == 2 and text in capsys.readouterr().err


def test_the_live_view_needs_a_terminal(capsys: pytest.CaptureFixture[str]) -> None:
    assert not sys.stdout.isatty()  # pytest captures it
    assert run_monitor() == 2
    assert 'use --once' in capsys.readouterr().err
