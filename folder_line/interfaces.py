"""The line's interfaces, in one place and without rclpy: names, topics, events, time.

Every layer takes these from here: the ROS nodes and ``folder-line run``
(:mod:`folder_line.ros`), the bag tools (:mod:`folder_line.bag`), the analysis
(:mod:`folder_line.analysis`), the monitor and the launch file. The numpy core
(:mod:`folder_line.core`) does not import this module: it knows machines, not ROS node
names; :data:`NODE_OF_UNIT` maps one to the other.

Topics
------
==================================  =================================  ==========================================
topic                               type                               meaning
==================================  =================================  ==========================================
``/clock``                          ``rosgraph_msgs/msg/Clock``        simulated time, published by ``line_clock``
``/line/<node>/joint_states``       ``sensor_msgs/msg/JointState``     joint positions (rad or m), velocities
                                                                       (rad/s or m/s), efforts (N m or N) of one
                                                                       machine; ``<node>`` is the node's name
``/line/events``                    ``sensor_msgs/msg/TimeReference``  discrete events of the line (kinds:
                                                                       ``EVENT_KINDS``)
``/diagnostics``                    ``diagnostic_msgs/msg/             constraint margins and faults, per machine
                                    DiagnosticArray``
``/line/supervisor/state``          ``std_msgs/msg/String``            state of the line's supervisor
``/line/sheet_counter/count``       ``std_msgs/msg/UInt64``            sheets delivered so far
``/line/sheet_counter/rate``        ``std_msgs/msg/Float64``           sheets (or leaves) per second
``/line/sheet_counter/landing_x``   ``std_msgs/msg/Float64``           landing x of each leaf, m (layup)
``/line/supervisor/commands``       ``sensor_msgs/msg/TimeReference``  drive commands: ``source`` = hold, unhold,
                                                                       stop or start; ``time_ref`` = effective
                                                                       sim time
``/line/participants``              ``std_msgs/msg/String``            ``line_clock``'s announcement: clock mode,
                                                                       end and the lockstep participants
``/line/markers``                   ``visualization_msgs/msg/          the machine drawn in frame ``line`` (RViz,
                                    MarkerArray``                      Foxglove), by ``sheet_counter``
==================================  =================================  ==========================================

The table is also data (:data:`TOPICS`); :data:`LINE_TOPIC_TYPES` lists every topic a
recorder takes, with its type. The ROS side maps the types to message classes.

Events
------
The machine nodes publish each exact event of the batch model on ``/line/events``
(``sensor_msgs/TimeReference``): ``time_ref`` is the event time (nearest ns) and
``source`` is ``'<kind> sheet=<id> cycle=<k> value=<repr>'`` (:func:`event_source`,
:func:`parse_event_source`). :data:`EVENT_OWNER` says which node publishes each kind.

Time
----
Times on the wire are integer nanoseconds (:data:`NS_PER_S`); a
``builtin_interfaces/Time`` holds at most :data:`TIME_MSG_MAX_NS`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

from folder_line.core.line.tuning import SET_PREFIX
from folder_line.core.numerics.timebase import NS_PER_S, seconds_to_ns
from folder_line.core.types.events import EVENT_KINDS

__all__ = [
    'CLOCK_TOPIC',
    'COMMANDS_TOPIC',
    'COMMAND_KINDS',
    'DIAGNOSTICS_TOPIC',
    'EVENTS_TOPIC',
    'EVENT_KINDS',
    'EVENT_OWNER',
    'GRANT_TOPIC',
    'JOINT_NODES',
    'JOINT_STATES_TOPIC_PATTERN',
    'KNOWN_PARTICIPANTS',
    'LANDING_TOPIC',
    'LINE_CLOCK',
    'LINE_TOPIC_TYPES',
    'MACHINE_NODES',
    'MARKERS_TOPIC',
    'NODE_OF_UNIT',
    'NS_PER_S',
    'OPERATOR_COMMANDS',
    'PARTICIPANTS_TOPIC',
    'PROGRESS_PATTERN',
    'RECORDER',
    'SHEET_COUNT_TOPIC',
    'SHEET_RATE_TOPIC',
    'SOURCE_PATTERN',
    'SUPERVISOR',
    'SUPERVISOR_STATE_TOPIC',
    'TICK_DONE_PATTERN',
    'TIME_MSG_MAX_NS',
    'TOPICS',
    'TUNABLE_PARAMETERS',
    'TUNE_TOPIC',
    'UNIT_OF_NODE',
    'TopicInfo',
    'event_source',
    'is_command_source',
    'joint_states_node',
    'joint_states_topic',
    'parse_event_source',
    'progress_topic',
    'seconds_to_ns',
    'stamp_ns',
    'tick_done_topic',
]

# --------------------------------------------------------------------------- nodes

#: the machine nodes that publish joint states, in start order
JOINT_NODES: tuple[str, ...] = ('crank_drive', 'belt_conveyor', 'feed_transporter', 'sheet_counter')
#: the supervisor's node name
SUPERVISOR = 'supervisor'
#: the machine nodes of the line, in start order
MACHINE_NODES: tuple[str, ...] = (*JOINT_NODES, SUPERVISOR)
#: the node that owns simulated time
LINE_CLOCK = 'line_clock'
#: the recorder's node name (a lockstep participant when ``folder-line run`` records)
RECORDER = 'line_recorder'
#: every node that can take part in the lockstep
KNOWN_PARTICIPANTS: tuple[str, ...] = (*MACHINE_NODES, RECORDER)

#: the core's machine units (:data:`folder_line.core.line.stream.UNITS`) -> the node that runs each
NODE_OF_UNIT: dict[str, str] = {
    'drive': 'crank_drive',
    'belts': 'belt_conveyor',
    'feed': 'feed_transporter',
    'counter': 'sheet_counter',
}
#: the node -> the core's machine unit it runs (the inverse of :data:`NODE_OF_UNIT`)
UNIT_OF_NODE: dict[str, str] = {node: unit for unit, node in NODE_OF_UNIT.items()}

# --------------------------------------------------------------------------- time

TIME_MSG_MAX_NS = (2**31 - 1) * NS_PER_S + NS_PER_S - 1
"""Largest time a ``builtin_interfaces/msg/Time`` holds (``sec`` is an int32), ns."""

# --------------------------------------------------------------------------- topics

CLOCK_TOPIC = '/clock'
"""Simulated time (``rosgraph_msgs/msg/Clock``); its only publisher is ``line_clock``."""

EVENTS_TOPIC = '/line/events'
"""Discrete events of the line (``sensor_msgs/msg/TimeReference``)."""

DIAGNOSTICS_TOPIC = '/diagnostics'
"""Constraint margins and faults (``diagnostic_msgs/msg/DiagnosticArray``)."""

SUPERVISOR_STATE_TOPIC = '/line/supervisor/state'
"""State of the line's supervisor (``std_msgs/msg/String``)."""

SHEET_COUNT_TOPIC = '/line/sheet_counter/count'
"""Number of sheets delivered so far (``std_msgs/msg/UInt64``)."""

SHEET_RATE_TOPIC = '/line/sheet_counter/rate'
"""Sheets (or leaves) per second over the counter's window (``std_msgs/msg/Float64``)."""

LANDING_TOPIC = '/line/sheet_counter/landing_x'
"""Landing x of each leaf on the container floor, m (``std_msgs/msg/Float64``; layup scenes)."""

COMMANDS_TOPIC = '/line/supervisor/commands'
"""The supervisor's drive commands (``sensor_msgs/msg/TimeReference``: ``source`` = hold, unhold,
stop or start; ``time_ref`` = effective sim time). Reliable, transient-local, keep-all, so
a node that starts late still learns every command."""

#: the supervisor's operator services, ``/line/supervisor/<command>`` (``std_srvs/Trigger``)
OPERATOR_COMMANDS: tuple[str, ...] = (
    'start',
    'stop',
    'hold',
    'unhold',
    'suspend',
    'unsuspend',
    'reset',
    'clear',
    'abort',
)

TUNE_TOPIC = '/line/supervisor/tune'
"""Operators' tunings asked of the supervisor (``std_msgs/msg/String``, ``'<node> <key>=<value>'``): a
machine node whose tunable parameter was set forwards it here; the supervisor times it (the next
cycle boundary) and publishes it on :data:`COMMANDS_TOPIC` as ``source = 'set <key>=<value>'``."""

#: the tunable parameters of the machine nodes: node -> parameter -> the tunable it sets
#: (:data:`folder_line.core.line.tuning.TUNABLES`); declared only where the scene has what it acts on
TUNABLE_PARAMETERS: dict[str, dict[str, str]] = {
    'crank_drive': {'press_speed': 'press.n_c'},
    'feed_transporter': {'V_tr': 'feed_transporter.V_tr'},
    'belt_conveyor': {'chute_belt_speed': 'layup.v_tr'},
    'sheet_counter': {'pile_lowering_time': 'pile.t_lower'},
}

GRANT_TOPIC = '/line/grant'
"""``line_clock``'s time grants to the participants (``sensor_msgs/msg/TimeReference``): ``header.stamp`` is
the last tick granted, ``time_ref`` the first tick of the current step, ``source`` ``'step=<ns>'``; the
participants take their ticks from it, never from ``/clock`` (see :mod:`folder_line.ros.lockstep`)."""

PARTICIPANTS_TOPIC = '/line/participants'
"""``line_clock``'s announcement of the lockstep participants (``std_msgs/msg/String``)."""

MARKERS_TOPIC = '/line/markers'
"""The machine as RViz/Foxglove markers in frame ``line`` (``visualization_msgs/msg/MarkerArray``),
published by ``sheet_counter`` at its ``marker_rate`` (:mod:`folder_line.bag.markers`)."""

JOINT_STATES_TOPIC_PATTERN = '/line/{node}/joint_states'
"""Joint states of one machine (``sensor_msgs/msg/JointState``); see :func:`joint_states_topic`."""

TICK_DONE_PATTERN = '/line/{node}/tick_done'
"""A participant's acknowledgements of every tick, several per message (``sensor_msgs/msg/TimeReference``, for
the recorder); see :func:`tick_done_topic`."""

PROGRESS_PATTERN = '/line/{node}/progress'
"""A participant's latest acknowledgement, now and then and while it waits (``sensor_msgs/msg/TimeReference``,
best-effort); see :func:`progress_topic`."""

#: the drive commands the supervisor publishes on :data:`COMMANDS_TOPIC`
COMMAND_KINDS: tuple[str, ...] = ('hold', 'unhold', 'stop', 'start')

_NODE_NAME = re.compile(r'^[A-Za-z_][A-Za-z0-9_]*$')  # ROS 2's rule for a node name (rcl_validate_node_name)


def stamp_ns(stamp: Any) -> int:
    """Integer ns of a ``builtin_interfaces/msg/Time`` (rclpy's message, rosbags' or mcap's decoded one)."""
    return int(stamp.sec) * NS_PER_S + int(stamp.nanosec)


def is_command_source(source: str) -> bool:
    """Whether ``source`` of a :data:`COMMANDS_TOPIC` message is a drive command kind or a tuning
    (``'set KEY=VALUE'``, :func:`folder_line.core.line.tuning.tuning_text`): what the supervisor publishes."""
    return source in COMMAND_KINDS or source.startswith(SET_PREFIX)


def _node_topic(pattern: str, node: str) -> str:
    if not _NODE_NAME.match(node):
        msg = f'node name {node!r}: must start with a letter or _ and hold only letters, digits and _'
        raise ValueError(msg)
    return pattern.format(node=node)


def joint_states_topic(node: str) -> str:
    """``/line/<node>/joint_states``.

    Raises
    ------
    ValueError
        ``node`` is not a plain node name (letters, digits, ``_``; no namespace).
    """
    return _node_topic(JOINT_STATES_TOPIC_PATTERN, node)


def joint_states_node(topic: str) -> str | None:
    """The node whose joint states ``topic`` carries, or None if it is not a joint-states topic."""
    head, _, tail = JOINT_STATES_TOPIC_PATTERN.partition('{node}')
    if topic.startswith(head) and topic.endswith(tail) and len(topic) > len(head) + len(tail):
        node = topic[len(head) : len(topic) - len(tail)]
        return node if _NODE_NAME.match(node) else None
    return None


def progress_topic(node: str) -> str:
    """``/line/<node>/progress``, the participant's latest acknowledgement (for the clock and the nodes).

    Raises
    ------
    ValueError
        ``node`` is not a plain node name.
    """
    return _node_topic(PROGRESS_PATTERN, node)


def tick_done_topic(node: str) -> str:
    """``/line/<node>/tick_done``, the participant's acknowledgements.

    Raises
    ------
    ValueError
        ``node`` is not a plain node name.
    """
    return _node_topic(TICK_DONE_PATTERN, node)


@dataclass(frozen=True)
class TopicInfo:
    """One topic of the line.

    Parameters
    ----------
    name : str
        Absolute topic name; ``{node}`` stands for a node's name in a pattern.
    type : str
        Message type as ``package/msg/Name`` (the spelling of bags and of ``ros2 topic``).
    description : str
        What is published there, with units.
    """

    name: str
    type: str
    description: str


TOPICS: tuple[TopicInfo, ...] = (
    TopicInfo(CLOCK_TOPIC, 'rosgraph_msgs/msg/Clock', 'simulated time, integer ns; published by line_clock'),
    TopicInfo(
        JOINT_STATES_TOPIC_PATTERN,
        'sensor_msgs/msg/JointState',
        'joint positions (rad or m), velocities (rad/s or m/s), efforts (N m or N) of one machine',
    ),
    TopicInfo(
        EVENTS_TOPIC,
        'sensor_msgs/msg/TimeReference',
        'discrete events of the line (kinds: folder_line.interfaces.EVENT_KINDS)',
    ),
    TopicInfo(DIAGNOSTICS_TOPIC, 'diagnostic_msgs/msg/DiagnosticArray', 'constraint margins and faults'),
    TopicInfo(SUPERVISOR_STATE_TOPIC, 'std_msgs/msg/String', 'state of the line supervisor'),
    TopicInfo(SHEET_COUNT_TOPIC, 'std_msgs/msg/UInt64', 'sheets delivered so far'),
    TopicInfo(SHEET_RATE_TOPIC, 'std_msgs/msg/Float64', 'sheets (or leaves) per second over the counter window'),
    TopicInfo(LANDING_TOPIC, 'std_msgs/msg/Float64', 'landing x of each leaf, m (layup scenes)'),
    TopicInfo(
        COMMANDS_TOPIC,
        'sensor_msgs/msg/TimeReference',
        'supervisor drive commands and tunings: source = hold/unhold/stop/start or "set KEY=VALUE", '
        'time_ref = effective sim time',
    ),
    TopicInfo(
        PARTICIPANTS_TOPIC,
        'std_msgs/msg/String',
        "line_clock's announcement: clock mode, end and the lockstep participants",
    ),
    TopicInfo(
        MARKERS_TOPIC,
        'visualization_msgs/msg/MarkerArray',
        "the machine drawn in frame 'line', one namespace per machine (folder_line.core.line.scenery)",
    ),
)

#: every topic a recorder of the line takes -> its type (``package/msg/Name``)
LINE_TOPIC_TYPES: dict[str, str] = {
    CLOCK_TOPIC: 'rosgraph_msgs/msg/Clock',
    **{joint_states_topic(n): 'sensor_msgs/msg/JointState' for n in JOINT_NODES},
    EVENTS_TOPIC: 'sensor_msgs/msg/TimeReference',
    DIAGNOSTICS_TOPIC: 'diagnostic_msgs/msg/DiagnosticArray',
    SUPERVISOR_STATE_TOPIC: 'std_msgs/msg/String',
    SHEET_COUNT_TOPIC: 'std_msgs/msg/UInt64',
    SHEET_RATE_TOPIC: 'std_msgs/msg/Float64',
    LANDING_TOPIC: 'std_msgs/msg/Float64',
    COMMANDS_TOPIC: 'sensor_msgs/msg/TimeReference',
    PARTICIPANTS_TOPIC: 'std_msgs/msg/String',
    MARKERS_TOPIC: 'visualization_msgs/msg/MarkerArray',
}

# --------------------------------------------------------------------------- events

#: which node publishes which event kind (every kind: test/test_core_boundary.py)
EVENT_OWNER: dict[str, str] = {
    'knife_contact': 'crank_drive',
    'knife_exit': 'crank_drive',
    'sheet_handover': 'feed_transporter',
    'at_stops': 'feed_transporter',
    'bounce': 'feed_transporter',
    'settled': 'feed_transporter',
    'released_on_pile': 'sheet_counter',
    'leaf_landed': 'sheet_counter',
    'leaf_spilled': 'sheet_counter',
    'leaf_enter': 'belt_conveyor',
    'leaf_exit': 'belt_conveyor',
    'leaf_damaged': 'belt_conveyor',
    'leaf_stick': 'belt_conveyor',
    'leaf_slip': 'belt_conveyor',
    'fault_missing': 'belt_conveyor',
    'fault_double': 'belt_conveyor',
    'fault_late': 'belt_conveyor',
    'belt_slowdown_start': 'belt_conveyor',
    'belt_slowdown_end': 'belt_conveyor',
}

#: the ``source`` of an event; ``value`` is Python's ``repr`` of a float (round-trip exact)
SOURCE_PATTERN = re.compile(r'^(?P<kind>\w+) sheet=(?P<sheet>-?\d+) cycle=(?P<cycle>-?\d+) value=(?P<value>\S+)$')


def event_source(kind: str, sheet: int, cycle: int, value: float) -> str:
    """``TimeReference.source`` of an event: ``'<kind> sheet=<id> cycle=<k> value=<repr>'``."""
    return f'{kind} sheet={int(sheet)} cycle={int(cycle)} value={float(value)!r}'


def parse_event_source(source: str) -> tuple[str, int, int, float]:
    """Inverse of :func:`event_source`: ``(kind, sheet, cycle, value)``.

    Raises
    ------
    ValueError
        ``source`` is not of that form, or names an unknown event kind.
    """
    m = SOURCE_PATTERN.match(source)
    if m is None or m['kind'] not in EVENT_KINDS:
        msg = f'not an event source: {source!r}'
        raise ValueError(msg)
    try:
        value = float(m['value'])
    except ValueError:
        msg = f'not an event source (value): {source!r}'
        raise ValueError(msg) from None
    return m['kind'], int(m['sheet']), int(m['cycle']), value
