"""The dyad kernel against a closed form, and its float, array and in-place forms against each other."""

from __future__ import annotations

import math

import numpy as np
import pytest

from folder_line.core.numerics.dyad import DyadLinks, heron, heron_into, joint, joint_into


def test_a_3_4_5_triangle_closes_where_the_closed_form_says() -> None:
    links = DyadLinks(3.0, 4.0)
    e = heron(25.0, links.plus2, links.minus2)
    assert e == 576.0  # (7² - 5²)(5² - 1²) = 24²: 16 × the area² (area 6)
    assert e * links.norm**2 == 1.0  # a right angle at the joint: sin² μ = 1
    assert joint(5.0, 0.0, 25.0, math.sqrt(e), links.half_diff) == pytest.approx((1.8, 2.4), rel=1e-15)
    assert joint(5.0, 0.0, 25.0, -math.sqrt(e), links.half_diff) == pytest.approx((1.8, -2.4), rel=1e-15)


def test_the_joint_closes_both_links_and_e_is_sin_squared_of_the_angle_at_the_joint() -> None:
    rng = np.random.default_rng(3)
    links = DyadLinks(0.7, 0.45)
    angle = rng.uniform(-math.pi, math.pi, 1000)
    dist = rng.uniform(0.26, 1.14, 1000)  # between |r0 - r1| and r0 + r1
    px, py = dist * np.cos(angle), dist * np.sin(angle)
    d2 = px * px + py * py
    e = heron(d2, links.plus2, links.minus2)
    x, y = joint(px, py, d2, np.sqrt(e), links.half_diff)
    np.testing.assert_allclose(np.hypot(x, y), 0.7, rtol=1e-12)
    np.testing.assert_allclose(np.hypot(px - x, py - y), 0.45, rtol=1e-12)
    assert np.all(px * y - py * x > 0.0)  # s > 0: the joint to the left of pivot -> P
    sin_mu = (x * (py - y) - y * (px - x)) / (0.7 * 0.45)  # (X - pivot) × (P - X) / (r0 r1)
    np.testing.assert_allclose(e * links.norm**2, sin_mu**2, rtol=1e-9, atol=1e-12)


def test_the_float_the_array_and_the_in_place_forms_give_the_same_bits() -> None:
    rng = np.random.default_rng(5)
    links = DyadLinks(1.3, 0.9)
    px, py = rng.uniform(0.5, 1.5, 500), rng.uniform(-0.8, 0.8, 500)
    d2, e, tmp = np.empty(500), np.empty(500), np.empty(500)
    heron_into(px, py, links.plus2, links.minus2, d2, e, tmp)
    np.testing.assert_array_equal(d2, px * px + py * py)
    np.testing.assert_array_equal(e, heron(px * px + py * py, links.plus2, links.minus2))
    s = np.sqrt(np.maximum(e, 0.0))
    x, y = joint(px, py, d2, s, links.half_diff)
    ox, oy, k1 = np.empty(500), np.empty(500), np.empty(500)
    joint_into(px, py, d2.copy(), s, links.half_diff, ox, oy, k1, tmp)
    np.testing.assert_array_equal(ox, x)
    np.testing.assert_array_equal(oy, y)
    one = [
        joint(float(a), float(b), float(c), float(d), links.half_diff) for a, b, c, d in zip(px, py, d2, s, strict=True)
    ]
    np.testing.assert_array_equal(np.array(one), np.column_stack((x, y)))
