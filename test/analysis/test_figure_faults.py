"""The figures of a run as an engineer reads them (issue #15, item 6): the start-up samples of
``exit_speeds.png`` marked apart, ``v_C`` and ``v_E`` both visible, one colour per quantity in
``analyze`` and ``report``.

The run is a ``simulate --bag`` of the ``line`` scene (``motor_dynamics``: the drive starts from
standstill and reaches speed at 1.79 s), 3 s long; no DDS.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from matplotlib.colors import to_rgba

from folder_line.analysis import colours, figures, read_recording
from folder_line.analysis.colours import QUANTITY_COLOURS
from folder_line.analysis.figure_data import at_speed_time, exit_speed_data, off_speed
from folder_line.analysis.figures import (
    efficiency_figure,
    exit_speeds_figure,
    pyplot,
)
from folder_line.analysis.paper_curves import coincidence
from folder_line.analysis.recording import JOINT_SAMPLES, Recording
from folder_line.analysis.replay import Evaluation, evaluate
from folder_line.cli import report
from folder_line.cli.main import main
from folder_line.config.params import load_params
from folder_line.core.supervision.settings import CHECK_PERIOD, SPEED_REACHED

START_UP = 'start-up (before the drive reached speed'


@pytest.fixture(scope='module')
def line_run(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Recording, Evaluation]]:
    bag = tmp_path_factory.mktemp('line') / 'bag'
    assert main(['simulate', '--scene', 'line', '--duration', '3', '--bag', str(bag)]) == 0
    rec = read_recording(bag)
    yield rec, evaluate(rec)


def _lines(ax: Any, prefix: str) -> list[Any]:
    return [ln for ln in ax.get_lines() if ln.get_label().startswith(prefix)]


def _first_at_speed(ev: Evaluation, t: float) -> bool:
    """``t`` is the first point of the check grid where the drive turns at ``speed_reached``."""
    rate = np.asarray(ev.drive.rate(np.array([t - CHECK_PERIOD, t])), dtype=float)
    return bool(rate[0] < SPEED_REACHED <= rate[1])


# --------------------------------------------------------------------------- start-up


def test_at_speed_time_is_the_first_execute(line_run: tuple[Recording, Evaluation]) -> None:
    rec, ev = line_run
    t_speed = at_speed_time(rec, ev)
    assert [s for _, s in rec.states][:2] == ['STARTING', 'EXECUTE']
    assert t_speed == rec.states[1][0] / 1e9
    assert 0.0 < t_speed < rec.t_end
    assert _first_at_speed(ev, t_speed)


def test_at_speed_time_from_the_drive_without_recorded_states(line_run: tuple[Recording, Evaluation]) -> None:
    rec, ev = line_run
    t_model = at_speed_time(dataclasses.replace(rec, states=[]), ev)
    assert _first_at_speed(ev, t_model)
    assert t_model == pytest.approx(at_speed_time(rec, ev), abs=1e-12)  # the supervisor decides on the same grid
    never = dataclasses.replace(rec, states=[(0, 'STARTING')])
    assert at_speed_time(never, ev) == math.inf


def test_exit_speeds_marks_the_start_up_samples(line_run: tuple[Recording, Evaluation]) -> None:
    rec, ev = line_run
    data = exit_speed_data(rec)
    assert data is not None and data['t'].size <= JOINT_SAMPLES  # every sample the reading kept is drawn
    t_speed = at_speed_time(rec, ev)
    early = data['t'] < t_speed
    assert 0 < np.count_nonzero(early) < early.size
    fig = exit_speeds_figure(rec, ev)
    try:
        ax_swing, ax_abs = fig.axes
        for ax, c, e in ((ax_swing, 'vC', 'vE'), (ax_abs, 'vaC', 'vaE')):
            marked = _lines(ax, START_UP)
            assert len(marked) == 1, [ln.get_label() for ln in ax.get_lines()]
            start = marked[0]
            assert to_rgba(start.get_color()) == to_rgba(QUANTITY_COLOURS['start_up'])
            np.testing.assert_array_equal(start.get_xdata(), np.degrees(data['phi'][early]))
            np.testing.assert_array_equal(start.get_ydata(), data[c][early])
            (steady_c,) = _lines(ax, 'recorded $v_{aC}$' if c == 'vaC' else r'recorded $\omega_3')
            (steady_e,) = _lines(ax, 'recorded $v_{aE}$' if e == 'vaE' else r'recorded $\omega_5')
            np.testing.assert_array_equal(steady_c.get_ydata(), data[c][~early])
            np.testing.assert_array_equal(steady_e.get_ydata(), data[e][~early])
            assert steady_c.get_marker() != start.get_marker()
        v_min = float(rec.scene.effect('chute_belts').v_min)
        # what users saw: points below v_min; they are the start-up, every sample at speed is above
        assert data['vaC'][early].min() < v_min
        assert min(data['vaC'][~early].min(), data['vaE'][~early].min()) >= v_min
    finally:
        pyplot().close(fig)


def test_no_start_up_entry_for_a_drive_at_speed_from_the_start(tmp_path: Path) -> None:
    assert main(['simulate', '--scene', 'layup', '--duration', '1', '--bag', str(tmp_path / 'bag')]) == 0
    rec = read_recording(tmp_path / 'bag')
    ev = evaluate(rec)
    assert at_speed_time(rec, ev) == 0.0
    fig = exit_speeds_figure(rec, ev)
    try:
        assert all(not _lines(ax, START_UP) for ax in fig.axes)
    finally:
        pyplot().close(fig)


# --------------------------------------------------------------------------- v_C and v_E


def test_coincidence() -> None:
    x = np.linspace(0.0, 2.0 * math.pi, 100)
    assert coincidence(np.sin(x), np.sin(x) + 0.004) == pytest.approx(0.004)
    assert coincidence(np.sin(x), np.cos(x)) is None
    assert coincidence(np.sin(x), 1.2 * np.sin(x)) is None


@pytest.mark.parametrize('where', ['report', 'analyze'])
def test_v_c_and_v_e_are_distinguishable(where: str, line_run: tuple[Recording, Evaluation]) -> None:
    lay = load_params('layup')
    fig = report.layup_speeds_figure(lay) if where == 'report' else exit_speeds_figure(*line_run)
    try:
        names = (('$v_C$ (', '$v_E$ (', '$v_C$'), ('$v_{aC}=', '$v_{aE}=', '$v_{aC}$'))
        for ax, (c_label, e_label, c_name) in zip(fig.axes, names, strict=True):
            (c,) = _lines(ax, c_label)
            (e,) = _lines(ax, e_label)
            assert to_rgba(c.get_color()) == to_rgba(QUANTITY_COLOURS['vC'])
            assert to_rgba(e.get_color()) == to_rgba(QUANTITY_COLOURS['vE'])
            assert c.get_linestyle() != e.get_linestyle()
            assert c.get_linewidth() > 2.0 * e.get_linewidth()  # C's wide line shows around E's
            assert c.get_marker() != e.get_marker()
            assert c.get_markevery() != e.get_markevery()  # E's markers between C's
            gap = coincidence(np.asarray(c.get_ydata()), np.asarray(e.get_ydata()))
            assert gap is not None  # this six-bar's exits do coincide, to 4 mm/s
            assert f'coincides with {c_name}' in e.get_label()
            assert f'{gap * 1e3:.2g} mm/s' in e.get_label()
    finally:
        pyplot().close(fig)


# --------------------------------------------------------------------------- colours


def test_one_colour_mapping_for_report_and_analyze() -> None:
    assert figures.QUANTITY_COLOURS is colours.QUANTITY_COLOURS
    assert report.QUANTITY_COLOURS is colours.QUANTITY_COLOURS
    assert report.PHASE_COLOURS is figures.PHASE_COLOURS is colours.PHASE_COLOURS


def test_eta_a_and_eta_b_keep_their_colours(line_run: tuple[Recording, Evaluation]) -> None:
    report_fig = report.delivery_figure(load_params('delivery'))
    analyze_fig = efficiency_figure(*line_run)
    try:
        for fig in (report_fig, analyze_fig):
            ax_eta = fig.axes[0]
            for name in ('eta_A', 'eta_B'):
                (ln,) = _lines(ax_eta, f'{name} (')
                assert to_rgba(ln.get_color()) == to_rgba(QUANTITY_COLOURS[name]), name
            (geo,) = _lines(ax_eta, 'eta (geometric')
            assert to_rgba(geo.get_color()) == to_rgba(QUANTITY_COLOURS['geometric'])
        a = {to_rgba(QUANTITY_COLOURS[k]) for k in ('eta_A', 'eta_B', 'paper_mirror', 'geometric')}
        assert len(a) == 4  # four quantities of one axes, four colours
    finally:
        pyplot().close(report_fig)
        pyplot().close(analyze_fig)


def test_the_ramps_of_a_hold_after_the_start_are_marked_too(tmp_path: Path) -> None:
    """A hold after the start-up (here the supervisor's, on a chute belt tuned too slow) ramps the drive down:
    those samples are off speed as the start-up's are, marked with them, and told apart in the legend."""
    bag = tmp_path / 'bag'
    assert (
        main(['simulate', '--scene', 'layup', '--duration', '8', '--tune', '3:layup.v_tr=0.5', '--bag', str(bag)]) == 0
    )
    rec = read_recording(bag)
    ev = evaluate(rec)
    assert [s for _, s in rec.states][-2:] == ['HOLDING', 'HELD']
    data = exit_speed_data(rec)
    assert data is not None
    t_hold = next(t_ns for t_ns, s in rec.states if s == 'HOLDING') / 1e9
    off = off_speed(rec, ev, data['t'])
    assert np.array_equal(off, (data['t'] < at_speed_time(rec, ev)) | (data['t'] >= t_hold))
    later = int(np.count_nonzero(data['t'] >= t_hold))
    assert later > 0
    fig = exit_speeds_figure(rec, ev)
    try:
        # this drive is at speed from t = 0: no start-up, only the hold
        assert at_speed_time(rec, ev) == 0.0 and later == int(off.sum())
        assert not _lines(fig.axes[0], START_UP)
        (marked,) = _lines(fig.axes[0], 'holds/stops (the drive ramping down or standing still)')
        assert marked.get_label().endswith(f': {later} ticks')
    finally:
        pyplot().close(fig)
