"""``folder-line sweep``: metrics of a scene over a grid of key values, one simulation per point, on Dask.

:func:`plan_sweep` checks everything before any work: every varied key against the scene
(:func:`folder_line.studies.keys.check_key`), the scene's own point (simulated once here:
it gives the metrics' paths and units, and a scene the model refuses is refused now), and
the metric names (:func:`folder_line.studies.points.resolve_metrics`). :func:`run_sweep`
maps :func:`folder_line.studies.points.evaluate_point` over one task per point
(:func:`folder_line.studies.runner.run_tasks`); :func:`sweep_columns` makes the table of
``sweep.csv``: one column per varied key, one per metric, and ``status``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import IO

from folder_line.config.scenes import SceneMapping
from folder_line.core.line.metric_units import metric_unit
from folder_line.core.line.metrics import flatten_metrics
from folder_line.studies.grid import Vary, grid_points
from folder_line.studies.keys import check_key, key_unit, scene_value
from folder_line.studies.montecarlo import Pool, SampleResult
from folder_line.studies.montecarlo_figures import ConstraintStats
from folder_line.studies.paper import paper_point
from folder_line.studies.points import (
    OK,
    PointResult,
    PointSampleTask,
    PointTask,
    evaluate_point,
    evaluate_point_sample,
    resolve_metrics,
    simulate_summary,
)
from folder_line.studies.runner import Cluster, for_each_result, run_tasks

__all__ = [
    'PROBABILITY_COLUMNS',
    'STATUS',
    'SweepPlan',
    'SweepResult',
    'plan_sweep',
    'run_sweep',
    'sweep_columns',
    'sweep_document',
]

#: the status column of ``sweep.csv``
STATUS = 'status'


@dataclass(frozen=True)
class SweepPlan:
    """A checked sweep, ready to run.

    Attributes
    ----------
    scene : str
        The scene's name.
    source : SceneMapping
        The complete scene mapping (the ``--set`` overrides applied).
    duration : float
        Line time per point, s.
    varies : tuple of Vary
        The varied keys and their values.
    points : tuple of dict
        Every point's key values, the first key slowest.
    metrics : tuple of str
        Metric paths.
    units : mapping of str to str
        Unit of each varied key and each metric ('' for counts and ratios).
    scene_point : dict of str to object
        The scene's own values of the varied keys (None where not known).
    scene_metrics : tuple of float or None
        The metrics at the scene's own point.
    paper_point : dict or None
        The papers' values of the varied keys, when every key has one (:mod:`folder_line.studies.paper`).
    samples : int or None
        Monte Carlo samples per point (None: one run with the scene's seed). With samples, a point's metric
        is its mean over the samples, and every constraint gets its violation probability.
    """

    scene: str
    source: SceneMapping
    duration: float
    varies: tuple[Vary, ...]
    points: tuple[dict[str, float | int], ...]
    metrics: tuple[str, ...]
    units: Mapping[str, str]
    scene_point: dict[str, object]
    scene_metrics: tuple[float | None, ...]
    paper_point: dict[str, float] | None
    samples: int | None = None

    @property
    def keys(self) -> tuple[str, ...]:
        """The varied keys, in the order given."""
        return tuple(v.key for v in self.varies)

    def tasks(self) -> list[PointTask]:
        """One task per point, in the order of :attr:`points`."""
        return [PointTask(self.source, tuple(p.items()), self.duration, self.metrics) for p in self.points]


@dataclass(frozen=True)
class SweepResult:
    """A sweep and its results, one per point in the order of ``plan.points``.

    Attributes
    ----------
    plan : SweepPlan
    results : tuple of PointResult
        The metrics at each point (with samples: their means).
    monte_carlo : tuple of (dict of str to ConstraintStats or None) or None
        With ``plan.samples``: per point, :func:`folder_line.studies.montecarlo.aggregate`'s ``constraints``
        (None where the model refused the point).
    """

    plan: SweepPlan
    results: tuple[PointResult, ...]
    monte_carlo: tuple[dict[str, ConstraintStats] | None, ...] | None = None

    @property
    def refused(self) -> int:
        """Points the model refused (or whose summary lacked a metric)."""
        return sum(r.status != OK for r in self.results)


def plan_sweep(
    source: SceneMapping,
    varies: Sequence[Vary],
    metric_names: Sequence[str],
    duration: float,
    samples: int | None = None,
) -> SweepPlan:
    """Check a sweep before any work.

    Parameters
    ----------
    source : mapping
        The complete scene mapping, ``--set`` applied (:func:`folder_line.config.scenes.scene_mapping`).
    varies : sequence of Vary
        The varied keys (at least one).
    metric_names : sequence of str
        Metric paths or unique suffixes (``--metric``); empty: the constraint margins and ``violations.count``.
    duration : float
        Line time per point, s.
    samples : int, optional
        Monte Carlo samples per point (:attr:`SweepPlan.samples`).

    Returns
    -------
    SweepPlan

    Raises
    ------
    ParameterError, AssemblyError
        A key the scene does not have, a key varied twice, too many points, an unknown or ambiguous
        metric, or a scene the model refuses at its own values.
    """
    varies = tuple(varies)
    for vary in varies:
        check_key(source, vary.key, '--vary')
    points = tuple(grid_points(varies))
    summary = simulate_summary(source, duration).as_json()
    flat = flatten_metrics(summary)
    metrics = resolve_metrics(metric_names, flat)
    keys = tuple(v.key for v in varies)
    units = {**{k: key_unit(source, k) for k in keys}, **{m: metric_unit(m, summary) for m in metrics}}
    return SweepPlan(
        scene=str(source.get('name', '')),
        source=source,
        duration=duration,
        varies=varies,
        points=points,
        metrics=metrics,
        units=units,
        scene_point={k: scene_value(source, k) for k in keys},
        scene_metrics=tuple(flat.get(m) for m in metrics),
        paper_point=paper_point(keys),
        samples=samples,
    )


def run_sweep(plan: SweepPlan, cluster: Cluster, progress: IO[str] | None = None) -> SweepResult:
    """Evaluate every point of ``plan`` on ``cluster`` (a progress bar on ``progress``).

    With ``plan.samples`` every (point, sample) pair is one task, all in one fan-out; each point's samples
    are pooled as they come (:class:`folder_line.studies.montecarlo.Pool`, bounded memory).
    """
    if plan.samples is None:
        results = run_tasks(evaluate_point, plan.tasks(), cluster, label='sweep', progress=progress)
        return SweepResult(plan, tuple(results))
    n = plan.samples
    tasks = [PointSampleTask(point, i) for point in plan.tasks() for i in range(n)]
    pools = [Pool() for _ in plan.points]  # each point's samples pooled as they come: bounded memory
    refusals: dict[int, tuple[int, PointResult]] = {}  # point -> its first refused sample (index, refusal)

    def take(i: int, r: SampleResult | PointResult) -> None:
        k = i // n
        if isinstance(r, PointResult):
            if k not in refusals or i < refusals[k][0]:
                refusals[k] = (i, r)
            return
        pools[k].add(r)

    for_each_result(evaluate_point_sample, tasks, cluster, take, label='sweep samples', progress=progress)
    points: list[PointResult] = []
    pooled: list[dict[str, ConstraintStats] | None] = []
    for k in range(len(plan.points)):
        if k in refusals:
            points.append(refusals[k][1])
            pooled.append(None)
            continue
        agg = pools[k].result()
        means = tuple(agg.metrics[m].mean if m in agg.metrics else None for m in plan.metrics)
        missing = [m for m, v in zip(plan.metrics, means, strict=True) if v is None]
        points.append(PointResult(means, OK if not missing else f'missing: {", ".join(missing)}'))
        pooled.append(agg.constraints)
    return SweepResult(plan, tuple(points), tuple(pooled))


#: columns of a constraint's violation probability per cycle (``sweep --samples``): p and its 95 % interval
PROBABILITY_COLUMNS = ('p_violation', 'p_violation_lo', 'p_violation_hi')


def sweep_columns(result: SweepResult) -> dict[str, list[float | int | str | None]]:
    """The table of ``sweep.csv``: each varied key, each metric (empty where refused), ``status``."""
    plan = result.plan
    columns: dict[str, list[float | int | str | None]] = {k: [p[k] for p in plan.points] for k in plan.keys}
    for i, metric in enumerate(plan.metrics):
        columns[metric] = [r.values[i] for r in result.results]
    if result.monte_carlo is not None:
        names: list[str] = []
        for pooled in result.monte_carlo:
            names += [c for c in pooled or {} if c not in names]
        for c in names:
            cells = [None if p is None or c not in p else p[c].p_cycle for p in result.monte_carlo]
            columns[f'{PROBABILITY_COLUMNS[0]}.{c}'] = [None if x is None else x.p for x in cells]
            columns[f'{PROBABILITY_COLUMNS[1]}.{c}'] = [None if x is None else x.ci95[0] for x in cells]
            columns[f'{PROBABILITY_COLUMNS[2]}.{c}'] = [None if x is None else x.ci95[1] for x in cells]
    columns[STATUS] = [r.status for r in result.results]
    return columns


def sweep_document(result: SweepResult, command: str, files: Sequence[str]) -> dict[str, object]:
    """``sweep.json``: the command, the scene, the keys and metrics with their units, the marked points."""
    plan = result.plan
    return {
        'command': command,
        'scene': plan.scene,
        'duration_s': plan.duration,
        'points': len(plan.points),
        'samples': plan.samples,
        'statistic': 'value of one run' if plan.samples is None else f'mean over {plan.samples} samples',
        'refused': result.refused,
        'keys': [
            {
                'key': v.key,
                'unit': plan.units[v.key],
                'start': v.start,
                'stop': v.stop,
                'n': v.n,
                'scene_value': plan.scene_point[v.key],
                'paper_value': None if plan.paper_point is None else plan.paper_point[v.key],
            }
            for v in plan.varies
        ],
        'metrics': [
            {'metric': m, 'unit': plan.units[m], 'at_scene_point': plan.scene_metrics[i]}
            for i, m in enumerate(plan.metrics)
        ],
        'files': list(files),
    }
