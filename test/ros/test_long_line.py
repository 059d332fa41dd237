"""A live line a day in: the five machine nodes with their defaults, and ``line_clock`` started at 86400 s.

The nodes have no horizon: each one fast-forwards a day of the ``folder`` line at batch speed
(keeping nothing) when the clock's first tick comes, then publishes every grid point of the
five seconds, each the line's value there, bit for bit; the supervisor judges what it saw
start (no cycle begun before it joined) and keeps the line running.
"""

from __future__ import annotations

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
