"""``analyze`` and ``animate`` on the streamed line: the numbers of before, whatever the windows.

* ``analyze`` of the committed runs (``test/data/``) gives the numbers, cyclogram rows, landing
  histogram and margin bars the whole-span analysis gave before the line was streamed
  (``data/before_streaming.json``: what ``analyze``, ``cycle_rows``, ``landing_data`` and the margins
  figure's histogram gave at commit 75af36e, the last one with the whole-span line model);
* the recorded events judged in tiny windows are judged as in one window (summary, violations,
  running figures, the figures' data), and as ``simulate`` judges its own events; the recorded
  events compared with the streamed line window by window are compared as in one window, and a
  changed recording is told apart event by event;
* ``animate --from S`` (a fast-forward to S, S not at a window boundary) draws at a line time t the
  frame a run from 0 draws at t, pixel for pixel.
"""

from __future__ import annotations

import copy
import importlib
import itertools
import json
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from folder_line.analysis import analyze, cycle_rows, landing_data, read_recording
from folder_line.analysis.animation import encode, extent
from folder_line.analysis.animation.render import FRAME_WINDOW, fast_forward, sceneries
from folder_line.analysis.event_check import EventCheck, compare_events
from folder_line.analysis.figures import margin_bars
from folder_line.analysis.recording import Recording
from folder_line.analysis.replay import Evaluation, _CycleRows, evaluate
from folder_line.analysis.report import _window
from folder_line.analysis.streaming import GRID_BINS, MarginHistogram, Thinned
from folder_line.cli.main import main
from folder_line.config.scenes import load_scene, scene_mapping
from folder_line.core.line.line_summary import ViolationRecord, Violations
from folder_line.core.line.model import LineModel, simulate
from folder_line.core.line.scene import Scene, parse_scene
from folder_line.core.line.scenery import Scenery
from folder_line.core.line.stream import LineStream
from folder_line.files.json_types import JsonObject
from folder_line.interfaces import EVENT_KINDS

from ._events_only import events_recording

#: the module (the package's ``render`` is its function)
render_mod = importlib.import_module('folder_line.analysis.animation.render')
DATA = Path(__file__).resolve().parents[1] / 'data'
BEFORE = json.loads((Path(__file__).resolve().parent / 'data' / 'before_streaming.json').read_text())
WINDOWS = {'whole': {}, 'from_1': {'t_from': 1.0}, 'to_1': {'t_to': 1.0}}


def _json(value: Any) -> Any:
    """As ``before_streaming.json`` holds it."""
    return json.loads(json.dumps(value, default=repr, sort_keys=True))


# --------------------------------------------------------------------------- (a) the numbers of before


@pytest.mark.parametrize('case', sorted(BEFORE))
def test_analyze_of_the_committed_runs_gives_the_numbers_of_before(case: str, tmp_path: Path) -> None:
    name, label = case.split('/')
    kw: dict[str, float] = WINDOWS[label]
    run = Path(shutil.copytree(DATA / name, tmp_path / name))
    result = analyze(run, tmp_path / 'out', **kw)  # type: ignore[arg-type]
    want = BEFORE[case]
    assert _json({k: result.summary.as_json()[k] for k in want['summary']}) == want['summary']
    ev = result.evaluation
    shown = _window(result.recording, kw.get('t_from', 0.0))
    assert _json([r.as_json() for r in cycle_rows(shown, ev, 8)]) == want['cycle_rows']
    land = landing_data(shown)
    assert (land is None) == ('landing' not in want)
    if land is not None:
        assert land.counts.tolist() == want['landing']['counts']
        assert land.edges.tolist() == want['landing']['edges']
        assert land.cv == want['landing']['cv']
        assert sorted(land.x.tolist()) == want['landing']['x'] and land.fraction == 1.0
    assert set(want['margin_bars']) == {n for n, m in ev.margins.items() if m.tally.evaluations}
    for cname, bars in want['margin_bars'].items():
        _, passed, violated = margin_bars(ev.margins[cname])
        assert (passed.tolist(), violated.tolist()) == (bars['passed'], bars['violated']), cname
        assert (ev.margins[cname].histogram.low, ev.margins[cname].histogram.high) == (bars['low'], bars['high'])
    # the recorded events against the streamed line: every event found, to the ns
    check = result.events_check
    assert check.error is None and check.recorded == check.model == check.matched > 0
    assert check.recorded_only == check.model_only == 0
    # folder_run was recorded before the streamed core: its rebounds differ in the last bit, nothing else
    assert check.largest_difference <= 1e-15
    assert {d.kind for d in check.differences} <= {'bounce'}
    assert (check.values_differ == 0) == check.agree
    assert "| recorded events equal to the line model's |" in result.report.read_text()


# --------------------------------------------------------------------------- (b) windows change nothing


def _late_faults() -> Scene:
    """folder_faults with sheets so late that some come after their cycle's knife (jammed, judged late)."""
    data = copy.deepcopy(scene_mapping('folder_faults'))
    data['effects']['faults'].update({'p_late': 0.2, 'late_delay': 0.1})
    return parse_scene(data)


def _recording(scene: Scene, duration: float, *, exact: bool = False) -> Recording:
    """The events of ``simulate`` as a recording holds them (times to the ns, unless ``exact``)."""
    return events_recording(scene, simulate(scene, duration, sample_rate=0.0).events, duration, to_the_ns=not exact)


RUNS = {
    'faults': lambda: _recording(load_scene('folder_faults'), 30.0),
    'late': lambda: _recording(_late_faults(), 12.0),
    'line': lambda: _recording(load_scene('line'), 6.0),
}


@pytest.fixture(scope='module', params=sorted(RUNS))
def run(request: pytest.FixtureRequest) -> Recording:
    rec: Recording = RUNS[request.param]()
    return rec


def _same_evaluation(a: Evaluation, b: Evaluation) -> None:
    assert a.summary == b.summary
    assert a.violations == b.violations
    assert (a.first_cycles, a.first_violated, a.around_violated) == (
        b.first_cycles,
        b.first_violated,
        b.around_violated,
    )
    assert a.cycle_margins == b.cycle_margins
    assert list(a.margins) == list(b.margins)
    for name, ma in a.margins.items():
        mb = b.margins[name]
        assert ma.tally == mb.tally, name
        for x, y in zip(ma.histogram.grid(), mb.histogram.grid(), strict=True):
            np.testing.assert_array_equal(x, y)
        for x, y in zip(margin_bars(ma), margin_bars(mb), strict=True):
            np.testing.assert_array_equal(x, y)


@pytest.mark.parametrize('t_from', [0.0, 2.5])
def test_the_windows_change_nothing_of_the_evaluation(run: Recording, t_from: float) -> None:
    one = evaluate(run, t_from, window=1e9)
    tiny = evaluate(run, t_from, window=0.0371)  # cuts anywhere: mid-cycle, between a sheet's events
    assert one.windows == 1 and tiny.windows > 50
    _same_evaluation(one, tiny)
    assert cycle_rows(_window(run, t_from), one) == cycle_rows(_window(run, t_from), tiny)
    assert one.summary.violations.count == len(one.violations)


def test_the_late_run_has_rows_judged_after_their_window() -> None:
    """The late scene exercises what the windows must get right: a signature's rows far from its knife."""
    rec = RUNS['late']()
    assert _CycleRows(rec.events).lag > 0
    ev = evaluate(rec)
    assert ev.summary.violations.count > 0 and ev.first_violated is not None
    assert len(ev.first_cycles) == 8 and set(ev.around_violated) <= {ev.first_violated + d for d in (-1, 0, 1)}


def test_the_judged_numbers_are_simulate_s(run: Recording) -> None:
    """With the model's own event times the recorded events are judged as ``simulate`` judges them, bit for bit."""
    exact = _recording(run.scene, run.t_end, exact=True)
    ev = evaluate(exact, window=0.5)
    sim = simulate(run.scene, run.t_end, sample_rate=0.0)
    want = sim.summary(max_violations=10**6)
    got = ev.summary
    assert (got.cycles, got.sheets_counted, got.events) == (want.cycles, want.sheets_counted, want.events)
    assert got.min_margin == want.min_margin and got.min_margin_s == want.min_margin_s
    every = [
        ViolationRecord(int(c.cycle[i]), c.name, float(c.margin[i]), c.unit)
        for c in sim.constraints
        for i in np.flatnonzero(c.violated)
    ]
    every.sort(key=lambda v: (v.cycle, v.constraint))
    assert got.violations == Violations(want.violations.count, every)
    for c in sim.constraints:
        h = ev.margins[c.name].histogram
        assert h.count == c.margin.size and h.violations == int(np.count_nonzero(c.violated))
        if c.margin.size:
            assert (h.low, h.high) == (c.margin.min(), c.margin.max())
    decided = {(v.constraint, v.cycle): v.t for v in ev.violations}
    bad = [(c, c.violated) for c in sim.constraints]
    assert decided == {(c.name, int(k)): float(t) for c, m in bad for k, t in zip(c.cycle[m], c.t[m], strict=True)}


def _check_dict(check: EventCheck) -> JsonObject:
    out = check.as_json()
    out.pop('windows')
    return out


def test_the_windows_change_nothing_of_the_comparison(run: Recording) -> None:
    one = compare_events(run, window=1e9)
    tiny = compare_events(run, window=0.0371)
    assert one.agree and one.recorded == run.events.size == one.matched, one.text()
    assert _check_dict(one) == _check_dict(tiny) and tiny.windows > 50
    late = compare_events(run, 2.5, window=0.0371, fast_forward=0.7)  # a fast-forward of several windows
    assert late.agree and late.recorded == int(np.count_nonzero(run.event_ns >= 2_500_000_000))
    assert _check_dict(late) == _check_dict(compare_events(run, 2.5))


def test_a_changed_recording_is_told_event_by_event() -> None:
    rec = RUNS['faults']()
    events, ns = rec.events.copy(), rec.event_ns.copy()
    original = events.copy()
    events['value'][10] += 1e-3  # another value
    ns[20] += 1  # a nanosecond late
    events['t'][20] = ns[20] / 1e9
    keep = np.ones(events.size, dtype=bool)
    keep[30] = False  # lost
    order = np.lexsort((events['sheet'], events['kind'], ns))
    order = order[keep[order]]
    changed = Recording(**{**rec.__dict__, 'events': events[order], 'event_ns': ns[order]})

    def row(i: int, t_ns: int, recorded: bool, model: bool) -> tuple[Any, ...]:
        e = original[i]
        return (t_ns / 1e9, EVENT_KINDS[int(e['kind'])], int(e['sheet']), int(e['cycle']), recorded, model)

    want = {
        row(10, int(rec.event_ns[10]), True, True),
        row(20, int(ns[20]), True, False),
        row(20, int(rec.event_ns[20]), False, True),
        row(30, int(rec.event_ns[30]), False, True),
    }
    for window in (1e9, 0.0371):
        check = compare_events(changed, window=window)
        assert not check.agree
        assert (check.values_differ, check.recorded_only, check.model_only) == (1, 1, 2), check.text()
        assert check.matched == events.size - 2 and check.largest_difference > 0.0
        got = {(d.t, d.kind, d.sheet, d.cycle, d.recorded is not None, d.model is not None) for d in check.differences}
        assert got == want
        (value,) = [d for d in check.differences if d.recorded is not None and d.model is not None]
        assert (value.recorded, value.model) == (float(events['value'][10]), float(original['value'][10]))


# --------------------------------------------------------------------------- the streamed figures' data


def test_a_margin_histogram_does_not_depend_on_how_the_margins_come() -> None:
    rng = np.random.default_rng(5)
    m = np.concatenate([rng.normal(0.0, 1e-3, 3000), rng.normal(0.02, 1e-5, 3000), [-0.5, 7.0]])
    one = MarginHistogram()
    one.add(m)
    parts = MarginHistogram()
    for chunk in np.array_split(m, 97):
        parts.add(chunk)
    for x, y in zip(one.grid(), parts.grid(), strict=True):
        np.testing.assert_array_equal(x, y)
    left, passed, violated = one.grid()
    assert left.size <= GRID_BINS and passed.sum() + violated.sum() == m.size == one.count
    assert violated.sum() == np.count_nonzero(m < 0.0) == one.violations and (one.low, one.high) == (-0.5, 7.0)
    width = 2.0**one.exponent  # the least power of two whose grid holds the range in GRID_BINS bins
    assert (7.0 - -0.5) / width <= GRID_BINS < 2 * (7.0 + 0.5) / width + 2
    np.testing.assert_array_equal(np.floor(m / width) * width >= left[0], True)
    edges = np.linspace(-0.5, 7.0, 31)
    p, v = one.counts(edges)
    direct = np.histogram(m, bins=edges)[0]
    assert p.sum() + v.sum() == m.size and np.abs(p + v - direct).sum() <= 2 * np.count_nonzero(
        np.min(np.abs(m[:, None] - edges[None, 1:-1]), axis=1) < width
    )


def test_a_thinned_sample_does_not_depend_on_how_the_rows_come() -> None:
    keys = np.arange(20_000, dtype=np.int64) * 5_000_000
    one = Thinned(300, np.dtype(np.int64))
    one.add(keys, keys)
    parts = Thinned(300, np.dtype(np.int64))
    for chunk in np.array_split(keys, 53):
        parts.add(chunk, chunk)
    np.testing.assert_array_equal(one.rows, parts.rows)
    assert one.seen == keys.size and 150 < one.rows.size <= 300 and one.fraction == 0.5**one.level


# --------------------------------------------------------------------------- (c) animate --from S


def _shapes(line: LineStream, times: np.ndarray) -> Iterator[tuple[float, Any]]:
    for t, scenery in sceneries(line, times):
        yield t, scenery.at(t)


def test_the_scenery_after_a_fast_forward_is_that_of_a_run_from_zero() -> None:
    scene = load_scene('line')
    s = 1.34375  # not at a window's end: the fast-forward's last window ends there, the run's do not
    times = s + np.arange(40) / 32.0
    from_zero = dict(_shapes(LineStream(scene), np.concatenate([np.arange(43) / 32.0, times])))
    for ff_window in (0.3, 600.0):
        line = LineStream(scene)
        fast_forward(line, s, ff_window)
        assert line.t == s and s % FRAME_WINDOW and s % ff_window
        for t, shapes in _shapes(line, times):
            want = from_zero[t]
            assert [(x.machine, x.part) for x in shapes] == [(x.machine, x.part) for x in want]
            for x, y in zip(shapes, want, strict=True):
                np.testing.assert_array_equal(x.points, y.points, err_msg=f'{x.machine}/{x.part} at {t}')


def test_animate_from_s_draws_the_frames_of_a_run_from_zero(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Both runs draw on the same axes (fixed here); the frames at the same line time are the same pixels."""
    scene = load_scene('line')
    fixed = extent(Scenery(LineModel(scene, 3.0)), np.linspace(0.0, 3.0, 60))
    monkeypatch.setattr(render_mod, 'extent', lambda scenery, times: fixed)
    frames: list[np.ndarray] = []
    write = encode.VideoWriter.write

    def keep(self: encode.VideoWriter, frame: np.ndarray) -> None:
        frames.append(frame.copy())
        write(self, frame)

    monkeypatch.setattr(encode.VideoWriter, 'write', keep)
    common = ['animate', '--scene', 'line', '--fps', '16', '--slowdown', '2', '--size', '160x96']  # 1/32 s a frame
    assert main([*common, '--from', '1.34375', '--duration', '0.5', '--out', str(tmp_path / 'late.mp4')]) == 0
    late = frames[:]
    frames.clear()
    assert main([*common, '--duration', '1.84375', '--out', str(tmp_path / 'whole.mp4')]) == 0
    assert len(late) == 16 and len(frames) == 59
    for i, frame in enumerate(late):  # line time 1.34375 + i/32 = frame 43 + i of the run from 0
        np.testing.assert_array_equal(frame, frames[43 + i], err_msg=f'frame {i}')
    assert not all(np.array_equal(a, b) for a, b in itertools.pairwise(late))  # the machine moves


def test_a_recorded_run_is_animated_from_its_stream(tmp_path: Path) -> None:
    """``analyze --animate``: the recorded commands are the stream's, and its overlays read the recorded states."""
    from folder_line.analysis.animation import TimeScale, recorded_run

    rec = read_recording(DATA / 'folder_run')
    shown = recorded_run(rec, TimeScale(0.5, 1.0, 10.0, 2.0))
    line = shown.model
    assert line is not shown.model and line.commands == rec.commands and line.t == -np.inf
    assert shown.until == rec.duration == 2.0
    assert shown.timeline.text(0.6).state == 'EXECUTE'
