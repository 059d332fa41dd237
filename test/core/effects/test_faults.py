from __future__ import annotations

import numpy as np
import pytest

from folder_line.core.effects.faults import Params, belt_factor, draw_sheet_faults, draw_slowdowns, fault_events
from folder_line.core.numerics.rng import stream
from folder_line.errors import ParameterError


def _p(**kw: float) -> Params:
    base = dict(
        p_missing=0.01,
        p_double=0.01,
        p_late=0.02,
        late_delay=0.004,
        p_slowdown=0.001,
        slowdown_factor=0.5,
        slowdown_duration=0.2,
    )
    base.update(kw)
    return Params(**base)


def test_rates_match_probabilities() -> None:
    f = draw_sheet_faults(_p(), 200_000, stream(1, 'x'))
    assert f.missing.mean() == pytest.approx(0.01, rel=0.1)
    assert f.double.mean() == pytest.approx(0.99 * 0.01, rel=0.1)
    assert not np.any(f.missing & f.double)
    assert np.all(f.delay[f.missing] == 0.0)
    assert set(np.unique(f.delay)) <= {0.0, 0.004}


def test_same_seed_same_faults_and_streams_independent() -> None:
    a = draw_sheet_faults(_p(), 1000, stream(7, 'folder.faults'))
    b = draw_sheet_faults(_p(), 1000, stream(7, 'folder.faults'))
    c = draw_sheet_faults(_p(), 1000, stream(7, 'layup.faults'))
    assert np.array_equal(a.missing, b.missing) and np.array_equal(a.delay, b.delay)
    assert not np.array_equal(a.missing | a.double, c.missing | c.double)


def test_zero_probabilities_draw_nothing() -> None:
    f = draw_sheet_faults(_p(p_missing=0.0, p_double=0.0, p_late=0.0), 5000, stream(3, 'x'))
    assert not f.missing.any() and not f.double.any() and not f.delay.any()
    s = draw_slowdowns(_p(p_slowdown=0.0), 100.0, 0.072, stream(3, 'y'))
    assert s.t_start.size == 0
    assert np.all(belt_factor(s, np.linspace(0, 100, 11)) == 1.0)


def test_slowdowns_merge_and_factor() -> None:
    s = draw_slowdowns(_p(p_slowdown=1.0, slowdown_duration=0.2), 1.0, 0.072, stream(3, 'y'))
    # every cycle starts one lasting 0.2 s > period: all merge into one interval
    assert s.t_start.size == 1
    assert s.t_start[0] < 0.072 and s.t_end[0] > 1.0
    t = np.array([s.t_start[0] - 1e-9, s.t_start[0], 0.5, s.t_end[0]])
    assert belt_factor(s, t).tolist() == [1.0, 0.5, 0.5, 1.0]


def test_fault_events_rows() -> None:
    f = draw_sheet_faults(_p(p_missing=0.5, p_double=0.5, p_late=0.5), 100, stream(5, 'z'))
    ev = fault_events(
        f,
        np.arange(100) * 0.072,
        np.arange(100),
        np.arange(100),
        draw_slowdowns(_p(p_slowdown=0.0), 7.2, 0.072, stream(5, 'w')),
        7.2,
    )
    assert ev.size == f.missing.sum() + f.double.sum() + (f.delay > 0).sum()
    assert np.all(np.diff(ev['t']) >= 0)


@pytest.mark.parametrize(
    ('key', 'value'), [('p_missing', 1.5), ('slowdown_factor', 0.0), ('late_delay', -1.0), ('p_late', float('nan'))]
)
def test_bad_params_named(key: str, value: float) -> None:
    with pytest.raises(ParameterError, match=f'effects.faults.{key}'):
        _p(**{key: value})


def test_a_longer_run_keeps_the_faults_of_the_shorter_one() -> None:
    p = _p(p_missing=0.2, p_double=0.2, p_late=0.2, p_slowdown=0.3, slowdown_duration=0.01)
    short = draw_sheet_faults(p, 100, stream(9, 'f'))
    long = draw_sheet_faults(p, 1000, stream(9, 'f'))
    assert np.array_equal(short.missing, long.missing[:100]) and np.array_equal(short.delay, long.delay[:100])
    s_short = draw_slowdowns(p, 7.2, 0.072, stream(9, 's'))
    s_long = draw_slowdowns(p, 72.0, 0.072, stream(9, 's'))
    n = s_short.t_start.size
    assert n > 0 and np.array_equal(s_short.t_start, s_long.t_start[:n])
