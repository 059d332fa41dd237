"""Node ``supervisor``: the line's state (PackML), its enforcement, its commands, its diagnostics.

The node is an adapter around :class:`folder_line.core.supervision.Supervisor` (the
logic, pure and replayable offline): it feeds it what it hears and publishes what it
decides.

Inputs
------
* ``/line/events``: the exact events the machine nodes publish (``time_ref`` = the
  event time); judged cycle by cycle with the same constraint code as the batch
  simulator (:mod:`folder_line.core.constraints`, causal evaluation);
* ``/line/<node>/joint_states`` of every node of the scene with joints: the header
  stamp is the node's tick (liveness: ``stale_periods`` periods of the node's
  ``rate``, taken to be this node's, and as many ``/clock`` messages); every value is
  checked for NaN/inf;
* ``/clock``: the clock messages (liveness counts them);
* ``/line/sheet_counter/rate`` and ``/line/sheet_counter/landing_x``: checked for
  NaN/inf (stamped with this node's clock: they carry no header). The sheet counter
  is not watched for liveness: it publishes no stamped periodic message.

Decisions lag the clock by ``event_latency`` (the watermark: every event up to
``t - event_latency`` is taken to have arrived; the logic counts the inputs that came
later, ``late`` in the diagnostics). A timing violation commands ``hold`` at the next
machine cycle boundary at least ``command_lead`` after the violating cycle's decision
(HOLDING, HELD at standstill), a missing sheet ``suspend`` (SUSPENDING, SUSPENDED), a
double sheet ``double_sheet`` (hold or abort), a stale node or a NaN/inf ``abort``
(``stop`` of the drive ``command_lead`` after the decision; ABORTING, ABORTED, which
only ``clear`` leaves). With ``enforce`` false nothing is commanded, only reported.

Outputs
-------
* ``/line/supervisor/state`` (``std_msgs/String``): the PackML state, every tick and
  on every accepted command.
* ``/line/supervisor/commands`` (``sensor_msgs/TimeReference``): drive commands
  (``source`` = hold, unhold, stop or start; ``time_ref`` = effective sim time;
  ``header.stamp`` = the time of the decision).
* ``/diagnostics`` (``diagnostic_msgs/DiagnosticArray``) at ``diag_rate`` Hz of sim
  time: one status per cyclogram constraint of the scene, with the margin of the
  latest evaluated cycle, the smallest margin so far, the unit, and the counts of
  evaluations and violations as key/values (from the line model under the commands
  issued); level OK, WARN (violated before) or ERROR (violated in the latest cycle).
  And, as they happen (stamped with their time), one array per event of the logic:
  ``folder_line/supervisor/violation`` (ERROR: ``t``, ``cycle``, ``constraint``,
  ``margin``, ``unit``, ``action``, ``state``), ``folder_line/supervisor/balance`` at
  every stop (``fed``, ``delivered``, ``in_machine`` and where; OK, or ERROR if a sheet
  is lost), ``folder_line/supervisor/operator`` per operator command; each also
  carries ``t_start``, ``watermark`` and ``late`` so that a bag of the run replays
  through :func:`folder_line.core.supervision.replay`.
* Services (``std_srvs/Trigger``) ``/line/supervisor/{start,stop,hold,unhold,suspend,
  unsuspend,reset,clear,abort}``: a legal command answers ``success`` with its
  effective time and publishes a drive command; an illegal one answers
  ``success = False`` with the reason (:class:`folder_line.core.packml.PackML`).
  Hold, suspend and stop take effect at the next cycle boundary at least
  ``command_lead`` s after the request, so the line stops between two sheets; start,
  unhold, unsuspend and abort take effect ``command_lead`` s after it. The request is
  applied at the watermark (``event_latency`` behind the clock), so that it is
  ordered with the automatic decisions exactly as in a replay.

The scene's drive starts the line at t = 0, so the supervisor starts in STARTING
and enters EXECUTE when the drive reaches speed. Acting states end on the check grid
(``n / rate``): HOLDING, SUSPENDING, STOPPING and ABORTING at standstill, STARTING,
UNHOLDING and UNSUSPENDING at speed (λ >= 0.99), RESETTING and CLEARING at the next
grid point.
"""

from __future__ import annotations

import math
import sys
from typing import Any, Callable

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import JointState, TimeReference
from std_msgs.msg import Float64, String
from std_srvs.srv import Trigger

from folder_line.core.drive import Command
from folder_line.core.events import EVENT_DTYPE, EVENT_KINDS
from folder_line.core.supervision import DRIVE_COMMANDS, SPEED_REACHED, STALE_PERIODS, Balance, Violation
from folder_line.core.supervision import Supervisor as Logic
from folder_line.errors import ParameterError
from folder_line.nodes.common import (
    CLOCK_TOPIC,
    COMMANDS_QOS,
    COMMANDS_TOPIC,
    DIAGNOSTICS_TOPIC,
    EVENTS_TOPIC,
    LANDING_TOPIC,
    NS_PER_S,
    PUBLISH_DEPTH,
    SHEET_RATE_TOPIC,
    SUPERVISOR_STATE_TOPIC,
    ParamSpec,
    joint_states_topic,
    ns_to_time_msg,
    run_node,
    seconds_to_ns,
    time_msg_to_ns,
)
from folder_line.nodes.machine import MachineNode, line_model, parse_event_source

__all__ = ['SERVICES', 'SPEED_REACHED', 'STATE_QOS', 'Supervisor', 'main']

#: service name -> (PackML command, drive command or None, waits for the next cycle boundary)
SERVICES: dict[str, tuple[str, str | None, bool]] = {
    name: (name, *DRIVE_COMMANDS[name])
    for name in ('start', 'stop', 'hold', 'unhold', 'suspend', 'unsuspend', 'reset', 'clear', 'abort')
}

STATE_QOS = QoSProfile(depth=PUBLISH_DEPTH, reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.TRANSIENT_LOCAL)
_INPUT_QOS = QoSProfile(depth=PUBLISH_DEPTH, reliability=ReliabilityPolicy.RELIABLE)


def _non_finite(*arrays: Any) -> int:
    return sum(int(np.count_nonzero(~np.isfinite(np.asarray(a, dtype=float)))) for a in arrays if len(a))


class Supervisor(MachineNode):
    """The ``supervisor`` node (see the module docstring).

    Attributes
    ----------
    logic : folder_line.core.supervision.Supervisor
        The decisions, violations, balances and transitions.
    """

    NODE_NAME = 'supervisor'
    EXTRA_SPECS = (
        ParamSpec('command_lead', 0.1, 'Earliest effective time of a drive command after its decision, in sim '
                  'time (must exceed event_latency)', unit='s', bounds=(0.0, 60.0), read_only=True),
        ParamSpec('diag_rate', 1.0, 'Rate of /diagnostics in sim time', unit='Hz', bounds=(0.01, 1000.0)),
        ParamSpec('stale_periods', STALE_PERIODS, 'A node not heard within this many of its periods (and '
                  'clock messages) is stale: abort', bounds=(0.0, 1e6), low_open=True, read_only=True),
        ParamSpec('enforce', True, 'Command hold, suspend and abort on violations (false: only report)',
                  read_only=True),
        ParamSpec('event_latency', 0.03, 'Decisions lag the clock by this much: events up to t - event_latency '
                  'are taken to be in', unit='s', bounds=(0.0, 60.0), read_only=True),
        ParamSpec('double_sheet', 'hold', 'What a double sheet leads to', choices=('hold', 'abort'),
                  read_only=True),
        ParamSpec('watch', '', 'Nodes expected from the start, comma-separated (the others are watched once '
                  'heard)', read_only=True),
    )

    def setup(self) -> None:
        v = self.values
        if v['command_lead'] <= v['event_latency']:
            raise ParameterError('command_lead', v['command_lead'],
                                 f'must exceed event_latency = {v["event_latency"]!r} s (a command must reach the '
                                 f'nodes before they publish past its effective time)')
        joint_nodes = list(self.model.nodes)
        expected = [w.strip() for w in v['watch'].split(',') if w.strip()]
        unknown = sorted(set(expected) - set(joint_nodes))
        if unknown:
            raise ParameterError('watch', v['watch'], f'only nodes with joint states in this scene can be watched: '
                                 f'{", ".join(joint_nodes)}')
        period = 1.0 / v['rate']
        key = self._key
        self.logic = Logic(self.model.scene, v['horizon'], periods=dict.fromkeys(joint_nodes, period),
                           expected=expected, clock_ticks=True, stale_periods=v['stale_periods'],
                           lead=v['command_lead'], check_period=period, enforce=v['enforce'],
                           double=v['double_sheet'], state='STARTING', t_start=None,
                           model_factory=lambda commands: line_model(*key, commands))
        self._latency_ns = seconds_to_ns(v['event_latency'])
        self._last_heard: dict[str, float] = {}
        self._prev_heard: dict[str, float] = {}  # the tick before the latest, per node
        self._joint_nodes = tuple(joint_nodes)
        self._rows: list[tuple[float, int, int, int, float]] = []
        self._n_violations = self._n_balances = 0
        self._state_pub = self.create_publisher(String, SUPERVISOR_STATE_TOPIC, STATE_QOS)
        self._diag_pub = self.create_publisher(DiagnosticArray, DIAGNOSTICS_TOPIC, PUBLISH_DEPTH)
        self._cmd_pub = self.create_publisher(TimeReference, COMMANDS_TOPIC, COMMANDS_QOS)
        self._next_diag_ns = 0
        self.published_state = self.published_diagnostics = self.published_commands = 0
        self.create_subscription(TimeReference, EVENTS_TOPIC, self._on_event, _INPUT_QOS)
        for node in joint_nodes:
            self.create_subscription(JointState, joint_states_topic(node), self._on_joints(node), _INPUT_QOS)
        self.create_subscription(ClockMsg, CLOCK_TOPIC, self._on_clock, _INPUT_QOS)
        for topic in (SHEET_RATE_TOPIC, LANDING_TOPIC):
            self.create_subscription(Float64, topic, self._on_float(topic), _INPUT_QOS)
        for name in SERVICES:
            self.create_service(Trigger, f'/line/supervisor/{name}', self._service(name))

    @property
    def packml(self) -> Any:
        """The PackML state machine (state and history) of the logic."""
        return self.logic.packml

    # ------------------------------------------------------------------ inputs

    def _on_event(self, msg: TimeReference) -> None:
        try:
            kind, sheet, cycle, value = parse_event_source(msg.source)
        except ValueError:
            self.get_logger().warning(f'ignoring an event I cannot parse: {msg.source!r}')
            return
        if not math.isfinite(value):
            self.logic.bad_value(EVENTS_TOPIC, time_msg_to_ns(msg.header.stamp) / NS_PER_S)
            return
        self._rows.append((time_msg_to_ns(msg.time_ref) / NS_PER_S, EVENT_KINDS.index(kind), sheet, cycle, value))

    def _on_joints(self, node: str) -> Callable[[JointState], None]:
        topic = joint_states_topic(node)

        def on_joints(msg: JointState) -> None:
            stamp = time_msg_to_ns(msg.header.stamp) / NS_PER_S
            last = self._last_heard.get(node)
            if last is None or stamp > last:
                if last is not None:
                    self._prev_heard[node] = last
                self._last_heard[node] = stamp
            self.logic.heard(node, stamp)
            bad = _non_finite(msg.position, msg.velocity, msg.effort)
            if bad:
                self.logic.bad_value(topic, stamp, bad)

        return on_joints

    def _on_clock(self, msg: ClockMsg) -> None:
        self.logic.clock(time_msg_to_ns(msg.clock) / NS_PER_S)

    def _on_float(self, topic: str) -> Callable[[Float64], None]:
        def on_float(msg: Float64) -> None:
            if not math.isfinite(msg.data):
                self.logic.bad_value(topic, max(self.get_clock().now().nanoseconds / NS_PER_S, self.logic.now))

        return on_float

    # ------------------------------------------------------------------ services

    def _service(self, name: str) -> Callable[[Trigger.Request, Trigger.Response], Trigger.Response]:
        def handle(request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
            response.success, response.message = self.request(name)
            return response

        return handle

    def request(self, name: str) -> tuple[bool, str]:
        """Apply service ``name`` now (at the watermark); returns (success, message)."""
        at_boundary = SERVICES[name][2]
        self._step(self.get_clock().now().nanoseconds)
        out = self.logic.command(name)
        self._publish_outputs()
        self._publish_status('operator', out.ok, f'{name}: {"accepted" if out.ok else out.message}',
                             {'t': self.logic.now, 'command': name, 'accepted': out.ok})
        if not out.ok:
            return False, out.message
        # publish the new state now: RESETTING and CLEARING end at the next grid point, before a tick publishes
        self._publish_state()
        if out.command is None:
            return True, f'{name}: {self.packml.state}'
        where = 'the next cycle boundary' if at_boundary else f'{self.values["command_lead"]:g} s after the request'
        return True, (f'{name}: {self.packml.state}, drive {out.command.kind} effective at {out.command.t:.6f} s '
                      f'({where})')

    # ------------------------------------------------------------------ tick

    def publish_extra(self, stamp_ns: int, t: float, events: np.ndarray) -> None:
        self._step(stamp_ns)
        self._publish_state()
        if stamp_ns >= self._next_diag_ns:
            self._diag_pub.publish(self.diagnostics(stamp_ns, t))
            self.published_diagnostics += 1
            self._next_diag_ns = stamp_ns + round(NS_PER_S / self.values['diag_rate'])

    def _step(self, now_ns: int) -> None:
        """Feed what arrived, advance the watermark to ``now - event_latency``, publish what was decided."""
        if self._rows:
            rows, self._rows = self._rows, []
            self.logic.feed(np.array(rows, dtype=EVENT_DTYPE))
        watermark = self._watermark(now_ns)
        if watermark > self.logic.now:
            self.logic.tick(watermark)
        self._publish_outputs()

    def _watermark(self, now_ns: int) -> float:
        """Line time up to which every event is taken to have arrived.

        ``event_latency`` behind the clock, and not past the previous tick heard from
        the slowest machine node: a node publishes a tick's events, then its joint
        states, so once the joint states of its next tick are in, the events up to this
        tick were sent a whole tick earlier (the ticks heard, not a nominal period: a
        node's first tick carries every event before it). Never more than
        ``stale_periods`` ticks behind the *freshest* node, so a dead node still goes
        stale while the others run. Staleness is measured against the other nodes, not
        the clock: when the whole executor stalls (a garbage-collection pause, a loaded
        machine) every node falls behind together and the watermark waits instead of
        overtaking events still queued. Until every machine node has been heard twice,
        the slowest counts as not started.
        """
        period = 1.0 / self.values['rate']
        window = self.values['stale_periods'] * period
        ahead = (now_ns - self._latency_ns) / NS_PER_S
        heard = self._last_heard
        if not heard:
            return ahead - window
        prev = self._prev_heard
        slowest = min(prev.values()) if len(prev) == len(self._joint_nodes) else -math.inf
        floor = min(ahead, max(heard.values()) - period) - window
        return max(min(ahead, slowest), floor)

    def _publish_state(self) -> None:
        self._state_pub.publish(String(data=self.packml.state))
        self.published_state += 1

    def _publish_outputs(self) -> None:
        for t, command in self.logic.take_commands():
            self._publish_command(t, command)
        violations = self.logic.violations
        for v in violations[self._n_violations:]:
            self._publish_violation(v)
        self._n_violations = len(violations)
        balances = self.logic.balances
        for b in balances[self._n_balances:]:
            self._publish_balance(b)
        self._n_balances = len(balances)

    def _publish_command(self, t: float, command: Command) -> None:
        msg = TimeReference()
        msg.header.stamp = ns_to_time_msg(max(0, round(t * NS_PER_S)))
        msg.header.frame_id = self.NODE_NAME
        msg.time_ref = ns_to_time_msg(round(command.t * NS_PER_S))
        msg.source = command.kind
        self._cmd_pub.publish(msg)  # also reaches this node's own subscription, which rebuilds the model
        self.published_commands += 1

    def _publish_status(self, what: str, ok: bool, message: str, values: dict[str, Any],
                        stamp: float | None = None) -> None:
        arr = DiagnosticArray()
        t = self.logic.now if stamp is None else stamp
        arr.header.stamp = ns_to_time_msg(max(0, round(t * NS_PER_S)) if math.isfinite(t) else 0)
        status = DiagnosticStatus()
        status.name = f'folder_line/supervisor/{what}'
        status.hardware_id = self.model.scene.name
        status.level = DiagnosticStatus.OK if ok else DiagnosticStatus.ERROR
        status.message = message
        extra = {'t_start': self.logic.t_start, 'watermark': self.logic.now, 'late': self.logic.late}
        status.values = [KeyValue(key=k, value=repr(v) if isinstance(v, float) else str(v))
                         for k, v in {**values, **extra}.items()]
        arr.status.append(status)
        self._diag_pub.publish(arr)
        self.published_diagnostics += 1

    def _publish_violation(self, v: Violation) -> None:
        self.get_logger().warning(f'{v.constraint} violated in cycle {v.cycle} at {v.t:.6f} s, margin {v.margin:.6g} '
                                  f'{v.unit}: {v.action} ({v.state})')
        self._publish_status('violation', False, f'{v.constraint} violated in cycle {v.cycle}: {v.action}',
                             {'t': v.t, 'cycle': v.cycle, 'constraint': v.constraint, 'margin': v.margin,
                              'unit': v.unit, 'action': v.action, 'state': v.state}, stamp=v.t)

    def _publish_balance(self, b: Balance) -> None:
        if not b.ok:
            self.get_logger().error(f'sheet balance broken at {b.t:.6f} s ({b.state}): fed {b.fed}, delivered '
                                    f'{b.delivered}, in the machine {b.in_machine}')
        self._publish_status('balance', b.ok, f'{b.state}: fed {b.fed} = delivered {b.delivered} + in the '
                             f'machine {b.in_machine}' + ('' if b.ok else ' BROKEN'),
                             {'t': b.t, 'state': b.state, 'fed': b.fed, 'delivered': b.delivered,
                              'in_machine': b.in_machine, **b.detail, 'ok': b.ok}, stamp=b.t)

    def published_counts(self) -> dict[str, int]:
        return {**super().published_counts(), SUPERVISOR_STATE_TOPIC: self.published_state,
                DIAGNOSTICS_TOPIC: self.published_diagnostics, COMMANDS_TOPIC: self.published_commands}

    def diagnostics(self, stamp_ns: int, t: float) -> DiagnosticArray:
        """One status per constraint, from the cycles evaluated by time ``t``."""
        arr = DiagnosticArray()
        arr.header.stamp = ns_to_time_msg(stamp_ns)
        for c in self.model.constraints:
            decided = c.decided_by(t)
            n = int(np.count_nonzero(decided))
            status = DiagnosticStatus()
            status.name = f'folder_line/{c.name}'
            status.hardware_id = self.model.scene.name
            if n == 0:
                status.level = DiagnosticStatus.OK
                status.message = 'no cycle evaluated yet'
                status.values = [KeyValue(key='unit', value=c.unit), KeyValue(key='evaluations', value='0')]
            else:
                done = c.margin[decided]
                i_last = int(np.flatnonzero(decided)[np.argmax(c.t[decided])])
                violations = int(np.count_nonzero(done < 0.0))
                last = float(c.margin[i_last])
                status.level = (DiagnosticStatus.ERROR if last < 0.0
                                else DiagnosticStatus.WARN if violations else DiagnosticStatus.OK)
                status.message = (f'violated in cycle {int(c.cycle[i_last])}' if last < 0.0
                                  else f'{violations} violations so far' if violations else 'ok')
                values: dict[str, Any] = {
                    'margin': repr(last), 'unit': c.unit, 'cycle': str(int(c.cycle[i_last])),
                    'min_margin': repr(float(done.min())), 'violations': str(violations), 'evaluations': str(n),
                }
                status.values = [KeyValue(key=k, value=v) for k, v in values.items()]
            arr.status.append(status)
        return arr


def main(args: list[str] | None = None) -> int:
    """Run ``supervisor`` until Ctrl-C; exit code 0 (2 on a bad parameter)."""
    return run_node(Supervisor, args)


if __name__ == '__main__':
    sys.exit(main())
