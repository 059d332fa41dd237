"""What the machine nodes share: the scene, the line model, the tick.

``crank_drive``, ``belt_conveyor``, ``feed_transporter`` and ``sheet_counter`` are
:class:`MachineNode` subclasses. Each builds the line model of its scene once
(:class:`folder_line.core.line.LineModel`, shared by the nodes of one process),
and on every tick of a timer on its own clock (simulated time from ``/clock``)
publishes, at the stamp ``t`` of that tick,

* its joints' states at ``t`` on ``/line/<node>/joint_states`` (if the scene gives
  the node joints), and
* the exact events of its machines with times in ``(t_prev, t]`` on
  ``/line/events`` as ``sensor_msgs/TimeReference``: ``time_ref`` is the event time
  (nearest ns), ``header.stamp`` the tick's stamp, ``header.frame_id`` the node,
  ``source`` is ``'<kind> sheet=<id> cycle=<k> value=<repr>'``
  (:func:`folder_line.event_text.event_source`, re-exported here).

So what a node publishes at stamp ``t`` depends only on the scene, ``t`` and the
supervisor's commands (``/line/supervisor/commands``, each with its effective
time): a command rebuilds the model, which leaves everything before the command's
effective time unchanged.
"""

from __future__ import annotations

import functools
import math
from typing import Any, Iterable, Mapping

import numpy as np
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState, TimeReference

from folder_line.core.drive import Command
from folder_line.core.events import EVENT_KINDS
from folder_line.core.line import LineModel
from folder_line.errors import ParameterError
from folder_line.event_text import event_source, parse_event_source
from folder_line.nodes.common import (
    COMMANDS_QOS,
    COMMANDS_TOPIC,
    EVENTS_TOPIC,
    NS_PER_S,
    PUBLISH_DEPTH,
    ParamSpec,
    declare_parameters,
    joint_states_topic,
    ns_to_time_msg,
    sim_time_overrides,
    time_msg_to_ns,
)
from folder_line.scenes import load_scene, parse_set

__all__ = ['EVENT_OWNER', 'MACHINE_SPECS', 'MachineNode', 'event_source', 'line_model', 'parse_event_source',
           'parse_overrides']

#: which node publishes which event kind
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
assert set(EVENT_OWNER) == set(EVENT_KINDS), 'every event kind needs a publishing node'

MACHINE_SPECS: tuple[ParamSpec, ...] = (
    ParamSpec('scene', 'folder', 'Scene name (config/scenes) or path of a scene YAML file', read_only=True),
    ParamSpec('overrides', '', 'Scene overrides, "MACHINE.KEY=VALUE" separated by ";" '
              '(e.g. "feed_transporter.V_tr=5.833;seed=3")', read_only=True),
    ParamSpec('horizon', 3600.0, 'Line time the model is built for; the node stops publishing after it',
              unit='s', bounds=(0.0, 1e7), low_open=True, read_only=True),
    ParamSpec('rate', 200.0, 'Publishing rate in simulated time', unit='Hz', bounds=(1.0, 5000.0)),
)


def parse_overrides(text: str) -> dict[str, Any]:
    """``'a.b=1;c=2'`` -> ``{'a.b': 1, 'c': 2}`` (empty items ignored)."""
    return parse_set(item.strip() for item in text.split(';') if item.strip())


@functools.lru_cache(maxsize=8)
def line_model(scene: str, overrides: str, horizon: float, commands: tuple[Command, ...]) -> LineModel:
    """The line model for a scene, shared by every node of a process that asks for the same one."""
    return LineModel(load_scene(scene, parse_overrides(overrides)), horizon, commands)


#: what :mod:`folder_line.scenes` calls the node parameters in its errors (the CLI's options)
_CLI_NAMES = {'--scene': 'scene', '--set': 'overrides'}


def _check_scene(values: Mapping[str, Any]) -> None:
    try:
        load_scene(values['scene'], parse_overrides(values['overrides']))
    except ParameterError as err:  # name the node's parameter, not the CLI option
        if err.key not in _CLI_NAMES:
            raise
        raise ParameterError(_CLI_NAMES[err.key], err.value, err.reason) from None


class MachineNode(Node):
    """Base of the machine nodes (see the module docstring).

    Parameters
    ----------
    parameter_overrides : iterable of Parameter, optional
        Starting parameter values (``use_sim_time`` is forced on).
    **kwargs
        Passed to ``rclpy.node.Node``.
    """

    NODE_NAME = 'machine'
    EXTRA_SPECS: tuple[ParamSpec, ...] = ()

    def __init__(self, *, parameter_overrides: Iterable[Parameter] | None = None, **kwargs: Any) -> None:
        super().__init__(self.NODE_NAME, parameter_overrides=sim_time_overrides(parameter_overrides), **kwargs)
        self.values = declare_parameters(self, MACHINE_SPECS + self.EXTRA_SPECS, cross_check=_check_scene)
        self._key = (self.values['scene'], self.values['overrides'], self.values['horizon'])
        self.commands: tuple[Command, ...] = ()
        self.model = line_model(*self._key, self.commands)
        self.horizon_ns = round(self.values['horizon'] * NS_PER_S)
        self.joints = self.model.nodes.get(self.NODE_NAME, ())
        self.kinds = np.array([EVENT_KINDS.index(k) for k, node in EVENT_OWNER.items() if node == self.NODE_NAME],
                              dtype=np.int16)
        self._last_ns: int | None = None
        self._horizon_logged = False
        self.published_joint_states = 0
        self.published_events = 0
        self._joint_pub = (self.create_publisher(JointState, joint_states_topic(self.NODE_NAME), PUBLISH_DEPTH)
                           if self.joints else None)
        self._event_pub = self.create_publisher(TimeReference, EVENTS_TOPIC, PUBLISH_DEPTH)
        self.create_subscription(TimeReference, COMMANDS_TOPIC, self._on_command, COMMANDS_QOS)
        self._timer = self.create_timer(1.0 / self.values['rate'], self._tick)
        self.add_post_set_parameters_callback(self._apply)
        self.setup()
        self.on_model()
        self.get_logger().info(f'scene {self.model.scene.name!r}, joints {list(self.joints)}, '
                               f'{self.values["rate"]:g} Hz of sim time, horizon {self.values["horizon"]:g} s')

    # ------------------------------------------------------------------ hooks

    def setup(self) -> None:
        """Subclass hook: create extra publishers."""

    def on_model(self) -> None:
        """Subclass hook: the line model was (re)built (at start and after each command)."""

    def publish_extra(self, stamp_ns: int, t: float, events: np.ndarray) -> None:
        """Subclass hook: called every tick with this node's events of ``(t_prev, t]``."""

    def published_counts(self) -> dict[str, int]:
        """Messages this node has published so far, per topic (the recorder's loss accounting).

        Subclasses with more publishers add theirs.
        """
        counts = {EVENTS_TOPIC: self.published_events}
        if self._joint_pub is not None:
            counts[joint_states_topic(self.NODE_NAME)] = self.published_joint_states
        return counts

    # ------------------------------------------------------------------ internals

    def _apply(self, parameters: list[Parameter]) -> None:
        for parameter in parameters:
            if parameter.name == 'rate':
                self._timer.timer_period_ns = round(NS_PER_S / parameter.value)

    def _on_command(self, msg: TimeReference) -> None:
        command = Command(t=time_msg_to_ns(msg.time_ref) / NS_PER_S, kind=msg.source)
        if command in self.commands:
            return
        if self._last_ns is not None and command.t * NS_PER_S < self._last_ns:
            self.get_logger().error(f'command {command.kind} effective at {command.t:.9f} s arrived after '
                                    f'stamp {self._last_ns / NS_PER_S:.9f} s was published: history diverges')
        self.commands = tuple(sorted(self.commands + (command,), key=lambda c: c.t))
        self.model = line_model(*self._key, self.commands)
        self.on_model()

    def _tick(self) -> None:
        now = self.get_clock().now().nanoseconds
        if self._last_ns is not None and now <= self._last_ns:
            return
        if now > self.horizon_ns:
            if not self._horizon_logged:
                self.get_logger().warning(f'sim time passed the horizon {self.values["horizon"]:g} s: not publishing')
                self._horizon_logged = True
            return
        self.publish_at(now)

    def publish_at(self, stamp_ns: int) -> None:
        """Publish everything of stamp ``stamp_ns`` (sim time, ns)."""
        t = stamp_ns / NS_PER_S
        t_prev = -math.inf if self._last_ns is None else self._last_ns / NS_PER_S
        self._last_ns = stamp_ns
        stamp = ns_to_time_msg(stamp_ns)
        # events first: a supervisor that has heard this tick's joint states may take its events as sent
        events = self.model.events_between(t_prev, t)
        mine = events[np.isin(events['kind'], self.kinds)] if events.size else events
        for row in mine:
            ref = TimeReference()
            ref.header.stamp = stamp
            ref.header.frame_id = self.NODE_NAME
            ref.time_ref = ns_to_time_msg(max(0, round(float(row['t']) * NS_PER_S)))
            ref.source = event_source(EVENT_KINDS[row['kind']], row['sheet'], row['cycle'], row['value'])
            self._event_pub.publish(ref)
            self.published_events += 1
        if self._joint_pub is not None:
            js = self.model.sample(self.NODE_NAME, np.array([t]))
            msg = JointState()
            msg.header.stamp = stamp
            msg.header.frame_id = self.NODE_NAME
            msg.name = list(js.names)
            msg.position = js.position[0].tolist()
            msg.velocity = js.velocity[0].tolist()
            msg.effort = [] if js.effort is None else js.effort[0].tolist()
            self._joint_pub.publish(msg)
            self.published_joint_states += 1
        self.publish_extra(stamp_ns, t, mine)
