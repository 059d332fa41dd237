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
from folder_line.core.line.model import simulate
from folder_line.core.line.scene import parse_scene
from folder_line.studies.montecarlo import (
    ConstraintSample,
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
    assert got.metrics['violations.count'] == direct.summary()['violations']['count']


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
    w = out['constraints']['w']
    assert w['p_cycle']['k'] == 2 and w['p_cycle']['n'] == 7 and w['p_cycle']['p'] == pytest.approx(2 / 7)
    assert w['p_run']['k'] == 1 and w['p_run']['n'] == 2
    assert w['margin']['quantiles']['0.5'] == 1.0 and w['margin']['quantiles']['0'] == -2.0
    assert sum(w['margin']['histogram']['counts']) == 7
    assert out['metrics']['x'] == {'mean': 0.5, 'std': pytest.approx(2**-0.5), 'min': 0.0, 'max': 1.0, 'n': 2}
    json.dumps(out)  # JSON-ready


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
    p = out['constraints']['feed_window']['p_cycle']
    expected = float(norm.cdf(-margin_mm / sigma))
    assert p['n'] == SAMPLES * cycles
    lo, hi = p['ci95']
    assert lo <= expected <= hi
    assert hi - lo < 0.5 * expected  # tight enough to mean something
    assert out['constraints']['feed_window']['margin']['std'] > 0.0


def test_one_or_two_workers_give_identical_aggregates() -> None:
    source = _jitter_source(1.0)
    one = monte_carlo(source, 2.0, 8, Cluster(workers=1))
    two = monte_carlo(source, 2.0, 8, Cluster(workers=2))
    assert json.dumps(one) == json.dumps(two)


def test_margins_equal_up_to_rounding_make_one_narrow_band() -> None:
    """On ``folder`` without variation, settled_before_knife's margins differ only by rounding (1e-17 s):
    the distribution is one value, not an error."""
    results = [run_sample(SampleTask(scene_mapping('folder'), 0.5, i)) for i in range(2)]
    spread = results[0].constraints['settled_before_knife'].margins
    assert 0.0 < np.ptp(spread) < 1e-12  # the case this guards
    margin = aggregate(results)['constraints']['settled_before_knife']['margin']
    counts, edges = margin['histogram']['counts'], margin['histogram']['edges']
    assert sum(counts) == margin['count'] and np.all(np.diff(edges) > 0)
    assert edges[0] <= margin['quantiles']['0'] and margin['quantiles']['1'] <= edges[-1]
