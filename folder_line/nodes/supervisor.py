"""Node ``supervisor``: the line's state (PackML), its commands, its diagnostics.

* ``/line/supervisor/state`` (``std_msgs/String``): the PackML state, every tick.
* ``/diagnostics`` (``diagnostic_msgs/DiagnosticArray``) at ``diag_rate`` Hz of sim
  time: one status per cyclogram constraint of the scene, with the margin of the
  latest evaluated cycle, the smallest margin so far, the unit, and the counts of
  evaluations and violations as key/values; level OK, WARN (violated before) or
  ERROR (violated in the latest cycle).
* Services (``std_srvs/Trigger``) ``/line/supervisor/{start,stop,hold,unhold,reset,
  clear,abort}``: a legal command answers ``success`` with its effective time and
  publishes a drive command on ``/line/supervisor/commands``; an illegal one answers
  ``success = False`` with the reason (:class:`folder_line.core.packml.PackML`).
  Hold and stop take effect at the next cycle boundary at least ``command_lead`` s
  after the request, so the line stops between two sheets; start, unhold and abort
  take effect ``command_lead`` s after it.

The scene's drive starts the line at t = 0, so the supervisor starts in STARTING
and enters EXECUTE when the drive reaches speed. Acting states end when the drive
does: HOLDING, STOPPING and ABORTING at standstill, STARTING and UNHOLDING at
speed (λ >= 0.99), RESETTING and CLEARING at the next tick.
"""

from __future__ import annotations

import math
import sys
from typing import Any, Callable

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import TimeReference
from std_msgs.msg import String
from std_srvs.srv import Trigger

from folder_line.core.packml import PackML
from folder_line.errors import TransitionError
from folder_line.nodes.common import (
    COMMANDS_QOS,
    COMMANDS_TOPIC,
    DIAGNOSTICS_TOPIC,
    NS_PER_S,
    PUBLISH_DEPTH,
    SUPERVISOR_STATE_TOPIC,
    ParamSpec,
    ns_to_time_msg,
    run_node,
)
from folder_line.nodes.machine import MachineNode

__all__ = ['SERVICES', 'Supervisor', 'main']

#: service name -> (PackML command, drive command or None, waits for the next cycle boundary)
SERVICES: dict[str, tuple[str, str | None, bool]] = {
    'start': ('start', 'start', False),
    'stop': ('stop', 'stop', True),
    'hold': ('hold', 'hold', True),
    'unhold': ('unhold', 'unhold', False),
    'reset': ('reset', None, False),
    'clear': ('clear', None, False),
    'abort': ('abort', 'stop', False),
}

SPEED_REACHED = 0.99
STATE_QOS = QoSProfile(depth=PUBLISH_DEPTH, reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.TRANSIENT_LOCAL)


class Supervisor(MachineNode):
    """The ``supervisor`` node (see the module docstring)."""

    NODE_NAME = 'supervisor'
    EXTRA_SPECS = (
        ParamSpec('command_lead', 0.1, 'Earliest effective time of a command after its request, in sim time',
                  unit='s', bounds=(0.0, 60.0)),
        ParamSpec('diag_rate', 1.0, 'Rate of /diagnostics in sim time', unit='Hz', bounds=(0.01, 1000.0)),
    )

    def setup(self) -> None:
        self.packml = PackML('STARTING')
        self._pending: float | None = 0.0  # effective time of the drive command the acting state waits for
        self._state_pub = self.create_publisher(String, SUPERVISOR_STATE_TOPIC, STATE_QOS)
        self._diag_pub = self.create_publisher(DiagnosticArray, DIAGNOSTICS_TOPIC, PUBLISH_DEPTH)
        self._cmd_pub = self.create_publisher(TimeReference, COMMANDS_TOPIC, COMMANDS_QOS)
        self._next_diag_ns = 0
        for name in SERVICES:
            self.create_service(Trigger, f'/line/supervisor/{name}', self._service(name))

    # ------------------------------------------------------------------ services

    def _service(self, name: str) -> Callable[[Trigger.Request, Trigger.Response], Trigger.Response]:
        def handle(request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
            response.success, response.message = self.request(name)
            return response

        return handle

    def request(self, name: str) -> tuple[bool, str]:
        """Apply service ``name`` now; returns (success, message)."""
        command, drive_command, at_boundary = SERVICES[name]
        now = self.get_clock().now().nanoseconds / NS_PER_S
        earliest = now + self.values['command_lead']
        try:
            self.packml.command(command, now)
        except TransitionError as err:
            return False, str(err)
        if drive_command is None:
            self._pending = None
            return True, f'{command}: {self.packml.state}'
        t_eff = self.model.next_cycle_boundary(earliest) if at_boundary else earliest
        if not math.isfinite(t_eff):  # no further cycle within the horizon (or the line stands): now
            t_eff = earliest
        msg = TimeReference()
        msg.header.stamp = ns_to_time_msg(round(now * NS_PER_S))
        msg.header.frame_id = self.NODE_NAME
        msg.time_ref = ns_to_time_msg(round(t_eff * NS_PER_S))
        msg.source = drive_command
        self._cmd_pub.publish(msg)  # also reaches this node's own subscription, which rebuilds the model
        self._pending = round(t_eff * NS_PER_S) / NS_PER_S
        where = 'the next cycle boundary' if at_boundary else f'{self.values["command_lead"]:g} s after the request'
        return True, f'{command}: {self.packml.state}, drive {drive_command} effective at {t_eff:.6f} s ({where})'

    # ------------------------------------------------------------------ tick

    def publish_extra(self, stamp_ns: int, t: float, events: np.ndarray) -> None:
        self._advance(t)
        self._state_pub.publish(String(data=self.packml.state))
        if stamp_ns >= self._next_diag_ns:
            self._diag_pub.publish(self.diagnostics(stamp_ns, t))
            self._next_diag_ns = stamp_ns + round(NS_PER_S / self.values['diag_rate'])

    def _advance(self, t: float) -> None:
        state = self.packml.state
        if state in ('RESETTING', 'CLEARING'):
            self.packml.state_complete(t)
            return
        if self._pending is None or t < self._pending:
            return
        rate = float(self.model.drive.rate(np.array([t]))[0])
        if state in ('STARTING', 'UNHOLDING', 'UNSUSPENDING') and rate >= SPEED_REACHED:
            self.packml.state_complete(t, 'drive at speed')
            self._pending = None
        elif state in ('HOLDING', 'STOPPING', 'ABORTING') and rate <= 0.0:
            self.packml.state_complete(t, 'drive at standstill')
            self._pending = None

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
