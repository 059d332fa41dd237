"""The sheet counter's table (folder_line.core.mechanisms.pile) against its closed form, alone and in the line model."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from folder_line.config.scenes import load_scene, scene_mapping
from folder_line.core.line.model import LineModel
from folder_line.core.line.scene import parse_scene
from folder_line.core.line.stream import UNITS
from folder_line.core.mechanisms.pile import T_LOWER, UNIT, PileTable, counted_event, pile_table
from folder_line.errors import ParameterError
from folder_line.interfaces import EVENT_KINDS

H = 0.0005  # m
TAU = 0.02  # s


def _settled(times: np.ndarray, tau: float, horizon: float) -> tuple[np.ndarray, np.ndarray]:
    """Times at which every lowering so far has ended and the next sheet has not come, and the sheets
    counted by then: midway between ``t_k + tau`` and ``t_{k+1}`` where that gap is open."""
    nxt = np.append(times[1:], horizon)
    mid = 0.5 * ((times + tau) + nxt)
    # open gaps only: a gap of an ulp or two rounds its midpoint onto one of its ends (hypothesis found
    # gaps equal to tau, where t_k + tau and t_{k+1} differ in the last bit)
    gap = (mid > times + tau) & (mid < nxt)
    return mid[gap], np.flatnonzero(gap) + 1


# ------------------------------------------------------------------ the closed form


def test_closed_form_by_hand() -> None:
    # a lone sheet, a double sheet (two at once), and a sheet arriving while the double still lowers
    table = PileTable('pile_table', np.array([0.1, 0.3, 0.3, 0.31]), H, TAU)
    t = np.array([0.0, 0.1, 0.105, 0.125, 0.2, 0.3, 0.305, 0.31, 0.315, 0.3225, 0.325, 0.335, 0.4])
    z, v = table.state(t)
    k = H / TAU  # m/s of one lowering
    assert_allclose(
        z,
        [0.0, 0.0, -0.25 * H, -H, -H, -H, -1.5 * H, -2.0 * H, -2.75 * H, -3.625 * H, -3.75 * H, -4 * H, -4 * H],
        rtol=1e-12,
        atol=1e-18,
    )
    assert_allclose(v, [0.0, -k, -k, 0.0, 0.0, -2 * k, -2 * k, -3 * k, -3 * k, -k, -k, 0.0, 0.0], rtol=1e-15)
    # at rest after n sheets: exactly -n h, bit for bit
    assert z[4] == -H * 1 and z[-1] == -H * 4 and z[0] == 0.0


def test_no_sheets_no_motion() -> None:
    z, v = PileTable('container_floor', np.zeros(0), H).state(np.linspace(0.0, 10.0, 11))
    assert np.all(z == 0.0) and np.all(v == 0.0)
    assert PileTable('pile_table', np.zeros(0), H).state(np.zeros(0))[0].shape == (0,)


@settings(max_examples=200, deadline=None)
@given(
    gaps=st.lists(st.sampled_from([0.0, 0.003, 0.011, 0.02, 0.035, 0.07, 0.5]), min_size=1, max_size=40),
    h=st.floats(1e-5, 0.01),
    tau=st.floats(1e-3, 0.1),
    start=st.floats(0.0, 1e5),
)
def test_properties(gaps: list[float], h: float, tau: float, start: float) -> None:
    times = start + np.cumsum(gaps)
    table = PileTable('pile_table', times, h, tau)
    horizon = float(times[-1]) + 2.0 * tau + 1.0
    t = np.sort(np.concatenate([np.linspace(start, horizon, 2001), times, times + tau, times + 0.5 * tau]))
    z, v = table.state(t)
    assert np.all(np.isfinite(z)) and np.all(np.isfinite(v))
    assert np.all(np.diff(z) <= 0.0)  # never rises, in floating point too
    started = np.searchsorted(times, t, side='right')
    done = np.searchsorted(times + tau, t, side='right')
    assert np.all(z <= -h * done) and np.all(z >= -h * started)  # between the sheets settled and the sheets come
    assert np.all(v == -(h / tau) * (started - done))
    ts, n = _settled(times, tau, horizon)
    zs, vs = table.state(ts)
    assert np.array_equal(zs, -h * n.astype(float)) and np.all(vs == 0.0)  # exactly -n h once settled
    assert table.state(np.array([horizon]))[0][0] == -h * times.size


def test_velocity_is_the_derivative() -> None:
    """ż is the right derivative: a forward difference over a step with no kink inside equals it, and the
    integral of ż is z."""
    times = np.array([0.05, 0.2, 0.205, 0.4, 0.4, 0.6])
    table = PileTable('container_floor', times, H, TAU)
    dt = 1e-4
    t = np.arange(0.0, 0.8, dt)
    z, v = table.state(t)
    z1, _ = table.state(t + dt)
    kinks = np.concatenate([times, times + TAU])
    smooth = ~np.any((kinks[None, :] > t[:, None] + 1e-12) & (kinks[None, :] < t[:, None] + dt - 1e-12), axis=1)
    assert np.count_nonzero(smooth) > 0.9 * t.size
    assert_allclose((z1 - z)[smooth] / dt, v[smooth], rtol=1e-6, atol=1e-9)
    fine = np.linspace(0.0, 0.8, 800_001)
    zf, vf = table.state(fine)
    integral = np.concatenate([[0.0], np.cumsum(0.5 * (vf[1:] + vf[:-1]) * np.diff(fine))])
    assert_allclose(integral, zf, atol=H * 1e-3)


def test_bad_input_is_refused() -> None:
    with pytest.raises(ParameterError, match='thickness'):
        PileTable('pile_table', np.zeros(1), 0.0)
    with pytest.raises(ParameterError, match='t_lower'):
        PileTable('pile_table', np.zeros(1), H, math.nan)
    with pytest.raises(ValueError, match='sorted'):
        PileTable('pile_table', np.array([1.0, 0.5]), H)
    with pytest.raises(ValueError, match='finite'):
        PileTable('pile_table', np.array([math.nan]), H)
    with pytest.raises(ValueError, match='finite'):
        PileTable('pile_table', np.array([1.0]), H).state(np.array([math.nan]))
    with pytest.raises(KeyError, match='counter'):
        PileTable('pile_table', np.array([1.0]), H).sample_unit('drive', np.array([1.0]))


# ------------------------------------------------------------------ in the line


@pytest.mark.parametrize(
    'name, joint, kind',
    [
        ('folder', 'pile_table', 'released_on_pile'),
        ('folder_faults', 'pile_table', 'released_on_pile'),
        ('layup', 'container_floor', 'leaf_landed'),
        ('layup_no_belts', 'container_floor', 'leaf_landed'),
        ('line', 'pile_table', 'released_on_pile'),
    ],
)
def test_the_line_lowers_one_thickness_per_counted_sheet(name: str, joint: str, kind: str) -> None:
    scene = load_scene(name)
    horizon = 30.0
    model = LineModel(scene, horizon)
    assert counted_event(scene.has_delivery) == kind
    assert model.units[UNIT] == (joint,) and list(model.units)[-1] == UNIT and UNIT in UNITS
    h = scene.sheets.thickness
    times = model.events['t'][model.events['kind'] == EVENT_KINDS.index(kind)]
    assert times.size > 100
    # between two sheets, once the table has settled: exactly -n h, at rest
    ts, n = _settled(times, T_LOWER, horizon)
    assert ts.size > 0.5 * times.size
    js = model.sample(UNIT, ts)
    assert js.names == (joint,) and js.effort is None
    assert np.array_equal(js.position[:, 0], -h * n.astype(float)) and np.all(js.velocity == 0.0)
    # on a node's grid: finite, non-increasing, between the settled and the arrived sheets
    t = np.arange(0.0, horizon, 1.0 / 200.0)
    js = model.sample(UNIT, t)
    z, v = js.position[:, 0], js.velocity[:, 0]
    assert np.all(np.isfinite(z)) and np.all(np.isfinite(v)) and np.all(np.diff(z) <= 0.0)
    counted = np.searchsorted(times, t, side='right')  # what the node counts at t
    assert np.all(z >= -h * counted) and np.all(z <= -h * np.searchsorted(times + T_LOWER, t, side='right'))
    assert np.all((v < 0.0) == (z > -h * counted))  # moving exactly while a sheet is not yet settled
    # a tick is the same as the grid, bit for bit
    i = np.random.default_rng(1).integers(0, t.size, 50)
    for k in i:
        one = model.sample(UNIT, np.array([t[k]]))
        assert one.position[0, 0] == z[k] and one.velocity[0, 0] == v[k]
    assert pile_table(scene.has_delivery, model.events, h).state(t)[0].tobytes() == z.tobytes()


def test_a_layup_without_flight_lands_nothing() -> None:
    data = scene_mapping('layup')
    del data['effects']['leaf_flight']  # unlisted: no leaf lands, the floor stays
    scene = parse_scene(data)
    model = LineModel(scene, 5.0)
    js = model.sample(UNIT, np.linspace(0.0, 5.0, 101))
    assert js.names == ('container_floor',) and np.all(js.position == 0.0) and np.all(js.velocity == 0.0)


def test_the_thickness_is_a_scene_key() -> None:
    assert load_scene('folder').sheets.thickness == 0.0005  # config/sheets.yaml
    assert load_scene('layup').sheets.thickness == 0.0003  # the scene's
    scene = load_scene('folder', {'sheets.thickness': 0.001})
    model = LineModel(scene, 3.0)
    n = int(np.count_nonzero(model.events['kind'] == EVENT_KINDS.index('released_on_pile')))
    assert model.sample(UNIT, np.array([3.0])).position[0, 0] == pytest.approx(-0.001 * n, rel=0.02)
    for bad in (0.0, -1e-4, 0.2, math.nan, math.inf, 'thin', True):
        with pytest.raises(ParameterError, match=r'sheets\.thickness'):
            load_scene('folder', {'sheets.thickness': bad})
