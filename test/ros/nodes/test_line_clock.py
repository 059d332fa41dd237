"""line_clock: lockstep ticks on the exact grid, the rtf ceiling, lost participants, wall mode, processes.

The clock runs in this process (the ``ros`` fixture) with :class:`FakeParticipant`
nodes that answer its ticks as a test tells them: at once, late, never, or only when
released. Every assertion on time is either exact (the stamps are integers on the
grid ``start_time + k / rate``) or an inequality that load cannot break (a message
arrives after it was published; an acknowledgement published late delays the next
tick); waits for completion have generous timeouts.
"""

from __future__ import annotations

import math
import signal
import subprocess
import sys
import time
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from hypothesis import given
from hypothesis import strategies as st
from rclpy.clock import Clock
from rclpy.clock_type import ClockType
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import TimeReference
from std_msgs.msg import String

from folder_line.core.supervision.lockstep import format_counts, format_ticks
from folder_line.errors import ParameterError
from folder_line.interfaces import (
    CLOCK_TOPIC,
    DIAGNOSTICS_TOPIC,
    GRANT_TOPIC,
    KNOWN_PARTICIPANTS,
    MACHINE_NODES,
    NS_PER_S,
    PARTICIPANTS_TOPIC,
    progress_topic,
    tick_done_topic,
)
from folder_line.ros.lockstep import ACK_QOS, GRANT_QOS, LINE_QOS, PARTICIPANTS_QOS
from folder_line.ros.lockstep_messages import (
    Announcement,
    format_announcement,
    grant_ticks,
    parse_announcement,
    read_ack,
    read_ticks,
)
from folder_line.ros.nodes.line_clock import EXIT_LOST, MAX_BURST, SPECS, LineClock, parse_participants
from folder_line.ros.ros_args import command_line_values
from folder_line.ros.signing import open_text, sign_text, without_signature
from folder_line.ros.time_msg import time_msg_to_ns

from .._signed import signed, time_reference

if TYPE_CHECKING:
    from ..conftest import Ros

REPO = Path(__file__).resolve().parents[3]
RELIABLE = QoSProfile(depth=10000, reliability=ReliabilityPolicy.RELIABLE)
MS = 1_000_000  # ns


# --------------------------------------------------------------------------- a participant the test drives


class FakeParticipant(Node):
    """A lockstep participant that acknowledges the ticks granted as the test says.

    Parameters
    ----------
    name : str
        Its participant name (one of ``KNOWN_PARTICIPANTS``); ``line_recorder``, the
        default, is waited for by ``line_clock`` only.
    delay : float
        Wall seconds from a tick's arrival to its acknowledgement (a one-shot steady timer).
    answers : int, optional
        Acknowledge only the first ``answers`` distinct ticks, then nothing.
    hold_from : int, optional
        Ticks at or after this stamp (ns) are held: not acknowledged until :meth:`run_to`.

    Attributes
    ----------
    ticks : list of int
        The distinct ticks received, in order (a repeated first tick once).
    arrival_ns : list of int
        Steady wall time (``time.monotonic_ns``) at which each of ``ticks`` first arrived.
    acked_ns : dict of int to int
        Tick -> steady wall time just before its first acknowledgement was published.
    held : int or None
        The tick being held.
    counts : dict of str to int
        What the acknowledgements say was published (the test publishes, if anything).
    """

    def __init__(
        self,
        context: Any,
        name: str = 'line_recorder',
        *,
        delay: float = 0.0,
        answers: int | None = None,
        hold_from: int | None = None,
    ) -> None:
        super().__init__(name, context=context)
        self.delay = delay
        self.answers = answers
        self.hold_from = hold_from
        self.pause_when: Any = None
        self.ticks: list[int] = []
        self.arrival_ns: list[int] = []
        self.acked_ns: dict[int, int] = {}
        self.held: int | None = None
        self.counts = {'messages': 0, 'events': 0, 'commands': 0}
        self.granted: int | None = None
        self.queue: list[int] = []  # ticks granted, not yet answered
        self.busy = False  # a delayed answer is under way
        self.grants = 0
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._pub = self.create_publisher(TimeReference, progress_topic(name), ACK_QOS)
        self.create_subscription(TimeReference, GRANT_TOPIC, self._on_grant, GRANT_QOS)

    def run_to(self, hold_from: int | None = None, when: Any = None) -> None:
        """Hold the ticks at or after ``hold_from`` (None: none), or from the first tick at whose arrival
        ``when(stamp)`` is true; go on with the ticks granted unless they are still to be held."""
        self.hold_from, self.pause_when = hold_from, when
        self.held = None
        self._work()

    def ack(self, stamp: int) -> None:
        """Publish the acknowledgement of ``stamp`` now."""
        msg = time_reference(self.get_name(), stamp, format_counts(self.counts), 'progress')
        self.acked_ns.setdefault(stamp, time.monotonic_ns())
        self._pub.publish(msg)

    def _on_grant(self, msg: TimeReference) -> None:
        self.grants += 1
        ticks = grant_ticks(msg, self.granted)
        if not ticks:
            if time_msg_to_ns(msg.header.stamp) in self.acked_ns:
                self.ack(time_msg_to_ns(msg.header.stamp))  # the repeated first grant: answer again
            return
        self.granted = ticks[-1]
        now = time.monotonic_ns()
        for stamp in ticks:
            self.ticks.append(stamp)
            self.arrival_ns.append(now)
        self.queue.extend(ticks)
        self._work()

    def _work(self) -> None:
        """Answer the queued ticks in order: at once, or each ``delay`` after the one before."""
        while self.queue and not self.busy and self.held is None:
            stamp = self.queue[0]
            if self.answers is not None and len(self.acked_ns) >= self.answers:
                return
            if (self.hold_from is not None and stamp >= self.hold_from) or (
                self.pause_when is not None and self.pause_when(stamp)
            ):
                self.held = stamp
                return
            self.queue.pop(0)
            if self.delay <= 0.0:
                self.ack(stamp)
                continue
            self._answer_later(stamp)
            return

    def _answer_later(self, stamp: int) -> None:
        """Answer ``stamp`` after ``delay`` s of wall time, then go on with the queue."""
        self.busy = True
        timer: list[Any] = []

        def later() -> None:
            timer[0].cancel()
            self.destroy_timer(timer[0])
            self.ack(stamp)
            self.busy = False
            self._work()

        timer.append(self.create_timer(self.delay, later, clock=self._steady))


def grid(start_ns: int, end_ns: int, step_ns: int) -> list[int]:
    """The clock's ticks from ``start_ns`` to ``end_ns`` inclusive: the grid, then ``end_ns`` if off it."""
    ticks = list(range(start_ns, end_ns + 1, step_ns))
    return ticks if ticks[-1] == end_ns else [*ticks, end_ns]


def params(**values: Any) -> list[Parameter]:
    return [Parameter(name, value=value) for name, value in values.items()]


def make_clock(ros: Ros, **values: Any) -> LineClock:
    """``line_clock`` waiting for ``line_recorder`` only, unless told otherwise."""
    values.setdefault('participants', 'line_recorder')
    return ros.add(LineClock(context=ros.context, parameter_overrides=params(**values)))


def distinct(stamps: Iterable[int]) -> list[int]:
    """``stamps`` without consecutive repeats (the clock repeats its first tick)."""
    out: list[int] = []
    for s in stamps:
        if not out or out[-1] != s:
            out.append(s)
    return out


def clock_stamps(received: Any) -> list[int]:
    return [time_msg_to_ns(m.clock) for m in received.messages]


# --------------------------------------------------------------------------- no graph


def test_specs() -> None:
    by_name = {s.name: s for s in SPECS}
    assert {n: s.default for n, s in by_name.items()} == {
        'rate': 200.0,
        'rtf': 1.0,
        'clock': 'lockstep',
        'participants': ','.join(MACHINE_NODES),
        'start_time': 0.0,
        'duration': 0.0,
        'lost_timeout': 3.0,
        'startup_timeout': 60.0,
        'window': 0.5,
    }
    assert by_name['rtf'].bounds == (0.0, 1000.0) and not by_name['rtf'].low_open
    assert by_name['rate'].bounds == (1.0, 10000.0)
    assert by_name['clock'].choices == ('lockstep', 'wall')
    assert {n for n, s in by_name.items() if not s.read_only} == {'rate', 'rtf'}


def test_participants_are_parsed_and_checked() -> None:
    assert parse_participants(' crank_drive, supervisor ,line_recorder') == (
        'crank_drive',
        'supervisor',
        'line_recorder',
    )
    for text, words in [
        ('crank_drive,jumper', 'unknown node(s) jumper'),
        ('supervisor,supervisor', 'names a node twice'),
        (' , ', 'names no node'),
    ]:
        with pytest.raises(ParameterError, match=r'^participants=') as info:
            parse_participants(text)
        assert words in str(info.value)


@given(
    names=st.lists(st.sampled_from(KNOWN_PARTICIPANTS), min_size=1, unique=True),
    clock=st.sampled_from(('lockstep', 'wall')),
    end=st.one_of(st.none(), st.integers(min_value=0, max_value=10**19 - 1)),
)
def test_announcement_round_trip(names: list[str], clock: str, end: int | None) -> None:
    a = Announcement(clock, end, tuple(names))
    text = format_announcement(a)
    assert parse_announcement(text) == a
    assert text.startswith(f'clock={clock} end=')


@pytest.mark.parametrize(
    ('text', 'words'),
    [
        ('', 'needs exactly clock=, end= and participants='),
        ('clock=lockstep end=none', 'needs exactly'),
        ('clock=lockstep end=none participants=crank_drive extra=1', 'needs exactly'),
        ('clock=banana end=none participants=crank_drive', "clock='banana': must be one of lockstep, wall"),
        ('clock=lockstep end=-5 participants=crank_drive', "end='-5': must be none or integer ns"),
        ('clock=lockstep end=1e9 participants=crank_drive', "end='1e9'"),
        ('clock=lockstep end=none participants=jumper', 'must be distinct names among'),
        ('clock=lockstep end=none participants=supervisor,supervisor', 'must be distinct names'),
        ('clock=lockstep end=none participants=', 'must be distinct names'),
        ('x' * 1001, 'characters (at most 1000)'),
    ],
)
def test_a_malformed_announcement_is_refused_with_the_reason(text: str, words: str) -> None:
    with pytest.raises(ValueError) as info:
        parse_announcement(sign_text(text, 'announcement'))  # signed: the text itself is refused
    assert words in str(info.value)


def test_an_announcement_not_signed_with_the_line_key_is_refused() -> None:
    text = format_announcement(Announcement('lockstep', None, ('crank_drive',)))
    for forged in (without_signature(text), text.replace('crank_drive', 'supervisor')):
        with pytest.raises(ValueError, match=r'^announcement: (unsigned|signature does not match)'):
            parse_announcement(forged)


@given(
    frame=st.text(max_size=60),
    stamp=st.integers(min_value=0, max_value=2**31 * NS_PER_S - 1),
    counts=st.fixed_dictionaries(
        {s: st.integers(min_value=0, max_value=2**63 - 1) for s in ('messages', 'events', 'commands')}
    ),
)
def test_an_acknowledgement_is_read_from_its_cdr_bytes_as_rclpy_wrote_them(
    frame: str, stamp: int, counts: dict[str, int]
) -> None:
    # read_ack decodes the raw bytes with rosbags: checked against rclpy's own serialization and deserialization
    msg = time_reference(frame, stamp, format_counts(counts), 'progress')
    data = serialize_message(msg)
    # a ROS string ends at its first NUL: rclpy reads '\x00' back as '' too
    assert deserialize_message(data, TimeReference).header.frame_id == frame.split('\x00', 1)[0]
    assert read_ack(data) == (frame.split('\x00', 1)[0], stamp, counts, stamp)


def test_the_acknowledgements_of_several_ticks_are_read_from_one_message() -> None:
    """tick_done carries every tick since the previous one (format_ticks): read back in order, with the
    promise of the last; a text that is not one is refused with the reason."""
    ticks = [
        (5_000_000 * k, {'messages': 3 * k, 'events': k // 2, 'commands': 0, '/line/events': k // 2}) for k in (1, 2, 3)
    ]
    msg = time_reference('crank_drive', ticks[-1][0], format_ticks(ticks), 'tick_done', ticks[-1][0] + 7)
    assert read_ticks(serialize_message(msg)) == ('crank_drive', ticks, ticks[-1][0] + 7)
    changed = without_signature(msg.source) + ' | 99999999999 messages=1'  # a tick before 0
    with pytest.raises(ValueError, match='signature does not match'):
        read_ticks(serialize_message(time_reference('crank_drive', 0, changed, 'progress', ticks[-1][0] + 7)))
    with pytest.raises(ValueError, match='tick gap'):
        read_ticks(
            serialize_message(time_reference('crank_drive', ticks[-1][0], changed, 'tick_done', ticks[-1][0] + 7))
        )


@given(data=st.binary(max_size=300))
def test_bytes_that_are_no_acknowledgement_are_refused_with_a_reason(data: bytes) -> None:
    good = time_reference('crank_drive', 0, format_counts({'messages': 1}), 'progress')
    try:
        read_ack(data)
    except ValueError as err:
        assert str(err)  # a reason, and nothing but ValueError
    else:  # random bytes may happen to be a valid acknowledgement: then it is one rclpy reads the same
        assert deserialize_message(data, TimeReference).source.startswith('messages=')
    with pytest.raises(ValueError, match='not a sensor_msgs/TimeReference'):
        read_ack(serialize_message(good)[:-3])
    with pytest.raises(ValueError, match="unexpected item 'garbage'"):
        read_ack(serialize_message(time_reference('crank_drive', 0, 'garbage', 'progress')))
    with pytest.raises(ValueError, match='unsigned, on a keyed line'):
        read_ack(serialize_message(TimeReference(source=format_counts({'messages': 1}))))


def test_topics_of_the_protocol() -> None:
    assert PARTICIPANTS_TOPIC == '/line/participants'
    assert tick_done_topic('crank_drive') == '/line/crank_drive/tick_done'
    assert progress_topic('crank_drive') == '/line/crank_drive/progress'
    assert PARTICIPANTS_QOS.depth == 1


# --------------------------------------------------------------------------- lockstep in this process


@pytest.mark.parametrize(('start', 'duration', 'rate'), [(2.5, 1.5, 200.0), (0.0, 0.1, 300.0)])
def test_lockstep_publishes_every_tick_of_the_grid_up_to_the_end_exactly(
    ros: Ros, start: float, duration: float, rate: float
) -> None:
    listener = ros.node('listener')
    announced = ros.subscribe(listener, String, PARTICIPANTS_TOPIC, PARTICIPANTS_QOS)
    fake = ros.add(FakeParticipant(ros.context))
    clock = make_clock(ros, start_time=start, duration=duration, rate=rate, rtf=0.0)
    start_ns, end_ns = round(start * NS_PER_S), round((start + duration) * NS_PER_S)
    assert ros.spin_until(clock.done.done, timeout=30.0)
    expected = grid(start_ns, end_ns, round(NS_PER_S / rate))
    assert fake.ticks == expected  # 301 ticks at 200 Hz; at 300 Hz 3333333 ns steps, then 0.1 s exactly
    assert clock.done.result() == end_ns and clock.ticks == len(expected) and clock.current == end_ns
    ros.spin_for(0.2)  # stopped: nothing after the end
    assert fake.ticks == expected and clock.ticks == len(expected)
    assert ros.spin_until(lambda: len(announced) == 1, timeout=10.0)
    assert [open_text(m.data, 'announcement') for m in announced.messages] == [
        f'clock=lockstep end={end_ns} participants=line_recorder'
    ]
    assert clock.lost == {} and clock.rejected == 0


def test_the_first_tick_is_granted_again_until_a_late_participant_answers_it(ros: Ros) -> None:
    listener = ros.node('listener')
    received = ros.subscribe(listener, ClockMsg, CLOCK_TOPIC, RELIABLE)
    grants = ros.subscribe(listener, TimeReference, GRANT_TOPIC, RELIABLE)
    clock = make_clock(ros, rate=100.0, duration=0.05, rtf=0.0)
    # nobody answers: the first tick granted again and again (a late subscriber gets it)
    assert ros.spin_until(lambda: len(grants) >= 3, timeout=20.0)
    assert {time_msg_to_ns(g.header.stamp) for g in grants.messages} == {0} and clock.current == 0
    assert clock_stamps(received) == [0] and clock.ticks == 1  # /clock once per tick
    fake = ros.add(FakeParticipant(ros.context))  # comes late, gets the first tick all the same
    assert ros.spin_until(clock.done.done, timeout=20.0)
    assert fake.ticks == grid(0, 50 * MS, 10 * MS) and clock.ticks == 6
    assert ros.spin_until(lambda: len(received) == 6, timeout=10.0)
    assert clock_stamps(received) == fake.ticks


def test_with_no_window_the_clock_waits_for_a_slow_participant_tick_by_tick(ros: Ros) -> None:
    slow = ros.add(FakeParticipant(ros.context, 'line_recorder', delay=0.02))
    prompt = ros.add(FakeParticipant(ros.context, 'crank_drive'))
    clock = make_clock(ros, participants='crank_drive,line_recorder', rate=100.0, duration=0.3, rtf=1.0, window=0.0)
    assert ros.spin_until(clock.done.done, timeout=30.0)
    expected = grid(0, 300 * MS, 10 * MS)
    assert slow.ticks == prompt.ticks == expected and clock.ticks == 31
    # tick k + 1 reached the prompt participant only after the slow one had acknowledged tick k
    for k in range(1, len(expected)):
        assert prompt.arrival_ns[k] > slow.acked_ns[expected[k - 1]], k
    # so sim time slowed down: 30 acknowledgements of at least 20 ms each for 0.3 s of sim time
    assert clock.rtf_achieved <= 0.3 / (30 * 0.02)
    assert clock.lost == {} and clock.late == {'crank_drive': 0, 'line_recorder': 0}


def test_the_clock_grants_up_to_its_window_ahead_of_the_slowest_participant(ros: Ros) -> None:
    slow = ros.add(FakeParticipant(ros.context, 'line_recorder', delay=0.01))
    prompt = ros.add(FakeParticipant(ros.context, 'crank_drive'))
    clock = make_clock(ros, participants='crank_drive,line_recorder', rate=100.0, duration=1.0, rtf=0.0, window=0.1)
    assert ros.spin_until(clock.done.done, timeout=60.0)
    expected = grid(0, NS_PER_S, 10 * MS)
    assert slow.ticks == prompt.ticks == expected and clock.ticks == 101 and clock.lost == {}
    acked = sorted(slow.acked_ns.items())
    ahead = 0
    for stamp, arrival in zip(prompt.ticks[1:], prompt.arrival_ns[1:], strict=True):
        # granted only once the slow one had answered the tick a window (0.1 s) before it
        answered = max((s for s, at in acked if at <= arrival), default=-1)
        assert stamp <= answered + 100 * MS, (stamp, answered)
        ahead = max(ahead, stamp - answered)
    assert ahead > 10 * MS  # it did run ahead: not a barrier per tick


@pytest.mark.parametrize('rtf', [0.5, 4.0])
def test_sim_time_is_never_ahead_of_rtf_times_wall_time(ros: Ros, rtf: float) -> None:
    fake = ros.add(FakeParticipant(ros.context))
    clock = make_clock(ros, rate=100.0, duration=0.2, rtf=rtf)
    assert ros.spin_until(clock.done.done, timeout=30.0)
    assert fake.ticks == grid(0, 200 * MS, 10 * MS)
    w0 = clock.first_done_wall  # the ceiling counts from the first tick every participant answered
    assert w0 is not None
    for stamp, arrival in zip(fake.ticks[1:], fake.arrival_ns[1:], strict=True):
        assert stamp / NS_PER_S <= rtf * (arrival / NS_PER_S - w0), (stamp, arrival / NS_PER_S - w0)
    assert 0.0 < clock.rtf_achieved <= rtf


def test_after_a_stall_sim_time_does_not_run_faster_than_rtf_to_catch_up(ros: Ros) -> None:
    fake = ros.add(FakeParticipant(ros.context, hold_from=100 * MS))
    clock = make_clock(ros, rate=100.0, duration=0.6, rtf=1.0, lost_timeout=60.0, window=0.05)
    assert ros.spin_until(lambda: fake.held == 100 * MS, timeout=30.0)
    ros.spin_for(0.5)  # a stall of half a second of wall time
    granted = fake.granted
    assert granted is not None and granted <= 150 * MS  # at most the window ahead of the participant
    fake.run_to(None)
    resumed = time.monotonic_ns()
    assert ros.spin_until(clock.done.done, timeout=30.0)
    assert fake.ticks == grid(0, 600 * MS, 10 * MS)
    # the ceiling counts afresh after the stall, from the first tick granted after it (granted after `resumed`),
    # with at most MAX_BURST of catching up: never faster than rtf beyond that
    later = [(s, a) for s, a in zip(fake.ticks, fake.arrival_ns, strict=True) if s > granted]
    s0 = later[0][0]
    burst = round(MAX_BURST * NS_PER_S)
    assert later[0][1] >= resumed
    for stamp, arrival in later[1:]:
        assert stamp - s0 <= (arrival - resumed) + burst, (stamp - s0, arrival - resumed)
    # without the fresh count the whole stall (0.5 s) would have been caught up at once
    assert (later[-1][1] - resumed) / NS_PER_S >= (later[-1][0] - s0) / NS_PER_S - MAX_BURST


def test_rate_and_rtf_changes_apply_from_the_current_tick(ros: Ros) -> None:
    fake = ros.add(FakeParticipant(ros.context, hold_from=100 * MS))
    clock = make_clock(ros, rate=100.0, duration=0.3, rtf=0.0, lost_timeout=60.0, window=0.0)
    assert ros.spin_until(lambda: fake.held == 100 * MS, timeout=30.0)
    result = clock.set_parameters_atomically(
        signed('line_clock', [Parameter('rate', value=50.0), Parameter('rtf', value=0.5)])
    )
    assert result.successful, result.reason
    fake.run_to(None)
    assert ros.spin_until(clock.done.done, timeout=30.0)
    # 10 ms steps up to the change, then 20 ms from the tick current at the change, to the end exactly
    assert fake.ticks == grid(0, 100 * MS, 10 * MS) + list(range(120 * MS, 300 * MS + 1, 20 * MS))
    # rtf 0.5 from the change: measured from no later than the tick's publication (after the acknowledgement
    # of the tick before), sim time never runs ahead of half the wall time
    i = fake.ticks.index(100 * MS)
    published_after = fake.acked_ns[90 * MS]
    for stamp, arrival in zip(fake.ticks[i + 1 :], fake.arrival_ns[i + 1 :], strict=True):
        assert (stamp - 100 * MS) <= 0.5 * (arrival - published_after), stamp


def test_rtf_0_has_no_ceiling(ros: Ros) -> None:
    """1000 ticks of 0.1 s: 100 s of sim time, done well before 100 s of wall time."""
    fake = ros.add(FakeParticipant(ros.context))
    clock = make_clock(ros, rate=10.0, duration=100.0, rtf=0.0)
    assert ros.spin_until(clock.done.done, timeout=60.0)
    assert fake.ticks == grid(0, 100 * NS_PER_S, 100 * MS) and clock.ticks == 1001
    assert clock.rtf_achieved > 100.0 / 60.0


def test_a_silent_participant_is_waited_for_and_lost_only_once_it_leaves_the_graph(ros: Ros) -> None:
    listener = ros.node('listener')
    diags = ros.subscribe(listener, DiagnosticArray, DIAGNOSTICS_TOPIC, LINE_QOS)
    prompt = ros.add(FakeParticipant(ros.context, 'line_recorder'))
    silent = ros.add(FakeParticipant(ros.context, 'crank_drive', answers=1))  # the first tick only
    clock = make_clock(
        ros, participants='crank_drive,line_recorder', rate=100.0, duration=0.2, rtf=0.0, lost_timeout=0.5, window=0.0
    )
    # alive (in the graph) but silent: waited for, and said so on /diagnostics, never lost
    assert ros.spin_until(lambda: 'crank_drive' in clock.waiting, timeout=20.0)
    assert ros.spin_until(
        lambda: any(s.name == 'folder_line/line_clock/waiting' for d in diags.messages for s in d.status), timeout=10.0
    )
    ros.spin_for(1.0)
    assert clock.lost == {} and clock.current == 10 * MS and not clock.done.done()
    [waiting] = [s for d in diags.messages for s in d.status if s.name.endswith('/waiting')]
    values = {kv.key: kv.value for kv in waiting.values}
    assert waiting.level == DiagnosticStatus.WARN and values['node'] == 'crank_drive'
    assert float(values['silent_wall_s']) > 0.5
    # its process ends (its node leaves the graph): now it is lost, named with the tick it did not answer
    silent_acked = dict(silent.acked_ns)
    ros.remove(silent)
    assert ros.spin_until(lambda: 'crank_drive' in clock.lost, timeout=20.0)
    assert clock.lost == {'crank_drive': 0.01} and 'crank_drive' not in clock.waiting
    assert ros.spin_until(clock.done.done, timeout=20.0)
    assert prompt.ticks == grid(0, 200 * MS, 10 * MS) and clock.ticks == 21
    assert list(silent_acked) == [0]
    assert ros.spin_until(
        lambda: any(s.name == 'folder_line/line_clock/lost' for d in diags.messages for s in d.status), timeout=10.0
    )
    [status] = [s for d in diags.messages for s in d.status if s.name.endswith('/lost')]
    values = {kv.key: kv.value for kv in status.values}
    assert status.level == DiagnosticStatus.ERROR and status.message == 'participant crank_drive lost at 0.010000000 s'
    assert (values['node'], values['tick'], values['limit_s']) == ('crank_drive', '0.01', '0.5')
    assert float(values['waited_wall_s']) >= 0.5  # waited > 0.5, printed to the ms


def test_a_participant_that_answers_again_is_taken_back(ros: Ros) -> None:
    listener = ros.node('listener')
    diags = ros.subscribe(listener, DiagnosticArray, DIAGNOSTICS_TOPIC, LINE_QOS)
    prompt = ros.add(FakeParticipant(ros.context, 'line_recorder'))
    paused = ros.add(FakeParticipant(ros.context, 'crank_drive', hold_from=50 * MS))
    clock = make_clock(
        ros, participants='crank_drive,line_recorder', rate=100.0, duration=0.2, rtf=0.0, lost_timeout=0.3
    )
    assert ros.spin_until(lambda: 'crank_drive' in clock.waiting, timeout=20.0)
    paused.run_to(None)  # cut off for a while, then back: nothing lost
    assert ros.spin_until(clock.done.done, timeout=20.0)
    assert clock.lost == {} and clock.waiting == {}
    assert paused.ticks == prompt.ticks == grid(0, 200 * MS, 10 * MS)
    assert ros.spin_until(
        lambda: any(s.name == 'folder_line/line_clock/resumed' for d in diags.messages for s in d.status), timeout=10.0
    )


def test_malformed_and_foreign_acknowledgements_are_rejected_and_counted(ros: Ros) -> None:
    fake = ros.add(FakeParticipant(ros.context, hold_from=50 * MS))
    clock = make_clock(ros, rate=100.0, duration=0.1, rtf=0.0, lost_timeout=60.0, window=0.0)
    hostile = ros.node('hostile')
    pub = hostile.create_publisher(TimeReference, progress_topic('line_recorder'), ACK_QOS)
    assert ros.spin_until(lambda: fake.held == 50 * MS and pub.get_subscription_count() == 1, timeout=20.0)
    for frame, source in [
        ('line_recorder', 'garbage'),
        ('line_recorder', 'messages=1 events=0'),
        ('line_recorder', 'messages=-1 events=0 commands=0'),
        ('crank_drive', 'messages=0 events=0 commands=0'),
    ]:
        pub.publish(time_reference(frame, 50 * MS, source, 'progress'))
    assert ros.spin_until(lambda: clock.rejected == 4, timeout=10.0)
    assert clock.current == 50 * MS  # none of them counted as line_recorder's answer
    fake.run_to(None)
    assert ros.spin_until(clock.done.done, timeout=20.0)
    assert fake.ticks == grid(0, 100 * MS, 10 * MS) and clock.rejected == 4 and clock.lost == {}


def test_wall_mode_paces_by_the_wall_clock_and_counts_late_participants(ros: Ros) -> None:
    listener = ros.node('listener')
    diags = ros.subscribe(listener, DiagnosticArray, DIAGNOSTICS_TOPIC, LINE_QOS)
    late = ros.add(FakeParticipant(ros.context, hold_from=10 * MS))
    clock = make_clock(ros, clock='wall', rate=100.0, duration=0.2, rtf=1.0, lost_timeout=60.0)
    # it answers nothing from 0.01 s on: the wall clock publishes every tick anyway
    assert ros.spin_until(lambda: late.granted == 200 * MS, timeout=30.0)
    assert late.held == 10 * MS
    assert late.ticks == grid(0, 200 * MS, 10 * MS)
    assert not clock.done.done()  # the last tick waits for its answer (or lost_timeout)
    late.run_to(None)  # answers the last tick
    assert ros.spin_until(clock.done.done, timeout=20.0)
    assert clock.late == {'line_recorder': 19}  # late at the ticks 0.02 ... 0.2 s: 0.01 ... 0.19 s unanswered
    assert clock.lost == {} and clock.ticks == 21
    w0 = clock.first_done_wall
    assert w0 is not None
    for stamp, arrival in zip(late.ticks[1:], late.arrival_ns[1:], strict=True):
        assert stamp / NS_PER_S <= arrival / NS_PER_S - w0  # rtf 1: the wall clock is a ceiling here too
    assert ros.spin_until(lambda: len(diags) == 1, timeout=10.0)
    [status] = diags.messages[0].status
    assert status.name == 'folder_line/line_clock/lateness'
    assert status.level == DiagnosticStatus.WARN and status.message == 'late ticks: line_recorder 19'
    assert {kv.key: kv.value for kv in status.values} == {'line_recorder': '19'}
    assert time_msg_to_ns(diags.messages[0].header.stamp) == 200 * MS


# --------------------------------------------------------------------------- parameters


def test_parameters_of_the_clock_are_validated(ros: Ros) -> None:
    clock = make_clock(ros)
    for name, value, reason in [
        ('rtf', math.nan, 'rtf=nan: must be finite (not NaN or inf)'),
        ('rtf', 0.0005, 'rtf=0.0005 rejected: rtf=0.0005: must be 0 (no ceiling) or in [0.001, 1000]'),
        ('rtf', 1000.5, 'rtf=1000.5: must be a float in [0, 1000]'),
        ('rtf', -1.0, 'rtf=-1.0: must be a float in [0, 1000]'),
        ('rtf', True, 'rtf=True: must be a float, got bool'),  # an integer is taken (as a float)
        ('rate', math.inf, 'rate=inf: must be finite (not NaN or inf)'),
        ('rate', 0.5, 'rate=0.5: must be a float in [1, 10000] Hz'),
        ('use_sim_time', True, 'use_sim_time=True rejected: use_sim_time=True: line_clock publishes /clock'),
    ]:
        result = clock.set_parameters_atomically(signed('line_clock', [Parameter(name, value=value)]))
        assert (result.successful, result.reason[: len(reason)]) == (False, reason)
    for name, value in [
        ('clock', 'wall'),
        ('participants', 'crank_drive'),
        ('start_time', 1.0),
        ('duration', 1.0),
        ('lost_timeout', 1.0),
        ('startup_timeout', 2.0),
        ('window', 1.0),
    ]:
        result = clock.set_parameters_atomically(signed('line_clock', [Parameter(name, value=value)]))
        assert not result.successful and 'read-only' in result.reason and name in result.reason
    assert clock.get_parameter('rtf').value == 1.0 and clock.get_parameter('rate').value == 200.0
    assert clock.get_parameter('use_sim_time').value is False
    [result] = clock.set_parameters([Parameter('rtf', value=0.0)])
    assert not result.successful and 'must be signed' in result.reason  # a keyed line's change is signed
    result = clock.set_parameters_atomically(signed('line_clock', [Parameter('rtf', value=0.0)]))
    assert result.successful  # 0: no ceiling, in lockstep


@pytest.mark.parametrize(
    ('overrides', 'message'),
    [
        ({'use_sim_time': True}, 'use_sim_time=True: line_clock publishes /clock'),
        ({'clock': 'wall', 'rtf': 0.0}, 'rtf=0.0: must be > 0 with clock=wall'),
        ({'participants': 'crank_drive,crank_drive'}, "participants='crank_drive,crank_drive': names a node twice"),
        ({'clock': 'banana'}, "clock='banana': must be one of lockstep, wall"),
    ],
)
def test_the_clock_refuses_to_start_on_a_bad_parameter(ros: Ros, overrides: dict[str, Any], message: str) -> None:
    """The node refuses, and ``refuse_start`` (the process's check of its command line, before DDS) refuses
    the same values in the same words."""
    with pytest.raises(ParameterError) as info:
        LineClock(context=ros.context, parameter_overrides=params(**overrides))
    assert str(info.value).startswith(message)
    with pytest.raises(ParameterError) as before_dds:
        LineClock.refuse_start(overrides)
    assert str(before_dds.value) == str(info.value)


def test_a_good_start_passes_the_command_line_check() -> None:
    good = ['--ros-args', '-p', 'participants:=crank_drive', '-p', 'rate:=100', '-p', 'rtf:=2', '--', 'extra']
    given = command_line_values(good, 'line_clock')
    assert given == {'participants': 'crank_drive', 'rate': 100, 'rtf': 2}
    LineClock.refuse_start(given)


# --------------------------------------------------------------------------- the node as a process


def start(node_env: dict[str, str], tmp_path: Path, *args: str, tag: str = '') -> tuple[subprocess.Popen[bytes], Path]:
    cmd = [sys.executable, '-m', 'folder_line.ros.nodes.line_clock', '--ros-args']
    for arg in args:
        cmd += ['-p', arg]
    err = tmp_path / f'stderr{tag}.txt'
    with open(err, 'wb') as error:
        process = subprocess.Popen(cmd, env=node_env, cwd=REPO, stdout=subprocess.DEVNULL, stderr=error)
    return process, err


def stop(process: subprocess.Popen[bytes]) -> None:
    if process.poll() is None:
        process.kill()
        process.wait(timeout=10)


@pytest.mark.parametrize('signum', [signal.SIGINT, signal.SIGTERM])
def test_process_runs_in_lockstep_across_processes_and_exits_0_on_signal(
    ros: Ros, node_env: dict[str, str], tmp_path: Path, signum: int
) -> None:
    fake = ros.add(FakeParticipant(ros.context))
    process, err = start(node_env, tmp_path, 'participants:=line_recorder', 'rate:=50.0', 'rtf:=2.0')
    try:
        assert ros.spin_until(lambda: len(fake.ticks) >= 10, timeout=30.0), err.read_text()
        assert fake.ticks[:10] == grid(0, 180 * MS, 20 * MS)
        process.send_signal(signum)
        assert process.wait(timeout=15) == 0
    finally:
        stop(process)
    text = err.read_text()
    assert 'Traceback' not in text and 'error' not in text.lower(), text


def test_process_exits_0_by_itself_after_duration(ros: Ros, node_env: dict[str, str], tmp_path: Path) -> None:
    fake = ros.add(FakeParticipant(ros.context))
    process, err = start(
        node_env, tmp_path, 'participants:=line_recorder', 'duration:=2.0', 'rtf:=0.0', 'start_time:=1.0'
    )
    try:
        assert ros.spin_until(lambda: process.poll() is not None, timeout=30.0), err.read_text()
        assert process.returncode == 0
    finally:
        stop(process)
    text = err.read_text()
    assert 'stopped at sim time 3.000000000 s: duration reached (401 ticks' in text
    assert 'Traceback' not in text, text
    assert fake.ticks == grid(NS_PER_S, 3 * NS_PER_S, 5 * MS)


def test_process_exits_3_when_a_participant_was_lost(node_env: dict[str, str], tmp_path: Path) -> None:
    process, err = start(
        node_env, tmp_path, 'participants:=crank_drive', 'duration:=0.1', 'rtf:=0.0', 'startup_timeout:=1.0'
    )
    try:  # nobody answers as crank_drive: lost after startup_timeout, then the clock runs to the end alone
        assert process.wait(timeout=60) == EXIT_LOST == 3
    finally:
        stop(process)
    text = err.read_text()
    assert 'participant crank_drive lost: no answer to tick 0.000000000 s' in text
    assert 'stopped at sim time 0.100000000 s: duration reached (21 ticks' in text and '; lost: crank_drive' in text
    assert 'Traceback' not in text, text


# At start rclpy applies the descriptors to the overrides itself (no pre-set callback runs
# on declaration), so values outside a finite range or of the wrong type get rclpy's words;
# they still name the parameter and the value.
BAD_STARTS = [
    (('rtf:=0.0005',), 'line_clock: error: rtf=0.0005: must be 0 (no ceiling) or in [0.001, 1000]'),
    (('clock:=wall', 'rtf:=0.0'), 'line_clock: error: rtf=0.0: must be > 0 with clock=wall'),
    (
        ('participants:=crank_drive,jumper',),
        "line_clock: error: participants='crank_drive,jumper': unknown node(s) jumper",
    ),
    (('duration:=-1.0',), 'line_clock: error: duration=-1.0: must be a float in [0, 1e+07] s'),
    (('rate:=nan',), 'line_clock: error: rate=nan: must be finite (not NaN or inf)'),
    (('rtf:=true',), 'line_clock: error: rtf=True: must be a float, got bool'),  # rtf:=5 is taken, as 5.0
]


#: a ROS domain no participant can be made on (Fast DDS's ports for it are out of range): a process that
#: made one would print Fast DDS's errors and end otherwise
NO_DOMAIN = '250'


def test_process_refuses_a_bad_parameter_with_exit_code_2(node_env: dict[str, str], tmp_path: Path) -> None:
    """Each bad start ends in exit code 2 and its one line, read from the command line before the process makes
    a DDS participant: on a domain where none can be made, nothing else is printed."""
    env = {**node_env, 'ROS_DOMAIN_ID': NO_DOMAIN}
    procs = [start(env, tmp_path, *args, tag=str(i)) for i, (args, _) in enumerate(BAD_STARTS)]
    try:
        for (args, message), (process, err) in zip(BAD_STARTS, procs, strict=True):
            assert process.wait(timeout=60) == 2, (args, err.read_text())
            lines = err.read_text().splitlines()
            assert len(lines) == 1 and lines[0].startswith(message), (args, lines)
    finally:
        for process, _ in procs:
            stop(process)
