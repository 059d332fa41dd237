"""``/line/markers`` in a recorded bag is the machine of the core's closed forms (issue 15, proof 1).

A live ``run`` of ``line`` (the layup, the folder and the delivery; 3 s from standstill, over a
whole crank turn of the layup) with ``--marker-rate 50`` and ``simulate --bag`` of the same run
are read with the independent reader (``mcap`` + ``mcap_ros2``, not ``folder_line.bag``). At every
marker stamp the pivots and link ends of the six-bar, the knife tip and the carriage on the
stroke equal, to 1e-9 m, positions computed here from the mechanisms' closed forms
(``layup_point``, ``knife.position``, the chain schedule and path) at the drive phase of the
same stamp -- not from :mod:`folder_line.core.line.scenery`, whose layout constants (where each
machine sits in frame ``line``) are the only thing taken from it.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from folder_line.cli.main import main
from folder_line.config.scenes import load_scene
from folder_line.core.line.drives import make_drive
from folder_line.core.line.model import LineModel
from folder_line.core.line.scenery import FOLDER_ORIGIN, LAYUP_ORIGIN, LINE_FRAME, PICKUP_DROP, Scenery
from folder_line.core.mechanisms import knife as knf
from folder_line.core.mechanisms.chain import chain_path, schedule
from folder_line.core.mechanisms.delivery_laws import LAWS
from folder_line.core.mechanisms.layup import layup_point

from ._line_runs import read_bag_mcap

RATE = 50.0
DURATION = 3.0
NS = 1_000_000_000
TOL = 1e-9


def _ids(scene_name: str) -> dict[tuple[str, str], int]:
    """(machine, part) -> marker id: the index among its machine's shapes (the order only)."""
    shapes = Scenery(LineModel(load_scene(scene_name, {}), 1.0)).at(0.0)
    seen: dict[str, int] = {}
    out = {}
    for s in shapes:
        out[(s.machine, s.part)] = seen.get(s.machine, 0)
        seen[s.machine] = out[(s.machine, s.part)] + 1
    return out


def _points(marker: Any) -> np.ndarray:
    return np.array([[p.x, p.y, p.z] for p in marker.points], dtype=float).reshape(-1, 3)


def _closed_form(scene: Any, theta: float) -> dict[str, Any]:
    """The key points at master phase Θ, m in frame ``line``, from the mechanisms alone."""
    lp = scene.machine('layup')
    ox, oy, oz = LAYUP_ORIGIN
    turns = theta * lp.n_kr / 60.0
    phi = 2.0 * math.pi * (turns - math.floor(turns))
    p = layup_point(lp, phi)
    r = lp.O2B / lp.l3
    xy = {
        'O1': (lp.a, lp.b),
        'O2': (0.0, 0.0),
        'O3': (lp.O2O3, 0.0),
        'A': (lp.a + lp.R_kr * math.cos(phi), lp.b + lp.R_kr * math.sin(phi)),
        'B': (p.xC * r, p.yC * r),
        'C': (p.xC, p.yC),
        'E': (p.xE, p.yE),
    }
    out: dict[str, Any] = {k: np.array([x + ox, oy, y + oz]) for k, (x, y) in xy.items()}
    kp = scene.machine('knife')
    phi_k = float(np.mod(knf.omega(kp) * theta, 2.0 * math.pi))
    out['knife_tip'] = np.array([FOLDER_ORIGIN[0], 0.0, FOLDER_ORIGIN[2] + kp.s_clear - knf.position(kp, phi_k)])
    sch, path = schedule(scene), chain_path(scene)
    a0, _ = sch.stroke_travel(np.array([theta]))
    a = float(a0[0])
    if 0.0 <= a <= sch.S:  # a carriage on the stroke: its chain pin over the curved guide
        chain, dp = scene.machine('delivery_chain'), scene.machine('delivery')
        u = float(path.position(np.array([a]))[0])
        xi = 2.0 - u if u > 1.0 else u
        out['carriage'] = np.array(
            [
                FOLDER_ORIGIN[0] + chain.L_transfer + chain.x_max * u,
                0.0,
                FOLDER_ORIGIN[2] - PICKUP_DROP + dp.Lambda * chain.x_max * float(LAWS[dp.law].psi(xi)),
            ]
        )
    return out


def _check_bag(bag: Path, scene: Any, theta_of: Any, ids: dict[tuple[str, str], int]) -> tuple[int, float, int]:
    """Every marker array of ``bag`` against the closed forms; (stamps, crank turns covered, carriage checks)."""
    records = read_bag_mcap(bag, ['/line/markers'])
    (key,) = records
    assert key == ('/line/markers', '')
    arrays = records[key]
    stamps = []
    turns = []
    carriages = 0
    for i, rec in enumerate(arrays):
        markers = list(rec.msg.markers)
        if i == 0:
            assert markers[0].action == 3  # DELETEALL first
            markers = markers[1:]
        stamp = markers[0].header.stamp.sec * NS + markers[0].header.stamp.nanosec
        assert rec.log_ns >= stamp and rec.log_ns - stamp < NS // 200  # published at its tick
        stamps.append(stamp)
        by = {(m.ns, m.id): m for m in markers}
        assert len(by) == len(markers)
        for m in markers:
            assert m.header.frame_id == LINE_FRAME and m.action in (0, 2) and not m.frame_locked
            assert (m.lifetime.sec, m.lifetime.nanosec) == (0, 0)
        theta = theta_of(stamp / NS)
        turns.append(theta * scene.machine('layup').n_kr / 60.0)
        want = _closed_form(scene, theta)
        link = _points(by[('layup', ids[('layup', 'link')])])
        ends = [want[k] for k in ('O1', 'A', 'A', 'B', 'O2', 'C', 'C', 'E', 'O3', 'E')]
        np.testing.assert_allclose(link, np.array(ends), rtol=0, atol=TOL)
        pivots = _points(by[('layup', ids[('layup', 'pivot')])])
        np.testing.assert_allclose(pivots, np.array([want['O1'], want['O2'], want['O3']]), rtol=0, atol=TOL)
        knife = _points(by[('folder', ids[('folder', 'knife')])])
        np.testing.assert_allclose(knife[3], want['knife_tip'], rtol=0, atol=TOL)
        pins = _points(by[('delivery', ids[('delivery', 'carriage')])])
        if 'carriage' in want:
            assert np.min(np.linalg.norm(pins - want['carriage'], axis=1)) <= TOL
            carriages += 1
    assert stamps == [round(i * NS / RATE) for i in range(len(stamps))]
    assert stamps[-1] == round(DURATION * NS)
    return len(stamps), turns[-1] - turns[0], carriages


@pytest.fixture(scope='module')
def bags(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    out = tmp_path_factory.mktemp('markers')
    argv = ['--scene', 'line', '--duration', str(DURATION), '--marker-rate', str(RATE)]
    assert main(['run', *argv, '--rtf', 'max', '--out', str(out / 'live')]) == 0
    assert main(['simulate', *argv, '--bag', str(out / 'batch')]) == 0
    return out / 'live' / 'bag', out / 'batch'


@pytest.mark.parametrize('which', ['live', 'batch'])
def test_recorded_markers_are_the_closed_forms_over_a_crank_turn(bags: tuple[Path, Path], which: str) -> None:
    scene = load_scene('line', {})
    # the drive of the nodes' model (the motor ODE over the run's horizon), not the scenery's
    drive = make_drive(scene)

    def theta_of(t: float) -> float:
        return float(np.asarray(drive.theta(np.array([t]))).reshape(-1)[0])

    n, turns, carriages = _check_bag(bags[0] if which == 'live' else bags[1], scene, theta_of, _ids('line'))
    assert n == round(DURATION * RATE) + 1
    assert turns > 1.0  # a whole crank turn of the layup (and ~30 knife cycles)
    assert carriages > 20


def test_live_and_batch_markers_are_the_same(bags: tuple[Path, Path]) -> None:
    live, batch = (read_bag_mcap(b, ['/line/markers'])[('/line/markers', '')] for b in bags)
    assert len(live) == len(batch)
    for a, b in zip(live, batch, strict=True):
        assert (a.log_ns, a.publish_ns) == (b.log_ns, b.publish_ns)
        assert a.value == b.value
