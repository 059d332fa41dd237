"""``simulate --plots DIR``: analyze's figures of the simulated line, streamed, from bounded data that is exact
where it counts (margins, landings, exits) and sampled where it draws points (joint states, single leaves)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from folder_line.analysis.figures import FIGURES
from folder_line.cli import plots
from folder_line.cli.main import main
from folder_line.config.scenes import load_scene
from folder_line.core.line.line_summary import LineSummary, WindowSummary
from folder_line.core.line.model import LineModel, simulate
from folder_line.core.line.stream import LineStream
from folder_line.core.types.events import event_kind

_FOLDER = {'efficiency.png', 'cyclogram.png', 'margins.png'}


@pytest.mark.parametrize(
    ('scene', 'figures'),
    [('line', set(FIGURES)), ('layup', {'exit_speeds.png', 'landing.png', 'margins.png'}), ('folder', _FOLDER)],
)
def test_each_scene_gets_its_figures_and_the_summary_of_the_same_run(
    scene: str, figures: set[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out, plain = tmp_path / 'plots', tmp_path / 'plain.json'
    drawn_json = tmp_path / 'drawn.json'
    assert main(['simulate', '--scene', scene, '--duration', '4', '--plots', str(out), '--json', str(drawn_json)]) == 0
    printed = capsys.readouterr().out
    assert {p.name for p in out.iterdir()} == figures
    for name in figures:
        assert f'wrote {out / name}' in printed
        assert (out / name).read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    assert main(['simulate', '--scene', scene, '--duration', '4', '--json', str(plain)]) == 0
    # one streamed run gives the figures and the summary: simulate's, bit for bit
    assert drawn_json.read_text() == plain.read_text()
    expected = simulate(load_scene(scene), 4.0, sample_rate=0.0).summary()
    assert json.loads(plain.read_text()) == json.loads(json.dumps(expected.as_json()))


def test_plots_with_bag_draws_that_bag(tmp_path: Path) -> None:
    out, bag = tmp_path / 'plots', tmp_path / 'bag'
    assert main(['simulate', '--scene', 'folder', '--duration', '2', '--bag', str(bag), '--plots', str(out)]) == 0
    assert (bag / 'metadata.yaml').is_file()
    assert {p.name for p in out.iterdir()} == _FOLDER


@pytest.fixture(scope='module')
def line_long() -> tuple[plots.FigureData, LineSummary | WindowSummary, float]:
    """A span of the line long enough that the figures keep a sample, not everything."""
    duration = 300.0
    data, summary = plots.collect(load_scene('line'), duration)
    return data, summary, duration


def test_what_the_figures_keep_is_bounded_and_its_counts_exact(line_long: tuple) -> None:
    data, summary, duration = line_long
    ticks = data.ticks
    assert ticks.total == round(duration * 200) + 1
    assert ticks.level == math.ceil(math.log2(ticks.total / plots.JOINT_SAMPLES))  # 60001 ticks: 1/16 drawn
    t = data.joint('t')
    assert 0.5 * plots.JOINT_SAMPLES < t.size < 1.5 * plots.JOINT_SAMPLES
    assert np.all(np.diff(t) > 0) and t[0] >= 0.0 and t[-1] <= duration
    assert np.allclose(t * 200, np.round(t * 200), rtol=0, atol=1e-6)  # on the tick grid
    for name, h in data.margins.items():
        m = summary.min_margin[name]
        assert (h.count, h.violated, h.low) == (m.evaluations, m.violations, m.margin)
        assert int(h.passed.sum() + h.failed.sum()) == h.count and h.passed.size <= plots.MARGIN_BINS
    assert data.landed.tolist() == summary.layup.landing.histogram.counts
    exits = summary.events['leaf_exit']
    assert data.exit_counts['C']['all'] + data.exit_counts['E']['all'] == exits
    for e in 'CE':
        at, off = data.exits[e, False], data.exits[e, True]
        assert at.count + off.count == data.exit_counts[e]['all'] and off.count == data.exit_counts[e]['early']
        assert at.column('v').size == min(plots.LEAF_SAMPLES, at.count) and off.column('v').size == off.count
    assert data.landed_x.count == summary.events['leaf_landed']
    assert data.landed_x.column('x').size == plots.LANDING_MARKS


def test_the_joint_states_drawn_are_the_line_s_at_those_ticks(line_long: tuple) -> None:
    data, _, _ = line_long
    t = data.joint('t')[:50]  # the start-up: the kept model of 3 s holds them
    t = t[t <= 3.0]
    model = LineModel(load_scene('line'), 3.0)
    crank = model.sample('drive', t)
    i = crank.names.index('layup_crank')
    assert np.array_equal(data.joint('phi')[: t.size], np.mod(crank.position[:, i], 2.0 * math.pi))
    assert np.array_equal(data.joint('w3')[: t.size], crank.velocity[:, crank.names.index('transporter3')])
    feed = model.sample('feed', t)
    assert np.array_equal(data.joint('x')[: t.size], feed.position[:, feed.names.index('carriage')])


def test_the_ticks_drawn_are_a_pseudo_random_nested_fraction_of_the_grid() -> None:
    every, drawn = plots.TickGrid(0.0, 100.0, 1000).between(-math.inf, 100.0)
    assert every.size == 20001 and drawn.size < 1.5 * 1000
    coarser = plots.TickGrid(0.0, 100.0, 500).between(-math.inf, 100.0)[1]
    assert set(coarser.tolist()) <= set(drawn.tolist())  # a level higher keeps a subset
    gaps = np.diff(np.round(drawn * 200).astype(int))
    assert len(set(gaps.tolist())) > 5  # no period: nothing to alias with a machine's
    # windows cut anywhere draw the same ticks
    ticks = plots.TickGrid(0.0, 100.0, 1000)
    parts = [ticks.between(a, b)[1] for a, b in [(-math.inf, 13.333), (13.333, 60.0), (60.0, 100.0)]]
    assert np.array_equal(np.concatenate(parts), drawn)


@pytest.mark.parametrize('whole', [False, True])
def test_the_streamed_histogram_counts_exactly_in_its_final_bins(whole: bool) -> None:
    rng = np.random.default_rng(4)
    chunks = [rng.normal(0.3, 0.01 * 10**k, 997) for k in range(5)]  # the spread grows chunk by chunk
    if whole:
        chunks = [np.round(c * 10) for c in chunks]
    h = plots.StreamedHistogram(whole=whole, max_bins=40)
    for c in chunks:
        h.add(c)
    x = np.concatenate(chunks)
    edges = h.edges
    assert h.passed.size <= 40 and edges[0] <= x.min() and x.max() < edges[-1]
    assert h.count == x.size and h.violated == int(np.count_nonzero(x < 0)) and h.low == x.min()
    assert np.array_equal(h.passed, np.histogram(x[x >= 0], edges)[0])
    assert np.array_equal(h.failed, np.histogram(x[x < 0], edges)[0])
    assert np.any(np.isclose(edges, 0.0 if not whole else -0.5, atol=0))  # no bin holds both kinds
    assert math.log2(h.width).is_integer()


def test_the_cyclogram_shows_the_first_cycles_and_the_first_violated_with_its_neighbours() -> None:
    scene = load_scene('folder_faults')
    data, summary = plots.collect(scene, 30.0)
    rows = data.cyclogram.done()
    first_bad = min(v.cycle for v in summary.violations.first)
    assert [r.cycle for r in rows] == [*range(8), first_bad - 1, first_bad, first_bad + 1]
    model = LineModel(scene, 30.0)
    ev = model.events
    for row in rows:
        contact = ev[(ev['kind'] == event_kind('knife_contact')) & (ev['cycle'] == row.cycle)]
        assert row.contact == contact['t'][0]
        hand = ev[(ev['kind'] == event_kind('sheet_handover')) & (ev['cycle'] == row.cycle)]
        assert [s.sheet for s in row.sheets] == hand['sheet'].tolist()
        for s in row.sheets:
            rel = ev[(ev['kind'] == event_kind('released_on_pile')) & (ev['sheet'] == s.sheet)]
            assert s.release == (rel['t'][0] if rel.size else None)
        for c in model.constraints:
            if c.name in row.margins:
                assert row.margins[c.name] == c.margin[c.cycle == row.cycle][0]
    assert any(m < 0 for m in rows[-2].margins.values())


def test_from_draws_the_window(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    scene = load_scene('folder_faults')
    start, duration = 40.0, 20.0
    data, summary = plots.collect(scene, duration, start=start)
    assert data.joint('t').min() >= start and data.joint('t').max() <= start + duration
    for name, h in data.margins.items():
        assert h.count == summary.min_margin[name].evaluations
    rows = data.cyclogram.done()
    stream = LineStream(scene)
    stream.advance(start + duration)
    timing = data.cyclogram.timing
    began = stream.drive.time_of(np.array([rows[0].cycle * timing.T + timing.knife.t_out]))[0]
    assert began >= start  # the first cycle drawn is the first whose feed began in the window
    assert data.cyclogram.cycles == summary.events['knife_contact']
    out = tmp_path / 'plots'
    argv = ['simulate', '--scene', 'folder_faults', '--from', '40', '--duration', '20', '--plots', str(out)]
    assert main(argv) == 0
    assert {p.name for p in out.iterdir()} == _FOLDER
    assert 'line time 40..60 s' in capsys.readouterr().out


@pytest.mark.parametrize(
    ('args', 'option'),
    [
        (['--samples', '3'], '--samples'),
        (['--list-keys'], '--plots'),
        (['--from', '1', '--samples', '3'], '--from'),
        (['--from', '1', '--list-keys'], '--from'),
    ],
)
def test_a_bad_combination_is_one_line_and_nothing_written(
    args: list[str], option: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / 'plots'
    argv = ['simulate', '--scene', 'folder', '--duration', '1', '--plots', str(out), *args]
    assert main(argv) == 2
    captured = capsys.readouterr()
    (line,) = captured.err.strip().splitlines()
    assert line.startswith('folder-line: error: ') and option in line, line
    assert captured.out == ''
    assert not out.exists()


def test_from_with_bag_is_refused_before_anything_is_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out, bag = tmp_path / 'plots', tmp_path / 'bag'
    argv = ['simulate', '--scene', 'folder', '--from', '1', '--bag', str(bag), '--plots', str(out)]
    assert main(argv) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.startswith('folder-line: error: --from=1.0: not with --bag: a bag is written from line time 0'), line
    assert not out.exists() and not bag.exists()


def test_a_plots_path_that_is_a_file_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / 'plots'
    out.write_text('mine\n')
    assert main(['simulate', '--scene', 'folder', '--duration', '1', '--plots', str(out)]) == 2
    captured = capsys.readouterr()
    assert '--plots' in captured.err and captured.out == ''
    assert out.read_text() == 'mine\n'


def test_a_figure_name_taken_by_a_folder_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / 'plots'
    (out / 'margins.png').mkdir(parents=True)
    assert main(['simulate', '--scene', 'folder', '--duration', '1', '--plots', str(out)]) == 2
    captured = capsys.readouterr()
    assert '--plots' in captured.err and 'margins.png' in captured.err and captured.out == ''
    assert [p.name for p in out.iterdir()] == ['margins.png']
