"""What the machine nodes share: the scene, the streamed line, the tick.

``crank_drive``, ``belt_conveyor``, ``feed_transporter``, ``sheet_counter`` and the
``supervisor`` are :class:`MachineNode` subclasses. Each runs the line of its scene as a
stream (:class:`folder_line.core.line.stream.LineStream`), computed a little ahead of its
clock in windows of :data:`CHUNK` s of line time and forgotten behind it, for ever, in
memory that does not grow with line time (a node started with a clock far into the line
first fast-forwards there, keeping nothing). It is a lockstep participant
(:mod:`folder_line.ros.lockstep`): on every tick ``t`` granted to it it publishes

* the exact events of its machines with times in ``(t_prev, t]`` on
  ``/line/events`` as ``sensor_msgs/TimeReference``: ``time_ref`` is the event time
  (nearest ns), ``header.stamp`` the tick, ``header.frame_id`` the node,
  ``source`` is ``'<kind> sheet=<id> cycle=<k> value=<repr>'``
  (:func:`folder_line.interfaces.event_source`); the first tick, at stamp ``t_0``, publishes
  the events at ``t_0`` only (a line joined while running is not replayed from 0);
* its joints' states on ``/line/<node>/joint_states`` at every point of its own
  grid (``rate`` Hz of sim time) in ``(t_prev, t]``, stamped with that grid point,
  so the clock's tick rate changes how many messages go out per tick, never what
  they hold;

then acknowledges the tick. A machine node runs tick ``t`` only once the supervisor
has promised ``t`` (an acknowledged tick of it, with every drive command it counts in,
whose promise, the tick plus ``command_lead``, reaches ``t``) or its previous tick is
complete, so every command that can take effect by ``t`` is applied: what a node
publishes at stamp ``t`` depends only
on the scene, ``t`` and the supervisor's commands (``/line/supervisor/commands``,
each with its effective time), never on the load of the machine. A command effective
inside the window computed ahead redoes that window from a copy of its start (the stamps
already published are before the command and do not change), so a command costs the
same at any line time.

Inputs that are malformed, unknown or out of order (a command of an unknown kind,
from anyone but the supervisor, or effective before the last tick published) are
rejected: logged once per kind, counted (:attr:`MachineNode.rejected`, in the
supervisor's diagnostics), and the node goes on. ``use_sim_time`` cannot be turned
off: it is refused at start and at run time.
"""

from __future__ import annotations

import math
import time
from array import array
from collections.abc import Iterable, Mapping
from typing import Any, Protocol, TypeVar

import numpy as np
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.publisher import Publisher
from rclpy.task import Future
from rclpy.type_support import Msg
from sensor_msgs.msg import JointState, TimeReference
from std_msgs.msg import String

from folder_line.config.run_config import RATE
from folder_line.config.scenes import InputNames, parse_set, shared_scene
from folder_line.core.limits import LOST_TIMEOUT, TICK_RATE
from folder_line.core.line.scene import Scene
from folder_line.core.line.stream import Checkpoint, LineStream
from folder_line.core.line.tuning import (
    SCENE_KEYS,
    TUNABLES,
    LineCommand,
    Tuning,
    check_tuning,
    command_of,
    scene_value,
)
from folder_line.core.types.events import EVENT_DTYPE
from folder_line.errors import FolderLineError, ParameterError
from folder_line.interfaces import (
    COMMAND_KINDS,
    COMMANDS_TOPIC,
    EVENT_KINDS,
    EVENT_OWNER,
    EVENTS_TOPIC,
    NS_PER_S,
    TUNABLE_PARAMETERS,
    TUNE_TOPIC,
    UNIT_OF_NODE,
    event_source,
    is_command_source,
)
from folder_line.ros.lockstep import LINE_QOS, Participant
from folder_line.ros.lockstep_messages import Announcement
from folder_line.ros.parameters import ParamSpec, declare_parameters, given_values, guard_changes, starting_values
from folder_line.ros.runtime import run_node
from folder_line.ros.signing import open_text, sign_text
from folder_line.ros.time_msg import ns_to_time_msg, time_msg_to_ns
from folder_line.ros.topics import COMMANDS_QOS, TUNE_QOS, joint_states_topic

__all__ = [
    'CHUNK',
    'EXIT_LOST',
    'FAST_FORWARD',
    'FAST_WINDOW',
    'KEEP',
    'MACHINE_SPECS',
    'NODE_NAMES',
    'MachineNode',
    'NodeMain',
    'machine_node',
    'node_scene',
    'parse_overrides',
]

#: a message type, as rclpy's ``Publisher`` takes it
_M = TypeVar('_M', bound=Msg)


MACHINE_SPECS: tuple[ParamSpec, ...] = (
    ParamSpec('scene', 'folder', 'Scene name (config/scenes) or path of a scene YAML file', read_only=True),
    ParamSpec(
        'overrides',
        '',
        'Scene overrides, "MACHINE.KEY=VALUE" separated by ";" (e.g. "feed_transporter.V_tr=5.833;seed=3")',
        read_only=True,
    ),
    ParamSpec(
        'rate',
        RATE,
        'Joint-state rate in simulated time (its own grid; changing it is harmless)',
        unit='Hz',
        bounds=TICK_RATE.bounds,
    ),
    ParamSpec(
        'lost_timeout',
        3.0,
        'Wall time a tick waits for the supervisor before it is declared lost',
        unit='s',
        bounds=LOST_TIMEOUT.bounds,
        read_only=True,
    ),
)

#: exit code of a node process whose line did not end as expected (a participant lost, a silent clock)
EXIT_LOST = 3

#: line time a node computes ahead of its tick in one window of its stream, s (a command effective inside
#: it redoes the window: at most this much line time is computed again)
CHUNK = 0.25
#: line time before its window the stream keeps (the longest clock step, a second, and a window): a grid
#: point or a marker between the last tick and the window it falls in is still drawn from the line, s
KEEP = 1.0 + CHUNK
#: a node whose first tick is further into the line than this fast-forwards there first, s
FAST_FORWARD = 60.0
#: line time per window of a fast-forward, s (nothing of it is kept)
FAST_WINDOW = 600.0


#: the scene loader's inputs in a node's words: its parameters
NODE_NAMES = InputNames(scene='scene', overrides='overrides')


def parse_overrides(text: str) -> dict[str, object]:
    """``'a.b=1;c=2'`` -> ``{'a.b': 1, 'c': 2}`` (empty items ignored; errors name ``overrides``)."""
    return parse_set((item.strip() for item in text.split(';') if item.strip()), NODE_NAMES)


def node_scene(scene: str, overrides: str = '') -> Scene:
    """The scene of the ``scene`` and ``overrides`` parameters, parsed once per process
    (:func:`folder_line.config.scenes.shared_scene`); errors name those parameters."""
    return shared_scene(scene, parse_overrides(overrides), names=NODE_NAMES)


#: why a line node refuses use_sim_time false
SIM_TIME_REASON = "a line node runs on the line's simulated time (/clock); it cannot be turned off"


def _check_sim_time(values: Mapping[str, object]) -> None:
    # the scene and the overrides are read-only: loaded once, at start (MachineNode.__init__)
    if values.get('use_sim_time') is False:
        raise ParameterError('use_sim_time', False, SIM_TIME_REASON)


def _check_tunable_start(node: str, spec: ParamSpec, value: object, scene: Scene) -> None:
    """A tunable starts at the scene's value: another start value belongs in the scene (``overrides``)."""
    key = TUNABLE_PARAMETERS[node][spec.name]
    if value != scene_value(scene, key):
        where = (
            f"the model's {scene_value(scene, key)!r} {spec.unit}; it has no scene key"
            if key not in SCENE_KEYS
            else f"the scene's {scene_value(scene, key)!r} {spec.unit}; to start at another value "
            f'set "{key}=..." in the overrides parameter'
        )
        raise ParameterError(spec.name, value, f'is changed on the running line; it starts at {where}')


class MachineNode(Node):
    """Base of the machine nodes (see the module docstring).

    Parameters
    ----------
    parameter_overrides : iterable of Parameter, optional
        Starting parameter values (``use_sim_time`` is on; false is refused).
    **kwargs
        Passed to ``rclpy.node.Node``.

    Attributes
    ----------
    done : rclpy.task.Future
        Completes when the clock's last tick (its announced end) is done.
    rejected : dict of str to int
        Inputs rejected so far, per kind.
    """

    NODE_NAME = 'machine'
    EXTRA_SPECS: tuple[ParamSpec, ...] = ()
    #: the node's stream judges the constraints (the supervisor's diagnostics); a machine node needs only its
    #: events and joints
    JUDGES = False

    def __init__(self, *, parameter_overrides: Iterable[Parameter[Any]] | None = None, **kwargs: Any) -> None:
        super().__init__(self.NODE_NAME, parameter_overrides=list(parameter_overrides or []), **kwargs)
        try:  # a node refused here is torn down at once, in order (not left to the garbage collector)
            self._make()
        except BaseException:
            self.destroy_node()
            raise

    def _make(self) -> None:
        """Check the parameters and the scene, then make the node's entities (after ``Node.__init__``)."""
        # use_sim_time defaults to true here: rclpy's TimeSource declared it with false, so it is declared again
        # with true, which takes a value given (constructor or --ros-args) as rclpy does; false is refused
        self.undeclare_parameter('use_sim_time')
        if self.declare_parameter('use_sim_time', True).value is False:
            raise ParameterError('use_sim_time', False, SIM_TIME_REASON)
        self.tunables = self._tunable_specs()
        self.values = declare_parameters(
            self, MACHINE_SPECS + self.EXTRA_SPECS + self.tunables, cross_check=_check_sim_time
        )
        self.scene: Scene = node_scene(self.values['scene'], self.values['overrides'])
        self._check_tunables_at_start()
        self.commands: tuple[LineCommand, ...] = ()
        self.kinds = np.array(
            [EVENT_KINDS.index(k) for k, node in EVENT_OWNER.items() if node == self.NODE_NAME], dtype=np.int16
        )
        self.stream = LineStream(self.scene, keep=KEEP, judge=self.JUDGES)
        self.unit = UNIT_OF_NODE.get(self.NODE_NAME, '')  # the core's machine unit this node runs ('' none)
        self.joints = self.stream.units.get(self.unit, ())
        self._last_ns: int | None = None  # the latest tick published
        self._grid_ns: int | None = None  # the latest grid point published
        self._period_ns = round(NS_PER_S / self.values['rate'])
        self._start: Checkpoint | None = None  # the stream at the start of the window it computed last
        self._pending = np.zeros(0, dtype=EVENT_DTYPE)  # this node's events computed, not yet published
        self._samples: tuple[int, int, list[tuple[array[float], array[float], array[float]]]] | None = None
        self._names: list[str] = list(self.joints)
        # one joint state message, refilled for every grid point (publishing serializes it at once)
        self._joint_msg = JointState()
        self._joint_msg.header.frame_id = self.NODE_NAME
        self._joint_msg.name = self._names
        self.rejected: dict[str, int] = {}
        self.published_joint_states = 0
        self.published_events = 0
        self.done: Future[int] = Future()
        self._joint_pub = (
            self.create_publisher(JointState, joint_states_topic(self.NODE_NAME), LINE_QOS) if self.joints else None
        )
        self._event_pub = self.create_publisher(TimeReference, EVENTS_TOPIC, LINE_QOS)
        self.create_subscription(TimeReference, COMMANDS_TOPIC, self._on_command, COMMANDS_QOS)
        self._tune_pub = self.create_publisher(String, TUNE_TOPIC, TUNE_QOS) if self.tunables else None
        self._tune_seq = 0
        if self.tunables:
            self.add_on_set_parameters_callback(self._screen_tunings)
        self.lockstep = Participant(
            self,
            self.depends,
            self._on_tick,
            needs=self.needs,
            promise=self.promise,
            on_lost=self.on_lost,
            on_reject=self.reject,
            on_end=self._on_end,
            lost_timeout=self.values['lost_timeout'],
        )
        self.add_post_set_parameters_callback(self._apply)
        self.signatures = guard_changes(self)  # on a keyed line, a change at run time must be signed
        self.setup()
        self.get_logger().info(
            f'scene {self.scene.name!r}, joints {list(self.joints)}, {self.values["rate"]:g} Hz of sim time'
        )

    # ------------------------------------------------------------------ hooks

    def depends(self, a: Announcement) -> dict[str, tuple[str, ...]]:
        """The producers this node waits for: the supervisor's commands (in wall mode too, so that a hold
        or a stop always reaches the machines in time; a machine that waits for them is late instead)."""
        return {'supervisor': ('commands',)}

    def needs(self, stamp: int, previous: int | None) -> tuple[int, int | None] | None:
        """Tick ``stamp`` runs once the supervisor promised it (no command of it can take effect at or before
        ``stamp``), or its ``previous`` tick is complete; the first tick runs at once."""
        return None if previous is None else (previous, stamp)

    def promise(self, stamp: int) -> int:
        """The promise acknowledged with tick ``stamp``: nothing this node publishes later matters before it."""
        return stamp

    def on_lost(self, producer: str, waited: float, stamp: int) -> None:
        """A producer this node waits for was declared lost (logged by the participant)."""

    def exit_code(self) -> int:
        """The process's exit code: :data:`EXIT_LOST` if the line did not end as expected here (a producer
        was lost, or the clock is silent and the last tick never came), else 0."""
        failed = self.lockstep.lost or (self.lockstep.clock_silent and not self.done.done())
        return EXIT_LOST if failed else 0

    def setup(self) -> None:
        """Subclass hook: create extra publishers."""

    def publish_sample(self, stamp_ns: int, t: float) -> None:
        """Subclass hook: called at every grid point ``t`` (after the joint states)."""

    def publish_extra(self, stamp_ns: int, t: float, events: np.ndarray) -> None:
        """Subclass hook: called every tick with this node's events of ``(t_prev, t]`` (after the samples)."""

    @property
    def period_ns(self) -> int:
        """The node's own grid step (its ``rate``), ns."""
        return int(self._period_ns)

    @property
    def publishes_joint_states(self) -> bool:
        """Whether the node has joint states in this scene (a layup has no feed transporter's)."""
        return self._joint_pub is not None

    def published_counts(self) -> dict[str, int]:
        """Messages this node has published so far, per topic (the recorder's loss accounting).

        Subclasses with more publishers add theirs.
        """
        counts = {EVENTS_TOPIC: self.published_events}
        if self._joint_pub is not None:
            counts[joint_states_topic(self.NODE_NAME)] = self.published_joint_states
        return counts

    def reject(self, kind: str, reason: str) -> None:
        """Count a rejected input of ``kind``; log the first of each kind."""
        n = self.rejected.get(kind, 0)
        self.rejected[kind] = n + 1
        if n == 0:
            self.get_logger().warning(f'rejected {kind}: {reason} (further rejections of this kind are only counted)')

    def publish(self, publisher: Publisher[_M], msg: _M, stream: str | None = None) -> None:
        """Publish and count (the tick's acknowledgement carries the counts)."""
        self.lockstep.publish(publisher, msg, stream)

    # ------------------------------------------------------------------ tuning

    def _tunable_specs(self) -> tuple[ParamSpec, ...]:
        """The parameters of this node's tunables the scene can take, each starting at the scene's value.

        The scene is read here from the starting ``scene`` and ``overrides`` (the values
        ``declare_parameters`` then checks): if they do not load, no tunable is declared
        and the declaration below names the fault.
        """
        if not TUNABLE_PARAMETERS.get(self.NODE_NAME):
            return ()
        try:
            start = starting_values(self, [spec for spec in MACHINE_SPECS if spec.name in ('scene', 'overrides')])
            scene = node_scene(str(start['scene']), str(start['overrides']))
        except FolderLineError:
            return ()
        return self.tunable_specs(scene)

    @classmethod
    def tunable_specs(cls, scene: Scene) -> tuple[ParamSpec, ...]:
        """The parameters of this node's tunables ``scene`` can take, each starting at the scene's value."""
        specs = []
        for param, key in TUNABLE_PARAMETERS.get(cls.NODE_NAME, {}).items():
            tunable = TUNABLES[key]
            if tunable.needs(scene):
                continue
            specs.append(
                ParamSpec(
                    param,
                    scene_value(scene, key),
                    f'{tunable.what[0].upper()}{tunable.what[1:]} ({key}), tunable on the running line: a new '
                    'value takes effect at the next machine cycle boundary the supervisor picks',
                    unit=tunable.unit,
                    bounds=tunable.limit.bounds,
                )
            )
        return tuple(specs)

    def _check_tunables_at_start(self) -> None:
        """A tunable starts at the scene's value: another start value belongs in the scene (``overrides``)."""
        for spec in self.tunables:
            _check_tunable_start(self.NODE_NAME, spec, self.values[spec.name], self.scene)

    @classmethod
    def refuse_start(cls, given: Mapping[str, object]) -> None:
        """Refuse, before any node is made, a start this node would refuse, with the node's own words.

        Parameters
        ----------
        given : mapping of str to object
            The starting values the command line gives (:func:`folder_line.ros.ros_args.command_line_values`).

        Raises
        ------
        FolderLineError
            What the node's start would raise first: an explicit ``use_sim_time`` false, a value
            its spec refuses, a scene that does not load, a tunable not at the scene's value.
        """
        if given.get('use_sim_time') is False:
            raise ParameterError('use_sim_time', False, SIM_TIME_REASON)
        values = given_values(MACHINE_SPECS + cls.EXTRA_SPECS, given)
        scene = node_scene(str(values['scene']), str(values['overrides']))
        for spec in cls.tunable_specs(scene):
            _check_tunable_start(cls.NODE_NAME, spec, spec.check(given.get(spec.name, spec.default)), scene)

    def _screen_tunings(self, parameters: list[Parameter[Any]]) -> SetParametersResult:
        """Refuse a tuning when no supervisor listens: nobody would time it, so it would never take effect."""
        names = TUNABLE_PARAMETERS.get(self.NODE_NAME, {})
        for parameter in parameters:
            if parameter.name in names and self._tune_pub is not None and self._tune_pub.get_subscription_count() == 0:
                return SetParametersResult(
                    successful=False,
                    reason=f'{parameter.name}={parameter.value!r}: no supervisor on this domain to time the change '
                    '(a tuning takes effect at the machine cycle boundary the supervisor picks)',
                )
        return SetParametersResult(successful=True)

    def _forward_tuning(self, name: str, value: float) -> None:
        key = TUNABLE_PARAMETERS[self.NODE_NAME][name]
        if self._tune_pub is None:
            return
        # numbered (wall ns, rising) and signed: a tuning read off the network cannot be played again
        self._tune_seq = max(self._tune_seq + 1, time.time_ns())
        text = f'{self.NODE_NAME} {key}={float(value)!r} #{self._tune_seq}'
        self._tune_pub.publish(String(data=sign_text(text, 'tune')))
        self.get_logger().info(
            f'{name} = {value!r} {TUNABLES[key].unit} asked of the supervisor: it takes effect at the next '
            'machine cycle boundary (see /line/supervisor/commands)'
        )

    # ------------------------------------------------------------------ internals

    def _apply(self, parameters: list[Parameter[Any]]) -> None:
        names = TUNABLE_PARAMETERS.get(self.NODE_NAME, {})
        for parameter in parameters:
            if parameter.name in self.values:  # what the node reads (rate_window, diag_rate, marker_rate, ...)
                self.values[parameter.name] = parameter.value
            if parameter.name == 'rate':
                self._period_ns = round(NS_PER_S / parameter.value)
            elif parameter.name in names:
                self._forward_tuning(parameter.name, parameter.value)

    def _on_command(self, msg: TimeReference) -> None:
        if msg.header.frame_id != 'supervisor':
            self.reject(
                'command', f'from {msg.header.frame_id[:40]!r}: drive commands are taken from the supervisor only'
            )
            return
        try:
            source = open_text(msg.source, 'command', msg.header.frame_id, msg.header.stamp, msg.time_ref)
        except ValueError as err:
            self.reject('command', str(err))
            return
        if not is_command_source(source):
            self.reject(
                'command',
                f'unknown drive command {source[:40]!r} (one of {", ".join(COMMAND_KINDS)}, or "set KEY=VALUE")',
            )
            return
        try:
            command = command_of(time_msg_to_ns(msg.time_ref) / NS_PER_S, source)
            if isinstance(command, Tuning):
                check_tuning(self.scene, command.key, command.value)
        except (ValueError, FolderLineError) as err:
            self.reject('command', f'{source[:60]!r}: {err}')
            return
        if command in self.commands:
            self.reject('command', f'{command.kind} at {command.t:.9f} s repeated')
            return
        if self._last_ns is not None and command.t * NS_PER_S < self._last_ns:
            self.reject(
                'command',
                f'{command.kind} effective at {command.t:.9f} s arrived after stamp '
                f'{self._last_ns / NS_PER_S:.9f} s was published',
            )
            return
        self.commands = tuple(sorted((*self.commands, command), key=lambda c: c.t))
        self._take_commands(command.t)
        self.lockstep.received('supervisor', 'commands')

    def _take_commands(self, t_effective: float) -> None:
        """Run the line under :attr:`commands` from now on: a command effective inside the window computed
        ahead redoes that window from its start (what was published is before the command)."""
        stream = self.stream
        if t_effective > stream.t or self._start is None:
            stream.set_commands(self.commands)
            return
        end = stream.t
        stream.restore(self._start, self.commands)
        window = stream.advance(end)
        last = -math.inf if self._last_ns is None else self._last_ns / NS_PER_S
        mine = window.events[np.isin(window.events['kind'], self.kinds)]
        self._pending = mine[mine['t'] > last]
        self._samples = None  # sampled again, from the stream under the commands

    # ------------------------------------------------------------------ the stream

    def _cover(self, stamp_ns: int) -> None:
        """Compute the line up to at least ``stamp_ns`` (ns): a window of :data:`CHUNK` s past it, after a
        fast-forward if the stream is far behind (a clock started far into the line)."""
        stream = self.stream
        t = stamp_ns / NS_PER_S
        if stream.t >= t:
            return
        if t - max(stream.t, 0.0) > FAST_FORWARD:  # far behind: get there at batch speed, keeping nothing
            target = t - CHUNK
            self.get_logger().info(f'fast-forwarding the line to {target:.9g} s of line time')
            while stream.t < target:
                stream.advance(min(target, max(stream.t, 0.0) + FAST_WINDOW))
                self.lockstep.working(stamp_ns)  # alive, for whoever waits for this tick
            self._pending = np.zeros(0, dtype=EVENT_DTYPE)
        self._start = stream.checkpoint()
        window = stream.advance(max(t, stream.t + CHUNK))
        mine = window.events[np.isin(window.events['kind'], self.kinds)]
        self._pending = np.concatenate((self._pending, mine)) if self._pending.size else mine

    def _on_tick(self, stamp_ns: int) -> None:
        self.publish_at(stamp_ns)

    def _on_end(self, stamp_ns: int) -> None:
        if not self.done.done():
            self.done.set_result(stamp_ns)

    def grid_points(self, stamp_ns: int) -> list[int]:
        """This node's grid points in ``(last grid point, stamp_ns]`` (the first tick is one)."""
        if self._grid_ns is None:
            return [stamp_ns]
        first = self._grid_ns + self._period_ns
        return list(range(first, stamp_ns + 1, self._period_ns))

    def _joint_row(self, g: int) -> tuple[array[float], array[float], array[float]]:
        """Position, velocity, effort of this node's joints at grid point ``g`` (ns), from the stream.

        The grid points of the window computed are sampled in one call (one numpy call costs
        about as much for one point as for many); the rows are dropped when the window or the
        grid (``rate``) changes, so every row is the line's value at its own time, whatever the
        clock's tick rate.
        """
        c = self._samples
        if c is not None:
            first, period, rows = c
            i, off = divmod(g - first, period)
            if period == self._period_ns and off == 0 and 0 <= i < len(rows):
                return rows[i]
        end = round(self.stream.t * NS_PER_S)
        n = max(1, (end - g) // self._period_ns + 1)
        times = np.array([g + k * self._period_ns for k in range(n)], dtype=float) / NS_PER_S
        js = self.stream.sample(self.unit, times)
        if list(js.names) != self._names:
            self._names = list(js.names)
            self._joint_msg.name = self._names
        # array('d') rows: the message takes them as they are (a list is checked value by value)
        pos, vel = [array('d', row) for row in js.position], [array('d', row) for row in js.velocity]
        eff = [array('d')] * n if js.effort is None else [array('d', row) for row in js.effort]
        rows = list(zip(pos, vel, eff, strict=True))
        self._samples = (g, self._period_ns, rows)
        return rows[0]

    def publish_at(self, stamp_ns: int) -> None:
        """Publish everything of the tick at ``stamp_ns`` (sim time, ns)."""
        t = stamp_ns / NS_PER_S
        first = self._last_ns is None
        self._cover(stamp_ns)
        if self._samples is not None and self._samples[0] + len(self._samples[2]) * self._samples[1] <= stamp_ns:
            self._samples = None  # a new window: its grid points are sampled when first needed
        self._last_ns = stamp_ns
        stamp = ns_to_time_msg(stamp_ns)
        pend = self._pending
        n = int(np.searchsorted(pend['t'], t, side='right'))
        mine, self._pending = pend[:n], pend[n:]
        if first:  # a line joined at t_0: its events before t_0 are not published
            mine = mine[mine['t'] >= t]
        for row in mine:
            ref = TimeReference()
            ref.header.stamp = stamp
            ref.header.frame_id = self.NODE_NAME
            ref.time_ref = ns_to_time_msg(max(0, round(float(row['t']) * NS_PER_S)))
            ref.source = event_source(EVENT_KINDS[row['kind']], row['sheet'], row['cycle'], row['value'])
            self.publish(self._event_pub, ref, 'events')
            self.published_events += 1
        self.on_events(mine)
        points = self.grid_points(stamp_ns)
        if points:
            self._grid_ns = points[-1]
            for g in points:
                if self._joint_pub is not None:
                    msg = self._joint_msg
                    msg.position, msg.velocity, msg.effort = self._joint_row(g)
                    msg.header.stamp = ns_to_time_msg(g)
                    self.publish(self._joint_pub, msg)
                    self.published_joint_states += 1
                self.publish_sample(g, g / NS_PER_S)
        self.publish_extra(stamp_ns, t, mine)

    def on_events(self, events: np.ndarray) -> None:
        """Subclass hook: this node's events of the tick, just published (before the grid points)."""


def node_exit_code(node: Node) -> int:
    """The exit code of a machine node's process (:meth:`MachineNode.exit_code`; 0 for any other node)."""
    return node.exit_code() if isinstance(node, MachineNode) else 0


class NodeMain(Protocol):
    """A node module's ``main(args=None) -> exit code``."""

    def __call__(self, args: list[str] | None = None) -> int: ...


def machine_node(name: str, module: str) -> tuple[type[MachineNode], NodeMain]:
    """The class and the ``main(args=None)`` of a machine node that needs nothing beyond :class:`MachineNode`.

    Parameters
    ----------
    name : str
        The node's name (``'feed_transporter'``); the class is named after it (``FeedTransporter``).
    module : str
        ``__name__`` of the module that starts the node, where the class and ``main`` are defined.

    Returns
    -------
    (type, callable)
        The :class:`MachineNode` subclass and its ``main``: runs the node until Ctrl-C
        (:func:`~folder_line.ros.runtime.run_node`) and returns the exit code, 0 (2 on a bad parameter).
    """
    title = ''.join(word.capitalize() for word in name.split('_'))
    cls = type(title, (MachineNode,), {'NODE_NAME': name, '__doc__': f'The ``{name}`` node.', '__module__': module})

    def main(args: list[str] | None = None) -> int:
        return run_node(cls, args, exit_code=node_exit_code)

    main.__doc__ = f'Run ``{name}`` until Ctrl-C; exit code 0 (2 on a bad parameter, 3 if the line did not end).'
    main.__module__ = module
    return cls, main
