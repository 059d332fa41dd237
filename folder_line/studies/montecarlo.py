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

Bounded memory
--------------
A sample is streamed window by window (:class:`folder_line.core.line.stream.LineStream`,
:data:`~folder_line.core.line.model.WINDOW` s at a time): its summary is ``simulate(...).summary()`` bit
for bit, and of each constraint's margins it keeps the count, the violations, the extremes, the mean and the
sum of squared deviations of all of them (combined window by window, then sample by sample in
index order: Chan et al.'s pairwise update), and a uniform random sample of at most
:data:`MARGIN_SAMPLE` margins: each margin draws a random 64-bit key (from the sample's seed
and the constraint's name) and the margins with the smallest keys are kept ("bottom-k"
sampling). The pool of all samples keeps the :data:`MARGIN_SAMPLE` smallest keys of theirs,
which is a uniform sample of all the margins pooled, as the results come in. So the counts,
probabilities, extremes, mean and std are exact, and the quantiles and the histogram are those
of every margin while the pool holds at most :data:`MARGIN_SAMPLE` of them (the distribution
says ``method``: ``every margin``), else of the uniform sample (its ``kept`` margins; the 0 and
1 quantiles stay the exact extremes). Memory: :data:`MARGIN_SAMPLE` margins per constraint,
whatever the duration and the number of samples.
"""

from __future__ import annotations

import dataclasses
import math
import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from types import MappingProxyType
from typing import IO

import numpy as np

from folder_line.config.scenes import SceneMapping
from folder_line.core.line.metrics import flatten_metrics
from folder_line.core.line.model import WINDOW
from folder_line.core.line.scene import parse_scene
from folder_line.core.line.stream import LineStream
from folder_line.errors import ParameterError
from folder_line.studies.montecarlo_figures import (
    EVERY_MARGIN,
    Aggregate,
    ConstraintStats,
    MarginDistribution,
    MarginHistogram,
    MetricStats,
    MonteCarloResult,
    Proportion,
)
from folder_line.studies.runner import Cluster, for_each_result

__all__ = [
    'CONFIDENCE',
    'MARGIN_SAMPLE',
    'QUANTILES',
    'ConstraintSample',
    'MarginStream',
    'Pool',
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
#: margins kept per constraint, by a sample and by the pool: a uniform random sample beyond (module docstring)
MARGIN_SAMPLE = 100_000
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
    source : SceneMapping
        The complete merged scene mapping (:func:`folder_line.config.scenes.scene_mapping`,
        or ``dict(scene.source)``); parsed on the worker.
    duration : float
        Line time, s.
    index : int
        The sample's index (its seed is :func:`sample_seed` of the scene's seed and it).
    """

    source: SceneMapping
    duration: float
    index: int


@dataclass(frozen=True, eq=False)
class ConstraintSample:
    """One constraint in one sample: exact figures of all its margins, and a bounded sample of them.

    Attributes
    ----------
    unit : str
        Unit of the margins (``s``, ``m``, ``sheets``, ...).
    evaluations, violations : int
        Cycles (or leaves) judged, and those with a negative margin.
    margins : ndarray
        The margins kept, in the order judged: all of them if there are at most
        :data:`MARGIN_SAMPLE`, else a uniform random sample of that many (``unit``).
    keys : ndarray of uint64, optional
        The random key of each margin kept (the smallest keys are kept); default: one per
        margin from its position (``margins`` must then be all of them).
    low, high, mean, m2 : float, optional
        Smallest, largest, mean of all the margins and the sum of their squared deviations from
        the mean (``unit``, ``unit**2``); default: of ``margins``.
    """

    unit: str
    evaluations: int
    violations: int
    margins: np.ndarray
    keys: np.ndarray | None = None
    low: float = math.nan
    high: float = math.nan
    mean: float = math.nan
    m2: float = math.nan

    def __post_init__(self) -> None:
        m = np.asarray(self.margins, dtype=float)
        if self.keys is None:
            if m.size != self.evaluations:
                raise ValueError('ConstraintSample: without keys the margins must be all of them')
            object.__setattr__(self, 'keys', _position_keys(m.size))
        if math.isnan(self.mean):
            n = m.size
            object.__setattr__(self, 'low', float(m.min()) if n else math.inf)
            object.__setattr__(self, 'high', float(m.max()) if n else -math.inf)
            object.__setattr__(self, 'mean', float(m.mean()) if n else 0.0)
            object.__setattr__(self, 'm2', float(np.sum((m - m.mean()) ** 2)) if n else 0.0)

    @property
    def complete(self) -> bool:
        """Every margin is kept."""
        return int(self.margins.size) == self.evaluations


def _position_keys(n: int) -> np.ndarray:
    """Keys for margins all kept: a hash of their position (any keys serve: none is dropped)."""
    z = np.arange(n, dtype=np.uint64) + np.uint64(0x9E3779B97F4A7C15)
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    out: np.ndarray = z ^ (z >> np.uint64(31))
    return out


def _chan(a: tuple[int, float, float], b: tuple[int, float, float]) -> tuple[int, float, float]:
    """Count, mean and sum of squared deviations of two sets joined (Chan, Golub and LeVeque)."""
    na, ma, sa = a
    nb, mb, sb = b
    if nb == 0:
        return a
    if na == 0:
        return b
    n = na + nb
    delta = mb - ma
    return n, ma + delta * nb / n, sa + sb + delta * delta * na * nb / n


def _smallest(keys: np.ndarray, cap: int) -> np.ndarray:
    """Positions of the ``cap`` smallest keys, in their original order."""
    if keys.size <= cap:
        return np.arange(keys.size)
    return np.sort(np.argsort(keys, kind='stable')[:cap])


class MarginStream:
    """One constraint's margins of one sample, window by window, in bounded memory (module docstring).

    Parameters
    ----------
    unit : str
    seed : int
        The sample's seed: with the constraint's ``name`` it seeds the margins' random keys.
    name : str
    cap : int, optional
        Margins kept at most (default :data:`MARGIN_SAMPLE`).
    """

    def __init__(self, unit: str, seed: int, name: str, cap: int | None = None) -> None:
        self.unit, self.cap = unit, MARGIN_SAMPLE if cap is None else cap
        self.bits = np.random.default_rng([int(seed), zlib.crc32(name.encode())]).bit_generator
        self.keys = np.zeros(0, dtype=np.uint64)
        self.margins = np.zeros(0)
        self.moments: tuple[int, float, float] = (0, 0.0, 0.0)
        self.violations = 0
        self.low, self.high = math.inf, -math.inf

    def add(self, margins: np.ndarray) -> None:
        """The margins of a window, in the order judged."""
        m = np.asarray(margins, dtype=float).reshape(-1)
        if m.size == 0:
            return
        mean = float(m.mean())
        self.moments = _chan(self.moments, (int(m.size), mean, float(np.sum((m - mean) ** 2))))
        self.violations += int(np.count_nonzero(m < 0.0))
        self.low, self.high = min(self.low, float(m.min())), max(self.high, float(m.max()))
        keys = np.asarray(self.bits.random_raw(m.size), dtype=np.uint64)
        self.keys = np.concatenate((self.keys, keys))
        self.margins = np.concatenate((self.margins, m))
        if self.keys.size > 2 * self.cap:
            self._cut()

    def _cut(self) -> None:
        keep = _smallest(self.keys, self.cap)
        self.keys, self.margins = self.keys[keep], self.margins[keep]

    def done(self) -> ConstraintSample:
        """The sample's figures of this constraint."""
        self._cut()
        n, mean, m2 = self.moments
        return ConstraintSample(self.unit, n, self.violations, self.margins, self.keys, self.low, self.high, mean, m2)


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
    """Parse ``task.source`` once, give it the sample's seed, stream it (events only) and report.

    The run is streamed in windows of :data:`~folder_line.core.line.model.WINDOW` s (its summary is
    ``simulate(...).summary()`` bit for bit); each constraint's margins go through a :class:`MarginStream`.
    """
    scene = parse_scene(task.source)
    seed = sample_seed(scene.seed, task.index)
    scene = dataclasses.replace(scene, seed=seed, source=MappingProxyType({**scene.source, 'seed': seed}))
    stream = LineStream(scene)
    margins = {name: MarginStream(tl.unit, seed, name) for name, tl in stream.tallies.constraints.items()}
    k = 1
    while stream.t < task.duration:
        for rows in stream.advance(min(task.duration, k * WINDOW)).constraints:
            margins[rows.name].add(rows.margin)
        k += 1
    for rows in stream.finish():
        margins[rows.name].add(rows.margin)
    return SampleResult(
        task.index, seed, flatten_metrics(stream.summary().as_json()), {name: m.done() for name, m in margins.items()}
    )


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


def _proportion(k: int, n: int) -> Proportion:
    return Proportion(k / n if n else None, clopper_pearson(k, n), k, n)


@dataclass
class _Pooled:
    """One constraint over the samples pooled so far: bounded (the smallest keys), plus each sample's scalars."""

    unit: str
    keys: np.ndarray
    margins: np.ndarray
    complete: bool = True
    scalars: dict[int, tuple[int, int, float, float, float, float]] = dataclasses.field(default_factory=dict)


class Pool:
    """Samples pooled as they come, in any order, in bounded memory; :meth:`result` is :func:`aggregate`'s.

    Parameters
    ----------
    cap : int, optional
        Margins kept per constraint (default :data:`MARGIN_SAMPLE`).
    """

    def __init__(self, cap: int | None = None) -> None:
        self.cap = MARGIN_SAMPLE if cap is None else cap
        self.constraints: dict[str, _Pooled] = {}
        self.order: dict[str, int] = {}  # constraint -> (sample index, position) it was first seen at, for the order
        self.metrics: dict[int, dict[str, float]] = {}
        self.seeds: dict[int, int] = {}

    def add(self, r: SampleResult) -> None:
        """Pool one sample."""
        self.metrics[r.index] = r.metrics
        self.seeds[r.index] = r.seed
        for pos, (name, c) in enumerate(r.constraints.items()):
            where = r.index * 1_000_000 + pos
            if name not in self.order or where < self.order[name]:
                self.order[name] = where
            pooled = self.constraints.get(name)
            if pooled is None:
                pooled = self.constraints[name] = _Pooled(c.unit, np.zeros(0, dtype=np.uint64), np.zeros(0))
            pooled.scalars[r.index] = (c.evaluations, c.violations, c.low, c.high, c.mean, c.m2)
            pooled.complete = pooled.complete and c.complete
            assert c.keys is not None  # set by ConstraintSample
            keys = np.concatenate((pooled.keys, c.keys))
            margins = np.concatenate((pooled.margins, np.asarray(c.margins, dtype=float)))
            keep = _smallest(keys, self.cap)
            if keep.size < keys.size:
                pooled.complete = False
            pooled.keys, pooled.margins = keys[keep], margins[keep]

    def result(self) -> Aggregate:
        """The aggregate of the samples pooled (:func:`aggregate`)."""
        indices = sorted(self.metrics)
        constraints: dict[str, ConstraintStats] = {}
        for name in sorted(self.constraints, key=lambda n: self.order[n]):
            pooled = self.constraints[name]
            rows = [pooled.scalars[i] for i in indices if i in pooled.scalars]
            evaluations = sum(r[0] for r in rows)
            violations = sum(r[1] for r in rows)
            moments: tuple[int, float, float] = (0, 0.0, 0.0)
            for n, _, _, _, mean, m2 in rows:  # in index order: the same figures whatever the order of arrival
                moments = _chan(moments, (n, mean, m2))
            low = min((r[2] for r in rows if r[0]), default=math.inf)
            high = max((r[3] for r in rows if r[0]), default=-math.inf)
            constraints[name] = ConstraintStats(
                pooled.unit,
                _proportion(violations, evaluations),
                _proportion(sum(1 for r in rows if r[1] > 0), len(rows)),
                _distribution(pooled.margins, moments, low, high, pooled.complete),
            )
        paths: dict[str, list[float]] = {}
        for i in indices:
            for path, value in self.metrics[i].items():
                paths.setdefault(path, []).append(value)
        metrics = {
            path: MetricStats(
                float(np.mean(v)),
                float(np.std(v, ddof=1)) if len(v) > 1 else 0.0,
                float(np.min(v)),
                float(np.max(v)),
                len(v),
            )
            for path, v in paths.items()
            if all(math.isfinite(x) for x in v)
        }
        return Aggregate(
            len(indices),
            tuple(self.seeds[i] for i in indices),
            f'Clopper-Pearson (exact binomial), {CONFIDENCE:.0%}',
            constraints,
            metrics,
        )


def _distribution(
    kept: np.ndarray, moments: tuple[int, float, float], low: float, high: float, complete: bool
) -> MarginDistribution:
    """The margin distribution: count, mean, std, extremes exact; quantiles and histogram of the margins kept."""
    count, mean, m2 = moments
    if count == 0 or kept.size == 0:
        return MarginDistribution(0)
    lo, hi = low, high
    if hi - lo <= _FLAT_ULPS * float(np.spacing(max(abs(lo), abs(hi)))):
        # one value up to rounding (a constraint no variation reaches): one narrow band around it, as
        # HIST_BINS bins of a few ulps each cannot be told apart
        half = 1e-9 * max(abs(lo), 1.0)
        lo, hi = lo - half, lo + half
    counts, edges = np.histogram(kept, bins=HIST_BINS, range=(lo, hi))
    quantiles = {f'{q:g}': float(v) for q, v in zip(QUANTILES, np.quantile(kept, QUANTILES), strict=True)}
    quantiles['0'], quantiles['1'] = low, high  # exact, kept or not
    return MarginDistribution(
        count=int(count),
        kept=int(kept.size),
        method=EVERY_MARGIN
        if complete
        else f'a uniform random sample of {kept.size} of the {count} margins (those of the smallest random keys)',
        mean=float(mean),
        std=float(math.sqrt(m2 / (count - 1))) if count > 1 else 0.0,
        min=low,
        max=high,
        quantiles=quantiles,
        histogram=MarginHistogram(tuple(int(c) for c in counts), tuple(float(e) for e in edges)),
    )


def aggregate(results: Sequence[SampleResult]) -> Aggregate:
    """Pool samples into violation probabilities, margin distributions and metric statistics (:class:`Pool`).

    Parameters
    ----------
    results : sequence of SampleResult
        The samples (in any order: they are pooled by index order).

    Returns
    -------
    Aggregate
        ``samples``, ``seeds``, ``interval`` (how the intervals are made), ``constraints`` (per name:
        ``unit``, ``p_cycle`` and ``p_run`` each a :class:`~folder_line.studies.montecarlo_figures.Proportion`,
        ``margin`` the distribution) and ``metrics`` (per path: ``mean``, ``std``, ``min``, ``max``, ``n``);
        its ``as_json()`` is JSON-ready.
    """
    pool = Pool()
    for r in sorted(results, key=lambda r: r.index):
        pool.add(r)
    return pool.result()


def monte_carlo(
    source: SceneMapping, duration: float, samples: int, cluster: Cluster, progress: IO[str] | None = None
) -> MonteCarloResult:
    """Run ``samples`` seeds of a scene on a Dask cluster and :func:`aggregate` them.

    Parameters
    ----------
    source : SceneMapping
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
    MonteCarloResult
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
    pool = Pool()
    for_each_result(run_sample, tasks, cluster, lambda _, r: pool.add(r), label='samples', progress=progress)
    return MonteCarloResult(scene.name, scene.seed, float(duration), pool.result())
