"""Monte Carlo over a scene's variation effects: many seeds, one table of probabilities.

A scene that lists variation effects (``arrival_jitter``, ``length_scatter``,
``speed_ripple``, ``property_scatter``, ``faults``: :mod:`folder_line.core.effects`)
draws them from its seed. Sample ``i`` of a scene seeded ``s`` is the same scene with
the seed :func:`sample_seed` ``(s, i)``; :func:`run_sample` simulates it (a module-level
function of a picklable :class:`SampleTask`, for :func:`folder_line.studies.runner.run_tasks`),
and :func:`aggregate` pools the samples into, per constraint:

* ``p_cycle``: the share of evaluated cycles (pooled over all samples) with a negative
  margin, with its 95 % **Clopper–Pearson** (exact binomial) interval;
* ``p_run``: the share of samples with at least one violation, with its interval;
* the margin distribution: quantiles, mean, std and a histogram, in the constraint's unit;

and, per metric (:func:`folder_line.core.line.metrics.flatten_metrics` of the summary),
mean, std, min and max over the samples. The pooled interval treats the cycles as
independent trials, which they are for per-sheet draws (``arrival_jitter``,
``length_scatter``, ``property_scatter``, sheet faults); with a per-run draw
(``speed_ripple``'s phase) or belt slow-downs the cycles of a run are correlated, and
``p_run`` is the honest figure.

Every sample carries its whole scene and its index, so the aggregate depends only on
the scene, the duration and the number of samples: not on the workers or their order.
"""

from __future__ import annotations

import dataclasses
import math
import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from types import MappingProxyType
from typing import IO, Any

import numpy as np

from folder_line.core.line.metrics import flatten_metrics
from folder_line.core.line.model import simulate
from folder_line.core.line.scene import parse_scene
from folder_line.errors import ParameterError
from folder_line.studies.runner import Cluster, run_tasks

__all__ = [
    'CONFIDENCE',
    'QUANTILES',
    'ConstraintSample',
    'SampleResult',
    'SampleTask',
    'aggregate',
    'clopper_pearson',
    'monte_carlo',
    'run_sample',
    'sample_seed',
]

#: confidence of every interval
CONFIDENCE = 0.95
#: quantiles of the margin distribution reported
QUANTILES = (0.0, 0.001, 0.01, 0.05, 0.25, 0.5, 0.75, 0.95, 0.99, 0.999, 1.0)
#: bins of the margin histogram
HIST_BINS = 30
#: a spread of margins within this many ulps is one value (its histogram is one narrow band)
_FLAT_ULPS = 1024
#: most samples of one Monte Carlo
MAX_SAMPLES = 1_000_000
_SALT = zlib.crc32(b'folder_line.studies.montecarlo')


def sample_seed(seed: int, index: int) -> int:
    """The seed of sample ``index`` of a scene seeded ``seed``, in [0, 2**63).

    ``SeedSequence([seed, index, salt])``'s first 64 bits with the top bit cleared: a
    pure function of (seed, index), so sample i is the same run on any worker. Sample 0
    is *not* the scene's own run (its seed differs from ``seed``).

    Parameters
    ----------
    seed : int
        The scene's seed (>= 0).
    index : int
        The sample's index (>= 0).
    """
    if seed < 0 or index < 0:
        raise ParameterError('seed' if seed < 0 else 'index', seed if seed < 0 else index, 'must be >= 0')
    state = np.random.SeedSequence([int(seed), int(index), _SALT]).generate_state(1, dtype=np.uint64)
    return int(state[0]) & (2**63 - 1)


@dataclass(frozen=True)
class SampleTask:
    """One Monte Carlo sample to run (picklable: plain data only).

    Attributes
    ----------
    source : dict
        The complete merged scene mapping (:func:`folder_line.config.scenes.scene_mapping`,
        or ``dict(scene.source)``); parsed on the worker.
    duration : float
        Line time, s.
    index : int
        The sample's index (its seed is :func:`sample_seed` of the scene's seed and it).
    """

    source: dict[str, Any]
    duration: float
    index: int


@dataclass(frozen=True, eq=False)
class ConstraintSample:
    """One constraint in one sample.

    Attributes
    ----------
    unit : str
        Unit of the margins (``s``, ``m``, ``sheets``, ...).
    evaluations, violations : int
        Cycles (or leaves) judged, and those with a negative margin.
    margins : ndarray
        The margin of every judged cycle, in ``unit``.
    """

    unit: str
    evaluations: int
    violations: int
    margins: np.ndarray


@dataclass(frozen=True, eq=False)
class SampleResult:
    """What one sample gives :func:`aggregate`.

    Attributes
    ----------
    index, seed : int
        The sample's index and the seed it ran with.
    metrics : dict of str to float
        :func:`folder_line.core.line.metrics.flatten_metrics` of its summary.
    constraints : dict of str to ConstraintSample
        Per constraint, in the model's order.
    """

    index: int
    seed: int
    metrics: dict[str, float]
    constraints: dict[str, ConstraintSample]


def run_sample(task: SampleTask) -> SampleResult:
    """Parse ``task.source`` once, give it the sample's seed, simulate (events only) and report."""
    scene = parse_scene(task.source)
    seed = sample_seed(scene.seed, task.index)
    scene = dataclasses.replace(scene, seed=seed, source=MappingProxyType({**scene.source, 'seed': seed}))
    result = simulate(scene, task.duration, sample_rate=0.0)
    constraints = {
        c.name: ConstraintSample(
            c.unit, int(c.margin.size), int(np.count_nonzero(c.violated)), np.asarray(c.margin, dtype=float)
        )
        for c in result.constraints
    }
    return SampleResult(task.index, seed, flatten_metrics(result.summary()), constraints)


def clopper_pearson(k: int, n: int, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """Exact (Clopper–Pearson) interval of a binomial proportion: ``k`` successes in ``n`` trials.

    ``[B⁻¹(α/2; k, n-k+1), B⁻¹(1-α/2; k+1, n-k)]`` with ``α = 1 - confidence`` (0 and 1 at
    the ends k = 0 and k = n); ``(0, 1)`` for n = 0.
    """
    if n <= 0:
        return 0.0, 1.0
    a = 1.0 - confidence
    from scipy.special import betaincinv

    lo = 0.0 if k == 0 else float(betaincinv(k, n - k + 1, a / 2.0))
    hi = 1.0 if k == n else float(betaincinv(k + 1, n - k, 1.0 - a / 2.0))
    return lo, hi


def _proportion(k: int, n: int) -> dict[str, Any]:
    lo, hi = clopper_pearson(k, n)
    return {'p': k / n if n else None, 'ci95': [lo, hi], 'k': k, 'n': n}


def _distribution(margins: np.ndarray) -> dict[str, Any]:
    if margins.size == 0:
        return {'count': 0}
    lo, hi = float(margins.min()), float(margins.max())
    if hi - lo <= _FLAT_ULPS * float(np.spacing(max(abs(lo), abs(hi)))):
        # one value up to rounding (a constraint no variation reaches): one narrow band around it, as
        # HIST_BINS bins of a few ulps each cannot be told apart
        half = 1e-9 * max(abs(lo), 1.0)
        lo, hi = lo - half, lo + half
    counts, edges = np.histogram(margins, bins=HIST_BINS, range=(lo, hi))
    return {
        'count': int(margins.size),
        'mean': float(margins.mean()),
        'std': float(margins.std(ddof=1)) if margins.size > 1 else 0.0,
        'quantiles': {f'{q:g}': float(v) for q, v in zip(QUANTILES, np.quantile(margins, QUANTILES), strict=True)},
        'histogram': {'counts': [int(c) for c in counts], 'edges': [float(e) for e in edges]},
    }


def aggregate(results: Sequence[SampleResult]) -> dict[str, Any]:
    """Pool samples into violation probabilities, margin distributions and metric statistics.

    Parameters
    ----------
    results : sequence of SampleResult
        The samples (in any order: they are pooled by index order).

    Returns
    -------
    dict
        JSON-ready: ``samples``, ``interval`` (how the intervals are made), ``constraints``
        (per name: ``unit``, ``p_cycle`` and ``p_run`` each ``{p, ci95, k, n}``, ``margin``
        the distribution) and ``metrics`` (per path: ``mean``, ``std``, ``min``, ``max``, ``n``).
    """
    ordered = sorted(results, key=lambda r: r.index)
    names: dict[str, str] = {}
    for r in ordered:
        for name, c in r.constraints.items():
            names.setdefault(name, c.unit)
    constraints: dict[str, Any] = {}
    for name, unit in names.items():
        present = [r.constraints[name] for r in ordered if name in r.constraints]
        evaluations = sum(c.evaluations for c in present)
        violations = sum(c.violations for c in present)
        runs_bad = sum(1 for c in present if c.violations > 0)
        margins = np.concatenate([c.margins for c in present]) if present else np.zeros(0)
        constraints[name] = {
            'unit': unit,
            'p_cycle': _proportion(violations, evaluations),
            'p_run': _proportion(runs_bad, len(present)),
            'margin': _distribution(margins),
        }
    paths: dict[str, list[float]] = {}
    for r in ordered:
        for path, value in r.metrics.items():
            paths.setdefault(path, []).append(value)
    metrics = {
        path: {
            'mean': float(np.mean(v)),
            'std': float(np.std(v, ddof=1)) if len(v) > 1 else 0.0,
            'min': float(np.min(v)),
            'max': float(np.max(v)),
            'n': len(v),
        }
        for path, v in paths.items()
        if all(math.isfinite(x) for x in v)
    }
    return {
        'samples': len(ordered),
        'seeds': [r.seed for r in ordered],
        'interval': f'Clopper-Pearson (exact binomial), {CONFIDENCE:.0%}',
        'constraints': constraints,
        'metrics': metrics,
    }


def monte_carlo(
    source: dict[str, Any], duration: float, samples: int, cluster: Cluster, progress: IO[str] | None = None
) -> dict[str, Any]:
    """Run ``samples`` seeds of a scene on a Dask cluster and :func:`aggregate` them.

    Parameters
    ----------
    source : dict
        Complete merged scene mapping (picklable; :class:`SampleTask`).
    duration : float
        Line time of each sample, s.
    samples : int
        How many (1 .. :data:`MAX_SAMPLES`).
    cluster : Cluster
        Where they run (:class:`folder_line.studies.runner.Cluster`).
    progress : text stream, optional
        Where the progress bar goes (None: nowhere).

    Returns
    -------
    dict
        :func:`aggregate`'s, with ``scene``, ``seed`` (the scene's) and ``duration_s``.

    Raises
    ------
    ParameterError
        ``--samples`` out of range, or the scene is invalid (parsed here once, before any work).
    """
    if isinstance(samples, bool) or not isinstance(samples, int) or not 1 <= samples <= MAX_SAMPLES:
        raise ParameterError('--samples', samples, f'must be a whole number in [1, {MAX_SAMPLES}]')
    scene = parse_scene(source)
    plain = dict(source)
    tasks = [SampleTask(plain, float(duration), i) for i in range(samples)]
    results = run_tasks(run_sample, tasks, cluster, label='samples', progress=progress)
    out = {'scene': scene.name, 'seed': scene.seed, 'duration_s': float(duration)}
    out.update(aggregate(results))
    return out
