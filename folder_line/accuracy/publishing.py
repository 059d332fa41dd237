"""Study ``publishing``: a JointState stream reconstructed by interpolation, against its cost in the live line.

What is measured
----------------
The machine nodes publish ``sensor_msgs/JointState`` at ``rate`` Hz of sim time; each
message holds the joints' positions and velocities from the core
(:meth:`folder_line.core.line.model.LineModel.sample`) at the tick's stamp. A user of the
bag rebuilds the continuous motion by interpolating between the messages. The
quantity is the **knife position** ``s`` (m) of the ``folder`` scene (joint ``knife``
of ``crank_drive``: a crank-slider at 50000 rev/h = 13.9 Hz, the fastest-oscillating
joint of the line; the belts and the chain move linearly in time at constant speed, so
any interpolation reproduces them exactly). For each rate the stream is built as the node
builds it, at the tick grid ``t_k = k / rate`` (the live node stamps each tick with the
``/clock`` time that triggered it, at or just after ``t_k``; the reconstruction uses
the stamps, so the grid is the nominal case), and rebuilt by two methods:

``linear interpolation``
    of the positions alone;
``cubic Hermite``
    of the positions and the velocities, both in every JointState.

Error: the largest ``|s_rebuilt(t) - s(t)|`` on a 100 kHz grid over the first
``duration`` s of line time (2 s, 1 s with ``quick``), m. Theory: linear
interpolation errs by at most ``max|s''| h^2 / 8`` and cubic Hermite by at most
``max|s''''| h^4 / 384`` for the spacing ``h = 1 / rate``; the tests check both
bounds and the slopes -2 and -4 of ``log error`` against ``log rate``.

Reference and its check
-----------------------
The exact knife position is the core's closed form ``s(omega_k t)``
(:mod:`folder_line.core.mechanisms.knife`, checked against the paper in ``test/core``), sampled
through the same :class:`~folder_line.core.line.model.LineModel` the nodes use. The test of
this study checks it against an independent crank-slider in mpmath (the rod's loop
equation solved by the secant method at 30 digits) to 1e-12 m, and the stream's
velocities against the differentiated loop equation to 1e-9 m/s.

Cost
----
CPU seconds per simulated second of the **live line** publishing at that rate: the
line of ``folder-line run`` in one process (:mod:`folder_line.ros.run`: ``line_clock``,
the five machine nodes with ``rate`` set, one ``SingleThreadedExecutor``, a private
rclpy context, real DDS) with the run's recorder
(:class:`folder_line.ros.recorder.LineRecorder`) writing the bag to a temporary
directory. The process CPU time (``time.process_time``: every thread, DDS included)
is read when the recorder first hears a sim time at or past the warm-up (start-up and
discovery excluded) and again when it hears the clock's last stamp, and divided by
the sim time between the two. Sim time starts once every publisher and subscription
of the line's topics in the process are matched (``folder-line run --processes``
waits likewise; in-process ``run`` starts the clock at once, and at a high real-time
factor the supervisor may then miss the first cycles' events and hold the line). The
real-time factor is chosen per rate so that every node ticks
:data:`TICKS_PER_WALL_S` times per wall second (``rtf = 200 / rate``), at most
:data:`RTF_MAX` (the in-process line's highest sustainable rtf at 200 Hz, docs/benchmarks.md,
"The nodes"; at 50 Hz and rtf 4 the supervisor was seen judging a cycle
without its ``settled`` event and holding); the clock publishes ``rate x rtf``
messages per wall second as ``folder-line run`` does, one per tick. The JointState
messages each joint node published in the measured span are counted: fewer than
:data:`MIN_PUBLISHED` of the ticks owed (``rate x span``) means the nodes skipped
ticks, and a cost measured on skipped ticks would understate the cost, so
:func:`run` (through :func:`measured_cost`) then measures again at half the
real-time factor, and a quarter (also when the supervisor ended other than in
EXECUTE), and raises :class:`~folder_line.errors.MeasurementError` if ticks are still
skipped. The row's ``reference`` gives the rtf, the share of ticks published and the
supervisor's final state. Both methods share the cost of their rate: the
interpolation itself is done offline, on the bag, and is not included.

Units: rate in Hz of sim time, error in m, cost in CPU s per simulated s.
"""

from __future__ import annotations

import math
import tempfile
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import rclpy
import yaml
from numpy.typing import NDArray
from rclpy.executors import Executor
from rclpy.parameter import Parameter

from folder_line.accuracy.measure import Row
from folder_line.bag.writer import BagWriter
from folder_line.config.run_config import RunConfig, clock_parameters
from folder_line.config.scenes import load_scene, scene_mapping
from folder_line.core.limits import TICK_RATE
from folder_line.core.line.model import LineModel, sample_times
from folder_line.core.line.scene import parse_scene
from folder_line.errors import MeasurementError, ParameterError
from folder_line.interfaces import JOINT_NODES, KNOWN_PARTICIPANTS, NODE_OF_UNIT, NS_PER_S
from folder_line.ros.nodes.line_clock import LineClock
from folder_line.ros.nodes.machine import MachineNode
from folder_line.ros.recorder import LINE_TOPICS, LineRecorder
from folder_line.ros.run import add_machine_nodes
from folder_line.ros.runtime import events_executor

__all__ = [
    'FINE_RATE',
    'JOINT',
    'JOINT_NODE',
    'JOINT_UNIT',
    'METHODS',
    'MIN_PUBLISHED',
    'RATES',
    'RATES_QUICK',
    'RTF_MAX',
    'RTF_SLACK',
    'SCENE',
    'TICKS_PER_WALL_S',
    'LiveCost',
    'check_published',
    'default_rtf',
    'knife_model',
    'knife_stream',
    'live_cost',
    'measured_cost',
    'reconstruct',
    'reconstruction_error',
    'run',
]

#: the scene whose knife is measured
SCENE = 'folder'
#: unit, node and joint measured (the knife position, m)
JOINT_UNIT = 'drive'
JOINT_NODE = NODE_OF_UNIT[JOINT_UNIT]
JOINT = 'knife'
#: the two reconstruction methods, in report order
METHODS = ('linear interpolation', 'cubic Hermite')
#: publishing rates of the full run and of ``quick``, Hz of sim time
RATES = (50.0, 100.0, 200.0, 500.0, 1000.0, 2000.0)
RATES_QUICK = (50.0, 200.0, 1000.0)
#: the fine grid the error is measured on, Hz
FINE_RATE = 100_000.0
#: node ticks per wall second the real-time factor is chosen for
TICKS_PER_WALL_S = 200.0
#: highest real-time factor used
RTF_MAX = 2.0
#: least fraction of the owed ticks that must have been published for a cost to count
MIN_PUBLISHED = 0.9
#: the machine nodes with joints in the folder scene (their JointState messages are counted)
_JOINT_NODES = JOINT_NODES


# --------------------------------------------------------------------------- error


def knife_model(duration: float) -> LineModel:
    """The line model of the ``folder`` scene over ``[0, duration]``, as the nodes build it.

    Parameters
    ----------
    duration : float
        Horizon, s (> 0).

    Returns
    -------
    LineModel
        Built from the shipped scene without overrides.
    """
    return LineModel(load_scene(SCENE), duration)


def knife_stream(
    model: LineModel, rate: float, duration: float
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """The knife's JointState stream at ``rate``: what ``crank_drive`` publishes at its tick grid.

    Parameters
    ----------
    model : LineModel
        The line (its horizon at least ``duration``).
    rate : float
        Publishing rate, Hz of sim time (> 0).
    duration : float
        Line time covered, s; the grid ``k / rate`` for k = 0 .. floor(duration·rate).

    Returns
    -------
    t : ndarray
        Stamps ``k / rate``, s.
    position : ndarray
        Knife position at each stamp, m.
    velocity : ndarray
        Knife velocity at each stamp, m/s.
    """
    if not (math.isfinite(rate) and rate > 0.0):
        raise ParameterError('rate', rate, 'must be a finite rate > 0 Hz')
    t = sample_times(duration, rate)
    js = model.sample(JOINT_UNIT, t)
    j = js.names.index(JOINT)
    return t, np.ascontiguousarray(js.position[:, j]), np.ascontiguousarray(js.velocity[:, j])


def reconstruct(
    method: str, t_k: NDArray[np.float64], p_k: NDArray[np.float64], v_k: NDArray[np.float64], t: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Rebuild a joint's position between the messages of a stream.

    Parameters
    ----------
    method : {'linear interpolation', 'cubic Hermite'}
        Linear interpolation of the positions, or the cubic Hermite interpolant of
        positions and velocities (C1, exact for cubics).
    t_k : ndarray, shape (N,)
        Message stamps, s, increasing, N >= 2.
    p_k, v_k : ndarray, shape (N,)
        Positions (unit u) and velocities (u/s) in the messages.
    t : ndarray
        Times to rebuild at, s, in ``[t_k[0], t_k[-1]]``.

    Returns
    -------
    ndarray
        Position at ``t``, unit u.
    """
    if method not in METHODS:
        raise ParameterError('method', method, f'unknown reconstruction; choose from {", ".join(METHODS)}')
    t = np.asarray(t, dtype=float)
    i = np.clip(np.searchsorted(t_k, t, side='right') - 1, 0, t_k.size - 2)
    t0, h = t_k[i], t_k[i + 1] - t_k[i]
    s = (t - t0) / h
    p0, p1 = p_k[i], p_k[i + 1]
    if method == 'linear interpolation':
        return p0 + s * (p1 - p0)
    s2 = s * s
    s3 = s2 * s
    h00 = 2.0 * s3 - 3.0 * s2 + 1.0
    h10 = s3 - 2.0 * s2 + s
    h01 = 3.0 * s2 - 2.0 * s3
    h11 = s3 - s2
    return h00 * p0 + h01 * p1 + h * (h10 * v_k[i] + h11 * v_k[i + 1])


def reconstruction_error(
    rate: float, method: str, *, duration: float = 2.0, fine_rate: float = FINE_RATE, model: LineModel | None = None
) -> float:
    """Largest error of the knife position rebuilt from a stream at ``rate``, m.

    Parameters
    ----------
    rate : float
        Publishing rate, Hz of sim time.
    method : str
        One of :data:`METHODS`.
    duration : float
        Line time compared over, s (from t = 0).
    fine_rate : float
        Density of the comparison grid, Hz.
    model : LineModel, optional
        The ``folder`` line over at least ``duration`` (built if not given).

    Returns
    -------
    float
        ``max |s_rebuilt(t) - s(t)|`` over the fine grid inside the stream's span, m.
    """
    model = knife_model(duration) if model is None else model
    t_k, p_k, v_k = knife_stream(model, rate, duration)
    t = np.arange(math.floor(t_k[-1] * fine_rate) + 1, dtype=float) / fine_rate
    js = model.sample(JOINT_UNIT, t)
    exact = js.position[:, js.names.index(JOINT)]
    return float(np.max(np.abs(reconstruct(method, t_k, p_k, v_k, t) - exact)))


# --------------------------------------------------------------------------- cost


@dataclass(frozen=True)
class LiveCost:
    """CPU cost of the live line publishing at one rate.

    Attributes
    ----------
    rate : float
        Publishing rate of the machine nodes, Hz of sim time.
    rtf : float
        Real-time factor of ``line_clock``.
    clock_rate : float
        ``/clock`` messages per wall second.
    t_start, t_end : float
        Sim time of the measured span (as heard by the recorder), s.
    cpu_s : float
        Process CPU time over the span, s.
    wall_s : float
        Wall time over the span, s.
    published : dict of str to int
        JointState messages each joint node published in the span.
    supervisor_state : str
        The supervisor's PackML state at the end.
    owed : dict of str to int
        Grid points each joint node owed over the span as far as it had got itself (a node runs
        ahead of the recorder by up to the clock's window); a node missing here owes
        :attr:`ticks_owed`.
    """

    rate: float
    rtf: float
    clock_rate: float
    t_start: float
    t_end: float
    cpu_s: float
    wall_s: float
    published: dict[str, int] = field(default_factory=dict)
    supervisor_state: str = ''
    owed: dict[str, int] = field(default_factory=dict)

    @property
    def span(self) -> float:
        """Measured sim time, s."""
        return self.t_end - self.t_start

    @property
    def cpu_s_per_sim_s(self) -> float:
        """CPU seconds per simulated second."""
        return self.cpu_s / self.span

    @property
    def ticks_owed(self) -> float:
        """Ticks each node owes over the span: ``rate x span``."""
        return self.rate * self.span

    def owed_by(self, node: str) -> float:
        """Ticks ``node`` owed over the span (:attr:`owed`, else :attr:`ticks_owed`)."""
        return self.owed.get(node, self.ticks_owed)

    @property
    def published_fraction(self) -> float:
        """Smallest fraction of its owed ticks a joint node published (1 = none skipped)."""
        return min(n / self.owed_by(node) for node, n in self.published.items())


def check_published(cost: LiveCost, min_fraction: float = MIN_PUBLISHED) -> None:
    """Refuse a cost measured while the nodes skipped ticks.

    Parameters
    ----------
    cost : LiveCost
        A measurement.
    min_fraction : float
        Least fraction of the owed ticks every joint node must have published.

    Raises
    ------
    MeasurementError
        A node published fewer; the message names it, the counts and the setup.
    """
    short = {n: c for n, c in cost.published.items() if c < min_fraction * cost.owed_by(n)}
    if short:
        worst = min(short, key=lambda n: short[n] / cost.owed_by(n))
        owed = cost.owed_by(worst)
        msg = (
            f'publishing at {cost.rate:g} Hz (rtf {cost.rtf:g}, /clock at {cost.clock_rate:g} Hz): '
            f'{worst} published {short[worst]} of {owed:.0f} ticks ({short[worst] / owed:.1%} < '
            f'{min_fraction:.0%}) in {cost.span:.3f} s of sim time; the cost of skipped ticks is not measured'
        )
        raise MeasurementError(msg)


#: how much longer than ``span / rtf`` a measured span may take and still count as kept pace
RTF_SLACK = 0.25


def default_rtf(rate: float) -> float:
    """Real-time factor for ``rate``: ``TICKS_PER_WALL_S`` ticks per wall second, at most ``RTF_MAX``.

    Parameters
    ----------
    rate : float
        Publishing rate, Hz of sim time.

    Returns
    -------
    float
        ``min(RTF_MAX, TICKS_PER_WALL_S / rate)``, sim s per wall s.
    """
    return min(RTF_MAX, TICKS_PER_WALL_S / rate)


def live_cost(
    rate: float,
    *,
    rtf: float | None = None,
    clock_rate: float | None = None,
    span_ticks: int = 600,
    warmup_wall: float = 0.5,
    scene: str = SCENE,
) -> LiveCost:
    """Measure the CPU cost of the in-process live line (with the run's recorder) at ``rate``.

    Builds the line as ``folder-line run`` does in-process (:func:`folder_line.ros.run.run_line`):
    a private rclpy context, the recorder writing the bag (to a temporary directory), the
    five nodes with the run's parameters and ``rate``, then ``line_clock`` in lockstep with
    all six as participants; spins one ``EventsExecutor`` until the clock's ``duration`` is
    reached; shuts down.

    Parameters
    ----------
    rate : float
        Publishing rate of the machine nodes, Hz of sim time, in the nodes' range (:data:`TICK_RATE`).
    rtf : float, optional
        Real-time factor; default :func:`default_rtf`.
    clock_rate : float, optional
        Ticks of ``line_clock`` per second of sim time; default ``rate`` as ``folder-line run``
        (a lower one sends several joint states per tick, the same ones).
    span_ticks : int
        Length of the measured span in ticks of the nodes (sim span ``span_ticks / rate``).
    warmup_wall : float
        Wall time before the span (start-up, discovery), s; in sim time ``warmup_wall x rtf``.
    scene : str
        Scene name or file.

    Returns
    -------
    LiveCost
        The measurement; see :func:`check_published` for its validity.
    """
    rtf = _checked_rtf(rate, rtf, span_ticks, warmup_wall)
    warmup = warmup_wall * rtf
    duration = warmup + span_ticks / rate
    cfg = RunConfig(scene=scene, duration=duration, rtf=rtf, rate=float(rate))
    clock_rate = float(rate) if clock_rate is None else float(clock_rate)
    start, end, state, joint_nodes = _run_live_line(cfg, scene, clock_rate, warmup)
    period_ns = round(NS_PER_S / float(rate))
    if start is None or end is None or end[0] <= start[0]:
        msg = (
            f'the live line at {rate:g} Hz (rtf {rtf:g}) did not reach {duration:.3f} s of sim time '
            f'within {3.0 * duration / rtf + 30.0:.0f} s of wall time'
        )
        raise MeasurementError(msg)
    return LiveCost(
        rate=float(rate),
        rtf=rtf,
        clock_rate=clock_rate,
        t_start=start[0],
        t_end=end[0],
        cpu_s=end[1] - start[1],
        wall_s=end[2] - start[2],
        published={n: end[3][n][0] - start[3][n][0] for n in joint_nodes},
        supervisor_state=state,
        owed={n: end[3][n][1] // period_ns - start[3][n][1] // period_ns for n in joint_nodes},
    )


def _checked_rtf(rate: float, rtf: float | None, span_ticks: int, warmup_wall: float) -> float:
    """The real-time factor of :func:`live_cost` (:func:`default_rtf` if None), its arguments checked."""
    TICK_RATE.check('rate', rate)
    rtf = default_rtf(rate) if rtf is None else float(rtf)
    if not (isinstance(span_ticks, int) and span_ticks >= 10):
        raise ParameterError('span_ticks', span_ticks, 'must be a whole number of ticks >= 10')
    if not (math.isfinite(warmup_wall) and warmup_wall >= 0.0):
        raise ParameterError('warmup_wall', warmup_wall, 'must be a finite wall time >= 0 s')
    if not (math.isfinite(rtf) and rtf > 0.0):
        raise ParameterError('rtf', rtf, 'must be a finite real-time factor > 0')
    return rtf


#: a point of the measured span: (sim time s, process CPU s, wall s, each joint node's :func:`_progress`)
_Mark = tuple[float, float, float, dict[str, tuple[int, int]]]


def _run_live_line(
    cfg: RunConfig, scene: str, clock_rate: float, warmup: float
) -> tuple[_Mark | None, _Mark | None, str, list[str]]:
    """Run the in-process live line of :func:`live_cost` (``cfg``, the clock at ``clock_rate`` per s of sim
    time) and take its marks at ``warmup`` s of sim time and when the clock is done.

    Returns
    -------
    start, end : tuple or None
        The marks (None if not reached within the wall-time deadline).
    state : str
        The supervisor's PackML state at the end.
    joint_nodes : list of str
        The joint nodes measured.
    """
    mapping = scene_mapping(scene)
    parsed = parse_scene(mapping)
    ctx = rclpy.Context()
    rclpy.init(
        args=['--ros-args', '--log-level', 'WARN'],
        context=ctx,
        signal_handler_options=rclpy.signals.SignalHandlerOptions.NO,
    )
    executor = events_executor(ctx)
    nodes: list[Any] = []
    with tempfile.TemporaryDirectory(prefix='folder_line_publishing_') as tmp:
        bag = BagWriter(
            Path(tmp) / 'bag',
            scene_source=yaml.safe_dump(mapping, sort_keys=False),
            effects=list(parsed.effects),
            scene_name=parsed.name,
            topics=LINE_TOPICS,
        )
        try:
            recorder = LineRecorder(sink=bag.write_serialized, context=ctx)
            nodes.append(recorder)
            executor.add_node(recorder)
            machines = add_machine_nodes(cfg, ctx, executor)
            nodes += machines
            joint_nodes = {n.NODE_NAME: n for n in machines if n.NODE_NAME in _JOINT_NODES}
            params = {**clock_parameters(cfg, KNOWN_PARTICIPANTS), 'rate': clock_rate}
            clock = LineClock(parameter_overrides=[Parameter(k, value=v) for k, v in params.items()], context=ctx)
            nodes.append(clock)
            executor.add_node(clock)
            deadline = time.monotonic() + 30.0 + 3.0 * cfg.duration / cfg.rtf
            start, end = _spin_span(executor, recorder, clock, joint_nodes, warmup, deadline)
            state = recorder.state
        finally:
            executor.shutdown()
            bag.close()
            for node in nodes:
                node.destroy_node()
            ctx.try_shutdown()
    return start, end, state, list(joint_nodes)


def _spin_span(
    executor: Executor,
    recorder: LineRecorder,
    clock: LineClock,
    joint_nodes: Mapping[str, MachineNode],
    warmup: float,
    deadline: float,
) -> tuple[_Mark | None, _Mark | None]:
    """Spin until the clock is done (or the wall-clock ``deadline``, s of ``time.monotonic``): the marks at
    the first tick of ``warmup`` s of sim time or later, taken as the recorder records it (one callback
    can record several ticks: a mark polled after it would start the span late), and at the clock's stop."""
    marks: list[_Mark] = []
    warmup_ns = round(warmup * NS_PER_S)

    def at_tick(stamp: int) -> None:
        if not marks and stamp >= warmup_ns:
            marks.append(_mark(stamp / NS_PER_S, joint_nodes))

    recorder.tick_observer = at_tick
    end: _Mark | None = None
    while end is None and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.01)
        sim = recorder.sim_time
        if marks and clock.done.done() and (stop_ns := clock.done.result()) is not None and sim >= stop_ns / 1e9:
            end = _mark(sim, joint_nodes)
    recorder.tick_observer = None
    return (marks[0] if marks else None), end


def _mark(sim: float, joint_nodes: Mapping[str, MachineNode]) -> _Mark:
    """The mark at ``sim`` s of sim time: the process's CPU time, the wall time, the nodes' progress."""
    return (sim, time.process_time(), time.monotonic(), {n: _progress(node) for n, node in joint_nodes.items()})


def _progress(node: MachineNode) -> tuple[int, int]:
    """A joint node's JointState messages so far and the last tick it did, ns (it has published every
    grid point up to that tick)."""
    last = node.lockstep.last_done
    return node.published_joint_states, -1 if last is None else int(last)


# --------------------------------------------------------------------------- study


def measured_cost(rate: float, *, span_ticks: int = 600, warmup_wall: float = 0.5, attempts: int = 5) -> LiveCost:
    """:func:`live_cost` at :func:`default_rtf`, measured again at half the rtf while the line did not keep up.

    A measurement is taken when every joint node published at least ``MIN_PUBLISHED``
    of its ticks, the supervisor ended in EXECUTE (it judged every cycle with all
    its events, as the batch simulation does) and the clock kept its real-time factor
    (the span took at most ``1 + RTF_SLACK`` times ``span / rtf`` of wall time: on a busy
    machine the lockstep line slows down instead, and its cost would be that of a line
    running flat out); otherwise it is repeated at half the real-time factor, up to
    ``attempts`` measurements in all.

    Parameters
    ----------
    rate : float
        Publishing rate, Hz of sim time.
    span_ticks : int
        Measured span, ticks.
    warmup_wall : float
        Warm-up, s of wall time.
    attempts : int
        Measurements at most (rtf, rtf/2, rtf/4, ...), >= 1.

    Returns
    -------
    LiveCost
        The first good measurement, else the last one if its ticks were published
        (its ``supervisor_state`` then says how the line ended).

    Raises
    ------
    MeasurementError
        The last attempt still skipped more than ``1 - MIN_PUBLISHED`` of the ticks.
    """
    rtf = default_rtf(rate)
    for _attempt in range(max(attempts, 1)):
        cost = live_cost(rate, rtf=rtf, span_ticks=span_ticks, warmup_wall=warmup_wall)
        kept_pace = cost.wall_s <= (1.0 + RTF_SLACK) * cost.span / cost.rtf
        if cost.published_fraction >= MIN_PUBLISHED and cost.supervisor_state == 'EXECUTE' and kept_pace:
            return cost
        rtf *= 0.5
    check_published(cost)
    return cost


def run(quick: bool = False) -> list[Row]:
    """Error of the rebuilt knife position and cost of the live line, per rate and method.

    Parameters
    ----------
    quick : bool
        Rates :data:`RATES_QUICK`, 1 s of error span and 300 ticks of cost span
        (else :data:`RATES`, 2 s and 1000 ticks).

    Returns
    -------
    list of Row
        One row per (method, rate): error in m of the knife position, cost in CPU s
        per simulated s of the live line (shared by both methods of a rate).

    Raises
    ------
    MeasurementError
        The live line skipped more than 10 % of its ticks even at a quarter of the
        real-time factor.
    """
    rates = RATES_QUICK if quick else RATES
    duration = 1.0 if quick else 2.0
    span_ticks = 300 if quick else 1000
    model = knife_model(duration)
    rows: list[Row] = []
    for rate in rates:
        cost = measured_cost(rate, span_ticks=span_ticks)
        reference = (
            f'core closed form s(omega_k t) on a {FINE_RATE / 1e3:g} kHz grid over {duration:g} s '
            f'(checked vs mpmath crank-slider to 1e-12 m); cost: in-process live line with the run '
            f'recorder writing the bag, rtf {cost.rtf:g}, {cost.published_fraction:.1%} of '
            f'{cost.ticks_owed:.0f} ticks published, supervisor {cost.supervisor_state}'
        )
        for method in METHODS:
            err = reconstruction_error(rate, method, duration=duration, model=model)
            rows.append(
                Row(
                    study='publishing',
                    method=method,
                    knob='rate',
                    value=float(rate),
                    error=err,
                    cpu_s_per_sim_s=cost.cpu_s_per_sim_s,
                    quantity='knife position',
                    unit='m',
                    reference=reference,
                )
            )
    return rows
