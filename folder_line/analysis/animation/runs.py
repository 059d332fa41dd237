"""What an animation shows, from the streamed line (``animate``) or from a recorded run (``analyze --animate``).

Each gives the line the scenery is drawn from -- a :class:`~folder_line.core.line.stream.LineStream`
under the run's drive commands and tunings, which :func:`~folder_line.analysis.animation.render.render`
advances window by window as it draws -- and the
:class:`~folder_line.analysis.animation.timeline.Timeline` of the overlays:

:func:`batch_run`
    the scene run as ``folder-line run`` and ``simulate --bag`` run it, without ROS: the streamed line
    with the supervisor's logic built as the live node builds it
    (:func:`folder_line.config.run_config.supervisor_logic`) in the loop, window by window (as
    :func:`folder_line.bag.batch.write_batch_bag` runs it): every :data:`TICK_STEP` s from t = 0 on
    (the live line's first tick) the events up to the tick fed, then the tick; when the logic issues a
    command, the stream goes back to the window's start (its checkpoint) and advances again under the
    new commands. Its transitions give the PackML states, its commands the drive the frames are drawn
    under (a hold brakes the machine in the picture), and the line's constraint rows decided by the end
    (``LineStream.advance``'s windows) the violations. Nothing of the line is kept: this pass keeps the
    states, the commands and the violations, and the frames are drawn in a second pass of the line
    under the commands found;
:func:`recorded_run`
    a recorded bag: the line streamed from the bag's scene under its recorded drive commands and
    tunings, the states recorded on ``/line/supervisor/state`` and the violations the supervisor
    published on ``/diagnostics``.

The overlays' machine cycle is read from the drive under the run's commands
(:class:`folder_line.core.line.cycles.MachineCycles`), at any time.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from folder_line.analysis.animation.timeline import Flag, Timeline, TimeScale
from folder_line.analysis.recording import Recording
from folder_line.config.run_config import SUPERVISOR_DEFAULTS, supervisor_logic
from folder_line.core.line.cycles import MachineCycles
from folder_line.core.line.drives import make_drive
from folder_line.core.line.scene import Scene
from folder_line.core.line.stream import LineStream
from folder_line.core.line.tuning import LineCommand, Tuning
from folder_line.core.types.events import ConstraintSeries
from folder_line.errors import ParameterError
from folder_line.interfaces import NS_PER_S

__all__ = ['JUDGED_AFTER', 'LOOP_WINDOW', 'TICK_STEP', 'AnimatedRun', 'batch_run', 'recorded_run', 'scale_note']

#: line time between two ticks of the batch supervisor, s. Its decisions do not depend on it (each has an
#: exact time that depends on the inputs only: :mod:`folder_line.core.supervision.supervisor`), as long as a
#: command's lead (0.1 s) is longer; 50 ms ticks cost a tenth of the live 5 ms ones.
TICK_STEP = 0.05
#: ticks per window of the supervisor's loop (a checkpoint at each window's start): 1 s of line time
LOOP_TICKS = 20
#: line time per window of the supervisor's loop, s
LOOP_WINDOW = LOOP_TICKS * TICK_STEP
#: line time the line runs on after the end for the cycles decided by then whose signatures were still on
#: their way, s (they are judged once the signature arrived, as the run's nodes would judge them)
JUDGED_AFTER = 1.0


@dataclass(frozen=True, eq=False)
class AnimatedRun:
    """A run ready to animate.

    Attributes
    ----------
    scene : Scene
    commands : tuple of Command or Tuning
        The drive commands and tunings of the run, each with its effective time.
    timeline : Timeline
        The overlays.
    title : str
        The header's first line.
    states : list of (float, str)
        ``(line time, state)`` of every state change (the first: the initial state).
    flags : list of Flag
        The violations.
    until : float
        Line time the line is known to, s (the axes may look that far ahead): ``inf`` for a batch run,
        the run's duration for a recorded one.
    """

    scene: Scene
    commands: tuple[LineCommand, ...]
    timeline: Timeline
    title: str
    states: list[tuple[float, str]]
    flags: list[Flag]
    until: float = math.inf

    @property
    def model(self) -> LineStream:
        """The line the frames are drawn from: a new stream under :attr:`commands`, at its start (each access
        a new one; :func:`~folder_line.analysis.animation.render.render` advances it)."""
        return LineStream(self.scene, self.commands)


def _cycle_word(scene: Scene) -> str:
    return 'knife cycle' if scene.has_folder else 'crank turn'


def _timeline(
    scene: Scene,
    commands: Sequence[LineCommand],
    states: Sequence[tuple[float, str]],
    flags: Sequence[Flag],
    slowdown: float,
) -> Timeline:
    """The overlays, with the machine cycles of the drive under ``commands`` (its own, asked at any time)."""
    drive = make_drive(scene, commands)
    cycles = MachineCycles(scene)
    return Timeline(
        lambda t: cycles.index(drive, t),
        lambda t: cycles.next_boundary(drive, t),
        _cycle_word(scene),
        states,
        flags,
        slowdown,
    )


def _add_flags(flags: dict[str, list[Flag]], rows: Sequence[ConstraintSeries], t_end: float) -> None:
    """Add the violated rows decided by ``t_end`` of a window (per constraint, in row order): only the violations
    are kept as the windows pass."""
    for c in rows:
        for i in np.flatnonzero(c.violated & (c.t <= t_end)).tolist():
            flags[c.name].append(Flag(float(c.t[i]), c.name, int(c.cycle[i]), float(c.margin[i]), c.unit))


def batch_run(scene: Scene, scale: TimeScale, tunings: Sequence[Tuning] = ()) -> AnimatedRun:
    """The scene over ``[0, scale.t_end]`` with the supervisor in the loop (see the module docstring).

    Parameters
    ----------
    scene : Scene
    scale : TimeScale
        The span animated (the loop runs from 0 to its end).
    tunings : sequence of Tuning
        The operator's changes, each asked at the last tick before its effective time (as
        ``simulate --bag`` asks them).

    Raises
    ------
    ParameterError
        A tuning the supervisor refuses (naming its key).
    """
    t_end = scale.t_end
    sup = supervisor_logic(scene, SUPERVISOR_DEFAULTS)
    line = LineStream(scene)
    found: dict[str, list[Flag]] = {name: [] for name in line.tallies.constraints}  # in the line's order
    pending = sorted(tunings, key=lambda tu: tu.t)  # each asked at the last tick before it, as simulate --bag does
    ticks: list[float] = []  # 0, step, 2 step, ..., t_end
    while not ticks or ticks[-1] < t_end:
        ticks.append(min(len(ticks) * TICK_STEP, t_end))
    k = 0
    while k < len(ticks):
        start = line.checkpoint()
        end = min(len(ticks), k + LOOP_TICKS)
        window = line.advance(ticks[end - 1])
        times = window.events['t']
        for i in range(k, end):
            w = ticks[i]
            lo = np.searchsorted(times, ticks[i - 1] if i else -math.inf, side='right')
            sup.feed(window.events[lo : np.searchsorted(times, w, side='right')])
            sup.tick(w)
            while pending and w < pending[0].t <= min((i + 1) * TICK_STEP, t_end):
                tu = pending.pop(0)
                out = sup.tune(tu.key, tu.value, w, effective=tu.t)
                if not out.ok:  # as simulate --bag: a refused change is said, never dropped
                    raise ParameterError(tu.key, tu.value, out.message)
            if tuple(sup.commands) != line.commands:
                # the line runs under it from its effective time on: back to the window's start, and again to w
                line.restore(start, sup.commands)
                window = line.advance(w)
                end = i + 1
                break
        _add_flags(found, window.constraints, t_end)
        k = end
    _add_flags(found, line.advance(t_end + JUDGED_AFTER).constraints + line.finish(), t_end)  # judged after the end
    states = [(0.0, 'STARTING')] + [(float(tr.t), str(tr.target)) for tr in sup.transitions]
    flags = [f for per in found.values() for f in per]
    commands = tuple(sup.commands)
    title = f'scene {scene.name}: the line seen from the side (the streamed line, supervisor in the loop)'
    return AnimatedRun(scene, commands, _timeline(scene, commands, states, flags, scale.slowdown), title, states, flags)


def recorded_run(rec: Recording, scale: TimeScale) -> AnimatedRun:
    """A recorded run (see the module docstring)."""
    states = [(ns / NS_PER_S, state) for ns, state in rec.states]
    flags = []
    for _, name, v in rec.supervisor_status:
        if not name.endswith('/violation'):
            continue
        try:
            flags.append(Flag(float(v['t']), v['constraint'], int(v['cycle']), float(v['margin']), v.get('unit', '')))
        except (KeyError, ValueError):  # a status the supervisor did not write: not drawn
            continue
    bag = Path(rec.bag.path)
    where = f'{bag.parent.name}/{bag.name}' if bag.parent.name else bag.name  # a run's bag is always bag/
    title = f'recorded run {where} (scene {rec.scene.name}): the line seen from the side'
    timeline = _timeline(rec.scene, rec.commands, states, flags, scale.slowdown)
    return AnimatedRun(rec.scene, rec.commands, timeline, title, states, flags, max(rec.duration, scale.t_end))


def scale_note(scale: TimeScale) -> str:
    """The time scale in words, for the header."""
    if scale.slowdown >= 1.0:
        speed = f'slow motion {scale.slowdown:g}x: 1 s of video = {1.0 / scale.slowdown:.4g} s of line'
    else:
        speed = f'fast motion {1.0 / scale.slowdown:.4g}x: 1 s of video = {1.0 / scale.slowdown:.4g} s of line'
    return f'{speed}; {scale.fps:g} frames/s, {scale.dt * 1e3:.4g} ms of line per frame'
