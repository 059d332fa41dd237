"""The line model and the batch line simulation: ``LineModel``, ``simulate(scene, duration)``.

:class:`LineModel` builds the parts of the line the scene has — L
(:class:`folder_line.core.line.layup_sim.LayupLine`) and F with D
(:class:`folder_line.core.line.folder_sim.FolderLine`) — on one master drive, once:
the drive (with the supervisor's commands, :func:`make_drive`), (b) the exact event
list and (c) the cyclogram constraints evaluated per cycle; and, from the events, the
sheet counter's table (:mod:`folder_line.core.mechanisms.pile`). Joint states are then
sampled at any times (:meth:`LineModel.sample`, one unit at a time: what a node's
timer tick needs). Only the effects the scene lists run.

:func:`simulate` is ``LineModel(scene, duration, commands).result(duration, rate)``:
(a) joint states sampled at the scene's rate, (b) events and (c) constraints.

What a node publishes at stamp t depends only on the scene, t and the commands:
every event time is a closed form or a root in the drive's phase, each sheet's and
leaf's on its own, and the random draws are prefix-consistent (a longer run extends
them, never reshuffles), so a model built for a longer horizon agrees with a shorter
one on everything up to the shorter one's end. One exception: with
``motor_dynamics`` the motor ODE's last step before the horizon is cut at the
horizon; while the motor has not settled into its periodic steady state (the first
~8 s of a start, or of a restart) a different horizon may change Θ there at the
level of the integrator's tolerance.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from folder_line.core.effects import motor_dynamics, speed_ripple
from folder_line.core.limits import DURATION, HORIZON, SAMPLE_RATE
from folder_line.core.line.events import (
    EVENT_KINDS,
    ConstraintSeries,
    JointSamples,
    merge_events,
)
from folder_line.core.line.folder_sim import FolderLine
from folder_line.core.line.layup_sim import LayupLine
from folder_line.core.line.scene import Scene
from folder_line.core.line.tuning import (
    LineCommand,
    Tuning,
    belt_steps,
    check_tuning,
    scene_value,
    tunings_of,
    values_from,
)
from folder_line.core.mechanisms.drive import Command, Drive, check_commands, commanded_drive, theta_rate
from folder_line.core.mechanisms.pile import T_LOWER, pile_table
from folder_line.core.numerics.validate import as_float
from folder_line.errors import ParameterError

__all__ = [
    'BYTES_PER_CYCLE',
    'BYTES_PER_LEAF',
    'MAX_CYCLES',
    'MEMORY_SHARE',
    'UNITS',
    'LineModel',
    'LineResult',
    'check_line_commands',
    'check_size',
    'make_drive',
    'memory_budget',
    'sample_times',
    'simulate',
]

#: the line's machine units that carry joints, in publishing order: ``drive`` the master drive's crank
#: shafts (the knife; the layup crank and its chutes), ``belts`` the belts that bring the sheets in (the
#: folder's first transporter; the layup's chute belts), ``feed`` the folder's feed transporter with the
#: delivery chain, ``counter`` the table under the counted sheets (:mod:`folder_line.core.mechanisms.pile`,
#: in every scene). The ROS side runs each in a node of its own (``folder_line.interfaces.NODE_OF_UNIT``).
UNITS = ('drive', 'belts', 'feed', 'counter')

#: longest horizon of a model, s (:data:`folder_line.core.limits.HORIZON`)
MAX_DURATION = HORIZON.hi
#: peak memory of a model per knife cycle and per leaf, bytes: measured by ``bench/bench_memory.py`` (the
#: growth of the peak RSS of ``simulate`` and its summary between 1 h and 4 h of line time: 1769 B per
#: cycle of ``folder``, 609 B per leaf of ``line``), rounded up
BYTES_PER_CYCLE = 1900
BYTES_PER_LEAF = 700
#: share of the machine's physical memory a model may take
MEMORY_SHARE = 0.75
#: most knife cycles or leaves a model is built for whatever the memory (~19 GB): beyond, the CPU time
#: alone (~10 min per 1e7 cycles) says to simulate shorter spans
MAX_CYCLES = 1e7


def memory_budget() -> int:
    """Bytes a model may take: :data:`MEMORY_SHARE` of this machine's physical memory."""
    try:
        physical = os.sysconf('SC_PHYS_PAGES') * os.sysconf('SC_PAGE_SIZE')
    except (OSError, ValueError, AttributeError):  # not POSIX: assume a small machine
        physical = 8 * 2**30
    return int(MEMORY_SHARE * physical)


@dataclass(frozen=True, eq=False)
class LineResult:
    """Everything :func:`simulate` computes.

    Attributes
    ----------
    scene : Scene
        The scene simulated.
    duration : float
        Line time simulated, s.
    events : ndarray of EVENT_DTYPE
        Exact events sorted by time.
    samples : dict of str to JointSamples
        Unit (:data:`UNITS`) -> joint states on the sample grid.
    constraints : list of ConstraintSeries
        Per-cycle constraint margins.
    parts : dict of str to dict
        Per part (``'layup'``, ``'folder'``) its summary figures.
    """

    scene: Scene
    duration: float
    events: np.ndarray
    samples: dict[str, JointSamples]
    constraints: list[ConstraintSeries]
    parts: dict[str, dict[str, Any]]

    def events_of(self, kind: str) -> np.ndarray:
        """Rows of one event kind."""
        rows: np.ndarray = self.events[self.events['kind'] == EVENT_KINDS.index(kind)]  # a field is typed Any
        return rows

    def constraint(self, name: str) -> ConstraintSeries:
        """A constraint by name (KeyError listing the names)."""
        for c in self.constraints:
            if c.name == name:
                return c
        msg = f'constraint {name!r} not evaluated; evaluated: {", ".join(c.name for c in self.constraints)}'
        raise KeyError(msg)

    def summary(self, max_violations: int = 10) -> dict[str, Any]:
        """JSON-ready summary (see the ``simulate`` verb of the CLI)."""
        folder = self.parts.get('folder', {})
        layup = self.parts.get('layup', {})
        violations: list[dict[str, Any]] = []
        count = 0
        min_margin: dict[str, dict[str, Any]] = {}
        for c in self.constraints:
            bad = np.flatnonzero(c.violated)
            count += int(bad.size)
            violations += [
                {'cycle': int(c.cycle[i]), 'constraint': c.name, 'margin': float(c.margin[i]), 'unit': c.unit}
                for i in bad[:max_violations]
            ]
            if c.margin.size:
                i = int(np.argmin(c.margin))
                min_margin[c.name] = {
                    'margin': float(c.margin[i]),
                    'unit': c.unit,
                    'cycle': int(c.cycle[i]),
                    'evaluations': int(c.margin.size),
                    'violations': int(bad.size),
                }
        violations.sort(key=lambda v: (v['cycle'], v['constraint']))
        out: dict[str, Any] = {
            'scene': self.scene.name,
            'duration_s': self.duration,
            'seed': self.scene.seed,
            'effects': list(self.scene.effects),
            'cycles': folder.get('cycles', layup.get('crank_cycles', 0)),
            'sheets_counted': folder.get('sheets_counted', layup.get('leaves_landed', 0)),
            'violations': {'count': count, 'first': violations[:max_violations]},
            'min_margin_s': {k: v['margin'] for k, v in min_margin.items() if v['unit'] == 's'},
            'min_margin': min_margin,
            'events': {
                k: int(n)
                for k, n in zip(EVENT_KINDS, np.bincount(self.events['kind'], minlength=len(EVENT_KINDS)), strict=True)
                if n
            },
        }
        if 'v_tr_over_v_d' in folder:
            out['v_tr_over_v_d'] = folder['v_tr_over_v_d']
        for part, figures in self.parts.items():
            out[part] = figures
        if 'landing_cv' in layup:
            out['landing_cv'] = layup['landing_cv']
            out['landing_histogram'] = layup.get('landing_histogram')
        return out


def check_line_commands(commands: Iterable[LineCommand]) -> tuple[LineCommand, ...]:
    """The supervisor's drive commands and the operator's tunings as one tuple, checked: each a
    :class:`Command` or a :class:`~folder_line.core.line.tuning.Tuning`, sorted by effective time.

    Raises
    ------
    ParameterError
        Anything else, or one earlier than the one before it.
    """
    return check_commands(commands, (Command, Tuning), 'a drive Command or a Tuning')


def make_drive(scene: Scene, duration: float, commands: Iterable[LineCommand] = ()) -> Drive:
    """The master drive of a scene under the supervisor's commands.

    The operator's tunings of ``press.n_c`` set the speed the generator heads for (as a
    factor of the scene's press speed). The motor ODE if the scene lists ``motor_dynamics``
    (:func:`folder_line.core.effects.motor_dynamics.build_drive`), else the drive
    profile with the ramp generator (:func:`folder_line.core.mechanisms.drive.commanded_drive`).
    Without commands both are exactly the drives of a run without a supervisor. With
    ``speed_ripple`` that drive is rippled on top
    (:class:`folder_line.core.effects.speed_ripple.RippleDrive`, its phase drawn from the seed).
    """
    commands = list(commands)
    drive_commands = [c for c in commands if isinstance(c, Command)]
    base: Drive
    if scene.has('motor_dynamics'):  # the press speed is not tunable there (core.line.tuning)
        base = motor_dynamics.build_drive(scene, duration, commands=drive_commands)
    else:
        tunings = [c for c in commands if isinstance(c, Tuning)]
        speeds = belt_steps(tunings, 'press.n_c', scene_value(scene, 'press.n_c')) if scene.has_folder else []
        base = commanded_drive(scene.drive, drive_commands, speeds)
    if scene.has('speed_ripple'):
        return speed_ripple.RippleDrive(base, scene.effect_params('speed_ripple'), speed_ripple.draw_phase(scene.seed))
    return base


def sample_times(duration: float, rate: float) -> np.ndarray:
    """The sample grid ``i / rate`` for i = 0 .. floor(duration·rate), s (empty if rate = 0)."""
    if rate <= 0.0:
        return np.zeros(0)
    n = int(math.floor(duration * rate * (1.0 + 1e-15))) + 1
    return np.arange(n, dtype=float) / rate


def _merge(unit: str, parts: list[JointSamples]) -> JointSamples:
    """Joints of one unit from several parts, concatenated in part order (efforts 0 where a part has none)."""
    merged = parts[0]
    for js in parts[1:]:
        prev = merged
        eff = None
        if prev.effort is not None or js.effort is not None:
            eff = np.hstack(
                [
                    prev.effort if prev.effort is not None else np.zeros_like(prev.position),
                    js.effort if js.effort is not None else np.zeros_like(js.position),
                ]
            )
        merged = JointSamples(
            unit,
            prev.names + js.names,
            prev.t,
            np.hstack([prev.position, js.position]),
            np.hstack([prev.velocity, js.velocity]),
            eff,
        )
    return merged


def check_size(scene: Scene, span: float, theta_end: float, key: str = 'horizon') -> None:
    """Refuse a span whose model would not fit in memory, before the events are built.

    The need is the knife cycles times :data:`BYTES_PER_CYCLE` plus the leaves times
    :data:`BYTES_PER_LEAF` (measured peak figures); it must fit :func:`memory_budget`, and
    neither count may pass :data:`MAX_CYCLES`.

    Parameters
    ----------
    scene : Scene
    span : float
        Line time, s.
    theta_end : float
        The master phase at ``span`` (nominal s): ``theta_end / period`` knife cycles run
        (a held line runs none). Leaves enter in line time, one per ``sheets.interval``.
    key : str
        The caller's name of the span, for the error.

    Raises
    ------
    ParameterError
        Naming ``key`` and the span, with the memory the model would need and the longest span that fits.
    """
    parts: list[tuple[float, str, int]] = []
    if scene.has_folder:
        parts.append((theta_end / float(scene.machine('knife').period), 'knife cycles', BYTES_PER_CYCLE))
    if scene.has_layup:
        parts.append((span / float(scene.sheets.interval), 'leaves', BYTES_PER_LEAF))
    need = sum(n * b for n, _, b in parts)
    budget = memory_budget()
    too_many = [(n, what) for n, what, _ in parts if n > MAX_CYCLES]
    if need <= budget and not too_many:
        return
    fits = span * min(budget / need if need > 0 else math.inf, *(MAX_CYCLES / n for n, _, _ in parts if n > 0))
    counts = ' and '.join(f'{n:.3g} {what} x {b} B' for n, what, b in parts)
    over = f', and more than {MAX_CYCLES:.0e} {too_many[0][1]}' if too_many else ''
    raise ParameterError(
        key,
        span,
        f'the model would need about {need / 1e9:.3g} GB of memory ({counts}, the '
        f'measured peak per cycle and leaf){over}; this machine allows {budget / 1e9:.3g} GB '
        f'({MEMORY_SHARE:.0%} of its memory): at most {fits:.4g} s of this scene',
    )


class LineModel:
    """The line of a scene over ``[0, horizon]``: built once, sampled anywhere.

    Construction computes everything that depends only on the scene, the horizon and
    the commands: the master drive, every event in ``[0, horizon]``, the constraints
    and the parts' summaries. :meth:`sample` then gives a unit's joint states at any
    times in ``[0, horizon]`` (bit for bit what :func:`simulate` samples at the same
    times), :meth:`events_between` the events of a tick.

    Parameters
    ----------
    scene : Scene
        Validated scene.
    horizon : float
        Line time the model covers, s (> 0).
    commands : iterable of Command or Tuning
        The supervisor's drive commands (:mod:`folder_line.core.mechanisms.drive`) and
        the operator's tunings (:mod:`folder_line.core.line.tuning`), sorted by effective
        time (ParameterError otherwise). Events before the earliest one's time are the
        same, bit for bit, with and without it.

    Attributes
    ----------
    scene : Scene
    horizon : float
    commands : tuple of Command or Tuning
    tunings : tuple of Tuning
        The tunings among the commands.
    pile : PileTable or SteppedPile
        The table under the counted sheets (:mod:`folder_line.core.mechanisms.pile`).
    drive : Drive
    events : ndarray of EVENT_DTYPE
        All events in ``[0, horizon]``, sorted by time (then kind, then sheet).
    constraints : list of ConstraintSeries
    parts : dict of str to dict
        Per part (``'folder'``, ``'layup'``) its summary figures.
    """

    def __init__(self, scene: Scene, horizon: float, commands: Iterable[LineCommand] = ()) -> None:
        self.scene = scene
        self.horizon = HORIZON.check('horizon', horizon)
        self.commands = check_line_commands(commands)
        self.tunings = tunings_of(self.commands)
        for tu in self.tunings:
            check_tuning(scene, tu.key, tu.value)
        self.drive = make_drive(scene, self.horizon, self.commands)
        check_size(scene, self.horizon, float(np.asarray(self.drive.theta(np.array(self.horizon)))))
        self._parts: dict[str, Any] = {}
        if scene.has_folder:
            self._parts['folder'] = FolderLine(scene, self.drive, self.horizon, self.tunings)
        if scene.has_layup:
            self._parts['layup'] = LayupLine(scene, self.drive, self.horizon, self.tunings)
        parts = list(self._parts.values())
        self.events = merge_events(p.events for p in parts)
        self._event_t = np.ascontiguousarray(self.events['t'])
        self.constraints: list[ConstraintSeries] = [c for p in parts for c in p.constraints]
        self.parts: dict[str, dict[str, Any]] = {name: p.summary for name, p in self._parts.items()}
        lowering = values_from(self.tunings, 'pile.t_lower', T_LOWER)
        table = pile_table(scene.has_delivery, self.events, scene.sheets.thickness, steps=lowering)
        self.pile = table  # the sheet counter's table (with the operator's lowering times)
        units: dict[str, list[Any]] = {}
        for p in [*parts, table]:
            for unit in p.units:
                units.setdefault(unit, []).append(p)
        self._unit_parts = {unit: units[unit] for unit in UNITS if unit in units}
        self._units = {unit: tuple(name for p in ps for name in p.units[unit]) for unit, ps in self._unit_parts.items()}
        self._theta_end = float(np.asarray(self.drive.theta(np.array(self.horizon))))
        self._cycle = self._cycle_definition()

    # ------------------------------------------------------------------ joint states

    @property
    def units(self) -> dict[str, tuple[str, ...]]:
        """Unit -> its joint names (in the order of :meth:`sample`'s columns); units without joints absent."""
        return dict(self._units)

    def _drive_state(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return theta_rate(self.drive, t)

    def sample(self, unit: str, t: npt.ArrayLike) -> JointSamples:
        """Joint states of one unit at line times ``t``.

        Parameters
        ----------
        unit : {'drive', 'belts', 'feed', 'counter'}
            A unit of :attr:`units` (:data:`UNITS`).
        t : array_like, shape (N,)
            Line times, s, in ``[0, horizon]`` (a node's tick: one element).

        Returns
        -------
        JointSamples
            Positions and velocities shaped (N, J) (efforts where the scene computes
            them), the joints of L and F of the same unit concatenated F first, as
            :func:`simulate` does. ``counter``: one joint, ``pile_table`` with
            the delivery, else ``container_floor`` (m, m/s; no effort;
            :mod:`folder_line.core.mechanisms.pile`).

        Raises
        ------
        KeyError
            ``unit`` has no joints in this scene (the message lists the units).
        """
        parts = self._unit_parts.get(unit)
        if parts is None:
            msg = f'unit {unit!r} has no joints in scene {self.scene.name!r}; units: {", ".join(self._units)}'
            raise KeyError(msg)
        tt = np.asarray(t, dtype=float).reshape(-1)
        theta, lam = self._drive_state(tt)
        return _merge(unit, [p.sample_unit(unit, tt, theta, lam) for p in parts])

    def sample_all(self, t: npt.ArrayLike) -> dict[str, JointSamples]:
        """Joint states of every unit at line times ``t`` (unit -> JointSamples)."""
        tt = np.asarray(t, dtype=float).reshape(-1)
        theta, lam = self._drive_state(tt)
        return {
            unit: _merge(unit, [p.sample_unit(unit, tt, theta, lam) for p in parts])
            for unit, parts in self._unit_parts.items()
        }

    def part(self, name: str) -> Any:
        """The line part ``'folder'`` (:class:`FolderLine`) or ``'layup'`` (:class:`LayupLine`) of the
        scene (KeyError naming the parts), for views of the machine such as
        :mod:`folder_line.core.line.scenery`."""
        try:
            return self._parts[name]
        except KeyError:
            msg = f'scene {self.scene.name!r} has no part {name!r}; parts: {", ".join(self._parts)}'
            raise KeyError(msg) from None

    # ------------------------------------------------------------------ events

    def events_between(self, t0: float, t1: float) -> np.ndarray:
        """The events with ``t0 < t <= t1`` (a tick's; ``t0`` may be ``-inf``), in table order."""
        if math.isnan(t0) or math.isnan(t1):
            raise ValueError(f'events_between: times must not be NaN, got ({t0!r}, {t1!r})')
        i0, i1 = np.searchsorted(self._event_t, [t0, t1], side='right')
        return self.events[i0 : max(i0, i1)]

    # ------------------------------------------------------------------ machine cycles

    def _cycle_definition(self) -> tuple[str, float, float]:
        """(what, first cycle start Θ_0, period in Θ) of the line's machine cycle."""
        if 'folder' in self._parts:
            timing = self._parts['folder'].timing
            return 'knife_exit', float(timing.knife.t_out), float(timing.T)
        lp = self.scene.machine('layup')
        return 'crank_turn', 0.0, 60.0 / float(lp.n_kr)

    def _start_phase(self, k: int) -> float:
        """Θ at which machine cycle k (>= 0) starts: for the folder the knife exit that ends cycle
        k - 1 (the same expression as the ``knife_exit`` events, so the times agree bit for bit)."""
        what, th0, period = self._cycle
        if what == 'knife_exit':
            return th0 if k == 0 else float((k - 1) * period + (period + th0))
        return float(k * period)

    def _start_time(self, k: int) -> float:
        """Line time at which cycle k starts (``inf`` if not within the horizon)."""
        th = self._start_phase(k)
        if th > self._theta_end:
            return math.inf
        return float(np.asarray(self.drive.time_of(np.array(th))))

    def cycle_index(self, t: float) -> int:
        """The machine cycle running at line time ``t``: the last one started at or before ``t`` (-1 before
        the first start). The folder's cycle k starts at the knife exit that ends cycle k - 1 (cycle 0 at
        the first knife exit phase ``t_out``, where the feed window opens); without F, the layup crank's
        turn k starts at ``Θ = k 60/n_kr``."""
        t = as_float('t', t)
        _, th0, period = self._cycle
        theta = float(np.asarray(self.drive.theta(np.array(min(max(t, 0.0), self.horizon)))))
        k = max(int(math.floor((theta - th0) / period)), -1)
        while self._start_time(k + 1) <= t:
            k += 1
        while k >= 0 and self._start_time(k) > t:
            k -= 1
        return k

    def next_cycle_boundary(self, t: float) -> float:
        """The start of the next machine cycle strictly after line time ``t``, s (see :meth:`cycle_index`).

        ``inf`` if no cycle starts after ``t`` within the horizon (the line is held,
        or the horizon comes first).
        """
        return self._start_time(self.cycle_index(t) + 1)

    # ------------------------------------------------------------------ batch

    def result(self, duration: float | None = None, sample_rate: float | None = None) -> LineResult:
        """The batch result of ``duration`` s (default: the horizon), sampled at ``sample_rate`` Hz.

        For a duration other than the horizon a model of that duration is built (the
        events, constraints and summaries of a run are those of its own length).

        Parameters
        ----------
        duration : float, optional
            Line time, s (> 0); default :attr:`horizon`.
        sample_rate : float, optional
            Joint-state rate, Hz; default the scene's; 0 for events only.
        """
        duration = self.horizon if duration is None else HORIZON.check('duration', duration)
        if duration != self.horizon:
            return LineModel(self.scene, duration, self.commands).result(duration, sample_rate)
        rate = self.scene.sample_rate if sample_rate is None else SAMPLE_RATE.check('sample_rate', sample_rate)
        t = sample_times(duration, rate)
        return LineResult(
            scene=self.scene,
            duration=duration,
            events=self.events,
            samples=self.sample_all(t) if t.size else {},
            constraints=list(self.constraints),
            parts=dict(self.parts),
        )


def simulate(
    scene: Scene, duration: float, *, sample_rate: float | None = None, commands: Iterable[LineCommand] = ()
) -> LineResult:
    """Simulate ``duration`` seconds of line time.

    Parameters
    ----------
    scene : Scene
        Validated scene.
    duration : float
        Line time, s (> 0).
    sample_rate : float, optional
        Joint-state rate, Hz; default the scene's; 0 for events only.
    commands : iterable of Command
        Supervisor commands with their effective times (:class:`LineModel`).

    Returns
    -------
    LineResult
    """
    duration = DURATION.check('duration', duration)
    rate = scene.sample_rate if sample_rate is None else SAMPLE_RATE.check('sample_rate', sample_rate)
    try:
        model = LineModel(scene, duration, commands)
    except ParameterError as exc:
        if exc.key != 'horizon':
            raise
        raise ParameterError('duration', duration, exc.reason) from None
    return model.result(duration, rate)
