"""The ``events`` accuracy study: its references, its detectors and its rows."""

from __future__ import annotations

import dataclasses
import math

import mpmath as mp
import numpy as np
import pytest

from folder_line.accuracy import events as E
from folder_line.accuracy.event_cases import (
    DPS,
    DRAG,
    SPAN_LAYUP,
    T_RAMP,
    EventCase,
    exit_states,
    front_stops_case,
    leaf_landing_case,
)
from folder_line.config.scenes import load_scene
from folder_line.core.effects import leaf_flight
from folder_line.core.line.drives import make_drive
from folder_line.core.line.layup_sim import LayupLine
from folder_line.core.types.events import event_kind
from folder_line.errors import MeasurementError

EPS = float(np.finfo(float).eps)


@pytest.fixture(scope='module')
def cases() -> dict[str, EventCase]:
    return {c.name: c for c in (front_stops_case(), leaf_landing_case())}


@pytest.fixture(params=E.CASES)
def case(request: pytest.FixtureRequest, cases: dict[str, EventCase]) -> EventCase:
    return cases[request.param]


# ------------------------------------------------------------------------------ reference


def test_cases_have_many_events(case: EventCase) -> None:
    assert case.n_events >= 25
    assert np.all(np.isfinite(case.t_start)) and np.all(case.t_start <= case.span)
    # every expected event lies in the span, after its watch started
    exp = case.expected
    assert np.all(case.t_core[exp] > case.t_start[exp]) and np.all(case.t_core[exp] <= case.span)


def test_reference_is_a_root_of_g_in_mpmath(case: EventCase) -> None:
    with mp.workdps(DPS):
        tiny = mp.mpf('1e-20')
        for k, r in enumerate(case.ref_mp):
            assert abs(case.g_mp(k, r)) < mp.mpf('1e-25')
            assert case.g_mp(k, r - tiny) < 0 < case.g_mp(k, r + tiny)
            # the float pair holds the mpmath root to ~1e-31 s
            assert abs(mp.mpf(case.ref_hi[k]) + mp.mpf(case.ref_lo[k]) - r) < mp.mpf('1e-28')


def test_reference_matches_an_independent_closed_form(case: EventCase) -> None:
    # front stops: sqrt(2 t_ramp Θ_a) / Θ_a + t_ramp/2; leaf landing: Lambert W of the drag flight
    with mp.workdps(DPS):
        worst = max(abs(case.closed_form_mp(k) - r) for k, r in enumerate(case.ref_mp))
    assert worst < mp.mpf('1e-25')


def test_reference_matches_the_core_event_table(case: EventCase) -> None:
    exp = case.expected
    diff = np.abs((case.t_core[exp] - case.ref_hi[exp]) - case.ref_lo[exp])
    assert diff.max() <= 1e-12
    # objects whose event is beyond the span per the core have their reference beyond it too
    assert np.all(case.ref_hi[~exp] > case.span - 1e-12)


def test_exact_method_is_the_core_event_table_bit_for_bit(case: EventCase) -> None:
    t = case.exact(np.arange(case.ids.size))
    assert np.array_equal(t[case.expected], case.t_core[case.expected])
    assert np.all(t[~case.expected] > case.span)


def test_g_vanishes_at_the_core_event_times(case: EventCase) -> None:
    exp = np.flatnonzero(case.expected)
    gv = case.g(exp, case.t_core[exp])
    assert np.max(np.abs(gv)) < 1e-12  # m
    # and g < 0 when the watch starts (signature just handed over, leaf at the exit)
    assert np.all(case.g(np.arange(case.ids.size), case.t_start) < 0.0)
    # the scalar form is the vectorised one
    for k in exp[:5].tolist():
        t = float(case.t_core[k]) - 1e-3
        assert case.g_scalar(k, t) == pytest.approx(float(case.g(np.array([k]), np.array([t]))[0]), abs=1e-15)


def test_front_stops_g_starts_at_minus_the_feed_length(cases: dict[str, EventCase]) -> None:
    # at the hand-over the belt has carried the signature 0 m: g = -L_feed (0.230 m, cyclogram.yaml)
    c = cases['front stops']
    g0 = c.g(np.arange(c.ids.size), c.t_start)
    np.testing.assert_allclose(g0, -0.230, atol=1e-12)
    # half the events during the ramp (t < t_ramp), where g is quadratic in t
    assert np.count_nonzero(c.t_core[c.expected] < T_RAMP) >= 10


def test_leaf_exit_states_reproduce_the_core() -> None:
    scene = load_scene('layup', {'leaf_flight.drag': DRAG})
    drive = make_drive(scene)
    line = LayupLine(scene, drive, SPAN_LAYUP)
    ids, fl = exit_states(line)
    lp = scene.machine('layup')
    ev = line.events
    exits = ev[ev['kind'] == event_kind('leaf_exit')]
    assert np.array_equal(ids, exits['sheet'])
    # the exit point is at the chute's length from its pivot (O2 at the origin, O3 at (O2O3, 0))
    r = np.where(ids % 2 == 0, np.hypot(fl.x0, fl.y0), np.hypot(fl.x0 - lp.O2O3, fl.y0))
    np.testing.assert_allclose(r, np.where(ids % 2 == 0, lp.l3, lp.l5), rtol=0, atol=1e-12)
    # the exit speed is the event's value (paper eq. 25 with the belt's speed)
    np.testing.assert_allclose(np.hypot(fl.vx, fl.vy), exits['value'], rtol=1e-14)
    # landing time and x from these states are the core's landing events
    params = scene.effect('leaf_flight')
    t_f, x_land = leaf_flight.landing(params, fl.x0, fl.y0, fl.vx, fl.vy, scene.machine('container').y_floor)
    landed = ev[ev['kind'] == event_kind('leaf_landed')]
    pos = {int(s): i for i, s in enumerate(ids.tolist())}
    i = np.array([pos[int(s)] for s in landed['sheet'].tolist()])
    assert i.size >= 25
    assert np.array_equal(fl.t_x[i] + t_f[i], landed['t'])
    assert np.array_equal(x_land[i], landed['value'])


# ------------------------------------------------------------------------------ methods


def test_sampling_reports_the_first_tick_at_or_after_the_event(case: EventCase) -> None:
    for rate in E.knob_settings(E.SAMPLING):
        det = E.detect(case, E.SAMPLING, rate)
        err = E.errors(case, det.t)
        assert err.min() >= -1e-15  # never before the event (to the rounding of g)
        assert err.max() <= 1.0 / rate + 1e-12
        # the events fall at all phases of the ticks: the worst is more than half a period late
        assert E.max_error(case, det.t) > 0.5 / rate
        # and the reported times are ticks
        exp = case.expected
        ticks = det.t[exp] * rate
        np.testing.assert_allclose(ticks, np.round(ticks), rtol=0, atol=1e-6)


def test_linear_interpolation_is_second_order(case: EventCase) -> None:
    err = {r: E.max_error(case, E.detect(case, E.INTERP, r).t) for r in E.knob_settings(E.INTERP)}
    samp = {r: E.max_error(case, E.detect(case, E.SAMPLING, r).t) for r in E.knob_settings(E.SAMPLING)}
    for r in (1e3, 3e3, 1e4, 3e4, 1e5):
        assert err[r] < samp[r] / 100.0
    # error ~ rate^-2: a decade of rate gains about two decades of error
    for lo, hi in ((1e3, 1e4), (1e4, 1e5)):
        assert 40.0 < err[lo] / err[hi] < 250.0
    # while plain sampling gains one
    assert 5.0 < samp[1e3] / samp[1e4] < 20.0


def test_root_finding_is_within_xtol(case: EventCase) -> None:
    errs = []
    for xtol in E.knob_settings(E.ROOT):
        det = E.detect(case, E.ROOT, xtol)
        e = E.max_error(case, det.t)
        assert e <= xtol + 4.0 * EPS * case.span + 1e-14
        errs.append(e)
    # the tightest tolerance beats every sampling setting, with fewer evaluations of g than 1 kHz polling
    best_sampled = min(E.max_error(case, E.detect(case, E.INTERP, r).t) for r in E.knob_settings(E.INTERP))
    assert errs[-1] < best_sampled
    assert E.detect(case, E.ROOT, 1e-12).evaluations < E.detect(case, E.SAMPLING, 1e3).evaluations


def test_exact_method_is_at_rounding_level(case: EventCase) -> None:
    for batch in E.knob_settings(E.EXACT):
        det = E.detect(case, E.EXACT, batch)
        assert E.max_error(case, det.t) <= 8.0 * EPS * case.span


def test_no_missed_or_double_events_at_any_setting(case: EventCase) -> None:
    for method in E.METHODS:
        for quick in (False, True):
            for value in E.knob_settings(method, quick):
                det = E.detect(case, method, value)  # raises on a missed or double event
                assert np.all(det.count[case.expected] == 1)
                assert np.all(det.count[~case.expected] == 0)
                assert np.all(np.isfinite(det.t[case.expected]))


def _bouncing(case: EventCase, d: float) -> EventCase:
    """The case with every object's g dipping below 0 for ``d`` s, ``d`` s after its event (a rebound)."""
    ref = case.ref_hi

    def g(idx: np.ndarray, t: np.ndarray) -> np.ndarray:
        tr = ref[idx]
        return np.where((t >= tr + d) & (t < tr + 2.0 * d), -1.0, case.g(idx, t))

    def g_scalar(k: int, t: float) -> float:
        return -1.0 if ref[k] + d <= t < ref[k] + 2.0 * d else case.g_scalar(k, t)

    return dataclasses.replace(case, g=g, g_scalar=g_scalar)


def test_double_events_are_failures(case: EventCase) -> None:
    with pytest.raises(MeasurementError, match='more than once'):
        E.detect(_bouncing(case, 5e-4), E.SAMPLING, 1e4)
    with pytest.raises(MeasurementError, match='more than once'):
        E.detect(_bouncing(case, 0.02), E.ROOT, 1e-9)


def test_missed_and_spurious_events_are_failures(case: EventCase) -> None:
    short = dataclasses.replace(case, span=0.6 * case.span)  # events after it cannot be detected
    for method, value in ((E.SAMPLING, 1e3), (E.INTERP, 1e4), (E.ROOT, 1e-6), (E.EXACT, 4.0)):
        with pytest.raises(MeasurementError, match='missed'):
            E.detect(short, method, value)
    none = dataclasses.replace(case, expected=np.zeros_like(case.expected))
    with pytest.raises(MeasurementError, match='not in the span'):
        E.detect(none, E.SAMPLING, 1e3)


# ------------------------------------------------------------------------------ rows


def test_knob_ranges_match_the_issue() -> None:
    for quick, least in ((False, 4), (True, 3)):
        for m in E.METHODS:
            assert len(E.knob_settings(m, quick)) >= least
    for m in (E.SAMPLING, E.INTERP):
        assert (min(E.knob_settings(m)), max(E.knob_settings(m))) == (100.0, 1e5)
    assert (max(E.knob_settings(E.ROOT)), min(E.knob_settings(E.ROOT))) == (1e-3, 1e-12)


def test_rows_are_finite_and_their_errors_are_the_detections(cases: dict[str, EventCase]) -> None:
    rows = E.measure_rows(list(cases.values()), quick=True, min_s=0.001, repeats=1)
    per_case = sum(len(E.knob_settings(m, True)) for m in E.METHODS)
    assert len(rows) == 2 * per_case
    assert {r.method for r in rows} == {f'{m} [{c}]' for m in E.METHODS for c in E.CASES}
    for r in rows:
        assert r.study == 'events' and r.unit == 's'
        assert math.isfinite(r.error) and r.error > 0.0
        assert math.isfinite(r.cpu_s_per_sim_s) and r.cpu_s_per_sim_s > 0.0
        method, name = r.method.rsplit(' [', 1)
        c = cases[name[:-1]]
        assert r.knob == E.KNOBS[method]
        assert r.error == E.max_error(c, E.detect(c, method, r.value).t)


def test_run_quick() -> None:
    rows = E.run(quick=True)
    assert len(rows) == 2 * sum(len(E.knob_settings(m, True)) for m in E.METHODS)
    assert all(math.isfinite(r.error) and math.isfinite(r.cpu_s_per_sim_s) and r.cpu_s_per_sim_s > 0 for r in rows)
