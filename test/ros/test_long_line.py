"""A live line a day in: the five machine nodes with their defaults, and ``line_clock`` started at 86400 s.

The nodes have no horizon: each one fast-forwards a day of the ``folder`` line at batch speed
(keeping nothing) when the clock's first tick comes, then publishes every grid point of the
five seconds, each the line's value there, bit for bit; the supervisor judges what it saw
start (no cycle begun before it joined) and keeps the line running.
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from sensor_msgs.msg import JointState
from std_msgs.msg import String

from folder_line.config.scenes import load_scene
from folder_line.core.line.stream import LineStream
from folder_line.interfaces import JOINT_NODES, NODE_OF_UNIT, NS_PER_S, SUPERVISOR_STATE_TOPIC
from folder_line.ros.nodes.belt_conveyor import BeltConveyor
from folder_line.ros.nodes.crank_drive import CrankDrive
from folder_line.ros.nodes.feed_transporter import FeedTransporter
from folder_line.ros.nodes.line_clock import EXIT_LOST
from folder_line.ros.nodes.sheet_counter import SheetCounter
from folder_line.ros.nodes.supervisor import STATE_QOS, Supervisor
from folder_line.ros.time_msg import time_msg_to_ns
from folder_line.ros.topics import joint_states_topic

from .nodes.test_line_clock import grid
from .nodes.test_machine_nodes import RELIABLE, STEP, start_clock

if TYPE_CHECKING:
    from .conftest import Ros

START = 86400.0  # a day into the line, s
SPAN = 5.0
REPO = Path(__file__).resolve().parents[2]
FAR = 200000.0  # s: a fast-forward of seconds of wall time


def test_a_line_joined_a_day_in_publishes_every_joint_state_as_the_line_has_it(ros: Ros) -> None:
    nodes = [ros.add(cls(context=ros.context)) for cls in (CrankDrive, BeltConveyor, FeedTransporter, SheetCounter)]
    sup = ros.add(Supervisor(context=ros.context))
    listener = ros.node('listener')
    states = {name: ros.subscribe(listener, JointState, joint_states_topic(name), RELIABLE) for name in JOINT_NODES}
    state = ros.subscribe(listener, String, SUPERVISOR_STATE_TOPIC, STATE_QOS)
    assert ros.spin_until(lambda: all(s.get_publisher_count() >= 1 for s in listener.subscriptions), timeout=20.0)
    names = [n.get_name() for n in [*nodes, sup]]
    clock = start_clock(ros, SPAN, names, start_time=START)
    assert ros.spin_until(
        lambda: clock.done.done() and all(len(states[n.get_name()]) == n.published_joint_states for n in nodes),
        timeout=600.0,
    )
    t0 = round(START * NS_PER_S)
    stamps = grid(t0, t0 + round(SPAN * NS_PER_S), STEP)
    # the reference: the line streamed here to the same day (the windows do not matter: test_stream)
    line = LineStream(load_scene('folder'))
    while line.t < START - 1.0:
        line.advance(min(START - 1.0, max(line.t, 0.0) + 3600.0))
    line.advance(START + SPAN)
    units = {node: unit for unit, node in NODE_OF_UNIT.items()}
    for name in JOINT_NODES:
        got = states[name].messages
        assert [time_msg_to_ns(m.header.stamp) for m in got] == stamps, name
        want = line.sample(units[name], np.array(stamps, dtype=float) / NS_PER_S)
        assert np.array([m.position for m in got]).tobytes() == want.position.tobytes(), name
        assert np.array([m.velocity for m in got]).tobytes() == want.velocity.tobytes(), name
    assert max(n.stream.t for n in nodes) < START + SPAN + 1.0  # computed a window ahead, not to a horizon
    assert sup.logic.violations == [] and {m.data for m in state.messages} <= {'STARTING', 'EXECUTE'}
    assert state.messages[-1].data == 'EXECUTE'


def test_a_node_held_up_by_a_fast_forward_longer_than_the_startup_timeout_is_not_lost(
    node_env: dict[str, str], tmp_path: Path
) -> None:
    """Processes joined 200000 s into ``folder`` with ``startup_timeout`` 5 s: ``crank_drive`` fast-forwards for
    longer than that (working, it says so); the supervisor waits for its events all that time before its own
    first tick, and says so too (the instant before the tick): nobody is lost, the clock exits 0."""

    def start(name: str, *params: str) -> tuple[subprocess.Popen[bytes], Path]:
        cmd = [sys.executable, '-m', f'folder_line.ros.nodes.{name}', '--ros-args']
        for p in params:
            cmd += ['-p', p]
        err = tmp_path / f'{name}.txt'
        with open(err, 'wb') as error:
            return subprocess.Popen(cmd, env=node_env, cwd=REPO, stdout=subprocess.DEVNULL, stderr=error), err

    procs = [start(name, 'scene:=folder') for name in ('crank_drive', 'supervisor')]
    clock: subprocess.Popen[bytes] | None = None
    try:
        # the nodes are up (their start-up is not the fast-forward) before the clock's startup_timeout runs
        while not all("scene 'folder'" in err.read_text() for _, err in procs):
            assert all(p.poll() is None for p, _ in procs), [err.read_text() for _, err in procs]
            time.sleep(0.1)
        clock, err = start(
            'line_clock',
            'participants:=crank_drive,supervisor',
            f'start_time:={FAR:.1f}',
            'duration:=0.05',
            'rtf:=0.0',
            'startup_timeout:=5.0',
        )
        procs.append((clock, err))
        code = clock.wait(timeout=600)
    finally:
        for p, _ in procs:
            if p.poll() is None:
                p.kill()
            p.wait(timeout=10)
    logs = {path.stem: path.read_text() for _, path in procs}
    assert f'fast-forwarding the line to {FAR - 0.25:.9g} s' in logs['crank_drive'], logs
    lines = logs['line_clock'].splitlines()
    started = next(line for line in lines if 'lockstep /clock at' in line)
    answered = next(line for line in lines if 'every participant answered the first tick' in line)
    stamp = [float(line.split('[')[2].split(']')[0]) for line in (started, answered)]  # '[INFO] [wall s] ...'
    assert stamp[1] - stamp[0] > 5.0, logs  # the first tick took longer than startup_timeout, or nothing is proved
    assert 'lost' not in logs['line_clock'] and 'Traceback' not in ''.join(logs.values()), logs
    assert f'stopped at sim time {FAR + 0.05:.9f} s: duration reached (11 ticks,' in logs['line_clock'], logs
    assert code == 0 != EXIT_LOST, logs
