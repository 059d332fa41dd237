"""The batch line simulation: ``simulate(scene, duration)``.

Runs the parts of the line the scene has — L (:mod:`folder_line.core.layup_sim`) and
F with D (:mod:`folder_line.core.folder_sim`) — on one master drive, and returns
(a) joint states sampled at the scene's rate, (b) the exact event list and (c) the
cyclogram constraints evaluated per cycle. Only the effects the scene lists run.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from folder_line.core.drive import Drive, build_drive
from folder_line.core.events import (
    EVENT_KINDS,
    ConstraintSeries,
    JointSamples,
    SubResult,
    merge_events,
)
from folder_line.core.scene import Scene
from folder_line.core.validate import in_range

__all__ = ['LineResult', 'make_drive', 'sample_times', 'simulate']

MAX_DURATION = 1e9  # s (~32 years): far beyond any run; time stays float64-exact to ~1e-7 s


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
        Node name -> joint states on the sample grid.
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
        return self.events[self.events['kind'] == EVENT_KINDS.index(kind)]

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
            violations += [{'cycle': int(c.cycle[i]), 'constraint': c.name, 'margin': float(c.margin[i]),
                            'unit': c.unit} for i in bad[:max_violations]]
            if c.margin.size:
                i = int(np.argmin(c.margin))
                min_margin[c.name] = {'margin': float(c.margin[i]), 'unit': c.unit, 'cycle': int(c.cycle[i]),
                                      'evaluations': int(c.margin.size), 'violations': int(bad.size)}
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
            'events': {k: int(n) for k, n in zip(EVENT_KINDS, np.bincount(self.events['kind'],
                                                                           minlength=len(EVENT_KINDS))) if n},
        }
        if 'v_tr_over_v_d' in folder:
            out['v_tr_over_v_d'] = folder['v_tr_over_v_d']
        for part, figures in self.parts.items():
            out[part] = figures
        if 'landing_cv' in layup:
            out['landing_cv'] = layup['landing_cv']
            out['landing_histogram'] = layup.get('landing_histogram')
        return out


def make_drive(scene: Scene, duration: float) -> Drive:
    """The master drive of a scene: the motor ODE if it lists ``motor_dynamics``."""
    if scene.has('motor_dynamics'):
        from folder_line.core.effects import motor_dynamics

        return motor_dynamics.build_drive(scene, duration)
    return build_drive(scene.drive)


def sample_times(duration: float, rate: float) -> np.ndarray:
    """The sample grid ``i / rate`` for i = 0 .. floor(duration·rate), s (empty if rate = 0)."""
    if rate <= 0.0:
        return np.zeros(0)
    n = int(math.floor(duration * rate * (1.0 + 1e-15))) + 1
    return np.arange(n, dtype=float) / rate


def _merge_samples(parts: list[SubResult]) -> dict[str, JointSamples]:
    merged: dict[str, JointSamples] = {}
    for part in parts:
        for node, js in part.samples.items():
            if node not in merged:
                merged[node] = js
                continue
            prev = merged[node]
            eff = None
            if prev.effort is not None or js.effort is not None:
                eff = np.hstack([prev.effort if prev.effort is not None else np.zeros_like(prev.position),
                                 js.effort if js.effort is not None else np.zeros_like(js.position)])
            merged[node] = JointSamples(node, prev.names + js.names, prev.t, np.hstack([prev.position, js.position]),
                                        np.hstack([prev.velocity, js.velocity]), eff)
    return merged


def simulate(scene: Scene, duration: float, *, sample_rate: float | None = None) -> LineResult:
    """Simulate ``duration`` seconds of line time.

    Parameters
    ----------
    scene : Scene
        Validated scene.
    duration : float
        Line time, s (> 0).
    sample_rate : float, optional
        Joint-state rate, Hz; default the scene's; 0 for events only.

    Returns
    -------
    LineResult
    """
    duration = in_range('duration', duration, 0.0, MAX_DURATION, lo_open=True)
    rate = scene.sample_rate if sample_rate is None else in_range('sample_rate', sample_rate, 0.0, 1e6)
    drive = make_drive(scene, duration)
    t = sample_times(duration, rate)
    parts: dict[str, SubResult] = {}
    if scene.has_folder:
        from folder_line.core.folder_sim import simulate_folder

        parts['folder'] = simulate_folder(scene, drive, duration, t)
    if scene.has_layup:
        from folder_line.core.layup_sim import simulate_layup

        parts['layup'] = simulate_layup(scene, drive, duration, t)
    results = list(parts.values())
    return LineResult(scene=scene, duration=duration,
                      events=merge_events(r.events for r in results),
                      samples=_merge_samples(results),
                      constraints=[c for r in results for c in r.constraints],
                      parts={name: r.summary for name, r in parts.items()})
