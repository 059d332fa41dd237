"""What a Monte Carlo gives (:func:`folder_line.studies.montecarlo.aggregate`, ``simulate --samples --json``).

Per constraint a :class:`ConstraintStats` (the violation probabilities per cycle and per run, each a
:class:`Proportion`, and the :class:`MarginDistribution`), per metric a :class:`MetricStats`, pooled
into an :class:`Aggregate`; :class:`MonteCarloResult` names the scene it was run on. ``as_json()`` gives
the JSON document, keys in the order written.
"""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = [
    'EVERY_MARGIN',
    'Aggregate',
    'ConstraintStats',
    'MarginDistribution',
    'MarginHistogram',
    'MetricStats',
    'MonteCarloResult',
    'Proportion',
]

#: :attr:`MarginDistribution.method` when the figures are of every margin (not of a uniform sample)
EVERY_MARGIN = 'every margin'


@dataclass(frozen=True)
class Proportion:
    """``k`` of ``n`` trials: the share ``p`` (None for n = 0) and its 95 % interval ``ci95`` (lo, hi)."""

    p: float | None
    ci95: tuple[float, float]
    k: int
    n: int

    def as_json(self) -> dict[str, object]:
        """``{'p', 'ci95', 'k', 'n'}``."""
        return {'p': self.p, 'ci95': list(self.ci95), 'k': self.k, 'n': self.n}


@dataclass(frozen=True)
class MarginHistogram:
    """Margins per bin (``counts``) between the bins' ``edges`` (one more than the bins, the margin's unit)."""

    counts: tuple[int, ...]
    edges: tuple[float, ...]

    def as_json(self) -> dict[str, object]:
        """``{'counts', 'edges'}``."""
        return {'counts': list(self.counts), 'edges': list(self.edges)}


@dataclass(frozen=True)
class MarginDistribution:
    """A constraint's margins over the samples, in its unit; ``count`` 0: none (the other fields unset).

    Attributes
    ----------
    count : int
        Margins in all (exact).
    kept : int
        Margins the quantiles and the histogram are of.
    method : str
        :data:`EVERY_MARGIN`, or which uniform sample was ``kept``.
    mean, std, min, max : float
        Of every margin (exact; ``std`` with ddof 1).
    quantiles : dict of str to float
        Quantile (``'0.5'``) -> margin; ``'0'`` and ``'1'`` are the exact extremes.
    histogram : MarginHistogram
    """

    count: int
    kept: int = 0
    method: str = EVERY_MARGIN
    mean: float = 0.0
    std: float = 0.0
    min: float = 0.0
    max: float = 0.0
    quantiles: dict[str, float] = field(default_factory=dict)
    histogram: MarginHistogram = MarginHistogram((), ())

    def as_json(self) -> dict[str, object]:
        """``{'count': 0}``, or ``{'count', 'kept', 'method', 'mean', 'std', 'min', 'max', 'quantiles',
        'histogram'}``."""
        if not self.count:
            return {'count': 0}
        return {
            'count': self.count,
            'kept': self.kept,
            'method': self.method,
            'mean': self.mean,
            'std': self.std,
            'min': self.min,
            'max': self.max,
            'quantiles': dict(self.quantiles),
            'histogram': self.histogram.as_json(),
        }


@dataclass(frozen=True)
class ConstraintStats:
    """One constraint over the samples: its ``unit``, the share of violated cycles (``p_cycle``) and of runs
    with a violation (``p_run``), and its ``margin`` distribution."""

    unit: str
    p_cycle: Proportion
    p_run: Proportion
    margin: MarginDistribution

    def as_json(self) -> dict[str, object]:
        """``{'unit', 'p_cycle', 'p_run', 'margin'}``."""
        return {
            'unit': self.unit,
            'p_cycle': self.p_cycle.as_json(),
            'p_run': self.p_run.as_json(),
            'margin': self.margin.as_json(),
        }


@dataclass(frozen=True)
class MetricStats:
    """One metric over the ``n`` samples, in its unit: ``mean``, ``std`` (ddof 1; 0 for one sample), ``min``,
    ``max``."""

    mean: float
    std: float
    min: float
    max: float
    n: int

    def as_json(self) -> dict[str, object]:
        """``{'mean', 'std', 'min', 'max', 'n'}``."""
        return {'mean': self.mean, 'std': self.std, 'min': self.min, 'max': self.max, 'n': self.n}


@dataclass(frozen=True)
class Aggregate:
    """Samples pooled (:func:`folder_line.studies.montecarlo.aggregate`).

    Attributes
    ----------
    samples : int
    seeds : tuple of int
        Each sample's seed, by index.
    interval : str
        How the intervals are made.
    constraints : dict of str to ConstraintStats
        In the model's order.
    metrics : dict of str to MetricStats
        Per metric path (those finite in every sample).
    """

    samples: int
    seeds: tuple[int, ...]
    interval: str
    constraints: dict[str, ConstraintStats]
    metrics: dict[str, MetricStats]

    def as_json(self) -> dict[str, object]:
        """``{'samples', 'seeds', 'interval', 'constraints', 'metrics'}``."""
        return {
            'samples': self.samples,
            'seeds': list(self.seeds),
            'interval': self.interval,
            'constraints': {name: c.as_json() for name, c in self.constraints.items()},
            'metrics': {path: m.as_json() for path, m in self.metrics.items()},
        }


@dataclass(frozen=True)
class MonteCarloResult:
    """A Monte Carlo of a scene (:func:`folder_line.studies.montecarlo.monte_carlo`): its ``scene`` name and
    ``seed``, the line time of each sample ``duration_s`` (s), and the :class:`Aggregate`."""

    scene: str
    seed: int
    duration_s: float
    aggregate: Aggregate

    def as_json(self) -> dict[str, object]:
        """``{'scene', 'seed', 'duration_s'}`` and the aggregate's keys (``simulate --samples --json``)."""
        return {'scene': self.scene, 'seed': self.seed, 'duration_s': self.duration_s, **self.aggregate.as_json()}
