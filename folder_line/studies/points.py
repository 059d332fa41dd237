"""One point of a study: a scene with some keys set, simulated, reduced to the metrics asked for.

A :class:`PointTask` carries everything the point depends on -- the complete merged scene
mapping, the point's overrides, the line time and the metric paths -- so that a Dask worker
evaluates it alone (:func:`evaluate_point`, a module-level function) and the result never
depends on which worker ran it or when. A point whose values the model refuses (a
:class:`~folder_line.errors.ParameterError`, an :class:`~folder_line.errors.AssemblyError`:
a geometry that does not assemble, ...) is a result with no metric values and a status
saying why; it does not stop the study.

Monte Carlo (``--samples N``) expands a point into N seeded sample tasks of the same
mapping (:class:`PointSampleTask`, :func:`evaluate_point_sample`), one per sample.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from folder_line.config.scenes import SceneMapping, apply_overrides
from folder_line.core.line.line_summary import LineSummary
from folder_line.core.line.metrics import flatten_metrics, resolve_metric
from folder_line.core.line.model import run_summary
from folder_line.core.line.scene import parse_scene
from folder_line.errors import FolderLineError, ParameterError, shorten
from folder_line.studies.montecarlo import SampleResult, SampleTask, run_sample

__all__ = [
    'OK',
    'PointResult',
    'PointSampleTask',
    'PointTask',
    'default_metrics',
    'evaluate_point',
    'evaluate_point_sample',
    'point_source',
    'resolve_metrics',
    'simulate_summary',
]

#: status of a point the model evaluated
OK = 'ok'
#: longest status text kept in a table, characters
STATUS_CHARS = 300


@dataclass(frozen=True)
class PointTask:
    """Everything one point depends on (picklable: plain mappings, tuples and numbers).

    Attributes
    ----------
    source : mapping
        The complete scene mapping (:func:`folder_line.config.scenes.scene_mapping`), not yet validated.
    overrides : tuple of (str, float)
        The point's ``--set`` overrides, in the order of the varied keys.
    duration : float
        Line time simulated, s.
    metrics : tuple of str
        Metric paths into the summary (:func:`folder_line.core.line.metrics.flatten_metrics`).
    """

    source: Mapping[str, object]
    overrides: tuple[tuple[str, float | int], ...]
    duration: float
    metrics: tuple[str, ...]


@dataclass(frozen=True)
class PointResult:
    """The metrics at one point.

    Attributes
    ----------
    values : tuple of float or None
        One per metric of the task, in the metric's unit; None where the point was refused or the
        summary lacks the metric.
    status : str
        :data:`OK`, ``'refused: <reason>'`` (the model refused the point's values) or
        ``'missing: <metric>'`` (the summary at this point lacks a metric).
    """

    values: tuple[float | None, ...]
    status: str


def point_source(task: PointTask) -> SceneMapping:
    """The point's complete scene mapping: the task's mapping with its overrides applied."""
    return apply_overrides(task.source, dict(task.overrides))


def simulate_summary(source: Mapping[str, object], duration: float) -> LineSummary:
    """Parse a complete scene mapping, simulate ``duration`` s of line time and return the summary (its
    metrics: :func:`folder_line.core.line.metrics.flatten_metrics` of its ``as_json()``).

    The run is streamed (:func:`folder_line.core.line.model.run_summary`): its memory does not grow with
    ``duration`` (s), and the summary is ``simulate(...).summary()`` bit for bit.
    """
    return run_summary(parse_scene(source), duration)


def evaluate_point(task: PointTask) -> PointResult:
    """Simulate one point and pick its metrics (run on a Dask worker; module-level, so it pickles).

    Parameters
    ----------
    task : PointTask
        The scene, the point's overrides, the line time (s) and the metric paths.

    Returns
    -------
    PointResult
        The metric values (each in its own unit), or no values and the model's reason for refusing the point.
    """
    try:
        flat = flatten_metrics(simulate_summary(point_source(task), task.duration).as_json())
    except FolderLineError as exc:  # the model refuses the point's values: a row that says why
        return _refusal(exc, len(task.metrics))
    values = tuple(flat.get(m) for m in task.metrics)
    missing = [m for m, v in zip(task.metrics, values, strict=True) if v is None]
    return PointResult(values, OK if not missing else f'missing: {", ".join(missing)}')


def _refusal(exc: FolderLineError, metrics: int) -> PointResult:
    return PointResult((None,) * metrics, shorten(f'refused: {" ".join(str(exc).split())}', STATUS_CHARS))


@dataclass(frozen=True)
class PointSampleTask:
    """Monte Carlo sample ``index`` of a point (``sweep --samples``): the point's scene with the sample's seed."""

    point: PointTask
    index: int


def evaluate_point_sample(task: PointSampleTask) -> SampleResult | PointResult:
    """One Monte Carlo sample of a point (:func:`folder_line.studies.montecarlo.run_sample` of the point's
    scene), or the point's refusal as in :func:`evaluate_point` (module-level: it runs on a Dask worker)."""
    try:
        return run_sample(SampleTask(point_source(task.point), task.point.duration, task.index))
    except FolderLineError as exc:
        return _refusal(exc, len(task.point.metrics))


def default_metrics(flat: Mapping[str, float]) -> tuple[str, ...]:
    """The scene's constraint margins (``min_margin.<constraint>.margin``) and ``violations.count``."""
    margins = [p for p in flat if p.startswith('min_margin.') and p.endswith('.margin')]
    return (*margins, *(['violations.count'] if 'violations.count' in flat else []))


def resolve_metrics(names: Sequence[str], flat: Mapping[str, float], option: str = '--metric') -> tuple[str, ...]:
    """Each name resolved to its metric path (:func:`resolve_metric`); none given: :func:`default_metrics`.

    Raises
    ------
    ParameterError
        A name that is no metric of the scene, an ambiguous one or one given twice (naming ``option``).
    """
    if not names:
        return default_metrics(flat)
    paths = tuple(resolve_metric(n, list(flat), option) for n in names)
    for path in paths:
        if paths.count(path) > 1:
            raise ParameterError(option, path, 'is asked for twice')
    return paths
