"""What an animation shows, from the batch model (``animate``) or from a recorded run (``analyze --animate``).

Each gives the line model whose scenery is drawn and the :class:`~folder_line.analysis.animation.timeline.Timeline`
of the overlays:

:func:`batch_run`
    the scene run as ``folder-line run`` and ``simulate --bag`` run it, without ROS: the line model over
    ``[0, t_end + 1 s]`` (the horizon ``run`` gives its nodes) and the supervisor's logic built as the live
    node builds it (:func:`folder_line.config.run_config.supervisor_logic`), in the closed loop (as
    :func:`folder_line.core.supervision.offline.run_closed_loop`, but ticked from t = 0 on, as the live
    line's first tick): the events up to each tick fed, then the tick; its commands rebuild the model.
    Its transitions give the PackML states, its commands the drive (a hold brakes the machine in the
    picture), and the final model's constraints (``model.constraints``) the violations;
:func:`recorded_run`
    a recorded bag: the model rebuilt from the bag's scene and its recorded drive commands (as
    :func:`folder_line.analysis.replay.evaluate` rebuilds the drive), the states recorded on
    ``/line/supervisor/state`` and the violations the supervisor published on ``/diagnostics``.
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
from folder_line.core.limits import HORIZON_MARGIN
from folder_line.core.line.model import LineModel, check_size
from folder_line.core.line.scene import Scene
from folder_line.core.line.tuning import LineCommand, Tuning
from folder_line.errors import ParameterError
from folder_line.interfaces import NS_PER_S

__all__ = ['TICK_STEP', 'AnimatedRun', 'batch_run', 'recorded_run', 'scale_note']

#: line time between two ticks of the batch supervisor, s. Its decisions do not depend on it (each has an
#: exact time that depends on the inputs only: :mod:`folder_line.core.supervision.supervisor`), as long as a
#: command's lead (0.1 s) is longer; 50 ms ticks cost a tenth of the live 5 ms ones.
TICK_STEP = 0.05


@dataclass(frozen=True, eq=False)
class AnimatedRun:
    """A run ready to animate.

    Attributes
    ----------
    model : LineModel
        The line model the scenery draws (with the drive commands of the run).
    timeline : Timeline
        The overlays.
    title : str
        The header's first line.
    states : list of (float, str)
        ``(line time, state)`` of every state change (the first: the initial state).
    flags : list of Flag
        The violations.
    """

    model: LineModel
    timeline: Timeline
    title: str
    states: list[tuple[float, str]]
    flags: list[Flag]


def _cycle_word(scene: Scene) -> str:
    return 'knife cycle' if scene.has_folder else 'crank turn'


def _timeline(
    model: LineModel, states: Sequence[tuple[float, str]], flags: Sequence[Flag], slowdown: float
) -> Timeline:
    return Timeline(model.cycle_index, model.next_cycle_boundary, _cycle_word(model.scene), states, flags, slowdown)


def batch_run(
    scene: Scene, scale: TimeScale, option: str = '--duration', tunings: Sequence[Tuning] = ()
) -> AnimatedRun:
    """The scene over ``[0, scale.t_end]`` with the supervisor in the loop (see the module docstring).

    Raises
    ------
    ParameterError
        The model would not fit in memory (naming ``option``).
    """
    t_end = scale.t_end
    horizon = t_end + HORIZON_MARGIN
    check_size(scene, t_end, horizon, option)
    models: dict[tuple[LineCommand, ...], LineModel] = {}

    def model_of(commands: tuple[LineCommand, ...]) -> LineModel:
        if commands not in models:
            models[commands] = LineModel(scene, horizon, commands)
        return models[commands]

    sup = supervisor_logic(scene, horizon, SUPERVISOR_DEFAULTS, model_of)
    pending = sorted(tunings, key=lambda tu: tu.t)  # each asked at the last tick before it, as simulate --bag does
    prev, i = -math.inf, 0
    while prev < t_end:  # ticks 0, step, 2 step, ..., t_end: the events up to each fed first, as the node is fed
        w = min(i * TICK_STEP, t_end)
        sup.feed(sup.model.events_between(prev, w))
        sup.tick(w)
        while pending and w < pending[0].t <= min((i + 1) * TICK_STEP, t_end):
            tu = pending.pop(0)
            out = sup.tune(tu.key, tu.value, w, effective=tu.t)
            if not out.ok:  # as simulate --bag: a refused change is said, never dropped
                raise ParameterError(tu.key, tu.value, out.message)
        prev, i = w, i + 1
    model = sup.model
    states = [(0.0, 'STARTING')] + [(float(tr.t), str(tr.target)) for tr in sup.transitions]
    flags = [
        Flag(float(c.t[i]), c.name, int(c.cycle[i]), float(c.margin[i]), c.unit)
        for c in model.constraints
        for i in np.flatnonzero(c.violated & (c.t <= t_end))
    ]
    title = f'scene {scene.name}: the line seen from the side (the batch model, supervisor in the loop)'
    return AnimatedRun(model, _timeline(model, states, flags, scale.slowdown), title, states, flags)


def recorded_run(rec: Recording, scale: TimeScale) -> AnimatedRun:
    """A recorded run (see the module docstring)."""
    model = LineModel(rec.scene, max(rec.horizon, scale.t_end), rec.commands)
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
    return AnimatedRun(model, _timeline(model, states, flags, scale.slowdown), title, states, flags)


def scale_note(scale: TimeScale) -> str:
    """The time scale in words, for the header."""
    if scale.slowdown >= 1.0:
        speed = f'slow motion {scale.slowdown:g}x: 1 s of video = {1.0 / scale.slowdown:.4g} s of line'
    else:
        speed = f'fast motion {1.0 / scale.slowdown:.4g}x: 1 s of video = {1.0 / scale.slowdown:.4g} s of line'
    return f'{speed}; {scale.fps:g} frames/s, {scale.dt * 1e3:.4g} ms of line per frame'
