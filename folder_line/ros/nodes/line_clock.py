"""Node ``line_clock``: the owner of simulated time, published tick by tick on ``/clock``.

Sim time advances on a fixed grid, ``t_k = start_time + k / rate`` (integer ns),
up to ``start_time + duration`` exactly. Before its first tick the node announces
the line's participants and clock mode on ``/line/participants`` (see
:mod:`folder_line.ros.lockstep`).

``clock = lockstep`` (default)
    Tick ``k + 1`` is published only once every participant has acknowledged tick
    ``k`` on ``/line/<node>/tick_done``: no tick is ever skipped, and when the machine
    is busy sim time slows down. ``rtf`` is a ceiling (sim seconds per wall second;
    ``0`` = as fast as the slowest participant allows). The first tick is repeated
    every 0.2 s of wall time until every participant has answered it, so sim time
    does not advance until all of them are up and matched.
``clock = wall`` (hardware in the loop)
    Ticks are published when the wall clock says (``rtf`` > 0 required), whatever the
    participants do; a participant whose acknowledgement of a tick is not in when the
    next tick is due is *late*. Lateness is counted per participant and published on
    ``/diagnostics`` (``folder_line/line_clock/lateness``, WARN) every second of sim
    time: its own state, never a constraint violation.

In both modes a participant that answers nothing for ``lost_timeout`` s of wall
time (``startup_timeout`` for the first tick) is declared lost: named in the log
and on ``/diagnostics`` (``folder_line/line_clock/lost``, ERROR), and no longer
waited for. With ``duration > 0`` the node stops once the last tick is answered
(as a process it then exits 0, or 3 if a participant was lost).

Parameters
----------
rate : float, Hz of sim time, [1, 10000], default 200.0
    Ticks per simulated second (dynamic).
rtf : float, [0, 1000], default 1.0
    Real-time factor ceiling; 0 = no ceiling (lockstep only); otherwise >= 0.001 (dynamic).
clock : str, lockstep or wall, default lockstep (read-only)
participants : str, default the five machine nodes (read-only)
    Comma-separated participant node names (``line_recorder`` for ``folder-line run``'s recorder).
start_time : float, s, [0, 1e7], default 0.0 (read-only)
duration : float, s, [0, 1e7], default 0.0 (read-only)
    Sim time to run for after ``start_time``; 0 runs until interrupted.
lost_timeout : float, s of wall time, [0.1, 3600], default 3.0 (read-only)
startup_timeout : float, s of wall time, [1, 3600], default 60.0 (read-only)
"""

from __future__ import annotations

import sys
import time
from collections.abc import Iterable, Mapping
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.clock import Clock
from rclpy.clock_type import ClockType
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.task import Future
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import TimeReference
from std_msgs.msg import String

from folder_line.core.limits import DURATION, LOST_TIMEOUT, RTF, TICK_RATE
from folder_line.core.supervision.lockstep import TickLedger
from folder_line.errors import ParameterError
from folder_line.interfaces import (
    CLOCK_TOPIC,
    DIAGNOSTICS_TOPIC,
    KNOWN_PARTICIPANTS,
    NS_PER_S,
    PARTICIPANTS_TOPIC,
    TIME_MSG_MAX_NS,
    seconds_to_ns,
    tick_done_topic,
)
from folder_line.ros.lockstep import (
    CLOCK_MODES,
    DEFAULT_PARTICIPANTS,
    LINE_QOS,
    PARTICIPANTS_QOS,
    TICK_QOS,
    Announcement,
    format_announcement,
    participant_names,
    read_ack,
)
from folder_line.ros.parameters import ParamSpec, declare_parameters
from folder_line.ros.runtime import run_node
from folder_line.ros.time_msg import ns_to_time_msg
from folder_line.ros.topics import CLOCK_QOS

__all__ = ['EXIT_LOST', 'NODE_NAME', 'SPECS', 'LineClock', 'main', 'parse_participants']

NODE_NAME = 'line_clock'
EXIT_LOST = 3
MIN_RTF = RTF.lo
REPEAT_FIRST = 0.2  # wall s between repetitions of the first tick

SPECS: tuple[ParamSpec, ...] = (
    ParamSpec('rate', 200.0, 'Ticks per second of simulated time', unit='Hz', bounds=TICK_RATE.bounds),
    ParamSpec(
        'rtf',
        1.0,
        'Real-time factor ceiling: simulated seconds per wall second (0: as fast as the line '
        f'allows, lockstep only; else >= {RTF.lo:g})',
        bounds=(0.0, RTF.hi),
    ),
    ParamSpec(
        'clock',
        'lockstep',
        'lockstep: wait for every participant each tick; wall: pace by the wall clock and count late participants',
        choices=CLOCK_MODES,
        read_only=True,
    ),
    ParamSpec(
        'participants',
        ','.join(DEFAULT_PARTICIPANTS),
        f'Comma-separated nodes that acknowledge every tick (of {", ".join(KNOWN_PARTICIPANTS)})',
        read_only=True,
    ),
    ParamSpec('start_time', 0.0, 'Simulated time at start', unit='s', bounds=(0.0, DURATION.hi), read_only=True),
    ParamSpec(
        'duration',
        0.0,
        'Simulated time to run for after start_time; 0 runs until interrupted',
        unit='s',
        bounds=(0.0, DURATION.hi),
        read_only=True,
    ),
    ParamSpec(
        'lost_timeout',
        3.0,
        'Wall time a tick waits for a participant before it is declared lost',
        unit='s',
        bounds=LOST_TIMEOUT.bounds,
        read_only=True,
    ),
    ParamSpec(
        'startup_timeout',
        60.0,
        'Wall time the first tick waits for every participant',
        unit='s',
        bounds=(1.0, 3600.0),
        read_only=True,
    ),
)


def parse_participants(text: str) -> tuple[str, ...]:
    """``'crank_drive, supervisor'`` -> ``('crank_drive', 'supervisor')``; ParameterError naming ``participants``."""
    try:
        return participant_names(text)
    except ValueError as err:
        raise ParameterError('participants', text, str(err)) from None


def _check(values: Mapping[str, Any]) -> None:
    if values.get('use_sim_time') is True:
        raise ParameterError('use_sim_time', True, 'line_clock publishes /clock and runs on the wall clock')
    parse_participants(values['participants'])
    rtf = values['rtf']
    if 0.0 < rtf < MIN_RTF:
        raise ParameterError('rtf', rtf, f'must be 0 (no ceiling) or in {RTF.text()}')
    if rtf == 0.0 and values['clock'] == 'wall':
        raise ParameterError('rtf', rtf, 'must be > 0 with clock=wall (the wall clock paces the ticks)')


class LineClock(Node):
    """Publishes simulated time on ``/clock`` (see the module docstring).

    Attributes
    ----------
    done : rclpy.task.Future
        Completes with the last stamp (ns) once the last tick is answered.
    lost : dict of str to float
        Participants declared lost -> the tick (s) they did not answer.
    late : dict of str to int
        Wall mode: ticks each participant answered late.
    ticks : int
        Ticks published (a repeated first tick counts once).
    """

    NODE_NAME = NODE_NAME

    def __init__(self, *, parameter_overrides: Iterable[Parameter[Any]] | None = None, **kwargs: Any) -> None:
        # use_sim_time is off by default; on, from the constructor or --ros-args, it is refused
        super().__init__(NODE_NAME, parameter_overrides=list(parameter_overrides or []), **kwargs)
        if self.get_parameter('use_sim_time').value:
            raise ParameterError('use_sim_time', True, 'line_clock publishes /clock and runs on the wall clock')
        v = self.values = declare_parameters(self, SPECS, cross_check=_check)
        self._wall = Clock(clock_type=ClockType.STEADY_TIME)
        self.mode: str = v['clock']
        self.participants = parse_participants(v['participants'])
        self._start = seconds_to_ns(v['start_time'])
        self._end = self._start + seconds_to_ns(v['duration']) if v['duration'] > 0.0 else None
        self._step: int = round(NS_PER_S / v['rate'])
        self._rtf: float = v['rtf']
        self.current: int | None = None  # the latest tick published, ns
        self._origin: tuple[int, float] | None = None  # (sim ns, wall s) the rtf ceiling counts from
        self._published_at = 0.0
        self.published_clock = 0
        self.ticks = 0
        self.lost: dict[str, float] = {}
        self.late: dict[str, int] = dict.fromkeys(self.participants, 0)
        self.rejected = 0
        self.done: Future[int] = Future()
        self.first_done_wall: float | None = None
        self._finished_wall: float | None = None
        self._ledger = TickLedger(self.participants)
        self._answered: set[str] = set()
        self._heard: dict[str, float] = dict.fromkeys(self.participants, time.monotonic())
        self._pub = self.create_publisher(ClockMsg, CLOCK_TOPIC, CLOCK_QOS)
        self._diag = self.create_publisher(DiagnosticArray, DIAGNOSTICS_TOPIC, LINE_QOS)
        announce = self.create_publisher(String, PARTICIPANTS_TOPIC, PARTICIPANTS_QOS)
        self.announcement = Announcement(self.mode, self._end, self.participants)
        announce.publish(String(data=format_announcement(self.announcement)))
        for name in self.participants:
            self.create_subscription(TimeReference, tick_done_topic(name), self._on_ack(name), TICK_QOS, raw=True)
        self._pacer = self.create_timer(1.0, self._on_pacer, clock=self._wall)
        self._pacer.cancel()
        self._watch = self.create_timer(0.1, self._on_watch, clock=self._wall)
        self._next_lateness = self._start + NS_PER_S
        self.add_post_set_parameters_callback(self._apply)
        rtf_text = 'no rtf ceiling' if self._rtf == 0.0 else f'rtf {self._rtf:g}'
        self.get_logger().info(
            f'{self.mode} /clock at {v["rate"]:g} Hz of sim time, {rtf_text}, from {v["start_time"]:g} s'
            + (f' for {v["duration"]:g} s' if self._end is not None else '')
            + f'; participants {", ".join(self.participants)}'
        )
        self._publish(self._start)

    # ------------------------------------------------------------------ state

    @property
    def rtf_achieved(self) -> float:
        """Sim seconds per wall second from the first tick answered by all to the last (0 before)."""
        if self.first_done_wall is None or self.current is None:
            return 0.0
        wall = (self._finished_wall or time.monotonic()) - self.first_done_wall
        return (self.current - self._start) / NS_PER_S / wall if wall > 0 else 0.0

    def published_counts(self) -> dict[str, int]:
        """Messages published so far, per topic (the recorder's loss accounting)."""
        return {CLOCK_TOPIC: self.published_clock, PARTICIPANTS_TOPIC: 1}

    # ------------------------------------------------------------------ internals

    def _apply(self, parameters: list[Parameter[Any]]) -> None:
        for p in parameters:
            if p.name == 'rtf':
                self._rtf = p.value
                if self.current is not None and self._origin is not None:
                    self._origin = (self.current, self._published_at)
            elif p.name == 'rate':
                self._step = round(NS_PER_S / p.value)

    def _on_ack(self, name: str) -> Any:
        def on_ack(data: bytes) -> None:
            try:
                frame_id, stamp, counts = read_ack(data)
            except ValueError:
                self.rejected += 1
                return
            if frame_id != name or self._ledger.ack(name, stamp, counts) is not None:
                self.rejected += 1
                return
            self._heard[name] = time.monotonic()  # a repeated acknowledgement too: alive, waiting for another
            if stamp == self.current:
                self._answered.add(name)
                if self._all_answered():
                    self._advance()

        return on_ack

    def _all_answered(self) -> bool:
        return all(p in self._answered or p in self.lost for p in self.participants)

    def _next_stamp(self) -> int | None:
        assert self.current is not None
        if self._end is not None and self.current >= self._end:
            return None
        nxt = self.current + self._step
        if self._end is not None:
            nxt = min(nxt, self._end)
        return min(nxt, TIME_MSG_MAX_NS)

    def _due(self, stamp: int) -> float:
        """Wall time (monotonic s) at which ``stamp`` may be published (the rtf ceiling)."""
        if self._rtf == 0.0 or self._origin is None:
            return 0.0
        sim0, wall0 = self._origin
        return wall0 + (stamp - sim0) / NS_PER_S / self._rtf

    def _advance(self) -> None:
        """Every participant answered the current tick (lockstep): publish the next, or finish."""
        assert self.current is not None, 'an answer (or a lost participant) is to a tick already published'
        if self.first_done_wall is None:
            self.first_done_wall = time.monotonic()
            self._origin = (self.current, self.first_done_wall)
            self._ledger_first_done()
        if self.mode == 'wall':
            return
        nxt = self._next_stamp()
        if nxt is None:
            self._finish('duration reached')
            return
        wait = self._due(nxt) - time.monotonic()
        if wait > 0.0:
            self._pacer.timer_period_ns = max(int(wait * NS_PER_S), 1)
            self._pacer.reset()
        else:
            self._publish(nxt)

    def _ledger_first_done(self) -> None:
        self.get_logger().info('every participant answered the first tick: sim time runs')
        if self.mode == 'wall':
            self._pacer.timer_period_ns = max(int(self._step / max(self._rtf, MIN_RTF)), 1)
            self._pacer.reset()

    def _on_pacer(self) -> None:
        if self.mode == 'lockstep':
            self._pacer.cancel()
            if self.current is None or not self._all_answered():
                return
            nxt = self._next_stamp()
            if nxt is None:
                self._finish('duration reached')
            elif time.monotonic() >= self._due(nxt):  # never early: rtf is a ceiling
                self._publish(nxt)
            else:
                self._advance()
            return
        # wall mode: publish every tick that is due, late participants counted
        while self.current is not None and not self.done.done():
            nxt = self._next_stamp()
            if nxt is None:
                if self._all_answered() or time.monotonic() - self._published_at > self.values['lost_timeout']:
                    self._finish('duration reached')
                return
            if time.monotonic() < self._due(nxt):
                return
            for p in self.participants:
                if p not in self._answered and p not in self.lost:
                    self.late[p] += 1
            self._publish(nxt)

    def _publish(self, stamp: int) -> None:
        now = time.monotonic()
        for p in self.participants:
            if p in self._answered:
                self._heard[p] = now  # waits count from the oldest tick not answered
        self.current = stamp
        self._answered = set()
        self._published_at = now
        self._pub.publish(ClockMsg(clock=ns_to_time_msg(stamp)))
        self.published_clock += 1
        self.ticks += 1
        if self.mode == 'wall' and stamp >= self._next_lateness:
            self._next_lateness = stamp + NS_PER_S
            self._report_lateness(stamp)
        if self.mode == 'lockstep' and self.first_done_wall is not None and self._all_answered():
            # every participant was lost: no answer will come to advance the clock; its pacer does
            self._pacer.timer_period_ns = 1
            self._pacer.reset()

    def _on_watch(self) -> None:
        """Repeat the first tick until everyone answered it; declare silent participants lost."""
        if self.current is None or self.done.done():
            return
        now = time.monotonic()
        first = self.first_done_wall is None
        if first and now - self._published_at >= REPEAT_FIRST and not self._all_answered():
            self._pub.publish(ClockMsg(clock=ns_to_time_msg(self.current)))
        limit = self.values['startup_timeout'] if first else self.values['lost_timeout']
        silent = [
            p
            for p in self.participants
            if p not in self._answered and p not in self.lost and now - self._heard[p] > limit
        ]
        for p in silent:
            waited = now - self._heard[p]
            self.lost[p] = self.current / NS_PER_S
            self._ledger.lose(p)
            self.get_logger().error(
                f'participant {p} lost: no answer to tick {self.current / NS_PER_S:.9f} s in '
                f'{waited:.1f} s of wall time (limit {limit:g} s)'
            )
            self._status(
                'lost',
                DiagnosticStatus.ERROR,
                f'participant {p} lost at {self.current / NS_PER_S:.9f} s',
                {
                    'node': p,
                    'tick': repr(self.current / NS_PER_S),
                    'waited_wall_s': f'{waited:.3f}',
                    'limit_s': repr(limit),
                },
                stamp=self.current,
            )
        if silent and self._all_answered():
            self._advance()

    def _report_lateness(self, stamp: int) -> None:
        worst = max(self.late.values(), default=0)
        level = DiagnosticStatus.WARN if worst else DiagnosticStatus.OK
        text = ', '.join(f'{p} {n}' for p, n in self.late.items() if n) or 'none'
        self._status('lateness', level, f'late ticks: {text}', {p: str(n) for p, n in self.late.items()}, stamp=stamp)

    def _status(self, what: str, level: bytes, message: str, values: Mapping[str, str], stamp: int) -> None:
        arr = DiagnosticArray()
        arr.header.stamp = ns_to_time_msg(stamp)
        arr.header.frame_id = NODE_NAME
        st = DiagnosticStatus(
            name=f'folder_line/line_clock/{what}', hardware_id=NODE_NAME, level=level, message=message
        )
        st.values = [KeyValue(key=k, value=v) for k, v in values.items()]
        arr.status.append(st)
        self._diag.publish(arr)

    def _finish(self, why: str) -> None:
        self._pacer.cancel()
        if self.done.done():
            return
        self._finished_wall = time.monotonic()
        assert self.current is not None
        if self.mode == 'wall':
            self._report_lateness(self.current)
        seconds, nanoseconds = divmod(self.current, NS_PER_S)
        lost = f'; lost: {", ".join(self.lost)}' if self.lost else ''
        self.get_logger().info(
            f'stopped at sim time {seconds}.{nanoseconds:09d} s: {why} '
            f'({self.ticks} ticks, rtf {self.rtf_achieved:.2f}){lost}'
        )
        self.done.set_result(self.current)


def main(args: list[str] | None = None) -> int:
    """Run ``line_clock`` until Ctrl-C or the end of ``duration``; exit 0, 2 on a bad parameter, 3 if a
    participant was lost."""
    return run_node(LineClock, args, exit_code=lambda node: EXIT_LOST if getattr(node, 'lost', None) else 0)


if __name__ == '__main__':
    sys.exit(main())
