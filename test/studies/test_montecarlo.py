"""Monte Carlo: seeds per sample, exact binomial intervals, and the issue's proof.

Proof (issue #13): with Gaussian arrival jitter on ``folder``, where the feed window
binds (margin +0.1 ms = 0.93 mm of belt travel at 9.3 m/s), a signature is late iff its
offset exceeds the margin in mm, so the Monte Carlo violation probability per cycle must
match Φ(-margin/σ) within its 95 % interval, at two values of σ. The margin comes from
the nominal run (no jitter), Φ from scipy.stats: both independent of the Monte Carlo code.
"""

from __future__ import annotations

import copy
import json
from typing import Any

import numpy as np
import pytest
from scipy.stats import binomtest, norm

from folder_line.config.scenes import scene_mapping
from folder_line.core.line.metrics import flatten_metrics
from folder_line.core.line.model import simulate
from folder_line.core.line.scene import parse_scene
from folder_line.studies.montecarlo import (
    ConstraintSample,
    MarginStream,
    Pool,
    SampleResult,
    SampleTask,
    aggregate,
    clopper_pearson,
    monte_carlo,
    run_sample,
    sample_seed,
)
from folder_line.studies.runner import Cluster

DURATION = 5.0  # 69 knife cycles per run at 50000 rev/h
SAMPLES = 60


def _jitter_source(sigma: float) -> dict[str, Any]:
    data = copy.deepcopy(scene_mapping('folder'))
    data['effects']['arrival_jitter'] = {'distribution': 'normal', 'sigma': sigma}
    return data


def test_sample_seeds_are_a_pure_function_of_seed_and_index() -> None:
    seeds = [sample_seed(1, i) for i in range(1000)]
    assert len(set(seeds)) == 1000 and all(0 <= s < 2**63 for s in seeds)
    assert seeds == [sample_seed(1, i) for i in range(1000)]
    assert sample_seed(2, 0) != sample_seed(1, 0) and sample_seed(1, 0) != 1


def test_a_sample_is_the_scene_with_its_own_seed() -> None:
    source = _jitter_source(1.0)
    got = run_sample(SampleTask(source, 2.0, 3))
    direct = simulate(parse_scene({**source, 'seed': sample_seed(1, 3)}), 2.0)
    fw = direct.constraint('feed_window')
    assert got.seed == sample_seed(1, 3)
    assert np.array_equal(got.constraints['feed_window'].margins, fw.margin)
    assert got.constraints['feed_window'].violations == int(np.count_nonzero(fw.violated))
    assert got.metrics['violations.count'] == direct.summary().violations.count


@pytest.mark.parametrize(('k', 'n'), [(0, 10), (3, 10), (10, 10), (83, 2760), (1, 1)])
def test_clopper_pearson_matches_scipy_exact_binomial(k: int, n: int) -> None:
    ci = binomtest(k, n).proportion_ci(confidence_level=0.95, method='exact')
    assert clopper_pearson(k, n) == pytest.approx((ci.low, ci.high), abs=1e-12)


def test_aggregate_pools_cycles_and_runs() -> None:
    def sample(i: int, margins: list[float]) -> SampleResult:
        m = np.array(margins)
        c = ConstraintSample('s', m.size, int(np.count_nonzero(m < 0.0)), m)
        return SampleResult(i, i, {'x': float(i)}, {'w': c})

    out = aggregate([sample(1, [0.5, 1.0, 2.0]), sample(0, [-1.0, 1.0, 3.0, -2.0])])
    w = out.constraints['w']
    assert w.p_cycle.k == 2 and w.p_cycle.n == 7 and w.p_cycle.p == pytest.approx(2 / 7)
    assert w.p_run.k == 1 and w.p_run.n == 2
    assert w.margin.quantiles['0.5'] == 1.0 and w.margin.quantiles['0'] == -2.0
    assert sum(w.margin.histogram.counts) == 7 == w.margin.kept == w.margin.count
    assert w.margin.method == 'every margin'
    assert w.margin.mean == pytest.approx(np.mean([0.5, 1.0, 2.0, -1.0, 1.0, 3.0, -2.0]), rel=1e-15)
    assert w.margin.std == pytest.approx(np.std([0.5, 1.0, 2.0, -1.0, 1.0, 3.0, -2.0], ddof=1), rel=1e-15)
    x = out.metrics['x']
    assert (x.mean, x.std, x.min, x.max, x.n) == (0.5, pytest.approx(2**-0.5), 0.0, 1.0, 2)
    json.dumps(out.as_json())  # JSON-ready


@pytest.fixture(scope='module')
def nominal() -> tuple[float, int]:
    """The nominal feed-window margin converted to mm of belt travel (every cycle has it, to rounding),
    and the cycles judged per run."""
    fw = simulate(parse_scene(scene_mapping('folder')), DURATION).constraint('feed_window')
    assert np.ptp(fw.margin) < 1e-15 and 0.05e-3 < fw.margin[0] < 0.2e-3  # it binds: +0.1 ms
    V_tr = parse_scene(scene_mapping('folder')).machine('feed_transporter').V_tr
    return float(np.mean(fw.margin)) * V_tr * 1e3, int(fw.margin.size)


@pytest.mark.parametrize('sigma', [0.5, 1.0])
def test_violation_probability_is_phi_of_minus_margin_over_sigma(nominal: tuple[float, int], sigma: float) -> None:
    margin_mm, cycles = nominal
    out = monte_carlo(_jitter_source(sigma), DURATION, SAMPLES, Cluster(workers=2))
    p = out.aggregate.constraints['feed_window'].p_cycle
    expected = float(norm.cdf(-margin_mm / sigma))
    assert p.n == SAMPLES * cycles
    lo, hi = p.ci95
    assert lo <= expected <= hi
    assert hi - lo < 0.5 * expected  # tight enough to mean something
    assert out.aggregate.constraints['feed_window'].margin.std > 0.0


def test_one_or_two_workers_give_identical_aggregates() -> None:
    source = _jitter_source(1.0)
    one = monte_carlo(source, 2.0, 8, Cluster(workers=1))
    two = monte_carlo(source, 2.0, 8, Cluster(workers=2))
    assert json.dumps(one.as_json()) == json.dumps(two.as_json())


def test_margins_equal_up_to_rounding_make_one_narrow_band() -> None:
    """On ``folder`` without variation, settled_before_knife's margins differ only by rounding (1e-17 s):
    the distribution is one value, not an error."""
    results = [run_sample(SampleTask(scene_mapping('folder'), 0.5, i)) for i in range(2)]
    spread = results[0].constraints['settled_before_knife'].margins
    assert 0.0 < np.ptp(spread) < 1e-12  # the case this guards
    margin = aggregate(results).constraints['settled_before_knife'].margin
    counts, edges = margin.histogram.counts, margin.histogram.edges
    assert sum(counts) == margin.count and np.all(np.diff(edges) > 0)
    assert edges[0] <= margin.quantiles['0'] and margin.quantiles['1'] <= edges[-1]


# --------------------------------------------------------------------------- bounded memory


def test_a_sample_keeps_a_bounded_uniform_sample_of_its_margins_and_exact_figures() -> None:
    rng = np.random.default_rng(7)
    margins = rng.normal(1.0, 0.5, 10_000)
    one = MarginStream('s', 5, 'feed_window', cap=300)
    one.add(margins)
    cut = MarginStream('s', 5, 'feed_window', cap=300)
    for part in np.array_split(margins, 37):  # windows cut anywhere: the same keys, the same sample
        cut.add(part)
    a, b = one.done(), cut.done()
    assert np.array_equal(a.margins, b.margins) and np.array_equal(a.keys, b.keys)
    assert a.margins.size == 300 and not a.complete
    assert (a.evaluations, a.violations) == (10_000, int(np.count_nonzero(margins < 0)))
    assert (a.low, a.high) == (margins.min(), margins.max())
    assert a.mean == pytest.approx(margins.mean(), rel=1e-12)
    assert a.m2 == pytest.approx(np.sum((margins - margins.mean()) ** 2), rel=1e-10)
    assert set(a.margins.tolist()) <= set(margins.tolist())
    order = np.searchsorted(np.sort(margins), a.margins)  # a uniform sample: its ranks spread over the whole
    assert 0.35 < np.median(order) / margins.size < 0.65
    assert MarginStream('s', 6, 'feed_window', cap=300).bits is not None  # another seed, other keys
    other = MarginStream('s', 6, 'feed_window', cap=300)
    other.add(margins)
    assert not np.array_equal(other.done().margins, a.margins)


def test_the_pool_is_a_uniform_sample_of_every_margin_whatever_the_order_of_arrival() -> None:
    rng = np.random.default_rng(3)

    def sample(i: int) -> SampleResult:
        m = MarginStream('s', i, 'w', cap=500)
        m.add(rng.normal(0.2 * i, 1.0, 2000))
        return SampleResult(i, i, {'x': float(i)}, {'w': m.done()})

    results = [sample(i) for i in range(6)]
    forward, backward = Pool(cap=500), Pool(cap=500)
    for r in results:
        forward.add(r)
    for r in reversed(results):
        backward.add(r)
    a, b = forward.result(), backward.result()
    assert json.dumps(a.as_json()) == json.dumps(b.as_json())
    margin = a.constraints['w'].margin
    assert margin.count == 12_000 and margin.kept == 500 and margin.method.startswith('a uniform random')
    assert sum(margin.histogram.counts) == 500
    assert margin.quantiles['0'] == margin.min == min(r.constraints['w'].low for r in results)
    assert margin.quantiles['1'] == margin.max
    everything = np.concatenate([r.constraints['w'].margins for r in results])
    assert margin.mean == pytest.approx(np.mean([r.constraints['w'].mean for r in results]), rel=1e-12)
    assert abs(margin.quantiles['0.5'] - np.median(everything)) < 0.2  # the median of a uniform sample of 500


def test_a_long_sample_keeps_a_bounded_number_of_margins(monkeypatch: pytest.MonkeyPatch) -> None:
    import folder_line.studies.montecarlo as mc

    monkeypatch.setattr(mc, 'MARGIN_SAMPLE', 100)
    monkeypatch.setattr(mc, 'WINDOW', 5.0)
    got = run_sample(SampleTask(_jitter_source(1.0), 30.0, 2))
    direct = simulate(parse_scene({**_jitter_source(1.0), 'seed': sample_seed(1, 2)}), 30.0)
    fw = direct.constraint('feed_window')
    c = got.constraints['feed_window']
    assert c.margins.size == 100 < c.evaluations == fw.margin.size
    assert c.violations == int(np.count_nonzero(fw.violated)) and (c.low, c.high) == (fw.margin.min(), fw.margin.max())
    assert got.metrics == flatten_metrics(direct.summary().as_json())  # the streamed summary: bit for bit
