"""The machine nodes over real DDS: topics, joint states, events and counts against the line model.

Every node here runs in a private context on the test's executor (the ``ros``
fixture) with ``line_clock`` in lockstep; a plain node subscribes to what they
publish. What a node publishes at a point of its grid is a pure function of the
scene and that time, so every received message is compared with
:class:`folder_line.core.line.model.LineModel` built here independently, to the bit, at
the message's own stamp, whatever the clock's tick rate.
"""

from __future__ import annotations

import math
import subprocess
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pytest
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.time_source import TimeSource
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import JointState, TimeReference
from std_msgs.msg import Float64, UInt64

from folder_line.config.scenes import load_scene
from folder_line.core.line.model import LineModel
from folder_line.errors import FolderLineError, ParameterError
from folder_line.interfaces import (
    CLOCK_TOPIC,
    COMMANDS_TOPIC,
    EVENT_KINDS,
    EVENT_OWNER,
    EVENTS_TOPIC,
    LANDING_TOPIC,
    NODE_OF_UNIT,
    NS_PER_S,
    PARTICIPANTS_TOPIC,
    SHEET_COUNT_TOPIC,
    SHEET_RATE_TOPIC,
    TOPICS,
    UNIT_OF_NODE,
    parse_event_source,
    progress_topic,
    tick_done_topic,
)
from folder_line.ros.lockstep import MISSING_FACTOR
from folder_line.ros.nodes.belt_conveyor import BeltConveyor
from folder_line.ros.nodes.crank_drive import CrankDrive
from folder_line.ros.nodes.feed_transporter import FeedTransporter
from folder_line.ros.nodes.line_clock import LineClock
from folder_line.ros.nodes.machine import MACHINE_SPECS, MachineNode
from folder_line.ros.nodes.sheet_counter import SheetCounter, counted_kind
from folder_line.ros.nodes.supervisor import Supervisor
from folder_line.ros.ros_args import command_line_values
from folder_line.ros.time_msg import ns_to_time_msg, time_msg_to_ns
from folder_line.ros.topics import joint_states_topic

from .._signed import signed
from .test_line_clock import FakeParticipant, grid

if TYPE_CHECKING:
    from ..conftest import Received, Ros

REPO = Path(__file__).resolve().parents[3]
RELIABLE = QoSProfile(depth=10000, reliability=ReliabilityPolicy.RELIABLE)
TYPES = {t.name: t.type for t in TOPICS}
MS = 1_000_000  # ns
STEP = 5 * MS  # the nodes' grid at their default rate, 200 Hz


# --------------------------------------------------------------------------- harness


def recording(cls: type[MachineNode]) -> type[MachineNode]:
    """``cls`` that also keeps the stamp (ns) of every tick it published."""

    class Recording(cls):  # type: ignore[valid-type, misc]
        def setup(self) -> None:
            super().setup()
            self.ticks: list[int] = []

        def publish_at(self, stamp_ns: int) -> None:
            super().publish_at(stamp_ns)
            self.ticks.append(stamp_ns)

    Recording.__name__ = cls.__name__
    return Recording


CLASSES: dict[str, type[MachineNode]] = {
    'crank_drive': recording(CrankDrive),
    'belt_conveyor': recording(BeltConveyor),
    'feed_transporter': recording(FeedTransporter),
    'sheet_counter': recording(SheetCounter),
}
ALL_CLASSES = (CrankDrive, BeltConveyor, FeedTransporter, SheetCounter, Supervisor)


def params(**values: Any) -> list[Parameter]:
    return [Parameter(name, value=value) for name, value in values.items()]


def subscribe(ros: Ros, node: Node, msg_type: type, topic: str) -> tuple[Received, Any]:
    """A reliable, deep subscription collecting every message; returns it with the subscription."""
    received = ros.subscribe(node, msg_type, topic, RELIABLE)
    return received, list(node.subscriptions)[-1]


def start_clock(ros: Ros, duration: float, participants: Any, **values: Any) -> LineClock:
    """``line_clock`` in lockstep for ``duration`` s of sim time, no rtf ceiling unless given, a barrier per tick
    (window 0) unless given: a test that holds the line holds it at the tick it names."""
    values.setdefault('rtf', 0.0)
    values.setdefault('window', 0.0)
    return ros.add(
        LineClock(
            context=ros.context,
            parameter_overrides=params(duration=duration, participants=','.join(participants), **values),
        )
    )


def stamp_ns(msg: Any) -> int:
    return time_msg_to_ns(msg.header.stamp)


def model_event_rows(model: LineModel, owner: str, t_end_ns: int) -> list[tuple[str, int, int, int, float]]:
    """``(kind, sheet, cycle, time_ref ns, value)`` of the model's events of ``owner`` up to ``t_end_ns``."""
    rows = []
    for row in model.events:
        kind = EVENT_KINDS[row['kind']]
        t_ns = round(float(row['t']) * NS_PER_S)
        if EVENT_OWNER[kind] == owner and t_ns <= t_end_ns:
            rows.append((kind, int(row['sheet']), int(row['cycle']), t_ns, float(row['value'])))
    return sorted(rows)


def event_rows(messages: list[TimeReference]) -> list[tuple[str, int, int, int, float]]:
    return sorted(
        (*parse_event_source(m.source)[:3], time_msg_to_ns(m.time_ref), parse_event_source(m.source)[3])
        for m in messages
    )


def use_events_executor(ros: Ros) -> None:
    """Spin this test's nodes with rclpy's EventsExecutor, as the node processes and ``folder-line run`` do."""
    ros.executor.shutdown()
    ros.executor = EventsExecutor(context=ros.context)  # type: ignore[assignment]


# --------------------------------------------------------------------------- the line in this process

EXPECTED_JOINTS = {
    'folder': {
        'crank_drive': ('knife_crank', 'knife'),
        'belt_conveyor': ('first_transporter',),
        'feed_transporter': ('feed_belt', 'chain', 'carriage'),
        'sheet_counter': ('pile_table',),
    },
    'layup': {
        'crank_drive': ('layup_crank', 'transporter3', 'transporter4'),
        'belt_conveyor': ('chute_belts',),
        'sheet_counter': ('container_floor',),
    },
    'line': {
        'crank_drive': ('knife_crank', 'knife', 'layup_crank', 'transporter3', 'transporter4'),
        'belt_conveyor': ('first_transporter', 'chute_belts'),
        'feed_transporter': ('feed_belt', 'chain', 'carriage'),
        'sheet_counter': ('pile_table',),
    },
}


@pytest.mark.parametrize(
    ('scene_name', 'clock_rate'), [('folder', 200.0), ('layup', 200.0), ('line', 200.0), ('folder', 1.0)]
)
def test_machine_nodes_publish_the_line_model_at_their_grid_points(  # noqa: PLR0915
    ros: Ros, scene_name: str, clock_rate: float
) -> None:
    """At 1 tick per second of sim time the nodes publish exactly what they publish at 200: the same
    messages at the same grid points (200 Hz, their own rate), only the events' header stamps (their
    tick) differ. (Long on purpose: one run, every topic of it checked against the model in turn.)"""
    duration = 2.0
    horizon = duration + 1.0
    scene = load_scene(scene_name)
    model = LineModel(scene, horizon)  # built here, not the nodes' cached one
    joints = EXPECTED_JOINTS[scene_name]
    assert {NODE_OF_UNIT[unit]: names for unit, names in model.units.items()} == joints

    nodes = {
        name: ros.add(cls(context=ros.context, parameter_overrides=params(scene=scene_name, horizon=horizon)))
        for name, cls in CLASSES.items()
    }
    listener = ros.node('listener')
    states = {name: subscribe(ros, listener, JointState, joint_states_topic(name)) for name in joints}
    events, events_sub = subscribe(ros, listener, TimeReference, EVENTS_TOPIC)
    counts, count_sub = subscribe(ros, listener, UInt64, SHEET_COUNT_TOPIC)
    rates, rate_sub = subscribe(ros, listener, Float64, SHEET_RATE_TOPIC)
    landings, landing_sub = subscribe(ros, listener, Float64, LANDING_TOPIC)
    subs = [s for _, s in states.values()] + [count_sub, rate_sub, landing_sub]
    # nothing is published before the clock runs: match every subscription first, then start it
    assert ros.spin_until(
        lambda: all(s.get_publisher_count() == 1 for s in subs) and events_sub.get_publisher_count() == len(nodes),
        timeout=20.0,
    )
    clock = start_clock(ros, duration, nodes, rate=clock_rate)
    end_ns = round(duration * NS_PER_S)
    ticks = grid(0, end_ns, round(NS_PER_S / clock_rate))
    points = grid(0, end_ns, STEP)  # the nodes' own grid

    def complete() -> bool:
        return (
            clock.done.done()
            and all(n.done.done() for n in nodes.values())
            and all(len(states[k][0]) == nodes[k].published_joint_states for k in states)
            and len(events) == sum(n.published_events for n in nodes.values())
            and len(counts) == len(rates) == len(points)
            and len(landings) == nodes['sheet_counter'].published_landing
        )

    assert ros.spin_until(complete, timeout=60.0)
    # lockstep: every node ran every tick of the clock, in order, none skipped, and stopped at the end
    assert clock.ticks == len(ticks)
    for name, node in nodes.items():
        assert node.ticks == ticks, name
        assert node.lockstep.ticks == len(ticks) and node.done.result() == end_ns
        assert node.rejected == {}

    # graph: every topic of the line under its documented name and type
    graph = dict(listener.get_topic_names_and_types())
    expected = {
        CLOCK_TOPIC: TYPES[CLOCK_TOPIC],
        EVENTS_TOPIC: TYPES[EVENTS_TOPIC],
        SHEET_COUNT_TOPIC: TYPES[SHEET_COUNT_TOPIC],
        SHEET_RATE_TOPIC: TYPES[SHEET_RATE_TOPIC],
        LANDING_TOPIC: TYPES[LANDING_TOPIC],
        COMMANDS_TOPIC: TYPES[COMMANDS_TOPIC],
        PARTICIPANTS_TOPIC: 'std_msgs/msg/String',
    }
    expected.update({joint_states_topic(n): 'sensor_msgs/msg/JointState' for n in joints})
    expected.update({tick_done_topic(n): 'sensor_msgs/msg/TimeReference' for n in nodes})
    expected.update({progress_topic(n): 'sensor_msgs/msg/TimeReference' for n in nodes})
    for topic, type_name in expected.items():
        assert graph.get(topic) == [type_name], (topic, graph.get(topic))
    missing = set(CLASSES) - set(joints)  # layup: no feed transporter, no topic
    assert not {joint_states_topic(n) for n in missing} & set(graph)
    assert all(not nodes[n].publishes_joint_states and nodes[n].published_joint_states == 0 for n in missing)

    # joint states: at every grid point, exactly the model there
    for name, (received, _) in states.items():
        msgs = received.messages
        stamps = np.array([stamp_ns(m) for m in msgs])
        assert stamps.tolist() == points, name
        expect = model.sample(UNIT_OF_NODE[name], stamps / NS_PER_S)
        names = joints[name]
        position = np.array([m.position for m in msgs])
        velocity = np.array([m.velocity for m in msgs])
        assert all(tuple(m.name) == names and m.header.frame_id == name for m in msgs)
        assert position.shape == velocity.shape == (len(msgs), len(names))
        assert np.all(np.isfinite(position)) and np.all(np.isfinite(velocity))
        np.testing.assert_array_equal(position, expect.position)
        np.testing.assert_array_equal(velocity, expect.velocity)
        effort = [list(m.effort) for m in msgs]
        if expect.effort is not None:  # chain_friction: the sprocket torque on the chain, 0 on every other joint
            assert scene.has('chain_friction')
            effort_arr = np.array(effort)
            assert effort_arr.shape == position.shape and np.all(np.isfinite(effort_arr))
            np.testing.assert_array_equal(effort_arr, expect.effort)
            chain = names.index('chain') if 'chain' in names else None
            others = [i for i in range(len(names)) if i != chain]
            assert np.all(effort_arr[:, others] == 0.0)
            if chain is not None:
                assert np.count_nonzero(effort_arr[:, chain] > 0.0) > len(msgs) // 2
        else:
            assert all(e == [] for e in effort)

    # events: each published once, by its owner, at the first tick at or after its time, exactly the model's
    by_owner: dict[str, list[TimeReference]] = {}
    for m in events.messages:
        by_owner.setdefault(m.header.frame_id, []).append(m)
    assert set(by_owner) <= set(nodes)
    tick_arr = np.array(ticks)
    for owner in nodes:
        mine = by_owner.get(owner, [])
        for m in mine:
            kind = parse_event_source(m.source)[0]
            assert EVENT_OWNER[kind] == owner
            t_ns, s_ns = time_msg_to_ns(m.time_ref), stamp_ns(m)
            i = int(np.searchsorted(tick_arr, s_ns))
            assert tick_arr[i] == s_ns and t_ns <= s_ns and (i == 0 or t_ns > tick_arr[i - 1])
        got = event_rows(mine)
        assert got == model_event_rows(model, owner, end_ns), owner
        assert len(got) == len(set(got))
    published = {EVENT_KINDS[k] for k in np.unique(model.events['kind'][model.events['t'] <= duration])}
    assert {parse_event_source(m.source)[0] for m in events.messages} == published

    # sheet counter: the count and rate at every grid point, the landing of every leaf
    t = np.array(points) / NS_PER_S
    counted = model.events[model.events['kind'] == counted_kind(scene.has_delivery)]['t']
    n_expected = np.searchsorted(counted, t, side='right')
    assert [m.data for m in counts.messages] == n_expected.tolist()
    assert n_expected[-1] > 0
    window = np.minimum(5.0, t)
    lagged = np.searchsorted(counted, t - window, side='right')
    expect_rate = np.where(window > 0.0, (n_expected - lagged) / np.where(window > 0.0, window, 1.0), 0.0)
    assert [m.data for m in rates.messages] == expect_rate.tolist()
    landed = model.events[(model.events['kind'] == EVENT_KINDS.index('leaf_landed')) & (model.events['t'] <= duration)][
        'value'
    ]
    assert [m.data for m in landings.messages] == landed.tolist()
    assert (len(landed) > 0) == scene.has_layup


def test_a_node_joined_an_hour_into_the_line_publishes_it_from_there(ros: Ros) -> None:
    """No horizon: a clock started at 3600 s gets every grid point and event from its first tick on, the line's
    values there (the node fast-forwarded to it keeping nothing), and none of the hour before."""
    start = 3600.0
    node = ros.add(CLASSES['feed_transporter'](context=ros.context))
    listener = ros.node('listener')
    received, sub = subscribe(ros, listener, JointState, joint_states_topic('feed_transporter'))
    events, esub = subscribe(ros, listener, TimeReference, EVENTS_TOPIC)
    assert ros.spin_until(lambda: sub.get_publisher_count() == 1 and esub.get_publisher_count() == 1, timeout=20.0)
    clock = start_clock(ros, 0.5, ['feed_transporter'], start_time=start)
    assert ros.spin_until(
        lambda: (
            clock.done.done() and len(received) == node.published_joint_states and len(events) == node.published_events
        ),
        timeout=60.0,
    )
    t0 = round(start * NS_PER_S)
    stamps = grid(t0, t0 + NS_PER_S // 2, STEP)
    assert [stamp_ns(m) for m in received.messages] == stamps and node.ticks == stamps
    model = LineModel(load_scene('folder'), start + 0.5)  # the whole hour, kept: the reference
    js = model.sample('feed', np.array(stamps, dtype=float) / NS_PER_S)
    got = np.array([m.position for m in received.messages])
    assert got.tobytes() == js.position.tobytes()
    own = model.events[
        np.isin(model.events['kind'], [EVENT_KINDS.index(k) for k, n in EVENT_OWNER.items() if n == 'feed_transporter'])
    ]
    own = own[(own['t'] >= start) & (own['t'] <= start + 0.5)]
    assert [m.source for m in events.messages] == [
        f'{EVENT_KINDS[r["kind"]]} sheet={r["sheet"]} cycle={r["cycle"]} value={float(r["value"])!r}' for r in own
    ]
    assert len(own) > 20 and node.stream.t < start + 1.0


def test_a_rate_change_on_a_machine_node_is_harmless(ros: Ros) -> None:
    """crank_drive to 1 Hz at 0.5 s of sim time, through its parameter service, on the full line spun by
    an EventsExecutor: its joint states go on from its last grid point in 1 s steps, nothing else changes."""
    use_events_executor(ros)
    common = params(scene='folder', horizon=3.0)
    nodes = {
        cls.NODE_NAME: ros.add(cls(context=ros.context, parameter_overrides=common))
        for cls in (CLASSES['crank_drive'], CLASSES['belt_conveyor'], FeedTransporter, SheetCounter, Supervisor)
    }
    crank, sup = nodes['crank_drive'], nodes['supervisor']
    hold = ros.add(FakeParticipant(ros.context, hold_from=NS_PER_S // 2))  # holds sim time at 0.5 s
    listener = ros.node('listener')
    client = AsyncParameterClient(listener, 'crank_drive')
    crank_js, crank_sub = subscribe(ros, listener, JointState, joint_states_topic('crank_drive'))
    belt_js, belt_sub = subscribe(ros, listener, JointState, joint_states_topic('belt_conveyor'))
    events, events_sub = subscribe(ros, listener, TimeReference, EVENTS_TOPIC)
    assert ros.spin_until(
        lambda: (
            crank_sub.get_publisher_count() == belt_sub.get_publisher_count() == 1
            and events_sub.get_publisher_count() == 5
            and client.services_are_ready()
        ),
        timeout=20.0,
    )
    clock = start_clock(ros, 2.0, [*nodes, 'line_recorder'], lost_timeout=60.0)
    assert ros.spin_until(
        lambda: hold.held == NS_PER_S // 2 and crank.lockstep.last_done == NS_PER_S // 2, timeout=30.0
    )
    # the node's sim clock reads the last tick it ran; a /clock from anyone else does not move it
    assert crank.get_clock().now().nanoseconds == NS_PER_S // 2
    assert not [s for s in crank.subscriptions if isinstance(getattr(s.callback, '__self__', None), TimeSource)]
    stranger = listener.create_publisher(ClockMsg, '/clock', 10)
    for _ in range(5):
        stranger.publish(ClockMsg(clock=ns_to_time_msg(100 * NS_PER_S)))
        ros.spin_for(0.05)
    assert crank.get_clock().now().nanoseconds == NS_PER_S // 2
    future = client.set_parameters_atomically(signed(crank.get_name(), [Parameter('rate', value=1.0)]))
    assert ros.spin_until(future.done, timeout=20.0)
    assert future.result().result.successful
    hold.run_to(None)
    assert ros.spin_until(
        lambda: (
            clock.done.done()
            and all(n.done.done() for n in nodes.values())
            and len(crank_js) == crank.published_joint_states
            and len(belt_js) == nodes['belt_conveyor'].published_joint_states
            and len(events) == sum(n.published_events for n in nodes.values())
        ),
        timeout=60.0,
    )
    end = 2 * NS_PER_S
    stamps = [stamp_ns(m) for m in crank_js.messages]
    assert stamps == [*grid(0, NS_PER_S // 2, STEP), 3 * NS_PER_S // 2]  # then 1.5 s; 2.5 s is past the end
    model = LineModel(load_scene('folder'), 3.0)
    expect = model.sample(UNIT_OF_NODE['crank_drive'], np.array(stamps) / NS_PER_S)
    np.testing.assert_array_equal([m.position for m in crank_js.messages], expect.position)
    assert [stamp_ns(m) for m in belt_js.messages] == grid(0, end, STEP)
    assert crank.ticks == nodes['belt_conveyor'].ticks == grid(0, end, STEP)  # every tick, acknowledged
    for owner in nodes:
        assert event_rows([m for m in events.messages if m.header.frame_id == owner]) == model_event_rows(
            model, owner, end
        ), owner
    assert all(n.lockstep.ticks == 401 and n.rejected == {} for n in nodes.values())
    assert sup.packml.state == 'EXECUTE' and sup.logic.violations == [] and sup.logic.lost_nodes == []
    assert clock.lost == {} and clock.ticks == 401


# --------------------------------------------------------------------------- parameters

BAD_RATES = [
    (math.nan, 'rate=nan: must be finite (not NaN or inf)'),
    (math.inf, 'rate=inf: must be finite (not NaN or inf)'),
    (0.0, 'rate=0.0: must be a float in [1, 10000] Hz'),
    (20000.0, 'rate=20000.0: must be a float in [1, 10000] Hz'),
    ('x', "rate='x': must be a float, got str"),
    (True, 'rate=True: must be a float, got bool'),  # an integer is taken (as a float)
]
NO_WALL_CLOCK = (
    "use_sim_time=False rejected: use_sim_time=False: a line node runs on the line's simulated time "
    '(/clock); it cannot be turned off'
)


def test_machine_parameters_are_validated_through_the_parameter_service(ros: Ros) -> None:
    nodes = [ros.add(cls(context=ros.context, parameter_overrides=params(horizon=2.0))) for cls in ALL_CLASSES]
    caller = ros.node('caller')
    clients = {n.get_name(): AsyncParameterClient(caller, n.get_name()) for n in nodes}
    assert ros.spin_until(lambda: all(c.services_are_ready() for c in clients.values()), timeout=20.0)

    def call(name: str, parameter: Parameter, sign: bool = True) -> tuple[bool, str]:
        change = signed(name, [parameter]) if sign else [parameter]  # signed as an insider's tools do
        future = clients[name].set_parameters_atomically(change)
        assert ros.spin_until(future.done, timeout=20.0)
        result = future.result().result
        return result.successful, result.reason

    for node in nodes:
        name = node.get_name()
        assert node.period_ns == STEP
        for value, reason in BAD_RATES:
            assert call(name, Parameter('rate', value=value)) == (False, reason)
            assert node.get_parameter('rate').value == 200.0 and node.period_ns == STEP
        for read_only, value in (('scene', 'layup'), ('overrides', 'seed=3'), ('lost_timeout', 1.0)):
            ok, reason = call(name, Parameter(read_only, value=value))
            assert not ok and 'read-only' in reason and read_only in reason
        assert node.get_parameter('scene').value == 'folder' and node.scene.name == 'folder'
        assert not node.has_parameter('horizon')  # the line runs until stopped: no horizon
        # the wall clock is refused at run time, with the reason naming use_sim_time
        assert call(name, Parameter('use_sim_time', value=False)) == (False, NO_WALL_CLOCK)
        assert node.get_parameter('use_sim_time').value is True
        ok, reason = call(name, Parameter('rate', value=400.0), sign=False)  # as ros2 param set would
        assert not ok and reason.startswith('this line is keyed: a change at run time must be signed')
        assert call(name, Parameter('rate', value=400.0)) == (True, '')
        assert node.period_ns == 2_500_000
    ok, reason = call('sheet_counter', Parameter('rate_window', value=-1.0))
    assert not ok and reason.startswith('rate_window=-1.0: must be a float in ')
    assert nodes[3].values['rate_window'] == 5.0
    # a writable parameter set at run time is what the node reads from then on (it once kept its start value)
    assert call('sheet_counter', Parameter('rate_window', value=1.5)) == (True, '')
    assert nodes[3].values['rate_window'] == 1.5
    assert call('sheet_counter', Parameter('marker_rate', value=0.0)) == (True, '')
    assert nodes[3].values['marker_rate'] == 0.0
    assert {s.name for s in MACHINE_SPECS} == {'scene', 'overrides', 'rate', 'lost_timeout'}


@pytest.mark.parametrize('cls', ALL_CLASSES, ids=lambda c: c.NODE_NAME)
def test_a_node_refuses_to_start_on_the_wall_clock(ros: Ros, cls: type[MachineNode]) -> None:
    with pytest.raises(ParameterError) as info:
        cls(context=ros.context, parameter_overrides=params(use_sim_time=False))
    assert str(info.value) == (
        "use_sim_time=False: a line node runs on the line's simulated time (/clock); it cannot be turned off"
    )


BAD_STARTS = [
    ('scene:=nope', "scene='nope': no such scene; shipped scenes: folder, "),
    ('scene:=/nonexistent/scene.yaml', "scene='/nonexistent/scene.yaml': no such file"),
    ('overrides:=feed_transporter.V_tr=-1', 'feed_transporter.V_tr=-1: must be in [0.001, 1000] m/s'),
    ('use_sim_time:=false', "use_sim_time=False: a line node runs on the line's simulated time (/clock)"),
    ('overrides:=feed_transporter.V_tr', "overrides='feed_transporter.V_tr': must be KEY=VALUE"),
    ('rate:=nan', 'rate=nan: must be finite (not NaN or inf)'),  # the start value checked by the spec, as a change
    ('lost_timeout:=0.0', 'lost_timeout=0.0: must be a float in [0.1, 3600] s'),
]


def test_a_node_refuses_to_start_on_a_bad_scene_in_process(ros: Ros) -> None:
    with pytest.raises(ParameterError, match=r"^scene='nope': no such scene"):
        CrankDrive(context=ros.context, parameter_overrides=params(scene='nope'))
    with pytest.raises(ParameterError, match=r'^feed_transporter\.V_tr=-1: must be in'):
        FeedTransporter(context=ros.context, parameter_overrides=params(overrides='feed_transporter.V_tr=-1'))


#: the processes of one line: five machine nodes and the clock
LINE_PROCESSES = 6
#: a ROS domain no participant can be made on (Fast DDS's ports for it are out of range): a process that
#: made one would print Fast DDS's errors and end otherwise
NO_DOMAIN = '250'


def test_node_processes_refuse_a_bad_start_with_exit_code_2_before_joining_the_network(
    node_env: dict[str, str], tmp_path: Path
) -> None:
    """Every node process refuses each bad start with exit code 2 and its one line, read from its command line
    before it makes a DDS participant: on a domain where none can be made, nothing else is printed.

    Started six at a time, as ``ros2 launch`` starts a line. A participant made and torn down again at
    once while the others discover each other now and then crashed inside Fast DDS (SIGSEGV in
    ``Node.destroy_node``; exit -11 with no line, once in about a hundred refusals on a loaded host): a
    start refused from the command line makes none (:mod:`folder_line.ros.ros_args`).
    """
    cases = [
        (node, param, words)
        for node in ('crank_drive', 'belt_conveyor', 'feed_transporter', 'sheet_counter', 'supervisor')
        for param, words in BAD_STARTS[:4]
    ]
    cases += [('crank_drive', param, words) for param, words in BAD_STARTS[4:]]
    env = {**node_env, 'ROS_DOMAIN_ID': NO_DOMAIN}
    for first in range(0, len(cases), LINE_PROCESSES):
        batch = list(enumerate(cases))[first : first + LINE_PROCESSES]
        procs = []
        for i, (node, param, _) in batch:
            err = tmp_path / f'{i}.err'
            with open(err, 'wb') as stderr:
                command = [sys.executable, '-m', f'folder_line.ros.nodes.{node}', '--ros-args', '-p', param]
                proc = subprocess.Popen(command, env=env, cwd=REPO, stdout=subprocess.DEVNULL, stderr=stderr)
            procs.append((proc, err))
        try:
            for (_, (node, param, words)), (proc, err) in zip(batch, procs, strict=True):
                assert proc.wait(timeout=60) == 2, (node, param, err.read_text())
                lines = err.read_text().splitlines()
                assert len(lines) == 1 and lines[0].startswith(f'{node}: error: '), (node, param, lines)
                assert words in lines[0], (words, lines[0])
        finally:
            for proc, _ in procs:
                if proc.poll() is None:
                    proc.kill()
                    proc.wait()


def test_a_rule_rcl_cannot_parse_is_refused_with_rcls_reason(node_env: dict[str, str]) -> None:
    """``-p bad`` (no ``:=``) fails in ``rclpy.init``: rcl logs its own line, the node adds one naming the rule."""
    command = [sys.executable, '-m', 'folder_line.ros.nodes.belt_conveyor', '--ros-args', '-p', 'bad']
    env = {**node_env, 'ROS_DOMAIN_ID': NO_DOMAIN}
    proc = subprocess.run(command, env=env, cwd=REPO, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert "belt_conveyor: error: failed to initialize rcl: Couldn't parse parameter override rule: '-p bad'" in (
        proc.stderr
    )
    assert 'Traceback' not in proc.stderr


def test_a_bad_start_the_command_line_does_not_show_is_refused_by_the_node(node_env: dict[str, str]) -> None:
    """A start whose arguments are not read before rcl (here the node renamed) is refused by the node
    itself, after it made its participant: the same line and exit code 2."""
    command = [
        *(sys.executable, '-m', 'folder_line.ros.nodes.crank_drive'),
        *('--ros-args', '-r', '__node:=crank_drive_2', '-p', 'scene:=nope'),
    ]
    proc = subprocess.run(command, env=node_env, cwd=REPO, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    lines = [line for line in proc.stderr.splitlines() if line.startswith('crank_drive: error: ')]
    assert len(lines) == 1 and "scene='nope': no such scene" in lines[0], proc.stderr


@pytest.mark.parametrize(('param', 'words'), BAD_STARTS)
def test_the_command_line_check_refuses_as_the_node_does(ros: Ros, param: str, words: str) -> None:
    """``refuse_start`` on the values read from ``--ros-args`` raises the node's own first refusal, word for
    word, for every bad start; and a good start passes it."""
    name = param.partition(':=')[0]
    given = command_line_values(['--ros-args', '-p', param], 'crank_drive')
    assert given is not None and name in given
    with pytest.raises(FolderLineError) as by_command_line:
        CLASSES['crank_drive'].refuse_start(given)
    with pytest.raises(FolderLineError) as by_node:
        CLASSES['crank_drive'](context=ros.context, parameter_overrides=[Parameter(name, value=given[name])])
    assert str(by_command_line.value) == str(by_node.value)
    assert words in str(by_node.value)
    good = ['--ros-args', '-p', 'scene:=line', '-p', 'rate:=100', '-p', 'lost_timeout:=5', '--', 'extra']
    for cls in CLASSES.values():
        cls.refuse_start(command_line_values(good, cls.NODE_NAME) or {})


def test_a_producer_whose_counted_messages_never_come_is_lost_not_waited_for_for_ever(ros: Ros) -> None:
    """A supervisor that acknowledges a drive command it never sends (as the recorder once missed tunings it did not
    count) holds crank_drive's next tick: crank_drive declares it lost after MISSING_FACTOR x lost_timeout, naming what
    is missing, and goes on; before that limit it waits (it is alive: its acknowledgements come)."""
    crank = ros.add(
        CLASSES['crank_drive'](context=ros.context, parameter_overrides=params(scene='folder', lost_timeout=0.3))
    )
    liar = ros.add(FakeParticipant(ros.context, 'supervisor'))
    liar.counts['commands'] = 1  # acknowledged, never published
    # alive and waiting, as a real participant: it repeats its latest acknowledgement (lockstep.HEARTBEAT)
    liar.create_timer(0.1, lambda: liar.ack(max(liar.acked_ns)) if liar.acked_ns else None)
    clock = start_clock(ros, 0.05, ['crank_drive', 'supervisor'], lost_timeout=60.0)
    t0 = time.monotonic()
    assert ros.spin_until(lambda: crank.lockstep.ledger is not None and crank.lockstep.ledger.live == (), timeout=30.0)
    waited = time.monotonic() - t0
    assert waited > MISSING_FACTOR * 0.3  # not before the limit: it was alive all along
    assert ros.spin_until(clock.done.done, timeout=30.0)
    assert crank.ticks == grid(0, 50 * MS, STEP)  # it went on without the supervisor: every tick published


def test_markers_turned_on_at_run_time_start_at_that_tick(ros: Ros) -> None:
    """marker_rate 0 at start, 5 Hz from t = 1800 s: one array at 1800 s, not the 9000 of the grid since 0."""
    counter = ros.add(SheetCounter(context=ros.context, parameter_overrides=params(scene='folder', marker_rate=0.0)))
    counter.publish_at(0)
    assert counter.published_markers == 0
    assert counter.set_parameters_atomically(signed('sheet_counter', [Parameter('marker_rate', value=5.0)])).successful
    counter.publish_at(1800 * NS_PER_S)  # the node fast-forwards there
    assert counter.published_markers == 1
    counter.publish_at(1800 * NS_PER_S + NS_PER_S // 2)  # then on its grid: 1800.2, 1800.4
    assert counter.published_markers == 3
