"""One point of a study: simulated on its own, or refused with the model's reason; metrics and keys."""

from __future__ import annotations

import pickle

import pytest

from folder_line.config.scenes import scene_mapping
from folder_line.errors import ParameterError
from folder_line.studies.keys import check_key, key_unit, scene_value
from folder_line.studies.points import OK, PointTask, evaluate_point, resolve_metrics

from ._closed_form import feed_margin

METRICS = ('min_margin_s.feed_window', 'violations.count')


@pytest.fixture(scope='module')
def folder() -> dict:
    return scene_mapping('folder')


def test_a_point_is_the_closed_form_margin(folder: dict) -> None:
    task = PointTask(folder, (('feed_transporter.V_tr', 8.0),), 0.5, METRICS)
    result = evaluate_point(pickle.loads(pickle.dumps(task)))  # what a Dask worker gets
    assert result.status == OK
    margin, count = result.values
    assert margin == pytest.approx(feed_margin(50000.0, 8.0), abs=1e-12)
    assert margin < 0 and count == 7  # 0.5 s at T = 0.072 s: 7 knife cycles, every feed late
    assert folder['machines']['feed_transporter']['V_tr'] == 9.3  # the task's mapping is not changed


@pytest.mark.parametrize(
    ('scene', 'key', 'value', 'reason'),
    [
        ('folder', 'feed_transporter.V_tr', -1.0, 'feed_transporter.V_tr=-1.0'),
        ('layup', 'layup.l2', 0.2, 'Grashof crank-rocker'),  # a rod too short for the crank-rocker
        ('layup', 'layup.l4', 0.1, 'loop O2-C-E-O3 cannot be assembled'),  # an AssemblyError
    ],
)
def test_a_refused_point_is_a_row_saying_why(scene: str, key: str, value: float, reason: str) -> None:
    result = evaluate_point(PointTask(scene_mapping(scene), ((key, value),), 0.2, ('violations.count',)))
    assert result.values == (None,)
    assert result.status.startswith('refused: ') and reason in result.status and '\n' not in result.status


def test_default_metrics_are_the_margins_and_the_violation_count() -> None:
    flat = {
        'cycles': 3.0,
        'min_margin.a.margin': 1.0,
        'min_margin.a.cycle': 0.0,
        'min_margin.b.margin': -1.0,
        'violations.count': 2.0,
        'min_margin_s.a': 1.0,
    }
    assert resolve_metrics([], flat) == ('min_margin.a.margin', 'min_margin.b.margin', 'violations.count')
    assert resolve_metrics(['count', 'min_margin_s.a'], flat) == ('violations.count', 'min_margin_s.a')
    with pytest.raises(ParameterError, match=r"^--metric='violations.count': is asked for twice"):
        resolve_metrics(['count', 'violations.count'], flat)
    with pytest.raises(ParameterError, match=r'^--metric=.margin.: is ambiguous'):
        resolve_metrics(['margin'], flat)


def test_keys_are_checked_against_the_scene(folder: dict) -> None:
    check_key(folder, 'feed_transporter.V_tr', '--vary')
    check_key(folder, 'stop_bounce.e', '--vary')  # a listed effect's parameter
    check_key(folder, 'seed', '--vary')
    check_key(folder, 'press.n_c', '--vary')  # the cylinder and the knife together
    with pytest.raises(ParameterError, match=r"^--vary='feed_transporter.Vtr': feed_transporter has no parameter"):
        check_key(folder, 'feed_transporter.Vtr', '--vary')
    with pytest.raises(ParameterError, match=r"^--find='layup.R_kr': scene 'folder' has no machine 'layup'"):
        check_key(folder, 'layup.R_kr', '--find')
    with pytest.raises(ParameterError, match=r"^--vary='feed_slip.mu': scene 'folder' does not list effect"):
        check_key(folder, 'feed_slip.mu', '--vary')
    with pytest.raises(ParameterError, match=r"^--vary='sheets.jitter': .*arrival_jitter"):  # folder never reads it
        check_key(folder, 'sheets.jitter', '--vary')


def test_keys_units_and_scene_values(folder: dict) -> None:
    assert [key_unit(folder, k) for k in ('feed_transporter.V_tr', 'knife.n_k', 'press.n_c', 'stop_bounce.e')] == [
        'm/s',
        'rev/h',
        'rev/h',
        '',  # a ratio
    ]
    assert key_unit(folder, 'layup.R_kr') == ''  # no layup in this scene
    assert scene_value(folder, 'feed_transporter.V_tr') == 9.3
    assert scene_value(folder, 'knife.n_k') == 50000.0
    assert scene_value(folder, 'seed') == 1
