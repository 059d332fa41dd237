"""How the text shows a margin (:mod:`folder_line.core.line.margin_text`): units, meanings, cycle or leaf."""

from __future__ import annotations

import pytest

from folder_line.config.scenes import load_scene
from folder_line.core.line.constraints import FOLDER_CONSTRAINTS, LAYUP_CONSTRAINTS, RELEASE_KV_TOL
from folder_line.core.line.margin_text import (
    CONSTRAINT_UNITS,
    MARGIN_LABELS,
    MARGIN_MEANINGS,
    PER_LEAF,
    best_possible,
    format_margin,
    margin_at,
    margin_constraint,
    margin_legend,
    margin_text,
    shown_unit,
)
from folder_line.core.line.model import simulate


@pytest.mark.parametrize(
    ('value', 'unit', 'constraint', 'text'),
    [
        (1e-4, 's', 'feed_window', '+0.1000 ms'),  # times in ms
        (-0.0049, 's', 'feed_window', '-4.9000 ms'),
        (0.000918875, 'm', 'rebound', '+0.9189 mm'),  # lengths in mm, never m beside ms
        (0.424586, 'm/s', 'chute_speed', '+0.4246 m/s'),  # speeds in m/s
        (1e-6, '1', 'release_at_min_speed', '+1e-06'),  # ratios plain
        (0.0, 'sheets', 'one_per_cycle', '1 sheet per cycle'),  # what 0 means, not '+0 sheets'
        (-1.0, 'sheets', 'one_per_cycle', '1 sheet off'),
        (-2.0, 'sheets', 'one_per_cycle', '2 sheets off'),
        (3e-9, 's', 'feed_window', '+3e-06 ms'),  # too small for 4 decimals: not '+0.0000 ms'
        (0.0, 's', 'feed_window', '+0.0000 ms'),
        (2.5, 'rev/h', '', '+2.5000 rev/h'),  # an unknown unit as it is
    ],
)
def test_each_unit_has_its_own_display(value: float, unit: str, constraint: str, text: str) -> None:
    assert format_margin(value, unit, constraint) == text


def test_short_and_significant_forms_for_figures() -> None:
    assert format_margin(1e-4, 's', 'feed_window', precision=3, fixed=False) == '+0.1 ms'
    assert format_margin(0.000918875, 'm', 'rebound', precision=3, fixed=False) == '+0.919 mm'
    assert format_margin(0.0, 'sheets', 'one_per_cycle', short=True) == '1 sheet'
    assert format_margin(-1.0, 'sheets', 'one_per_cycle', short=True) == '1 sheet off'


def test_shown_unit() -> None:
    assert shown_unit('s') == (1e3, 'ms')
    assert shown_unit('m') == (1e3, 'mm')
    assert shown_unit('m/s') == (1.0, 'm/s')
    assert shown_unit('1') == (1.0, '')
    assert shown_unit('N m') == (1.0, 'N m')


def test_best_possible_where_the_constraint_has_one() -> None:
    assert best_possible('one_per_cycle', 0.0) and not best_possible('one_per_cycle', -1.0)
    assert best_possible('release_at_min_speed', RELEASE_KV_TOL)
    assert not best_possible('release_at_min_speed', 0.5 * RELEASE_KV_TOL)
    assert not best_possible('feed_window', 1.0)  # more is better: no best
    assert margin_text(0.0, 'sheets', 'one_per_cycle') == '1 sheet per cycle (best possible)'
    assert margin_text(RELEASE_KV_TOL, '1', 'release_at_min_speed') == '+1e-06 (best possible)'
    assert margin_text(1e-4, 's', 'feed_window') == '+0.1000 ms'


def test_per_leaf_constraints_name_a_leaf() -> None:
    assert PER_LEAF == frozenset(LAYUP_CONSTRAINTS) == {'chute_speed'}
    assert margin_at('chute_speed', 448) == 'leaf 448'
    for name in FOLDER_CONSTRAINTS:
        assert margin_at(name, 13) == 'cycle 13'


def test_margin_constraint_of_a_metric_path() -> None:
    assert margin_constraint('min_margin.rebound.margin') == 'rebound'
    assert margin_constraint('min_margin_s.feed_window') == 'feed_window'
    assert margin_constraint('folder.knife_window_s') == ''


def test_the_tables_cover_every_constraint_with_the_units_the_constraints_report() -> None:
    """Every constraint the line evaluates has a unit, a label and a meaning here, and the unit is its own."""
    result = simulate(load_scene('line'), 2.0, sample_rate=0.0)
    seen = {c.name: c.unit for c in result.constraints}
    assert set(seen) == set(FOLDER_CONSTRAINTS) | set(LAYUP_CONSTRAINTS)
    assert seen == {name: CONSTRAINT_UNITS[name] for name in seen}
    assert set(CONSTRAINT_UNITS) == set(MARGIN_LABELS) == set(MARGIN_MEANINGS) == set(seen)


def test_legend_one_aligned_line_per_known_constraint() -> None:
    lines = margin_legend(['rebound', 'unknown', 'one_per_cycle'])
    assert lines == [
        f'  rebound        {MARGIN_MEANINGS["rebound"]}',
        f'  one_per_cycle  {MARGIN_MEANINGS["one_per_cycle"]}',
    ]
    assert 'best possible' in MARGIN_MEANINGS['one_per_cycle'] and 'per leaf' in MARGIN_MEANINGS['chute_speed']
