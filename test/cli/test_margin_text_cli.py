"""Margins in every text output: one unit per kind, what one_per_cycle means, ``leaf k`` for chute_speed."""

from __future__ import annotations

import io
import re
from pathlib import Path
from types import SimpleNamespace

import pytest

from folder_line.analysis.event_check import EventCheck
from folder_line.analysis.figures import _margin_text
from folder_line.analysis.report import print_analysis
from folder_line.analysis.summary import AnalysisSummary
from folder_line.bag.statuses import violation_status
from folder_line.cli.main import main
from folder_line.cli.montecarlo import print_table
from folder_line.cli.summary import print_summary
from folder_line.cli.sweep import _range_text
from folder_line.core.line.line_summary import LineSummary, MarginFigures, ViolationRecord, Violations
from folder_line.core.line.margin_text import MARGIN_MEANINGS
from folder_line.core.supervision.records import Violation
from folder_line.studies.montecarlo_figures import (
    Aggregate,
    ConstraintStats,
    MarginDistribution,
    MonteCarloResult,
    Proportion,
)


def _margin_rows(text: str) -> dict[str, str]:
    section = text.split('smallest margin per constraint (>= 0 passes):\n', 1)[1].split('what the margins mean:', 1)[0]
    return {line.split()[0]: line for line in section.splitlines()}


def test_simulate_prints_each_margin_in_its_own_unit_and_says_what_it_means(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(['simulate', '--scene', 'line', '--duration', '2']) == 0
    text = capsys.readouterr().out
    rows = _margin_rows(text)
    assert set(rows) == set(MARGIN_MEANINGS)
    assert re.search(r' \+\d+\.\d{4} ms  at cycle \d+ ', rows['feed_window'])
    assert re.search(r' \+\d+\.\d{4} ms  at cycle \d+ ', rows['settled_before_knife'])
    assert re.search(r' \+0\.\d{4} mm  at cycle \d+ ', rows['rebound'])  # not '+0.000918875 m'
    assert re.search(r' \+0\.\d{4} m/s  at leaf \d+ ', rows['chute_speed'])  # a leaf, not a cycle
    assert ' 1 sheet per cycle  at cycle 0 ' in rows['one_per_cycle'] and rows['one_per_cycle'].endswith(
        'best possible'
    )
    assert ' +1e-06  at cycle ' in rows['release_at_min_speed']
    assert '+0 sheets' not in text and not any(re.search(r'\d m(?![a-z/])', row) for row in rows.values())  # no metres
    legend = text.split('what the margins mean:\n', 1)[1]
    for name, meaning in MARGIN_MEANINGS.items():
        assert re.search(rf'^  {name} +{re.escape(meaning)}$', legend, re.MULTILINE), name


def _summary(violations: list[ViolationRecord]) -> LineSummary:
    return LineSummary(
        scene='made up',
        duration_s=1.0,
        seed=1,
        effects=[],
        cycles=3,
        sheets_counted=3,
        violations=Violations(len(violations), violations),
        min_margin={
            'one_per_cycle': MarginFigures(margin=-1.0, unit='sheets', cycle=2, violations=1, evaluations=3),
            'chute_speed': MarginFigures(margin=-0.25, unit='m/s', cycle=448, violations=1, evaluations=500),
        },
        events={},
    )


def test_violations_name_the_leaf_of_chute_speed_and_the_sheets_off() -> None:
    out = io.StringIO()
    first = [
        ViolationRecord(cycle=2, constraint='one_per_cycle', margin=-1.0, unit='sheets'),
        ViolationRecord(cycle=448, constraint='chute_speed', margin=-0.25, unit='m/s'),
    ]
    print_summary(_summary(first), out)
    text = out.getvalue()
    assert '  cycle 2: one_per_cycle margin 1 sheet off\n' in text
    assert '  leaf 448: chute_speed margin -0.2500 m/s\n' in text
    rows = _margin_rows(text)
    assert '1 sheet off  at cycle 2 ' in rows['one_per_cycle'] and 'best possible' not in rows['one_per_cycle']
    assert '-0.2500 m/s  at leaf 448 ' in rows['chute_speed'] and 'cycle 448' not in text


def test_monte_carlo_table_in_the_same_units_with_the_legend() -> None:
    def entry(unit: str, q: tuple[float, float, float]) -> ConstraintStats:
        return ConstraintStats(
            unit,
            Proportion(0.0, (0.0, 0.01), 0, 40),
            Proportion(0.0, (0.0, 0.6), 0, 4),
            MarginDistribution(10, quantiles={'0.01': q[0], '0.5': q[1], '0.99': q[2]}),
        )

    constraints = {
        'feed_window': entry('s', (-3e-5, 1e-4, 2e-4)),
        'one_per_cycle': entry('sheets', (-1.0, 0.0, 0.0)),
        'rebound': entry('m', (0.000918875, 0.000918875, 0.000918875)),
    }
    result = MonteCarloResult('folder_jitter', 1, 2.0, Aggregate(4, (), 'Clopper-Pearson', constraints, {}))
    out = io.StringIO()
    print_table(result, out)
    lines = out.getvalue().splitlines()
    table = lines[: lines.index('what the margins mean (>= 0 passes):')]
    row = {line.split()[0]: line for line in table[2:]}
    assert row['feed_window'].endswith('-0.0300 ms         +0.1000 ms         +0.2000 ms')
    assert row['one_per_cycle'].endswith('1 sheet off  1 sheet per cycle  1 sheet per cycle')
    assert row['rebound'].endswith('+0.9189 mm' + ' ' * 9 + '+0.9189 mm' + ' ' * 9 + '+0.9189 mm')
    assert 'what the margins mean (>= 0 passes):' in lines
    assert f'  rebound        {MARGIN_MEANINGS["rebound"]}' in lines


def test_sweep_prints_margin_ranges_as_its_chart_shows_them() -> None:
    assert _range_text('min_margin_s.feed_window', 's', -0.0205968, 0.0249567) == '-20.5968 ms to +24.9567 ms'
    assert _range_text('min_margin.rebound.margin', 'm', -0.00045, 0.00155) == '-0.4500 mm to +1.5500 mm'
    assert _range_text('min_margin.one_per_cycle.margin', 'sheets', 0.0, 0.0) == '1 sheet per cycle at every point'
    assert _range_text('violations.count', '', 0.0, 27.0) == '0 to 27'
    assert _range_text('folder.knife_window_s', 's', 0.03, 0.03) == '0.03 to 0.03 s'  # not a margin: as it is


def test_cyclogram_margins_of_a_cycle() -> None:
    text = _margin_text(
        {
            'feed_window': 1e-4,
            'settled_before_knife': 0.0120975,
            'one_per_cycle': -1.0,
            'rebound': 0.000918875,
            'release_at_min_speed': 1e-6,
        }
    )
    assert text == 'feed +0.1 ms | settled +12.1 ms | 1 sheet off | rebound +0.919 mm | K_v at release +1e-06'
    assert _margin_text({'one_per_cycle': 0.0}) == '1 sheet'


def test_diagnostics_and_the_supervisors_text_name_the_leaf() -> None:
    leaf = Violation(2.5, 448, 'chute_speed', -0.25, 'm/s', 'hold', 'EXECUTE')
    ok, message, values = violation_status(leaf)
    assert not ok and message == 'chute_speed violated in leaf 448: hold'
    assert values['cycle'] == 448 and values['margin'] == -0.25  # the values stay as they were: SI, the index
    cycle = Violation(1.0, 13, 'feed_window', -0.0049, 's', 'hold', 'EXECUTE')
    assert violation_status(cycle)[1] == 'feed_window violated in cycle 13: hold'


def _analysis_summary() -> AnalysisSummary:
    """:func:`_summary` with no violation, as ``analyze`` holds it."""
    return AnalysisSummary(
        scene='made up',
        duration_s=1.0,
        seed=1,
        effects=[],
        cycles=3,
        sheets_counted=3,
        violations=Violations(0, []),
        min_margin={
            'one_per_cycle': MarginFigures(margin=-1.0, unit='sheets', cycle=2, evaluations=3, violations=1),
            'chute_speed': MarginFigures(margin=-0.25, unit='m/s', cycle=448, evaluations=500, violations=1),
        },
        events={},
        t_end=1.0,
        t_from=0.0,
        sheet_counter=None,
        messages={},
        lost=None,
        events_check=EventCheck(0.0, 1.0),
        recorded_transitions=[],
        gaps=[],
        unjudged='',
        transitions=[],
        replay_matches=None,
        replay_violations=None,
        transitions_source='',
    )


def test_analyze_prints_margins_in_the_same_units(tmp_path: Path) -> None:
    summary = _analysis_summary()
    result = SimpleNamespace(summary=summary, report=tmp_path / 'report.md', figures={}, csv={}, out=tmp_path)
    out = io.StringIO()
    print_analysis(result, out)  # type: ignore[arg-type]
    text = out.getvalue()
    assert '  one_per_cycle            min margin 1 sheet off, at cycle 2, 1 of 3 violated\n' in text
    assert '  chute_speed              min margin -0.2500 m/s, at leaf 448, 1 of 500 violated\n' in text
