"""What an animation shows, from the batch model (``animate``) or from a recorded run (``analyze --animate``).

Each gives the line model whose scenery is drawn and the :class:`~folder_line.analysis.animation.timeline.Timeline`
of the overlays:

:func:`batch_run`
    the scene run as ``folder-line run`` and ``simulate --bag`` run it, without ROS: the line model over
    ``[0, t_end + 1 s]`` (the horizon ``run`` gives its nodes) and the supervisor's logic with the live
    node's settings (:data:`folder_line.config.run_config.SUPERVISOR_DEFAULTS`) in the closed loop of
    :func:`folder_line.core.supervision.offline.run_closed_loop`, ticked every 5 ms as the clock ticks: its
    transitions give the PackML states, its commands the drive (a hold brakes the machine in the
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

import numpy as np

from folder_line.analysis.animation.timeline import Flag, TimeScale, Timeline
from folder_line.analysis.recording import Recording
from folder_line.config.run_config import RATE, SUPERVISOR_DEFAULTS
from folder_line.core.limits import HORIZON_MARGIN
from folder_line.core.line.model import LineModel, check_size
from folder_line.core.line.scene import Scene
from folder_line.core.supervision.offline import run_closed_loop
from folder_line.interfaces import NS_PER_S

__all__ = ['AnimatedRun', 'batch_run', 'recorded_run', 'scale_note']


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


def _timeline(model: LineModel, states: Sequence[tuple[float, str]], flags: Sequence[Flag], slowdown: float) -> Timeline:
    return Timeline(
        model.cycle_index, model.next_cycle_boundary, _cycle_word(model.scene), states, flags, slowdown
    )


def batch_run(scene: Scene, scale: TimeScale, option: str = '--duration') -> AnimatedRun:
    """The scene over ``[0, scale.t_end]`` with the supervisor in the loop (see the module docstring).

    Raises
    ------
    ParameterError
        The model would not fit in memory (naming ``option``).
    """
    t_end = scale.t_end
    horizon = t_end + HORIZON_MARGIN
    check_size(scene, t_end, horizon, option)
    step = 1.0 / RATE
    settings = SUPERVISOR_DEFAULTS
    sup, model, _ = run_closed_loop(
        scene,
        horizon,
        min(horizon, math.ceil(t_end / step - 1e-9) * step),
        step=step,
        periods={},
        lead=settings['command_lead'],
        check_period=1.0 / settings['rate'],
        enforce=settings['enforce'],
        double=settings['double_sheet'],
        state='STARTING',
        t_start=None,
    )
    states = [(0.0, 'STARTING')] + [(float(tr.t), str(tr.target)) for tr in sup.transitions]
    flags = [
        Flag(float(c.t[i]), c.name, int(c.cycle[i]), float(c.margin[i]), c.unit)
        for c in model.constraints
        for i in np.flatnonzero(c.violated & (c.t <= t_end))
    ]
    title = f'scene {scene.name} ({", ".join(scene.effects) or "no effects"}): the line seen from the side'
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
    title = f'recorded run {rec.bag.path} (scene {rec.scene.name}): the line seen from the side'
    return AnimatedRun(model, _timeline(model, states, flags, scale.slowdown), title, states, flags)


def scale_note(scale: TimeScale) -> str:
    """The time scale in words, for the header."""
    if scale.slowdown >= 1.0:
        speed = f'slow motion {scale.slowdown:g}x: 1 s of video = {1.0 / scale.slowdown:.4g} s of line'
    else:
        speed = f'fast motion {1.0 / scale.slowdown:.4g}x: 1 s of video = {1.0 / scale.slowdown:.4g} s of line'
    return f'{speed}; {scale.fps:g} frames/s, {scale.dt * 1e3:.4g} ms of line per frame'
