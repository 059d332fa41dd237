"""The layup geometry optimiser: bounds, the staged evaluation, determinism, the verdict."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import pytest

from folder_line.config.scenes import scene_mapping
from folder_line.errors import ParameterError
from folder_line.studies.optimize import (
    DEFAULT_KEYS,
    Bound,
    OptimizeSettings,
    default_bounds,
    evaluate,
    optimize_layup,
    parse_design_vary,
)
from folder_line.studies.optimize_output import histogram_lines, result_document, verdict

FAST = OptimizeSettings(duration=60.0, maxiter=2, popsize=3)


@pytest.fixture(scope='module')
def layup() -> dict[str, Any]:
    return scene_mapping('layup')


def test_parse_design_vary_reads_bounds() -> None:
    assert parse_design_vary(['layup.l4=0.55:0.7', 'layup.a=-0.7:-0.5']) == (
        Bound('l4', 0.55, 0.7),
        Bound('a', -0.7, -0.5),
    )


@pytest.mark.parametrize(
    ('item', 'why'),
    [
        ('l4=0.5:0.7', 'layup.KEY=LO:HI'),
        ('layup.l4=0.5', 'layup.KEY=LO:HI'),
        ('layup.n_kr=20:40', 'not a link'),
        ('layup.l4=0.7:0.5', 'LO < HI'),
        ('layup.l4=x:0.5', 'not a number'),
        ('layup.l4=nan:0.5', 'finite'),
        ('layup.l4=-0.1:0.5', '> 0'),
    ],
)
def test_parse_design_vary_refuses_naming_the_option(item: str, why: str) -> None:
    with pytest.raises(ParameterError, match=why) as exc:
        parse_design_vary([item])
    assert str(exc.value).startswith('--vary=')


def test_parse_design_vary_refuses_a_key_twice() -> None:
    with pytest.raises(ParameterError, match='twice'):
        parse_design_vary(['layup.l4=0.5:0.7', 'layup.l4=0.6:0.8'])


def test_default_bounds_are_the_scene_values_plus_minus_the_span(layup: dict[str, Any]) -> None:
    bounds = default_bounds(layup['machines']['layup'], span=0.1)
    assert [b.key for b in bounds] == list(DEFAULT_KEYS)
    for b in bounds:
        v = layup['machines']['layup'][b.key]
        assert (b.lo, b.hi) == pytest.approx((0.9 * v, 1.1 * v), rel=1e-15)


@pytest.mark.parametrize(
    ('values', 'broken'),
    [
        ({'R_kr': 0.3}, 'crank_rocker'),  # the crank is no longer the shortest link
        ({'l4': 0.6, 'l5': 0.6}, 'assembly'),  # loop 2 opens for part of the turn
        ({'O2O3': 1.1, 'l4': 0.8}, 'transmission_deg'),  # loop 2 closes, but μ2 drops to 25°
        ({'O2O3': 0.9, 'l4': 0.9}, 'exits_right'),  # chute 4 swings over the right wall
        ({'l3': 1.4, 'l5': 1.35, 'l4': 0.62}, 'exits_floor'),  # the chutes reach below the floor
    ],
)
def test_a_candidate_breaking_a_geometric_constraint_is_not_simulated(
    layup: dict[str, Any], values: dict[str, float], broken: str
) -> None:
    cand = evaluate(layup, values, FAST)
    assert cand.constraints[broken] < 0.0
    assert not cand.geometry_ok and cand.summary is None and not cand.feasible
    assert cand.objective == math.inf


def test_the_scene_geometry_is_feasible_and_simulated(layup: dict[str, Any]) -> None:
    cand = evaluate(layup, {}, FAST)
    assert cand.geometry_ok and cand.feasible
    assert all(v >= 0.0 for v in cand.constraints.values())
    assert cand.landing_cv == cand.summary.layup.landing.histogram.cv  # type: ignore[union-attr]
    # 40° is far from the shipped geometry's smallest transmission angles (68.4° and 67.1°)
    assert cand.constraints['transmission_deg'] == pytest.approx(min(cand.transmission_deg.values()) - 40.0)  # type: ignore[type-var]


def test_a_spilling_geometry_is_simulated_and_penalised(layup: dict[str, Any]) -> None:
    # faster belts throw the leaves of chute 4 over the right wall: the geometry is fine, the leaves are not
    fast = dict(layup, machines=dict(layup['machines'], layup=dict(layup['machines']['layup'], v_tr=4.4)))
    cand = evaluate(fast, {}, FAST)
    assert cand.geometry_ok and cand.summary is not None
    spilled = cand.summary.layup.leaves_spilled + cand.summary.layup.leaves_damaged  # type: ignore[union-attr]
    assert spilled > 0 and cand.constraints['no_spill_or_damage'] == -spilled
    assert not cand.feasible and cand.objective > 10.0


def test_optimize_is_deterministic_and_never_worse_than_the_start(layup: dict[str, Any]) -> None:
    bounds = default_bounds(layup['machines']['layup'], ('l4', 'O2O3'), 0.1)
    one = optimize_layup(layup, bounds, FAST)
    two = optimize_layup(layup, bounds, FAST)
    assert one.best.values == two.best.values and one.evaluations == two.evaluations
    assert one.start.feasible and one.best.feasible
    assert one.best.landing_cv <= one.start.landing_cv  # type: ignore[operator]
    doc = result_document(one)
    assert doc['best']['values'] == one.best.values and doc['optimizer']['seed'] == FAST.seed
    assert len(histogram_lines(one)) == 1 + len(doc['start']['landing_histogram']['counts'])


def test_the_verdict_says_when_the_start_is_not_beaten(layup: dict[str, Any]) -> None:
    bounds = default_bounds(layup['machines']['layup'], ('l4',), 0.1)
    res = optimize_layup(layup, bounds, FAST)
    unbeaten = dataclasses.replace(res, best=res.start)
    text = verdict(unbeaten)
    assert text.startswith('the start geometry could not be beaten')
    assert f'{res.start.landing_cv:.4f}' in text and 'candidates' in text


def test_a_scene_without_landing_is_refused() -> None:
    with pytest.raises(ParameterError, match='leaf_flight'):
        optimize_layup(scene_mapping('folder'), (Bound('l4', 0.5, 0.7),), FAST)
