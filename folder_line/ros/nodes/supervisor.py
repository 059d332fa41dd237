"""Node ``supervisor``: the line's state (PackML), its enforcement, its commands, its diagnostics.

The node is an adapter around :class:`folder_line.core.supervision.supervisor.Supervisor` (the
logic, pure and replayable offline): it feeds it what it hears and publishes what it
decides. It is a lockstep participant (:mod:`folder_line.ros.lockstep`) that waits,
at every tick ``t``, for every machine participant's tick ``t`` to be complete: their
acknowledgements are in and so is every event they count. Only then is the logic
advanced to ``t`` (the watermark is exact), so a cycle is never judged on missing
input, however busy the machine; a slow node only slows sim time down.

Inputs
------
* ``/line/events``: the exact events the machine nodes publish (``time_ref`` = the
  event time), counted per publishing node (``header.frame_id``, which must be the
  node that owns the event kind); judged cycle by cycle with the same constraint
  code as the batch simulator (:mod:`folder_line.core.line.constraints`, causal evaluation);
* ``/line/<node>/joint_states`` of every node of the scene with joints, and
  ``/line/sheet_counter/rate`` and ``/line/sheet_counter/landing_x``: checked for NaN/inf;
* ``/line/<node>/progress``: the machine participants' acknowledgements.

A participant that does not complete a tick within ``lost_timeout`` s of wall time is
waited for, and named; one whose process is gone from the graph as well is *lost*: the
logic aborts with cause ``lost:<node>`` (ABORTING, then ABORTED at standstill) and judges
nothing after that time. A malformed, unknown or out-of-order
input on any subscribed topic is rejected, logged once per kind and counted in the
``folder_line/supervisor/inputs`` diagnostic; the node keeps running.

A timing violation commands ``hold`` at the next machine cycle boundary at least
``command_lead`` after the violating cycle's decision (HOLDING, HELD at standstill),
a missing sheet ``suspend`` (SUSPENDING, SUSPENDED), a double sheet ``double_sheet``
(hold or abort), a NaN/inf ``abort`` (``stop`` of the drive ``command_lead`` after
the decision; ABORTING, ABORTED, which only ``clear`` leaves). With ``enforce`` false
nothing is commanded, only reported.

Outputs
-------
* ``/line/supervisor/state`` (``std_msgs/String``, transient-local: a late
  ``ros2 topic echo`` gets the current state): the PackML state at every point of
  its grid (``rate``) and on every accepted command.
* ``/line/supervisor/commands`` (``sensor_msgs/TimeReference``): drive commands
  (``source`` = hold, unhold, stop or start; ``time_ref`` = effective sim time;
  ``header.stamp`` = the time of the decision; ``header.frame_id`` = ``supervisor``).
* ``/diagnostics`` (``diagnostic_msgs/DiagnosticArray``) at ``diag_rate`` Hz of sim
  time: one status per cyclogram constraint of the scene, with the margin of the
  latest evaluated cycle, the smallest margin so far, the unit, and the counts of
  evaluations and violations as key/values; level OK, WARN (violated before) or
  ERROR (violated in the latest cycle); and ``folder_line/supervisor/inputs`` with the
  rejected inputs per kind. And, as they happen (stamped with their time), one array
  per event of the logic: ``folder_line/supervisor/violation`` (ERROR: ``t``,
  ``cycle``, ``constraint``, ``margin``, ``unit``, ``action``, ``state``),
  ``folder_line/supervisor/balance`` at every stop (``fed``, ``delivered``,
  ``in_machine`` and where; OK, or ERROR if a sheet is lost),
  ``folder_line/supervisor/operator`` per operator command; each also carries
  ``t_start``, ``watermark`` and ``late`` so that a bag of the run replays through
  :func:`folder_line.core.supervision.offline.replay`.
* Services (``std_srvs/Trigger``) ``/line/supervisor/{start,stop,hold,unhold,suspend,
  unsuspend,reset,clear,abort}``: a legal command answers ``success`` with its
  effective time and publishes a drive command; an illegal one answers
  ``success = False`` with the reason (:class:`folder_line.core.supervision.packml.PackML`).
  A command is timed at the clock: decided at the latest tick the supervisor
  completed, it takes effect at the next cycle boundary at least ``command_lead`` s
  later (hold, suspend, stop), or ``command_lead`` s later (start, unhold,
  unsuspend, abort). ``command_lead`` must exceed the clock's tick step (the machine
  nodes may already be one tick further); a command that cannot be timed so is refused.
  On a keyed line a call is answered only after a signed request for it (the parameter
  ``operator_command`` set with ``line_signature``, :mod:`folder_line.ros.signing`) within the
  last ``REQUEST_WINDOW`` s, each used once; otherwise it is refused with the reason and counted.

The scene's drive starts the line at t = 0, so the supervisor starts in STARTING
and enters EXECUTE when the drive reaches speed. Acting states end on the check grid
(``n / rate``): HOLDING, SUSPENDING, STOPPING and ABORTING at standstill, STARTING,
UNHOLDING and UNSUSPENDING at speed (λ >= 0.99), RESETTING and CLEARING at the next
grid point.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState, TimeReference
from std_msgs.msg import Float64, String
from std_srvs.srv import Trigger

from folder_line.bag.statuses import (
    ERROR,
    OK,
    WARN,
    Status,
    balance_status,
    constraint_statuses,
    event_status,
    status_stamp,
    tuning_status,
    violation_status,
)
from folder_line.config.run_config import SUPERVISOR_DEFAULTS, supervisor_logic
from folder_line.core.line.margin_text import format_margin, margin_at
from folder_line.core.line.tuning import SET_PREFIX, LineCommand, parse_tuning_text
from folder_line.core.supervision.balance import Balance
from folder_line.core.supervision.commands import DRIVE_COMMANDS
from folder_line.core.supervision.packml import PackML
from folder_line.core.supervision.records import Outcome, Violation
from folder_line.core.types.events import EVENT_DTYPE
from folder_line.interfaces import (
    COMMANDS_TOPIC,
    DIAGNOSTICS_TOPIC,
    EVENT_KINDS,
    EVENT_OWNER,
    EVENTS_TOPIC,
    LANDING_TOPIC,
    MACHINE_NODES,
    NODE_OF_UNIT,
    NS_PER_S,
    OPERATOR_COMMANDS,
    SHEET_RATE_TOPIC,
    SUPERVISOR_STATE_TOPIC,
    TUNABLE_PARAMETERS,
    TUNE_TOPIC,
    parse_event_source,
    seconds_to_ns,
)
from folder_line.ros.lockstep import LINE_QOS
from folder_line.ros.lockstep_messages import Announcement
from folder_line.ros.nodes.machine import FAST_WINDOW, MachineNode, node_exit_code
from folder_line.ros.parameters import ParamSpec
from folder_line.ros.runtime import run_node
from folder_line.ros.signing import REQUEST_WINDOW, SIGNATURE_PARAMETER, open_text, sign_text
from folder_line.ros.time_msg import ns_to_time_msg, time_msg_to_ns
from folder_line.ros.topics import COMMANDS_QOS, PUBLISH_DEPTH, TUNE_QOS, joint_states_topic

__all__ = ['RECORDS_KEPT', 'SERVICES', 'STATE_QOS', 'Supervisor', 'main']

#: ns the supervisor's promise stays short of ``command_lead`` (a command's effective time travels rounded to ns)
PROMISE_MARGIN = 1000
#: violations and balances the node keeps after publishing them (the memory does not grow with line time)
RECORDS_KEPT = 1000
#: service name -> (PackML command, drive command or None, waits for the next cycle boundary)
SERVICES: dict[str, tuple[str, str | None, bool]] = {name: (name, *DRIVE_COMMANDS[name]) for name in OPERATOR_COMMANDS}

STATE_QOS = QoSProfile(
    depth=PUBLISH_DEPTH, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
)


#: :mod:`folder_line.bag.statuses` levels -> the message's byte constants
_LEVELS = {OK: DiagnosticStatus.OK, WARN: DiagnosticStatus.WARN, ERROR: DiagnosticStatus.ERROR}


def _status_msg(status: Status) -> DiagnosticStatus:
    """The rclpy message of a :class:`~folder_line.bag.statuses.Status` (shared with ``simulate --bag``)."""
    return DiagnosticStatus(
        level=_LEVELS[status.level],
        name=status.name,
        message=status.message,
        hardware_id=status.hardware_id,
        values=[KeyValue(key=k, value=v) for k, v in status.values],
    )


def _non_finite(*arrays: Sequence[float]) -> int:
    """NaN and inf values in ``arrays`` (sequences of float)."""
    # a NaN or an inf makes the sum non-finite, so a finite sum (the usual case, in C) needs no count;
    # a non-finite sum may come from an overflow of finite values, so the count itself is exact
    if math.isfinite(sum(sum(a) for a in arrays)):
        return 0
    return sum(int(np.count_nonzero(~np.isfinite(np.asarray(a, dtype=float)))) for a in arrays if len(a))


class Supervisor(MachineNode):
    """The ``supervisor`` node (see the module docstring).

    Attributes
    ----------
    logic : folder_line.core.supervision.supervisor.Supervisor
        The decisions, violations, balances and transitions.
    """

    NODE_NAME = 'supervisor'
    JUDGES = True
    EXTRA_SPECS = (
        ParamSpec(
            'command_lead',
            SUPERVISOR_DEFAULTS['command_lead'],
            'Earliest effective time of a drive command after its decision, in sim '
            "time (must exceed the clock's tick step)",
            unit='s',
            bounds=(0.001, 60.0),
            read_only=True,
        ),
        ParamSpec('diag_rate', 1.0, 'Rate of /diagnostics in sim time', unit='Hz', bounds=(0.01, 1000.0)),
        ParamSpec(
            'enforce',
            SUPERVISOR_DEFAULTS['enforce'],
            'Command hold, suspend and abort on violations (false: only report)',
            read_only=True,
        ),
        ParamSpec(
            'double_sheet',
            SUPERVISOR_DEFAULTS['double_sheet'],
            'What a double sheet leads to',
            choices=('hold', 'abort'),
            read_only=True,
        ),
        ParamSpec(
            'operator_command',
            '',
            "On a keyed line, the operator command whose service call comes next, set with the line's "
            'signature (folder-line hold and the other operator verbs do both)',
            choices=('', *SERVICES),
        ),
    )

    def setup(self) -> None:
        v = self.values
        joint_nodes = [NODE_OF_UNIT[unit] for unit in self.stream.units]
        self.logic = supervisor_logic(self.scene, v)
        self._n_violations = self._n_balances = 0
        self._joint_nodes = tuple(joint_nodes)
        self._rows: list[tuple[float, int, int, int, float]] = []
        self._n_rejected = 0
        self._clock_step: int | None = None
        self._lead_ns = seconds_to_ns(v['command_lead'])
        self._state_pub = self.create_publisher(String, SUPERVISOR_STATE_TOPIC, STATE_QOS)
        self._diag_pub = self.create_publisher(DiagnosticArray, DIAGNOSTICS_TOPIC, LINE_QOS)
        self._cmd_pub = self.create_publisher(TimeReference, COMMANDS_TOPIC, COMMANDS_QOS)
        self._next_diag_ns = 0
        self.published_state = self.published_diagnostics = self.published_commands = 0
        self.create_subscription(TimeReference, EVENTS_TOPIC, self._on_event, LINE_QOS)
        for node in joint_nodes:
            self.create_subscription(JointState, joint_states_topic(node), self._on_joints(node), LINE_QOS)
        for topic in (SHEET_RATE_TOPIC, LANDING_TOPIC):
            self.create_subscription(Float64, topic, self._on_float(topic), LINE_QOS)
        for name in SERVICES:
            self.create_service(Trigger, f'/line/supervisor/{name}', self._service(name))
        self.create_subscription(String, TUNE_TOPIC, self._on_tune, TUNE_QOS)
        self._tune_numbers: dict[str, int] = {}
        self._signed: dict[str, float] = {}  # operator command -> wall s its signed request came
        self.add_post_set_parameters_callback(self._on_signed_command)

    def depends(self, a: Announcement) -> dict[str, tuple[str, ...]]:
        """Every machine participant, with its events."""
        return {n: ('events',) for n in MACHINE_NODES if n != self.NODE_NAME}

    def needs(self, stamp: int, previous: int | None) -> tuple[int, int | None] | None:
        """Tick ``stamp`` runs once every machine participant's tick ``stamp`` is complete."""
        if previous is not None:
            step = stamp - previous
            self._clock_step = step if self._clock_step is None else max(self._clock_step, step)
        return (stamp, None)

    def promise(self, stamp: int) -> int:
        """Every command decided after tick ``stamp`` takes effect ``command_lead`` after it at the earliest
        (a decision is never before the latest tick done), so the machines may run up to just before that."""
        return stamp + max(self._lead_ns - PROMISE_MARGIN, 0)

    def on_lost(self, producer: str, waited: float, stamp: int) -> None:
        """A machine participant stopped answering: abort, naming it (decided at the last complete tick)."""
        t = max(self.logic.now, 0.0) if math.isfinite(self.logic.now) else 0.0
        self.logic.lost(producer, t, waited)

    @property
    def packml(self) -> PackML:
        """The PackML state machine (state and history) of the logic."""
        return self.logic.packml

    # ------------------------------------------------------------------ inputs

    def _on_event(self, msg: TimeReference) -> None:
        try:
            kind, sheet, cycle, value = parse_event_source(msg.source)
        except ValueError as err:
            self.reject('event', f'cannot parse {msg.source[:60]!r}: {err}')
            return
        owner = EVENT_OWNER[kind]
        if msg.header.frame_id != owner:
            self.reject('event', f'{kind} from {msg.header.frame_id[:40]!r}: only {owner} publishes it')
            return
        t_ns = time_msg_to_ns(msg.time_ref)
        # late: its tick (header.stamp) was complete already. Not its time_ref: an event just after a tick is
        # published at the next tick, yet its time rounded to the ns can be that tick's stamp
        tick_ns = time_msg_to_ns(msg.header.stamp)
        ledger = self.lockstep.ledger
        last = ledger.complete(owner) if ledger is not None and ledger.knows(owner) else None
        if last is not None and tick_ns <= last:
            self.reject(
                'event',
                f'{kind} at {t_ns / NS_PER_S:.9f} s from {owner} arrived after its tick '
                f'{tick_ns / NS_PER_S:.9f} s was complete',
            )
            return
        if not math.isfinite(value):
            self.logic.bad_value(EVENTS_TOPIC, max(time_msg_to_ns(msg.header.stamp) / NS_PER_S, self.logic.now))
        else:
            self._rows.append((t_ns / NS_PER_S, EVENT_KINDS.index(kind), sheet, cycle, value))
        self.lockstep.received(owner, 'events')

    def _on_joints(self, node: str) -> Callable[[JointState], None]:
        topic = joint_states_topic(node)

        def on_joints(msg: JointState) -> None:
            if msg.header.frame_id != node:
                self.reject('joint_states', f'{topic} from {msg.header.frame_id[:40]!r}: only {node} publishes it')
                return
            bad = _non_finite(msg.position, msg.velocity, msg.effort)
            if bad:
                stamp = time_msg_to_ns(msg.header.stamp) / NS_PER_S
                self.logic.bad_value(topic, max(stamp, self.logic.now) if math.isfinite(stamp) else self.logic.now, bad)

        return on_joints

    def _on_float(self, topic: str) -> Callable[[Float64], None]:
        def on_float(msg: Float64) -> None:
            if not math.isfinite(msg.data):
                self.logic.bad_value(topic, max(self.logic.now, 0.0))

        return on_float

    # ------------------------------------------------------------------ services

    def _service(self, name: str) -> Callable[[Trigger.Request, Trigger.Response], Trigger.Response]:
        def handle(request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
            why = self._unsigned(name)
            if why:
                response.success, response.message = False, why
                self.reject('operator', why)
            else:
                response.success, response.message = self.request(name)
            return response

        return handle

    def _on_signed_command(self, parameters: list[Parameter[Any]]) -> None:
        for parameter in parameters:
            if parameter.name == 'operator_command' and parameter.value:
                self._signed[parameter.value] = time.monotonic()

    def _unsigned(self, name: str) -> str:
        """On a keyed line, why the call of service ``name`` is refused ('' if a signed request of it came
        within ``REQUEST_WINDOW`` s, which the call uses up)."""
        if not self.signatures.signer.keyed:
            return ''
        signed = self._signed.pop(name, None)
        if signed is not None and time.monotonic() - signed <= REQUEST_WINDOW:
            return ''
        return (
            f'{name}: refused: this line is keyed, and a command must first be signed with its key '
            f'(set operator_command={name} with {SIGNATURE_PARAMETER}); folder-line {name} does both'
        )

    def _untimeable(self, name: str) -> str:
        """Why a command or tuning ``name`` cannot be timed now ('' if it can)."""
        lead_ns = seconds_to_ns(self.values['command_lead'])
        if self._clock_step is not None and self._clock_step >= lead_ns:
            return (
                f'{name}: refused: the clock steps {self._clock_step / NS_PER_S:g} s per tick, not less '
                f'than command_lead = {self.values["command_lead"]:g} s, so the command could take effect '
                'in a tick the machines already published'
            )
        return ''

    def _on_tune(self, msg: String) -> None:
        """An operator's tuning forwarded by the machine node whose parameter was set
        (``'<node> <key>=<value> #<number>'``, signed on a keyed line; each node's numbers rise)."""
        try:
            text = open_text(msg.data, 'tune')
        except ValueError as err:
            self.reject('tuning', f'{msg.data[:60]!r}: {err}')
            return
        node, _, change = text.partition(' ')
        change, _, seq = change.partition(' #')
        try:
            key, value = parse_tuning_text(SET_PREFIX + change)
        except ValueError as err:
            self.reject('tuning', f'{text[:60]!r}: {err}')
            return
        if not seq.isdigit() or len(seq) > 19 or int(seq) <= self._tune_numbers.get(node, -1):
            self.reject('tuning', f'{text[:60]!r}: not numbered after the previous tuning from {node[:40]!r}')
            return
        if key not in TUNABLE_PARAMETERS.get(node, {}).values():
            self.reject('tuning', f'{text[:60]!r}: not a tunable of node {node[:40]!r}')
            return
        self._tune_numbers[node] = int(seq)
        logic = self.logic
        t = logic.now if math.isfinite(logic.now) else (logic.t_start or 0.0)
        why = self._untimeable(f'{key}={value!r}')
        out = Outcome(False, why) if why else logic.tune(key, value, t)
        self._publish_outputs()
        effective = out.command.t if out.ok and out.command is not None else math.nan
        self._publish_status('tuning', *tuning_status(t, key, value, effective, out.message))
        if out.ok:
            self.get_logger().info(f'tuning from {node}: {out.message}')
        else:
            self.get_logger().warning(f'tuning from {node} refused: {out.message}')

    def request(self, name: str) -> tuple[bool, str]:
        """Apply service ``name`` at the latest tick completed; returns (success, message)."""
        at_boundary = SERVICES[name][2]
        why = self._untimeable(name) if SERVICES[name][1] is not None else ''
        if why:
            return False, why
        out = self.logic.command(name)
        self._publish_outputs()
        self._publish_status(
            'operator',
            out.ok,
            f'{name}: {"accepted" if out.ok else out.message}',
            {'t': self.logic.now, 'command': name, 'accepted': out.ok},
        )
        if not out.ok:
            return False, out.message
        # publish the new state now: RESETTING and CLEARING end at the next grid point, before a tick publishes
        self._publish_state()
        if out.command is None:
            return True, f'{name}: {self.packml.state}'
        where = 'the next cycle boundary' if at_boundary else f'{self.values["command_lead"]:g} s after the request'
        return True, (
            f'{name}: {self.packml.state}, drive {out.command.kind} effective at {out.command.t:.6f} s ({where})'
        )

    # ------------------------------------------------------------------ tick

    def publish_at(self, stamp_ns: int) -> None:
        """Advance the logic to the tick (every machine participant's input up to it is in), then publish."""
        if self._rows:
            rows, self._rows = self._rows, []
            self.logic.feed(np.array(rows, dtype=EVENT_DTYPE))
        self.logic.tick(stamp_ns / NS_PER_S)
        self._publish_outputs()
        super().publish_at(stamp_ns)

    def _cover(self, stamp_ns: int) -> None:
        """The supervisor's stream is advanced only to a diagnostics stamp (:meth:`diagnostics`)."""

    def publish_sample(self, stamp_ns: int, t: float) -> None:
        self._publish_state()

    def publish_extra(self, stamp_ns: int, t: float, events: np.ndarray) -> None:
        if stamp_ns >= self._next_diag_ns:
            arr = self.diagnostics(stamp_ns, t)
            self.publish(self._diag_pub, arr)
            self.published_diagnostics += 1
            self._next_diag_ns = stamp_ns + round(NS_PER_S / self.values['diag_rate'])

    def _publish_state(self) -> None:
        self.publish(self._state_pub, String(data=self.packml.state))
        self.published_state += 1

    def _publish_outputs(self) -> None:
        for t, command in self.logic.take_commands():
            self._publish_command(t, command)
        logic = self.logic
        for v in logic.violations[self._n_violations :]:
            self._publish_violation(v)
        for b in logic.balances[self._n_balances :]:
            self._publish_balance(b)
        # published: the last RECORDS_KEPT of each are kept (for a look at the node), not every one since the start
        del logic.violations[:-RECORDS_KEPT]
        del logic.balances[:-RECORDS_KEPT]
        self._n_violations, self._n_balances = len(logic.violations), len(logic.balances)

    def _publish_command(self, t: float, command: LineCommand) -> None:
        msg = TimeReference()
        msg.header.stamp = ns_to_time_msg(max(0, round(t * NS_PER_S)))
        msg.header.frame_id = self.NODE_NAME
        msg.time_ref = ns_to_time_msg(round(command.t * NS_PER_S))
        msg.source = sign_text(command.kind, 'command', msg.header.frame_id, msg.header.stamp, msg.time_ref)
        self.publish(self._cmd_pub, msg, 'commands')  # also reaches this node's own subscription (its model)
        self.published_commands += 1

    def _publish_status(
        self, what: str, ok: bool, message: str, values: dict[str, object], stamp: float | None = None
    ) -> None:
        logic = self.logic
        status = event_status(
            what,
            ok,
            message,
            values,
            self.scene.name,
            t_start=logic.t_start,
            watermark=logic.now,
            late=logic.late,
        )
        arr = DiagnosticArray()
        arr.header.stamp = ns_to_time_msg(status_stamp(logic.now if stamp is None else stamp))
        arr.header.frame_id = self.NODE_NAME
        arr.status.append(_status_msg(status))
        self.publish(self._diag_pub, arr)
        self.published_diagnostics += 1

    def _publish_violation(self, v: Violation) -> None:
        self.get_logger().warning(
            f'{v.constraint} violated in {margin_at(v.constraint, v.cycle)} at {v.t:.6f} s, '
            f'margin {format_margin(v.margin, v.unit, v.constraint)}: {v.action} ({v.state})'
        )
        self._publish_status('violation', *violation_status(v), stamp=v.t)

    def _publish_balance(self, b: Balance) -> None:
        if b.missing:
            self.get_logger().warning(f'sheet balance at {b.t:.6f} s ({b.state}) not judged: {b.missing}')
        elif not b.ok:
            self.get_logger().error(
                f'sheet balance broken at {b.t:.6f} s ({b.state}): fed {b.fed}, delivered '
                f'{b.delivered}, in the machine {b.in_machine}'
            )
        self._publish_status('balance', *balance_status(b), stamp=b.t)

    def published_counts(self) -> dict[str, int]:
        return {
            **super().published_counts(),
            SUPERVISOR_STATE_TOPIC: self.published_state,
            DIAGNOSTICS_TOPIC: self.published_diagnostics,
            COMMANDS_TOPIC: self.published_commands,
        }

    def diagnostics(self, stamp: int, t: float) -> DiagnosticArray:
        """One status per constraint, from the cycles the line judged by time ``t`` (its stream advanced there,
        :func:`constraint_statuses`)."""
        stream = self.stream
        while stream.t < t:  # a clock started far into the line: in windows, keeping nothing behind them
            stream.advance(min(t, max(stream.t, 0.0) + FAST_WINDOW))
            self.lockstep.working(stamp)
        arr = DiagnosticArray()
        arr.header.stamp = ns_to_time_msg(stamp)
        arr.header.frame_id = self.NODE_NAME
        tallies = self.stream.tallies.constraints.values()
        statuses = constraint_statuses(tallies, self.scene.name, self.rejected, self.logic.lost_nodes)
        arr.status = [_status_msg(st) for st in statuses]
        return arr


def main(args: list[str] | None = None) -> int:
    """Run ``supervisor`` until Ctrl-C; exit code 0 (2 on a bad parameter, 3 if the line did not end)."""
    return run_node(Supervisor, args, exit_code=node_exit_code)


if __name__ == '__main__':
    sys.exit(main())
