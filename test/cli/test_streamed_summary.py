"""``simulate`` streams: its summary is the kept model's bit for bit whatever the windows, ``--from S`` is the
window S..S+D of a run from 0, and a long run shows the line time done and the wall time left."""

from __future__ import annotations

import io
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from folder_line import progress
from folder_line.cli import main as cli
from folder_line.cli import simulate as simulate_cli
from folder_line.cli import summary as summary_cli
from folder_line.config.scenes import list_scenes, load_scene
from folder_line.core.line.line_summary import LineSummary
from folder_line.core.line.model import simulate
from folder_line.core.line.stream import LineStream
from folder_line.core.line.tuning import Tuning
from folder_line.core.types.events import EVENT_KINDS

SCENES = list_scenes()


def _json(summary: LineSummary) -> Any:
    """What ``--json`` holds of a summary (floats round-trip exactly)."""
    return json.loads(json.dumps(summary.as_json()))


def test_every_shipped_scene_is_tested() -> None:
    assert set(SCENES) >= {'folder', 'folder_faults', 'folder_jitter', 'layup', 'layup_no_belts', 'line'}


@pytest.mark.parametrize('scene', SCENES)
def test_the_summary_is_the_kept_model_s_over_a_span_cut_in_windows(
    scene: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """30 s cut in windows of 7 s (none on a cycle boundary) give simulate(...).summary() bit for bit."""
    monkeypatch.setattr(summary_cli, 'WINDOW', 7.0)
    out = tmp_path / 's.json'
    assert cli.main(['simulate', '--scene', scene, '--duration', '30', '--json', str(out)]) == 0
    assert capsys.readouterr().err == ''  # no bar off a terminal
    kept = simulate(load_scene(scene), 30.0, sample_rate=0.0).summary()
    assert json.loads(out.read_text()) == _json(kept)


def test_the_windows_are_really_cut(monkeypatch: pytest.MonkeyPatch) -> None:
    seen: list[float] = []
    monkeypatch.setattr(summary_cli, 'WINDOW', 7.0)
    summary_cli.line_summary(load_scene('folder'), 30.0, progress=seen.append)
    assert seen == [7.0, 14.0, 21.0, 28.0, 30.0]


def test_tunings_are_commands_of_the_streamed_run(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(summary_cli, 'WINDOW', 3.0)
    out = tmp_path / 's.json'
    argv = ['simulate', '--scene', 'folder', '--duration', '12', '--tune', '5:feed_transporter.V_tr=8.0']
    assert cli.main([*argv, '--tune', '7.5:press.n_c=45000', '--json', str(out)]) == 0
    tunings = [Tuning(5.0, 'feed_transporter.V_tr', 8.0), Tuning(7.5, 'press.n_c', 45000.0)]
    kept = simulate(load_scene('folder'), 12.0, sample_rate=0.0, commands=tunings).summary()
    got = json.loads(out.read_text())
    assert got.pop('tunings') == [
        {'t': 5.0, 'key': 'feed_transporter.V_tr', 'value': 8.0, 'unit': 'm/s'},
        {'t': 7.5, 'key': 'press.n_c', 'value': 45000.0, 'unit': 'rev/h'},
    ]
    assert got == _json(kept)
    assert kept.violations.count > 0  # the slower feed does change the run


def test_list_metrics_lists_the_streamed_summary(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(summary_cli, 'WINDOW', 2.0)
    assert cli.main(['simulate', '--scene', 'layup', '--duration', '9', '--list-metrics']) == 0
    text = capsys.readouterr().out
    kept = simulate(load_scene('layup'), 9.0, sample_rate=0.0).summary()
    assert '  layup.leaves_landed' in text and f'{float(kept.layup.leaves_landed):.10g}' in text
    assert "metrics of scene 'layup' over 9 s" in text


# --------------------------------------------------------------------------- --from


def _direct_window(scene: str, start: float, end: float, commands: tuple = ()) -> dict[str, Any]:
    """The window by hand: one stream advanced to ``start`` in one go, then to ``end`` in one window."""
    stream = LineStream(load_scene(scene), commands)
    before = stream.advance(start) if start > 0.0 else None
    evaluated_before = {n: t.evaluations for n, t in stream.tallies.constraints.items()}
    kinds_before = stream.tallies.kinds.copy()
    cycles_before = stream.summary().cycles if before is not None else 0
    window = stream.advance(end)
    rows = [*window.constraints, *stream.finish()]
    after = stream.summary()
    out: dict[str, Any] = {'cycles': after.cycles - cycles_before, 'constraints': {}}
    kinds = stream.tallies.kinds - kinds_before
    out['events'] = {k: int(n) for k, n in zip(EVENT_KINDS, kinds.tolist(), strict=True) if n}
    for name in stream.tallies.constraints:
        m = np.concatenate([r.margin for r in rows if r.name == name] or [np.zeros(0)])
        out['constraints'][name] = (m.size, int(np.count_nonzero(m < 0)), float(m.min()) if m.size else None)
        assert stream.tallies.constraints[name].evaluations - evaluated_before[name] == m.size
    return out


@pytest.mark.parametrize(('scene', 'start'), [('folder_faults', 33.3), ('line', 12.0), ('layup', 61.0)])
def test_from_s_is_the_window_of_a_run_from_0(
    scene: str, start: float, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """What the help says: the line runs from 0 and is fast-forwarded; the summary is of S..S+D: the cycles,
    events and constraint rows handed out from S on (checked against one stream advanced by hand)."""
    monkeypatch.setattr(summary_cli, 'WINDOW', 4.0)
    monkeypatch.setattr(summary_cli, 'FAST_FORWARD', 10.0)  # the fast-forward in several windows too
    out = tmp_path / 'w.json'
    assert cli.main(['simulate', '--scene', scene, '--from', f'{start}', '--duration', '20', '--json', str(out)]) == 0
    got = json.loads(out.read_text())
    assert (got['from_s'], got['to_s'], got['duration_s']) == (start, start + 20.0, 20.0)
    want = _direct_window(scene, start, start + 20.0)
    assert got['cycles'] == want['cycles'] and got['events'] == want['events']
    for name, (n, bad, low) in want['constraints'].items():
        if n:
            m = got['min_margin'][name]
            assert (m['evaluations'], m['violations'], m['margin']) == (n, bad, low)
        else:
            assert name not in got['min_margin']
    assert got['violations']['count'] == sum(bad for _, bad, _ in want['constraints'].values())
    assert 'folder' not in got and 'layup' not in got  # a run's cumulative figures are not the window's


@pytest.mark.parametrize('scene', SCENES)
def test_from_0_is_the_run_itself(scene: str) -> None:
    full = simulate(load_scene(scene), 15.0, sample_rate=0.0).summary().as_json()
    window = summary_cli.window_summary(load_scene(scene), 0.0, 15.0, window=4.0).as_json()
    assert {k: v for k, v in window.items() if k not in ('from_s', 'to_s')} == {k: full[k] for k in window if k in full}
    assert set(window) - set(full) == {'from_s', 'to_s'}


def test_windows_add_up_to_the_run() -> None:
    """Events, cycles and sheets of 0..S and of S..S+D are those of 0..S+D."""
    scene = load_scene('line')
    head = simulate(scene, 8.0, sample_rate=0.0).summary()
    tail = summary_cli.window_summary(scene, 8.0, 12.0, window=5.0)
    whole = simulate(scene, 20.0, sample_rate=0.0).summary()
    assert {k: head.events.get(k, 0) + tail.events.get(k, 0) for k in whole.events} == whole.events
    assert head.cycles + tail.cycles == whole.cycles
    assert head.sheets_counted + tail.sheets_counted == whole.sheets_counted
    counts = np.add(head.layup.landing.histogram.counts, tail.landing.counts)
    assert counts.tolist() == whole.layup.landing.histogram.counts


def test_a_tuning_before_from_acts_in_the_fast_forward(tmp_path: Path) -> None:
    out = tmp_path / 'w.json'
    argv = ['simulate', '--scene', 'folder', '--from', '10', '--duration', '5', '--json', str(out)]
    assert cli.main([*argv, '--tune', '4:feed_transporter.V_tr=8.0']) == 0
    got = json.loads(out.read_text())
    want = _direct_window('folder', 10.0, 15.0, (Tuning(4.0, 'feed_transporter.V_tr', 8.0),))
    assert got['min_margin']['feed_window']['violations'] == want['constraints']['feed_window'][1] > 0
    assert got['tunings'][0]['t'] == 4.0


def test_from_is_printed_and_listed_as_the_window(capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(['simulate', '--scene', 'folder', '--from', '3600', '--duration', '60']) == 0
    text = capsys.readouterr().out
    assert text.startswith('scene folder: line time 3600..3660 s (60 s from --from 3600), seed 1')
    assert 'the line ran from 0 s; counted from 3600 s on' in text
    assert 'cycles: 833 ' in text
    assert cli.main(['simulate', '--scene', 'folder', '--from', '3600', '--duration', '60', '--list-metrics']) == 0
    listed = capsys.readouterr().out
    assert 'over line time 3600..3660 s (--from)' in listed and '  from_s' in listed


def test_the_help_says_what_from_does(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        cli.main(['simulate', '--help'])
    text = ' '.join(capsys.readouterr().out.split())
    assert '--from S the line time the output starts at' in text
    assert 'fast-forwarded to S keeping nothing' in text and 'window S..S+D' in text
    assert 'Not with --bag or --samples' in text


@pytest.mark.parametrize(
    ('args', 'words'),
    [
        (['--from', '5', '--bag', 'B'], '--from=5.0: not with --bag'),
        (['--from', '5', '--samples', '2'], '--from=5.0: not with --samples'),
        (['--from', '9999990', '--duration', '20'], '--from=9999990.0: --from + --duration = 10000010 s of line time'),
        (['--from', '5', '--duration', '1', '--tune', '6.5:pile.t_lower=0.1'], 'T must be before'),
    ],
)
def test_a_bad_from_is_one_line_and_nothing_written(
    args: list[str], words: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / 'w.json'
    rest = [str(tmp_path / a) if a == 'B' else a for a in args]
    argv = ['simulate', '--scene', 'folder', *rest, *([] if 'B' in args else ['--json', str(out)])]
    assert cli.main(argv) == 2
    captured = capsys.readouterr()
    (line,) = captured.err.strip().splitlines()
    assert line.startswith('folder-line: error: ') and words in line, line
    assert captured.out == '' and not out.exists() and not (tmp_path / 'B').exists()


# --------------------------------------------------------------------------- the progress bar


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_a_long_run_on_a_terminal_shows_line_time_and_the_wall_time_left(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    terminal = _Terminal()
    monkeypatch.setattr('sys.stderr', terminal)
    monkeypatch.setattr(summary_cli, 'WINDOW', 10.0)
    monkeypatch.setattr(simulate_cli, 'BAR_DELAY', 0.0)
    monkeypatch.setattr(progress, 'ESTIMATE_AFTER', 0.0)
    drawn: list[str] = []
    real_show = progress.LineTimeProgress.show

    def show(self: progress.LineTimeProgress, t: float, *, force: bool = False) -> None:
        real_show(self, t, force=True)  # every window drawn, not one per redraw period
        drawn.append(self.shown)

    monkeypatch.setattr(progress.LineTimeProgress, 'show', show)
    assert cli.main(['simulate', '--scene', 'line', '--duration', '120']) == 0
    assert drawn[0] == f'[{"." * 40}]    0.00 / 120 s of line time'
    middle = drawn[len(drawn) // 2]
    assert '/ 120 s of line time, ' in middle and middle.endswith(' left'), middle
    assert drawn[-1].startswith(f'[{"#" * 40}]  120.00 / 120 s of line time, done in '), drawn[-1]
    screen = terminal.getvalue()
    assert screen.endswith('\n') and '\r' in screen
    assert capsys.readouterr().out.startswith('scene line: 120 s of line time')  # the result on stdout, whole


def test_a_quick_run_on_a_terminal_shows_no_bar(monkeypatch: pytest.MonkeyPatch) -> None:
    terminal = _Terminal()
    monkeypatch.setattr('sys.stderr', terminal)
    assert cli.main(['simulate', '--scene', 'folder', '--duration', '1']) == 0
    assert terminal.getvalue() == ''  # done within BAR_DELAY


def test_the_estimate_is_wall_time_per_line_time_since_the_line_moved() -> None:
    now = [0.0]
    bar = progress.LineTimeProgress(io.StringIO(), 1000.0, clock=lambda: now[0])
    bar.show(0.0)
    now[0] = 4.0
    bar.show(200.0)
    assert bar.left(200.0, 4.0) == pytest.approx(16.0) and math.isfinite(bar.left(200.0, 4.0) or math.inf)
