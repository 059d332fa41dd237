"""``solve``: conditions, ranges, and the boundary found by a scan and brentq (continuous and step metrics)."""

from __future__ import annotations

import pytest

from folder_line.config.scenes import scene_mapping
from folder_line.errors import ParameterError
from folder_line.studies.grid import parse_bounds
from folder_line.studies.runner import Cluster
from folder_line.studies.solve import Condition, parse_condition, solve_boundary

from ._closed_form import v_tr_min

ONE = Cluster(workers=1)


@pytest.mark.parametrize(
    ('text', 'expected'),
    [
        ('min_margin_s.feed_window>=0', Condition('min_margin_s.feed_window', '>=', 0.0)),
        (' V_tr_min <= 10.5 ', Condition('V_tr_min', '<=', 10.5)),
        ('violations.count<1', Condition('violations.count', '<', 1.0)),
        ('feed_window>-1e-3', Condition('feed_window', '>', -1e-3)),
    ],
)
def test_conditions_parse(text: str, expected: Condition) -> None:
    assert parse_condition(text) == expected


@pytest.mark.parametrize('text', ['feed_window', 'feed_window=0', 'feed_window>=', '>=0', 'a>=b', 'a>=inf', 'a=>0'])
def test_a_bad_condition_is_refused_naming_where(text: str) -> None:
    with pytest.raises(ParameterError, match=r'^--where='):
        parse_condition(text)


def test_conditions_hold_on_the_right_side_of_the_threshold() -> None:
    assert Condition('m', '>=', 0.0).holds(0.0) and not Condition('m', '>', 0.0).holds(0.0)
    assert Condition('m', '<=', 1.0).holds(1.0) and not Condition('m', '<', 1.0).holds(1.0)
    assert Condition('m', '<', 1.0).distance(0.25) == 0.75 and Condition('m', '>', 1.0).distance(0.25) == -0.75


def test_between() -> None:
    assert parse_bounds('5:15') == (5.0, 15.0)
    for bad in ('5', '5:x', '15:5', '5:5', '1:2:3', 'nan:1'):
        with pytest.raises(ParameterError, match=r'^--between='):
            parse_bounds(bad)


def test_a_step_metric_is_bracketed_to_the_tolerance() -> None:
    """violations.count jumps from 7 to 0 at V_tr,min (closed form): brentq's bisection steps close on the jump."""
    cond = parse_condition('violations.count<1')
    result = solve_boundary(
        scene_mapping('folder'), 'feed_transporter.V_tr', cond, 0.5, ONE, between=(5.0, 13.0), tol=1e-5, scan=5
    )
    assert result.holds == 'above' and result.bracket == (9.0, 11.0)
    assert abs(result.value - v_tr_min(50000.0)) <= 1e-5
    # 0.5 s: 7 knife cycles; too slow, every feed is late (and at 5 m/s the signature is not settled
    # before the knife either); at 13 m/s it rebounds too far: the first change, 9 -> 11, is the one solved
    assert [m for _, m in result.scan] == [21.0, 7.0, 7.0, 0.0, 7.0]
    assert 1 + 5 + 1 <= result.evaluations <= 1 + 5 + 40  # the scene, the scan, brentq's steps (its ends: the scan's)


def test_no_change_in_the_range_names_the_range_and_the_ends() -> None:
    with pytest.raises(ParameterError) as exc:
        solve_boundary(
            scene_mapping('folder'),
            'feed_transporter.V_tr',
            parse_condition('feed_window>=0'),
            0.2,
            ONE,
            between=(10.0, 20.0),
            scan=3,
        )
    text = str(exc.value)
    assert text.startswith("--between='10:20': min_margin_s.feed_window>=0 holds everywhere in the range")
    assert 'at 10 and' in text and 'at 20' in text


def test_no_default_range_around_zero() -> None:
    with pytest.raises(ParameterError, match=r'^--between=None: needed: the scene value of sheets.phase is 0.0'):
        solve_boundary(scene_mapping('folder'), 'sheets.phase', parse_condition('feed_window>=0'), 0.2, ONE)
