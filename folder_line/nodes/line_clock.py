"""Node ``line_clock``: the owner of simulated time, published on ``/clock``.

Every other node of the line runs with ``use_sim_time`` and takes its ``t`` from
here. ``line_clock`` itself runs on the steady wall clock (never on sim time):
a wall timer at ``publish_rate`` Hz publishes

    sim = sim_0 + rtf * (wall - wall_0)

in integer nanoseconds, computed from the origin ``(wall_0, sim_0)`` rather than
by adding increments, so that it does not drift; the origin is moved to the
current instant when ``rtf`` changes, so sim time stays continuous and monotonic.
With ``duration > 0`` the last message is exactly ``start_time + duration`` and
the node stops (as a process it then exits 0).

Parameters
----------
publish_rate : float, Hz, [1, 1000], default 200.0
    Messages per wall second (dynamic).
rtf : float, (0, 1000], default 1.0
    Real-time factor: simulated seconds per wall second (dynamic).
start_time : float, s, [0, 1e9], default 0.0
    Sim time at start (read-only).
duration : float, s, [0, 1e9], default 0.0
    Sim time to run for after ``start_time``; 0 runs until interrupted (read-only).
"""

from __future__ import annotations

import sys
from typing import Any, Iterable, Mapping

from rclpy.clock import Clock
from rclpy.clock_type import ClockType
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.task import Future
from rosgraph_msgs.msg import Clock as ClockMsg

from folder_line.errors import ParameterError
from folder_line.nodes.common import (
    CLOCK_QOS,
    CLOCK_TOPIC,
    NS_PER_S,
    TIME_MSG_MAX_NS,
    ParamSpec,
    declare_parameters,
    ns_to_time_msg,
    run_node,
    seconds_to_ns,
    sim_time_overrides,
)

__all__ = ['NODE_NAME', 'SPECS', 'SimTimeline', 'LineClock', 'main']

NODE_NAME = 'line_clock'

SPECS: tuple[ParamSpec, ...] = (
    ParamSpec('publish_rate', 200.0, 'Messages on /clock per second of wall time', unit='Hz',
              bounds=(1.0, 1000.0)),
    ParamSpec('rtf', 1.0, 'Real-time factor: simulated seconds per wall second',
              bounds=(0.0, 1000.0), low_open=True),
    ParamSpec('start_time', 0.0, 'Simulated time at start', unit='s', bounds=(0.0, 1e9), read_only=True),
    ParamSpec('duration', 0.0, 'Simulated time to run for after start_time; 0 runs until interrupted',
              unit='s', bounds=(0.0, 1e9), read_only=True),
)


class SimTimeline:
    """Sim time as an exact function of wall time: ``sim = sim_0 + floor(rtf * (wall - wall_0))``.

    All times are integer nanoseconds; ``rtf`` is used as the exact rational value
    of its float, so ``at`` has no rounding drift however far ``wall`` is from the
    origin, and it never decreases as ``wall`` grows.

    Parameters
    ----------
    sim_0 : int
        Sim time at the origin, ns.
    wall_0 : int
        Wall (steady) time at the origin, ns.
    rtf : float
        Real-time factor, > 0 and finite.
    """

    def __init__(self, sim_0: int, wall_0: int, rtf: float) -> None:
        self._sim_0 = int(sim_0)
        self._wall_0 = int(wall_0)
        self._set(rtf)

    def _set(self, rtf: float) -> None:
        if not (isinstance(rtf, float) and 0.0 < rtf < float('inf')):
            raise ParameterError('rtf', rtf, 'must be a finite float > 0')
        self._rtf = rtf
        self._num, self._den = rtf.as_integer_ratio()

    @property
    def rtf(self) -> float:
        """Current real-time factor."""
        return self._rtf

    @property
    def origin(self) -> tuple[int, int]:
        """``(sim_0, wall_0)`` in ns."""
        return self._sim_0, self._wall_0

    def at(self, wall: int) -> int:
        """Sim time at wall time ``wall``, ns (``sim_0`` for a wall time before the origin)."""
        elapsed = max(int(wall) - self._wall_0, 0)
        return self._sim_0 + (self._num * elapsed) // self._den

    def set_rtf(self, rtf: float, wall: int) -> None:
        """Change the real-time factor from wall time ``wall`` on, keeping sim time continuous."""
        sim = self.at(wall)
        self._set(rtf)
        self._sim_0, self._wall_0 = sim, max(int(wall), self._wall_0)


class LineClock(Node):
    """Publishes simulated time on ``/clock`` (see the module docstring).

    Parameters
    ----------
    parameter_overrides : iterable of Parameter, optional
        Starting values of the parameters (``use_sim_time`` must not be true).
    **kwargs
        Passed to ``rclpy.node.Node`` (``context``, ``cli_args``, ...).

    Attributes
    ----------
    done : rclpy.task.Future
        Completes with the last stamp (ns) once ``duration`` is reached.
    """

    NODE_NAME = NODE_NAME

    def __init__(self, *, parameter_overrides: Iterable[Parameter] | None = None, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, parameter_overrides=sim_time_overrides(parameter_overrides, use_sim_time=False),
                         **kwargs)
        if self.get_parameter('use_sim_time').value:
            raise ParameterError('use_sim_time', True, 'line_clock publishes /clock and runs on the wall clock')
        self._wall = Clock(clock_type=ClockType.STEADY_TIME)
        values = declare_parameters(self, SPECS, cross_check=_no_sim_time)
        start = seconds_to_ns(values['start_time'])
        self._end = start + seconds_to_ns(values['duration']) if values['duration'] > 0.0 else None
        self._timeline = SimTimeline(start, self._now_wall(), values['rtf'])
        self._last: int | None = None
        self.published_clock = 0
        self.done: Future = Future()
        self._publisher = self.create_publisher(ClockMsg, CLOCK_TOPIC, CLOCK_QOS)
        self._timer = self.create_timer(1.0 / values['publish_rate'], self._tick, clock=self._wall)
        self.add_post_set_parameters_callback(self._apply)
        self.get_logger().info(
            f'publishing {CLOCK_TOPIC} at {values["publish_rate"]:g} Hz, rtf {values["rtf"]:g}, '
            f'from {values["start_time"]:g} s' + (f' for {values["duration"]:g} s' if self._end else ''))

    def published_counts(self) -> dict[str, int]:
        """Messages published so far, per topic (the recorder's loss accounting)."""
        return {CLOCK_TOPIC: self.published_clock}

    def _now_wall(self) -> int:
        return self._wall.now().nanoseconds

    def _apply(self, parameters: list[Parameter]) -> None:
        for parameter in parameters:
            if parameter.name == 'rtf':
                self._timeline.set_rtf(parameter.value, self._now_wall())
            elif parameter.name == 'publish_rate':
                self._timer.timer_period_ns = round(NS_PER_S / parameter.value)

    def _tick(self) -> None:
        sim = self._timeline.at(self._now_wall())
        stop = None
        if self._end is not None and sim >= self._end:
            sim, stop = self._end, 'duration reached'
        elif sim >= TIME_MSG_MAX_NS:
            sim, stop = TIME_MSG_MAX_NS, 'sim time reached the largest builtin_interfaces/Time'
        if self._last is None or sim > self._last:
            self._publisher.publish(ClockMsg(clock=ns_to_time_msg(sim)))
            self.published_clock += 1
            self._last = sim
        if stop is not None:
            self._timer.cancel()
            seconds, nanoseconds = divmod(sim, NS_PER_S)
            self.get_logger().info(f'stopped at sim time {seconds}.{nanoseconds:09d} s: {stop}')
            if not self.done.done():
                self.done.set_result(sim)


def _no_sim_time(values: Mapping[str, Any]) -> None:
    if values.get('use_sim_time') is True:
        raise ParameterError('use_sim_time', True, 'line_clock publishes /clock and runs on the wall clock')


def main(args: list[str] | None = None) -> int:
    """Run ``line_clock`` until Ctrl-C or ``duration``; exit code 0 (2 on a bad parameter)."""
    return run_node(LineClock, args)


if __name__ == '__main__':
    sys.exit(main())
