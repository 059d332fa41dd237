"""``--vary KEY=START:STOP:N`` and the grid of a sweep."""

from __future__ import annotations

import pytest

from folder_line.errors import ParameterError
from folder_line.studies.grid import MAX_POINTS, Vary, grid_points, parse_vary


def test_values_are_linear_with_both_ends() -> None:
    v = parse_vary('feed_transporter.V_tr=8:11:7')
    assert (v.key, v.n, v.whole) == ('feed_transporter.V_tr', 7, False)
    assert v.values == pytest.approx([8.0, 8.5, 9.0, 9.5, 10.0, 10.5, 11.0], abs=0.0)
    assert parse_vary('k.x=2.5:2.5:1').values == (2.5,)
    assert parse_vary('k.x=3:-3:3').values == (3.0, 0.0, -3.0)  # a falling range is kept in its order


def test_whole_numbers_stay_whole() -> None:
    v = parse_vary('container.bins=10:40:4')
    assert v.whole and v.values == (10, 20, 30, 40) and all(type(x) is int for x in v.values)
    assert parse_vary('container.bins=10:40:3').values == (10, 25, 40)  # a step of 15: still whole
    assert not parse_vary('container.bins=10:41:4').whole  # a step of 31/3
    assert not parse_vary('container.bins=10.0:40:4').whole  # written as a decimal
    assert not parse_vary('k.x=0:1:3').whole  # 0, 0.5, 1


@pytest.mark.parametrize(
    ('text', 'reason'),
    [
        ('feed_transporter.V_tr', 'must be KEY=START:STOP:N'),
        ('=1:2:3', 'must be KEY=START:STOP:N'),
        ('k.x=1:2', 'must be KEY=START:STOP:N'),
        ('k.x=1:2:3:4', 'must be KEY=START:STOP:N'),
        ('k.x=a:2:3', 'START and STOP must be numbers'),
        ('k.x=1:inf:3', 'must be finite'),
        ('k.x=nan:1:3', 'must be finite'),
        ('k.x=1:2:0', 'N must be a whole number in [1, 10000]'),
        ('k.x=1:2:2.5', 'N must be a whole number'),
        ('k.x=1:2:10001', 'N must be a whole number in [1, 10000]'),
        ('k.x=1:2:1', 'N=1 is one value'),
        ('k.x=1:1:3', 'START equals STOP'),
    ],
)
def test_bad_vary_is_one_line_naming_the_option_and_the_text(text: str, reason: str) -> None:
    with pytest.raises(ParameterError) as exc:
        parse_vary(text)
    message = str(exc.value)
    assert message.startswith(f'--vary={text!r}: ') and reason in message and '\n' not in message


def test_grid_is_the_product_first_key_slowest() -> None:
    a, b = Vary('s.a', 1.0, 2.0, 2), Vary('s.b', 10.0, 30.0, 3)
    assert grid_points([a, b]) == [
        {'s.a': 1.0, 's.b': 10.0},
        {'s.a': 1.0, 's.b': 20.0},
        {'s.a': 1.0, 's.b': 30.0},
        {'s.a': 2.0, 's.b': 10.0},
        {'s.a': 2.0, 's.b': 20.0},
        {'s.a': 2.0, 's.b': 30.0},
    ]


def test_grid_refuses_a_key_twice_and_too_many_points() -> None:
    with pytest.raises(ParameterError, match=r"^--vary='s.a': is varied twice"):
        grid_points([Vary('s.a', 1.0, 2.0, 2), Vary('s.a', 3.0, 4.0, 2)])
    big = [Vary(f's.k{i}', 0.0, 1.0, 1000) for i in range(3)]
    with pytest.raises(ParameterError, match=f'at most {MAX_POINTS}'):
        grid_points(big)
