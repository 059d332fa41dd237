"""The accuracy benchmark's plumbing: Pareto helpers, outputs, the CLI verb (synthetic rows, no study run)."""

from __future__ import annotations

import csv
import json
import math

import pytest

from folder_line.accuracy import output, pareto
from folder_line.accuracy.bench import STUDIES, BenchResult, check_studies
from folder_line.accuracy.measure import COLUMNS, Row, cpu_per_call
from folder_line.cli import main as cli
from folder_line.errors import ParameterError


def _row(
    method: str, value: float, error: float, cpu: float, study: str = 'fourbar', quantity: str = 'rocker angle'
) -> Row:
    return Row(study, method, 'rtol', value, error, cpu, quantity, 'rad', 'synthetic')


def _power_law(method: str, c_err: float, c_cpu: float, order: float) -> list[Row]:
    """error = c_err h^order, cpu = c_cpu / h for h = 1e-1 .. 1e-4: a method of that order."""
    return [_row(method, h, c_err * h**order, c_cpu / h) for h in (1e-1, 1e-2, 1e-3, 1e-4)]


def test_row_rejects_non_finite_and_negative_values():
    with pytest.raises(ValueError, match='error'):
        _row('m', 1.0, math.nan, 1.0)
    with pytest.raises(ValueError, match='cpu_s_per_sim_s'):
        _row('m', 1.0, 1.0, math.inf)
    with pytest.raises(ValueError, match='error >= 0'):
        _row('m', 1.0, -1e-9, 1.0)
    with pytest.raises(ValueError, match='cpu_s_per_sim_s > 0'):
        _row('m', 1.0, 1.0, 0.0)
    assert list(_row('m', 1.0, 0.0, 1.0).as_dict()) == list(COLUMNS)
    assert COLUMNS[:5] == ('method', 'knob', 'value', 'error', 'cpu_s_per_sim_s')


def test_pareto_front_drops_dominated_points():
    rows = [
        _row('a', 1, 1e-3, 1.0),
        _row('a', 2, 1e-2, 2.0),
        _row('b', 3, 1e-6, 3.0),
        _row('b', 4, 1e-6, 4.0),
        _row('b', 5, 1e-9, 10.0),
    ]
    front = pareto.pareto_front(rows)
    assert [r.value for r in front] == [1, 3, 5]


def test_cheapest_picks_the_least_cpu_that_reaches_the_target():
    rows = _power_law('slow', 1.0, 1.0, 2) + _power_law('fast', 1.0, 1.0, 4)
    ch = pareto.cheapest(rows, 'fourbar', 1e-8)
    assert ch.row is not None and ch.row.method == 'fast' and ch.row.value == 1e-2
    assert pareto.cheapest(rows, 'fourbar', 1e-30).row is None
    assert pareto.cheapest(rows, 'motor', 1.0).row is None


def test_equal_error_ratio_on_power_laws_matches_the_closed_form():
    # a: error = h^4, cpu = 1/h; b: error = h^2, cpu = 1/h. At error E: cpu_a = E^-1/4, cpu_b = E^-1/2.
    rows = _power_law('a', 1.0, 1.0, 4) + _power_law('b', 1.0, 1.0, 2)
    q = pareto.equal_error_ratio(rows, 'fourbar', 'a', 'b', error=1e-6)
    assert q.reached
    assert q.cpu_b == pytest.approx(1e3, rel=1e-12)  # log-log interpolation is exact on a power law
    assert q.cpu_a == pytest.approx(1e2)  # the cheapest measured point of a at or below 1e-6: h = 1e-2 (1e-8)
    assert q.ratio == pytest.approx(10.0)
    # default level: a's best error 1e-16 is beyond b's best 1e-8, so the ratio is a lower bound at b's best
    q = pareto.equal_error_ratio(rows, 'fourbar', 'a', 'b')
    assert not q.reached and q.error == pytest.approx(1e-8) and q.cpu_b == pytest.approx(1e4)
    assert q.cpu_a == pytest.approx(1e2) and q.ratio == pytest.approx(100.0)
    with pytest.raises(ValueError, match='never reaches'):
        pareto.equal_error_ratio(rows, 'fourbar', 'a', 'b', error=1e-20)
    with pytest.raises(KeyError):
        pareto.equal_error_ratio(rows, 'fourbar', 'a', 'nope')


def test_cpu_per_call_measures_process_time_not_sleep():
    import time

    busy = cpu_per_call(lambda: sum(range(20000)), min_s=0.01)
    idle = cpu_per_call(lambda: time.sleep(0.002), min_s=0.001, repeats=1)
    assert 0.0 < busy < 0.05
    assert idle < 0.002  # sleeping costs (almost) no CPU


def _result() -> BenchResult:
    rows = (
        _power_law('closed form (folder_line)', 1e-12, 1e-3, 0)
        + _power_law('solve_ivp RK45', 1.0, 1e-2, 1)
        + [_row('exact', 1.0, 0.0, 5e-3, study='events', quantity='event time')]
    )
    return BenchResult(tuple(rows), True, {'fourbar': 1.0, 'events': 0.5}, {'python': '3.11', 'platform': 'x'})


def test_write_outputs_csv_markdown_png_json(tmp_path):
    res = _result()
    paths = output.write_outputs(res, tmp_path / 'acc', 'folder-line bench accuracy --quick')
    assert sorted(p.name for p in paths) == ['accuracy.csv', 'accuracy.json', 'accuracy.md', 'accuracy.png']
    with open(tmp_path / 'acc' / 'accuracy.csv', newline='') as fh:
        got = list(csv.DictReader(fh))
    assert list(got[0]) == list(COLUMNS) and len(got) == len(res.rows)
    assert [float(g['error']) for g in got] == [r.error for r in res.rows]  # repr: round-trip exact
    md = (tmp_path / 'acc' / 'accuracy.md').read_text()
    assert '| fourbar | closed form (folder_line) | solve_ivp RK45 |' in md
    assert 'folder-line bench accuracy --quick' in md
    png = (tmp_path / 'acc' / 'accuracy.png').read_bytes()
    assert png[:8] == b'\x89PNG\r\n\x1a\n' and len(png) > 10_000
    doc = json.loads((tmp_path / 'acc' / 'accuracy.json').read_text())
    assert doc['quick'] is True and len(doc['rows']) == len(res.rows)
    (cmp,) = [c for c in doc['comparisons'] if c['method_b'] == 'solve_ivp RK45']
    assert cmp['ratio'] > 1.0


def test_a_failing_render_writes_nothing(tmp_path, monkeypatch):
    def boom(rows):
        raise RuntimeError('render failed')

    monkeypatch.setattr(output, 'pareto_png', boom)
    with pytest.raises(RuntimeError):
        output.write_outputs(_result(), tmp_path / 'acc', 'cmd')
    assert not (tmp_path / 'acc').exists()


def test_check_studies():
    assert check_studies(None) == STUDIES
    assert check_studies(['events', 'linkage']) == ('linkage', 'events')
    with pytest.raises(ParameterError, match="--only='nope'"):
        check_studies(['nope'])


def test_cli_rejects_bad_input_with_exit_2_and_writes_nothing(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(['bench', 'accuracy', '--only', 'nope', '--out', str(tmp_path / 'a')])
    assert exc.value.code == 2
    assert "--only: invalid choice: 'nope'" in capsys.readouterr().err
    blocker = tmp_path / 'file'
    blocker.write_text('x')
    assert cli.main(['bench', 'accuracy', '--quick', '--out', str(blocker)]) == 2
    err = capsys.readouterr().err
    assert err.count('\n') == 1 and f'--out={str(blocker)!r}' in err and 'not a directory' in err
    assert blocker.read_text() == 'x' and not (tmp_path / 'a').exists()
