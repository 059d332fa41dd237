"""The scenery (core/line/scenery.py): shapes well formed, key points on the closed forms, invariants."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from folder_line.config.scenes import load_scene
from folder_line.core.line.model import LineModel
from folder_line.core.line.scenery import FOLDER_ORIGIN, LAYUP_ORIGIN, PICKUP_DROP, Scenery, Shape
from folder_line.core.mechanisms import knife as knf
from folder_line.core.mechanisms.chain import chain_path, schedule
from folder_line.core.mechanisms.delivery_laws import LAWS
from folder_line.core.mechanisms.layup import layup_point
from folder_line.core.numerics.constants import G

KINDS = {'strip', 'segments', 'points', 'box'}


@pytest.fixture(scope='module')
def line() -> Scenery:
    return Scenery(LineModel(load_scene('line', {}), 6.0))


@pytest.fixture(scope='module')
def layup_no_belts() -> Scenery:
    return Scenery(LineModel(load_scene('layup_no_belts', {}), 4.0))


def _parts(shapes: tuple[Shape, ...]) -> list[tuple[str, str, str]]:
    return [(s.machine, s.part, s.kind) for s in shapes]


def _shape(shapes: tuple[Shape, ...], machine: str, part: str) -> Shape:
    (found,) = [s for s in shapes if (s.machine, s.part) == (machine, part)]
    return found


def _theta(sc: Scenery, t: float) -> float:
    return float(np.asarray(sc.line.drive.theta(np.array([t]))).reshape(-1)[0])


def test_shapes_are_well_formed_and_in_a_stable_order(line: Scenery) -> None:
    order = _parts(line.at(0.0))
    assert {m for m, _, _ in order} == {'layup', 'container', 'folder', 'delivery', 'pile'}
    for t in np.linspace(0.0, 6.0, 37):
        shapes = line.at(float(t))
        assert _parts(shapes) == order
        for s in shapes:
            assert s.kind in KINDS
            assert s.points.dtype == np.float64 and s.points.ndim == 2 and s.points.shape[1] == 3
            assert not s.points.flags.writeable
            assert np.all(np.isfinite(s.points)), (s.machine, s.part, t)
            assert all(0.0 <= c <= 1.0 for c in s.rgba) and s.width >= 0.0
            if s.kind == 'segments':
                assert s.points.shape[0] % 2 == 0
            if s.kind == 'box':
                assert s.points.shape == (2, 3) and np.all(s.points[0] <= s.points[1])
            if s.machine in {'layup', 'container'}:
                assert np.all(s.points[:, 0] < 2.0)  # the layup never reaches the folder's place
            else:
                assert np.all(s.points[:, 0] > 2.0)


def test_only_the_machines_of_the_scene(layup_no_belts: Scenery) -> None:
    shapes = layup_no_belts.at(1.0)
    assert {s.machine for s in shapes} == {'layup', 'container'}
    assert _shape(shapes, 'layup', 'belt_mark').points.shape == (0, 3)  # no belts to move
    assert set(layup_no_belts.vertices(1.0)) == {f'layup/{k}' for k in ('O1', 'O2', 'O3', 'A', 'B', 'C', 'E')}


def test_layup_vertices_and_links_are_the_closed_form_over_a_crank_turn(line: Scenery) -> None:
    lp = line.line.scene.machine('layup')
    ox, oy, oz = LAYUP_ORIGIN
    # a whole crank turn (2 s at 30 rev/min) once the motor has run up, at 97 stamps
    for t in np.linspace(4.0, 6.0, 97):
        theta = _theta(line, float(t))
        turns = theta * lp.n_kr / 60.0
        phi = 2.0 * math.pi * (turns - math.floor(turns))
        p = layup_point(lp, phi)
        xA, yA = lp.a + lp.R_kr * math.cos(phi), lp.b + lp.R_kr * math.sin(phi)
        r = lp.O2B / lp.l3
        want = {
            'O1': (lp.a, lp.b),
            'O2': (0.0, 0.0),
            'O3': (lp.O2O3, 0.0),
            'A': (xA, yA),
            'B': (p.xC * r, p.yC * r),
            'C': (p.xC, p.yC),
            'E': (p.xE, p.yE),
        }
        v = line.vertices(float(t))
        for name, (x, y) in want.items():
            assert_allclose(v[f'layup/{name}'], [x + ox, oy, y + oz], rtol=0, atol=1e-9, err_msg=name)
        links = _shape(line.at(float(t)), 'layup', 'link').points.reshape(5, 2, 3)
        lengths = np.linalg.norm(links[:, 1] - links[:, 0], axis=1)
        assert_allclose(lengths, [lp.R_kr, lp.l2, lp.l3, lp.l4, lp.l5], rtol=0, atol=1e-12)
        # B lies on chute 3 at O2B from O2
        assert_allclose(np.linalg.norm(v['layup/B'] - v['layup/O2']), lp.O2B, rtol=0, atol=1e-12)


def test_knife_is_the_closed_form(line: Scenery) -> None:
    kp = line.line.scene.machine('knife')
    omega_k = 2.0 * math.pi * kp.n_k / 3600.0
    for t in np.linspace(5.0, 5.072, 41):  # one knife cycle
        phi = float(np.mod(omega_k * _theta(line, float(t)), 2.0 * math.pi))
        tip = line.vertices(float(t))['folder/knife_tip']
        assert_allclose(
            tip, [FOLDER_ORIGIN[0], 0.0, FOLDER_ORIGIN[2] + kp.s_clear - knf.position(kp, phi)], rtol=0, atol=1e-9
        )
        pin = line.vertices(float(t))['folder/knife_pin']
        assert_allclose(np.linalg.norm(tip - pin), kp.L_k, rtol=0, atol=1e-12)  # the rod keeps its length


def test_carriages_lie_on_the_chain_path(line: Scenery) -> None:
    scene = line.line.scene
    sch, path = schedule(scene), chain_path(scene)
    chain = scene.machine('delivery_chain')
    dp = scene.machine('delivery')
    psi = LAWS[dp.law].psi
    x_p0, z0 = FOLDER_ORIGIN[0], FOLDER_ORIGIN[2] - PICKUP_DROP
    x_s0 = x_p0 + chain.L_transfer
    on_stroke = 0
    for t in np.linspace(5.0, 5.144, 73):
        theta = _theta(line, float(t))
        pins = [p for k, p in line.vertices(float(t)).items() if k.startswith('delivery/carriage_')]
        assert len(pins) >= 2
        # the carriage that entered the stroke last, from the schedule and the path
        a0, _ = sch.stroke_travel(np.array([theta]))
        u = float(path.position(np.array([min(max(float(a0[0]), 0.0), sch.S)]))[0])
        xi = 2.0 - u if u > 1.0 else u
        want = np.array([x_s0 + chain.x_max * u, 0.0, z0 + dp.Lambda * chain.x_max * float(psi(xi))])
        gaps = [float(np.linalg.norm(p - want)) for p in pins]
        if 0.0 <= float(a0[0]) <= sch.S:
            on_stroke += 1
            assert min(gaps) < 1e-9
        for p in pins:  # every pin on a piece of the drawn loop: transfer, stroke or the return
            if x_p0 - 1e-12 <= p[0] <= x_s0 and abs(p[2] - z0) < 1e-12:
                continue
            if x_s0 <= p[0] <= x_s0 + 2 * chain.x_max and p[2] >= z0 - 1e-12:
                uu = (p[0] - x_s0) / chain.x_max
                assert_allclose(p[2], z0 + dp.Lambda * chain.x_max * psi(2.0 - uu if uu > 1.0 else uu), atol=1e-9)
                continue
            assert p[2] < z0  # the return run is below the stroke
    assert on_stroke > 10


def test_carriages_are_a_pitch_apart_along_the_loop(line: Scenery) -> None:
    sch = schedule(line.line.scene)
    travel = line.carriage_travel(_theta(line, 5.0))
    gaps = np.mod(np.diff(np.sort(travel)), line.loop)
    assert_allclose(gaps, sch.pitch, rtol=1e-12)


def test_leaves_in_the_air_lie_on_their_flight_paths(line: Scenery) -> None:
    f = line.layup_part.flights_view()
    lp_floor = line.line.scene.machine('container').y_floor
    ox, _, oz = LAYUP_ORIGIN
    seen = 0
    for t in np.linspace(3.0, 6.0, 31):
        leaves = _shape(line.at(float(t)), 'layup', 'leaf').points
        air = (f['t_exit'] <= t) & (f['t_land'] > t)
        tau = t - f['t_exit'][air]
        x = f['x0'][air] + f['vx'][air] * tau  # drag 0: the parabola
        y = f['y0'][air] + f['vy'][air] * tau - 0.5 * G * tau * tau
        want = np.stack([x + ox, np.zeros_like(x), y + oz], axis=1)
        assert leaves.shape == want.shape
        assert_allclose(leaves, want, rtol=0, atol=1e-9)
        assert np.all(y >= lp_floor)
        seen += len(leaves)
    assert seen > 10


def test_the_pile_grows_with_the_sheets_counted(line: Scenery) -> None:
    early = _shape(line.at(1.0), 'pile', 'pile').points
    late = _shape(line.at(6.0), 'pile', 'pile').points
    assert late[1, 2] - late[0, 2] > early[1, 2] - early[0, 2]
