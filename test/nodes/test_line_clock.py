"""line_clock: exact sim-time arithmetic, /clock over real DDS, process exit codes."""

from __future__ import annotations

import math
import signal
import subprocess
import sys
import time
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock as ClockMsg

from folder_line.errors import ParameterError
from folder_line.nodes.common import CLOCK_TOPIC, NS_PER_S, time_msg_to_ns
from folder_line.nodes.line_clock import SPECS, LineClock, SimTimeline

if TYPE_CHECKING:
    from conftest import Received, Ros

REPO = Path(__file__).resolve().parents[2]

# --------------------------------------------------------------------------- SimTimeline (no graph)


def test_rtf_1_is_the_identity_on_elapsed_wall_time() -> None:
    line = SimTimeline(sim_0=5 * NS_PER_S, wall_0=10**12, rtf=1.0)
    for elapsed in (0, 1, 999_999_999, 10**15 + 7):
        assert line.at(10**12 + elapsed) == 5 * NS_PER_S + elapsed
    assert line.at(10**12 - 5) == 5 * NS_PER_S  # before the origin: the start


@given(rtf=st.floats(min_value=1e-6, max_value=1000.0), elapsed=st.integers(min_value=0, max_value=10**17))
def test_no_drift_however_far_from_the_origin(rtf: float, elapsed: int) -> None:
    line = SimTimeline(sim_0=0, wall_0=0, rtf=rtf)
    exact = Fraction(rtf) * elapsed
    assert line.at(elapsed) == math.floor(exact)
    assert 0 <= exact - line.at(elapsed) < 1  # within 1 ns of the exact value, at any distance


@given(steps=st.lists(st.tuples(st.integers(min_value=0, max_value=10**10),
                                st.one_of(st.none(), st.floats(min_value=1e-3, max_value=1000.0))),
                      min_size=1, max_size=30))
def test_monotonic_and_continuous_across_rtf_changes(steps: list[tuple[int, float | None]]) -> None:
    line = SimTimeline(sim_0=7, wall_0=100, rtf=1.0)
    wall, last = 100, line.at(100)
    for dt, new_rtf in steps:
        wall += dt
        now = line.at(wall)
        assert now >= last
        if new_rtf is not None:
            line.set_rtf(new_rtf, wall)
            assert line.at(wall) == now  # no jump at the change
            assert line.rtf == new_rtf and line.origin == (now, wall)
        last = now


@pytest.mark.parametrize('rtf', [0.0, -1.0, math.nan, math.inf, 1])
def test_invalid_rtf_is_refused(rtf: Any) -> None:
    with pytest.raises(ParameterError, match='rtf='):
        SimTimeline(0, 0, rtf)


def test_specs() -> None:
    by_name = {s.name: s for s in SPECS}
    assert {n: s.default for n, s in by_name.items()} == {
        'publish_rate': 200.0, 'rtf': 1.0, 'start_time': 0.0, 'duration': 0.0}
    assert by_name['rtf'].low_open and by_name['rtf'].bounds == (0.0, 1000.0)
    assert by_name['start_time'].read_only and by_name['duration'].read_only
    assert not by_name['rtf'].read_only and not by_name['publish_rate'].read_only


# --------------------------------------------------------------------------- the node in this process (real DDS)

def stamps(received: Received) -> np.ndarray:
    return np.array([time_msg_to_ns(m.clock) for m in received.messages], dtype=np.int64)


def make_clock(ros: Ros, **params: float) -> LineClock:
    overrides = [Parameter(name, value=value) for name, value in params.items()]
    return ros.add(LineClock(context=ros.context, parameter_overrides=overrides))


def measure(ros: Ros, received: Received, seconds: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Stamps and arrival times (ns) of the messages received during a window of ``seconds``."""
    first = len(received)
    t0 = time.monotonic()
    ros.spin_for(seconds)
    elapsed = time.monotonic() - t0
    return stamps(received)[first:], np.array(received.arrival_ns[first:], dtype=np.int64), elapsed


@pytest.mark.parametrize('rtf', [1.0, 5.0])
def test_clock_is_monotonic_at_publish_rate_and_advances_at_rtf(ros: Ros, rtf: float) -> None:
    listener = ros.node('listener')
    received = ros.subscribe(listener, ClockMsg, CLOCK_TOPIC)
    clock = make_clock(ros, publish_rate=100.0, rtf=rtf, start_time=3.0)
    assert ros.spin_until(lambda: len(received) >= 3, timeout=20.0)
    assert stamps(received)[0] >= 3 * NS_PER_S
    sim, wall, elapsed = measure(ros, received, 1.0)
    assert np.all(np.diff(sim) > 0)
    expected = 100.0 * elapsed
    assert 0.6 * expected <= len(sim) <= 1.1 * expected + 2
    slope = np.polyfit((wall - wall[0]).astype(float), (sim - sim[0]).astype(float), 1)[0]
    assert slope == pytest.approx(rtf, rel=0.1)
    assert not clock.done.done()


def test_rtf_and_rate_changes_apply_without_a_jump(ros: Ros) -> None:
    listener = ros.node('listener')
    received = ros.subscribe(listener, ClockMsg, CLOCK_TOPIC)
    clock = make_clock(ros, publish_rate=100.0)
    assert ros.spin_until(lambda: len(received) >= 3, timeout=20.0)
    before, wall_before, _ = measure(ros, received, 0.3)
    results = clock.set_parameters([Parameter('rtf', value=4.0), Parameter('publish_rate', value=50.0)])
    assert all(r.successful for r in results)
    after, wall, elapsed = measure(ros, received, 0.8)
    assert np.all(np.diff(np.concatenate([before, after])) > 0)
    # continuity: across the change sim time moves by at most rtf x the wall gap (plus 20 ms of
    # delivery jitter); without the rebase it would jump by 3 x the ~0.3 s run before the change
    assert after[0] - before[-1] <= 4.0 * (wall[0] - wall_before[-1] + 0.02 * NS_PER_S)
    assert 0.6 * 50.0 * elapsed <= len(after) <= 1.1 * 50.0 * elapsed + 2
    slope = np.polyfit((wall - wall[0]).astype(float), (after - after[0]).astype(float), 1)[0]
    assert slope == pytest.approx(4.0, rel=0.1)


def test_parameters_of_the_clock_are_validated(ros: Ros) -> None:
    clock = make_clock(ros)
    for name, value, reason in [
        ('rtf', math.nan, 'rtf=nan: must be finite (not NaN or inf)'),
        ('rtf', 0.0, 'rtf=0.0: must be a float in (0, 1000]'),
        ('rtf', 1000.5, 'rtf=1000.5: must be a float in (0, 1000]'),
        ('rtf', 5, 'rtf=5: must be a float (write 5.0), got int'),
        ('publish_rate', math.inf, 'publish_rate=inf: must be finite (not NaN or inf)'),
        ('publish_rate', 0.5, 'publish_rate=0.5: must be a float in [1, 1000] Hz'),
        ('use_sim_time', True, 'use_sim_time=True rejected: use_sim_time=True: line_clock publishes /clock'),
    ]:
        [result] = clock.set_parameters([Parameter(name, value=value)])
        assert (result.successful, result.reason[:len(reason)]) == (False, reason)
    [result] = clock.set_parameters([Parameter('start_time', value=1.0)])
    assert not result.successful and 'read-only' in result.reason
    assert clock.get_parameter('rtf').value == 1.0
    assert clock.get_parameter('use_sim_time').value is False


def test_the_clock_refuses_to_run_on_sim_time(ros: Ros) -> None:
    with pytest.raises(ParameterError, match='use_sim_time=True'):
        LineClock(context=ros.context, parameter_overrides=[Parameter('use_sim_time', value=True)])


def test_stops_at_exactly_start_plus_duration(ros: Ros) -> None:
    listener = ros.node('listener')
    received = ros.subscribe(listener, ClockMsg, CLOCK_TOPIC)
    clock = make_clock(ros, start_time=2.5, duration=1.5, rtf=3.0, publish_rate=200.0)
    end = 4 * NS_PER_S
    assert ros.spin_until(lambda: len(received) > 0 and stamps(received)[-1] == end, timeout=20.0)
    assert clock.done.done() and clock.done.result() == end
    count = len(received)
    ros.spin_for(0.2)
    assert len(received) == count  # stopped
    sim = stamps(received)
    assert np.all(np.diff(sim) > 0)
    assert sim[0] >= int(2.5 * NS_PER_S) and sim[-1] == end and np.all(sim <= end)
    assert count >= 20  # about 0.5 s of wall time at 200 Hz


# --------------------------------------------------------------------------- the node as a process

def start(node_env: dict[str, str], tmp_path: Path, *params: str) -> tuple[subprocess.Popen[bytes], Path]:
    args = [sys.executable, '-m', 'folder_line.nodes.line_clock', '--ros-args']
    for param in params:
        args += ['-p', param]
    err = tmp_path / 'stderr.txt'
    with open(tmp_path / 'stdout.txt', 'wb') as out, open(err, 'wb') as error:
        process = subprocess.Popen(args, env=node_env, cwd=REPO, stdout=out, stderr=error)
    return process, err


def stop(process: subprocess.Popen[bytes]) -> None:
    if process.poll() is None:
        process.kill()
        process.wait(timeout=10)


@pytest.mark.parametrize('signum', [signal.SIGINT, signal.SIGTERM])
def test_process_publishes_across_processes_and_exits_0_on_signal(
        ros: Ros, node_env: dict[str, str], tmp_path: Path, signum: int) -> None:
    listener = ros.node('listener')
    received = ros.subscribe(listener, ClockMsg, CLOCK_TOPIC)
    process, err = start(node_env, tmp_path, 'publish_rate:=50.0', 'rtf:=2.0')
    try:
        assert ros.spin_until(lambda: len(received) >= 10, timeout=30.0), err.read_text()
        assert np.all(np.diff(stamps(received)) > 0)
        process.send_signal(signum)
        assert process.wait(timeout=15) == 0
    finally:
        stop(process)
    text = err.read_text()
    assert 'Traceback' not in text and 'error' not in text.lower(), text


def test_process_exits_0_by_itself_after_duration(node_env: dict[str, str], tmp_path: Path) -> None:
    process, err = start(node_env, tmp_path, 'duration:=2.0', 'rtf:=4.0', 'start_time:=1.0')
    try:
        assert process.wait(timeout=30) == 0
    finally:
        stop(process)
    text = err.read_text()
    assert 'stopped at sim time 3.000000000 s: duration reached' in text
    assert 'Traceback' not in text, text


# At start rclpy applies the descriptors to the overrides itself (no pre-set callback runs
# on declaration), so values outside a finite range or of the wrong type get rclpy's words;
# they still name the parameter and the value.
@pytest.mark.parametrize(('param', 'message'), [
    ('rtf:=0.0', 'line_clock: error: rtf=0.0: must be a float in (0, 1000]'),
    ('duration:=-1.0', 'line_clock: error: Invalid parameter value (-1.0) for parameter. Reason: Parameter duration'),
    ('publish_rate:=nan', 'line_clock: error: Invalid parameter value (nan) for parameter. Reason: Parameter publish'),
    ('rtf:=5', "line_clock: error: Trying to set parameter 'rtf' to '5' of type 'INTEGER', expecting type 'DOUBLE'"),
    ('rtf:=2000.0', 'line_clock: error: Invalid parameter value (2000.0) for parameter. Reason: Parameter rtf out'),
])
def test_process_refuses_a_bad_parameter_with_exit_code_2(
        node_env: dict[str, str], tmp_path: Path, param: str, message: str) -> None:
    process, err = start(node_env, tmp_path, param)
    try:
        assert process.wait(timeout=30) == 2
    finally:
        stop(process)
    text = err.read_text()
    assert 'Traceback' not in text
    [line] = [x for x in text.splitlines() if x.startswith('line_clock: error: ')]
    assert line.startswith(message)
    assert param.split(':=')[0] in line
