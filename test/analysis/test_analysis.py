"""Replay analysis of recorded runs (``folder-line analyze``): real bags of real runs.

Recorded runs, no DDS: the committed runs of the folder scene and of the layup scene
(2 s each, ``test/data/``, see its README), copied into ``tmp_path`` and analysed
there. The figures, the CSVs, the figures' data, the CLI and the absence of ROS are
checked on them, the data against the model's kinematics sample by sample.

Live runs: three in-process runs of the line, each on this process's own ROS domain
and recorded by ``run_line`` in ``tmp_path``: the folder scene (2 s), the layup scene
(2 s) and the folder with seeded faults (2 s: a late sheet in cycle 13 makes the
supervisor hold the line). What the live line did is checked there: the analysis of
each against ``simulate`` of the bag's scene for the line time reached, the events
against the line model at the nanosecond (and ``analyze``'s own comparison with the streamed
line), the replayed supervisor against the states the live one published.
"""

from __future__ import annotations

import io
import json
import math
import re
import shutil
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from _loaded import ros_modules_loaded
from hypothesis import given
from hypothesis import strategies as st

from folder_line.analysis import (
    SUPERVISOR_DEFAULTS,
    AnalysisResult,
    analyze,
    csv_name,
    cycle_rows,
    efficiency_data,
    evaluate,
    exit_speed_data,
    landing_data,
    recorded_transitions,
    transitions_agree,
)
from folder_line.analysis.supervisor_replay import StateTransition
from folder_line.core.line.line_summary import LineSummary
from folder_line.core.line.margin_text import MARGIN_MEANINGS, shown_unit
from folder_line.core.line.model import LineModel, simulate
from folder_line.interfaces import (
    CLOCK_TOPIC,
    COMMANDS_TOPIC,
    DIAGNOSTICS_TOPIC,
    EVENT_KINDS,
    EVENTS_TOPIC,
    LANDING_TOPIC,
    SHEET_COUNT_TOPIC,
    SUPERVISOR_STATE_TOPIC,
    event_source,
    parse_event_source,
)

REPO = Path(__file__).resolve().parents[2]
DATA = Path(__file__).resolve().parents[1] / 'data'
PNG = b'\x89PNG\r\n\x1a\n'


def _record(base: Path, scene: str, duration: float) -> Path:
    """Run the line in-process (rtf 2) on this process's own ROS domain (test/conftest.py); the run directory."""
    from folder_line.config.run_config import RunConfig
    from folder_line.ros.run import run_line

    out = base / scene
    run_line(RunConfig(scene=scene, duration=duration, rtf=2.0, out=out), io.StringIO())
    return out


def _recorded(base: Path, scene: str) -> Path:
    """A copy in ``base`` of the committed run of ``scene`` (test/data/README.md): no DDS."""
    return Path(shutil.copytree(DATA / f'{scene}_run', base / scene))


@pytest.fixture(scope='module')
def folder_recorded(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Path, AnalysisResult]]:
    run = _recorded(tmp_path_factory.mktemp('recorded'), 'folder')
    yield run, analyze(run, run / 'analysis', csv=True)


@pytest.fixture(scope='module')
def layup_recorded(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Path, AnalysisResult]]:
    run = _recorded(tmp_path_factory.mktemp('recorded'), 'layup')
    yield run, analyze(run / 'bag')  # a bag directory; default output beside it


@pytest.fixture(scope='module')
def folder_live(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Path, AnalysisResult]]:
    run = _record(tmp_path_factory.mktemp('runs'), 'folder', 2.0)
    yield run, analyze(run, run / 'analysis')


@pytest.fixture(scope='module')
def layup_live(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Path, AnalysisResult]]:
    run = _record(tmp_path_factory.mktemp('runs'), 'layup', 2.0)
    yield run, analyze(run / 'bag')  # a bag directory; default output beside it


@pytest.fixture(scope='module')
def faults_live(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Path, AnalysisResult]]:
    run = _record(tmp_path_factory.mktemp('runs'), 'folder_faults', 2.0)
    yield run, analyze(run, run / 'analysis')


# --------------------------------------------------------------------------- helpers


def _report_table(report: str) -> dict[str, str]:
    """``| quantity | value |`` rows of report.md's summary."""
    section = report.split('## Summary', 1)[1].split('##', 1)[0]
    return {m[1].strip(): m[2].strip() for m in re.finditer(r'^\| ([^|]+) \| ([^|]+) \|$', section, re.MULTILINE)}


def _margin_back(text: str) -> tuple[float, str]:
    """A margin of report.md read back: (value in the unit shown, unit shown); one_per_cycle as sheets."""
    text = text.removesuffix(' (best possible)')
    if text == '1 sheet per cycle':
        return 0.0, 'sheets'
    off = re.fullmatch(r'(\S+) sheets? off', text)
    if off:
        return -float(off[1]), 'sheets'
    number, _, unit = text.partition(' ')
    return float(number), unit


def _report_constraints(report: str) -> dict[str, dict[str, Any]]:
    section = report.split('## Constraints', 1)[1].split('##', 1)[0]
    out = {}
    for m in re.finditer(r'^\| (\w+) \| (\d+) \| ([^|]+) \| (cycle|leaf) (-?\d+) \| (\d+) \|$', section, re.MULTILINE):
        value, unit = _margin_back(m[3].strip())
        out[m[1]] = {
            'text': m[3].strip(),
            'shown_unit': unit,
            'evaluations': int(m[2]),
            'margin': value,
            'at': m[4],
            'cycle': int(m[5]),
            'violations': int(m[6]),
        }
    assert 'What the margins mean:' in section
    for name in out:
        assert f'- `{name}`: {MARGIN_MEANINGS[name]}' in section
    return out


def _check_png(path: Path) -> None:
    data = path.read_bytes()
    assert data[:8] == PNG, path
    assert len(data) > 10_000, path  # a drawn figure, not an empty canvas
    assert not list(path.parent.glob(f'.{path.name}.*.tmp'))


def _check_numbers(result: AnalysisResult) -> LineSummary:
    """report.md's numbers are simulate()'s for the line time reached (with the recorded commands)."""
    rec = result.recording
    expected = simulate(rec.scene, rec.t_end, sample_rate=0.0, commands=rec.commands).summary()
    report = result.report.read_text(encoding='utf-8')
    table = _report_table(report)
    assert int(table['cycles']) == expected.cycles == result.summary.cycles
    assert int(table['sheets counted']) == expected.sheets_counted == result.summary.sheets_counted
    assert int(table['violations']) == expected.violations.count
    rows = _report_constraints(report)
    assert set(rows) == set(expected.min_margin) and rows
    for name, want in expected.min_margin.items():
        got = rows[name]
        factor, unit = shown_unit(want.unit)
        unit = 'sheets' if name == 'one_per_cycle' else unit
        at = 'leaf' if name == 'chute_speed' else 'cycle'
        assert (got['shown_unit'], got['at'], got['evaluations'], got['violations']) == (
            unit,
            at,
            want.evaluations,
            want.violations,
        ), name
        assert want.unit in ('s', 'm', 'm/s', 'sheets', '1'), name  # so the text shows ms, mm, m/s or a count
        # printed to 6 decimals of ms and mm; the recorded event times are the exact ones rounded to the ns
        assert got['margin'] / factor == pytest.approx(want.margin, rel=1e-5, abs=3e-9), name
    return expected


def _sorted_events(ns: np.ndarray, events: np.ndarray) -> list[tuple[int, int, int, int, float]]:
    return sorted(
        zip(
            ns.tolist(),
            events['kind'].tolist(),
            events['sheet'].tolist(),
            events['cycle'].tolist(),
            events['value'].tolist(),
            strict=True,
        )
    )


def _check_events(result: AnalysisResult, run: Path) -> None:
    """The decoded events are the line model's, time to the nanosecond, values bit for bit."""
    rec = result.recording
    horizon = json.loads((run / 'run.json').read_text())['duration_s'] + 1.0  # the nodes' model horizon
    model = LineModel(rec.scene, horizon, rec.commands).events
    model = model[model['t'] <= rec.t_end]
    ns = np.round(model['t'] * 1e9).astype(np.int64)
    assert rec.events.size == model.size > 0
    assert _sorted_events(rec.event_ns, rec.events) == _sorted_events(ns, model)
    sim = simulate(rec.scene, rec.t_end, sample_rate=0.0, commands=rec.commands).events
    assert _sorted_events(rec.event_ns, rec.events) == _sorted_events(np.round(sim['t'] * 1e9).astype(np.int64), sim)
    assert np.array_equal(rec.events['t'], rec.event_ns / 1e9)
    assert rec.bad_events == 0
    # analyze's own comparison, window by window against the streamed line, says so too
    check = result.events_check
    assert check.agree and check.recorded == check.matched == rec.events.size, check.text()
    assert result.summary.events_check.agree is True
    assert "| recorded events equal to the line model's | yes |" in result.report.read_text(encoding='utf-8')


# --------------------------------------------------------------------------- folder


def test_folder_figures(folder_recorded: tuple[Path, AnalysisResult]) -> None:
    _, result = folder_recorded
    assert set(result.figures) == {'efficiency.png', 'cyclogram.png', 'margins.png'}
    for path in result.figures.values():
        _check_png(path)
        assert path.parent == result.out
    report = result.report.read_text(encoding='utf-8')
    for name in result.figures:
        assert f']({name})' in report
    assert not (result.out / 'exit_speeds.png').exists() and not (result.out / 'landing.png').exists()


def test_folder_numbers_match_simulate(folder_live: tuple[Path, AnalysisResult]) -> None:
    run, result = folder_live
    expected = _check_numbers(result)
    rec = result.recording
    assert rec.t_end == json.loads((run / 'run.json').read_text())['sim_time_reached_s'] == 2.0
    assert expected.cycles == 27 and expected.sheets_counted == 26  # 2 s at T = 72 ms
    assert rec.sheet_count == expected.sheets_counted  # what sheet_counter published last
    assert result.summary.violations.count == 0
    report = result.report.read_text(encoding='utf-8')
    assert 'No constraint was violated.' in report
    # lost messages: from run.json, 0 on every topic of an in-process run
    for topic, info in rec.bag.topics.items():
        assert f'| {topic} | {info.type} | {info.count} | {info.count} | 0 |' in report


def test_folder_events_equal_the_line_model_to_the_ns(folder_live: tuple[Path, AnalysisResult]) -> None:
    run, result = folder_live
    _check_events(result, run)


def test_folder_csv_one_file_per_topic(folder_recorded: tuple[Path, AnalysisResult]) -> None:
    import csv

    _, result = folder_recorded
    rec = result.recording
    csv_dir = result.out / 'csv'
    assert set(result.csv) == set(rec.bag.topics)
    assert sorted(p.name for p in csv_dir.iterdir()) == sorted(csv_name(t) for t in rec.bag.topics)
    tables = {}
    for topic, info in rec.bag.topics.items():
        with result.csv[topic].open(newline='') as fh:
            rows = list(csv.reader(fh))
        assert rows[0][0] == 't'
        if topic != DIAGNOSTICS_TOPIC:
            assert len(rows) - 1 == info.count, topic
        assert all(len(r) == len(rows[0]) for r in rows)
        tables[topic] = rows
    js = tables['/line/feed_transporter/joint_states']
    joints = ('feed_belt', 'chain', 'carriage')
    assert js[0] == [
        't',
        'header.stamp',
        'header.frame_id',
        *(f'{q}.{j}' for q in ('position', 'velocity', 'effort') for j in joints),
    ]
    ft = rec.joints['feed_transporter']
    col = js[0].index('velocity.carriage')
    assert [float(r[col]) for r in js[1:]] == ft.column('carriage', 'velocity').tolist()  # repr: exact
    assert [float(r[1]) for r in js[1:]] == ft.t.tolist()  # the stamp in s, as the analysis reads it
    ev = tables[EVENTS_TOPIC]
    assert ev[0] == ['t', 'header.stamp', 'header.frame_id', 'time_ref', 'kind', 'sheet', 'cycle', 'value']
    assert sorted((r[4], int(r[5]), int(r[6]), float(r[7])) for r in ev[1:]) == sorted(
        (EVENT_KINDS[k], s, c, v)
        for k, s, c, v in zip(
            rec.events['kind'].tolist(),
            rec.events['sheet'].tolist(),
            rec.events['cycle'].tolist(),
            rec.events['value'].tolist(),
            strict=True,
        )
    )
    assert sorted(float(r[3]) for r in ev[1:]) == sorted(rec.events['t'].tolist())
    diag = tables[DIAGNOSTICS_TOPIC]
    assert diag[0][:6] == ['t', 'header.stamp', 'name', 'level', 'message', 'hardware_id']
    assert 'values.evaluations' in diag[0]
    statuses = [(str(st.name), int(st.level)) for _, _, m in rec.bag.messages([DIAGNOSTICS_TOPIC]) for st in m.status]
    assert [(r[2], int(r[3])) for r in diag[1:]] == statuses  # one row per status
    assert tables[CLOCK_TOPIC][0] == ['t', 'clock']
    assert [float(r[0]) for r in tables[CLOCK_TOPIC][1:]] == [float(r[1]) for r in tables[CLOCK_TOPIC][1:]]
    states = tables[SUPERVISOR_STATE_TOPIC]
    assert states[0] == ['t', 'data'] and states[-1][1] == 'EXECUTE'
    assert len(tables[COMMANDS_TOPIC]) == 1 and len(tables[LANDING_TOPIC]) == 1  # header only: no message
    assert int(tables[SHEET_COUNT_TOPIC][-1][1]) == rec.sheet_count
    assert not list(csv_dir.glob('.*.tmp'))


def test_efficiency_data_is_the_recorded_delivery(folder_recorded: tuple[Path, AnalysisResult]) -> None:
    """η and K_v at the stroke positions recovered from the recorded carriage, the recorded torque."""
    from folder_line.core.effects import chain_friction
    from folder_line.core.mechanisms import delivery as dlv

    _, result = folder_recorded
    rec = result.recording
    ev = evaluate(rec)
    data = efficiency_data(rec, ev)
    assert data is not None and data['u'].size > 100
    plan = ev.plan
    # the carriage displacement inverted: u reproduces the recorded position through the model
    st_u = dlv.evaluate_stroke(plan.params, data['u'], return_section='geometric')
    x = data['u'] * plan.chain.x_max + plan.rod * (1.0 - np.cos(st_u.alpha))
    np.testing.assert_allclose(x, data['x'], atol=2e-6)
    # recorded carriage speed / chain speed is the model's K_v there (constant drive)
    np.testing.assert_allclose(data['K_v'], data['K_v_model'], atol=2e-4)
    assert data['eta'].min() >= 0.59 and data['eta'].max() <= 0.99
    # the recorded sprocket torque is the model's at the recorded chain phase
    ft = rec.joints['feed_transporter']
    on = (ft.column('carriage') > 0.0) | (ft.column('carriage', 'velocity') > 0.0)
    theta = ft.column('chain')[on] / plan.v_A
    np.testing.assert_allclose(data['torque'], chain_friction.sprocket_torque(rec.scene, theta), rtol=1e-9, atol=1e-9)


def test_cyclogram_rows_follow_the_operations(folder_recorded: tuple[Path, AnalysisResult]) -> None:
    _, result = folder_recorded
    rec = result.recording
    ev = evaluate(rec)
    rows = cycle_rows(rec, ev, 5)
    assert [r.cycle for r in rows] == [0, 1, 2, 3, 4]
    tm = ev.timing
    for r in rows:
        (s,) = r.sheets
        assert r.start <= s.handover < s.at_stops <= r.deadline < s.settled < r.contact < r.exit < s.release
        assert r.contact - r.start == pytest.approx(tm.T - tm.t_knife, abs=2e-9)  # constant drive
        assert r.exit - r.contact == pytest.approx(tm.t_knife, abs=2e-9)
        assert set(r.margins) == {
            'feed_window',
            'settled_before_knife',
            'one_per_cycle',
            'rebound',
            'release_at_min_speed',
        }
        assert r.margins['feed_window'] == pytest.approx(r.deadline - s.at_stops, abs=2e-9)


# --------------------------------------------------------------------------- layup


def test_layup_figures(layup_recorded: tuple[Path, AnalysisResult]) -> None:
    run, result = layup_recorded
    assert result.out == run / 'analysis'
    assert set(result.figures) == {'exit_speeds.png', 'margins.png', 'landing.png'}
    for path in result.figures.values():
        _check_png(path)
    assert result.csv == {} and not (result.out / 'csv').exists()


def test_layup_numbers_match_simulate(layup_live: tuple[Path, AnalysisResult]) -> None:
    _, result = layup_live
    expected = _check_numbers(result)
    assert expected.sheets_counted > 10  # leaves landed
    rec = result.recording
    assert rec.sheet_count == expected.sheets_counted
    # the landing histogram is the simulator's
    land = landing_data(rec)
    assert land is not None
    assert expected.layup is not None and expected.layup.landing is not None
    hist = expected.layup.landing.histogram
    assert land.counts.tolist() == hist.counts
    np.testing.assert_array_equal(land.edges, hist.edges)
    assert land.cv == pytest.approx(hist.cv, rel=1e-12)
    # sheet_counter's landing_x topic carries the same x as the leaf_landed events
    np.testing.assert_array_equal(np.sort(rec.landing_x), np.sort(land.x))


def test_layup_events_equal_the_line_model_to_the_ns(layup_live: tuple[Path, AnalysisResult]) -> None:
    run, result = layup_live
    _check_events(result, run)


def test_exit_speeds_are_the_recorded_kinematics(layup_recorded: tuple[Path, AnalysisResult]) -> None:
    """v_C = ω3 l3 from the recorded joint states is the six-bar's at the recorded crank angle."""
    from folder_line.core.mechanisms.layup import LayupModel

    _, result = layup_recorded
    rec = result.recording
    data = exit_speed_data(rec)
    assert data is not None and data['t'].size >= 150
    lp = rec.scene.machine('layup')
    st = LayupModel(lp).arrays(data['phi'], accelerations=False)
    np.testing.assert_allclose(data['vC'], st.vC, atol=1e-9)
    np.testing.assert_allclose(data['vE'], st.vE, atol=1e-9)
    np.testing.assert_array_equal(data['v_belt'], lp.v_tr)  # constant drive, no slow-down
    np.testing.assert_allclose(data['vaC'], np.hypot(st.vC, lp.v_tr), atol=1e-9)
    assert data['vaE'].min() >= lp.v_tr
    # the recorded crank angle is the drive's: φ = 2π n_kr/60 t (mod 2π)
    np.testing.assert_allclose(np.exp(1j * data['phi']), np.exp(1j * 2 * math.pi * lp.n_kr / 60 * data['t']), atol=1e-9)


# --------------------------------------------------------------------------- supervisor


def test_replay_reproduces_the_recorded_states(faults_live: tuple[Path, AnalysisResult]) -> None:
    """The folder with faults: the recorded events replayed through the supervisor logic take the
    live run's transitions (a late sheet in cycle 13 holds the line)."""
    _, result = faults_live
    s = result.summary
    recorded = [t.target for t in recorded_transitions(result.recording.states)]
    replayed = [t.target for t in s.transitions]
    assert s.replay_matches is True, (recorded, replayed, s.replay_violations)
    assert s.replay_violations is not None
    assert 'HOLDING' in replayed and replayed[-1] == recorded[-1] == 'HELD'
    held = [v for v in s.replay_violations if v.action == 'hold']
    assert held and held[0].cycle == 13 and held[0].constraint == 'feed_window'
    # the hold is in the bag as a drive command, and the analysis judges with it: simulate agrees
    assert [c.kind for c in result.recording.commands] == ['hold']
    _check_numbers(result)
    report = result.report.read_text(encoding='utf-8')
    assert '| cycle 13 | feed_window | -4.9' in report  # the violations table (batch, as simulate judges), in ms


def test_transitions_agree_allows_states_within_one_tick() -> None:
    def to(t: float, state: str) -> StateTransition:
        return StateTransition(t, '', state)

    rec = [to(0.03, 'EXECUTE'), to(1.2, 'HOLDING'), to(1.8, 'HELD')]
    rep = [to(0.0, 'EXECUTE'), to(1.1, 'HOLDING'), to(1.75, 'HELD')]
    assert transitions_agree(rep, rec)
    assert not transitions_agree(rep[:2], rec)  # ends elsewhere
    assert not transitions_agree(rep, rec[:1] + rec[2:] + [to(2.0, 'HOLDING')])
    assert not transitions_agree([rep[0], replace(rep[1], t=1.3), rep[2]], rec)  # decided after it showed
    assert transitions_agree(rep, [rec[0], rec[2]])  # HOLDING within one tick
    # a state entered twice (EXECUTE again after an unhold): each showing has its own transition
    again = [to(2.5, 'UNHOLDING'), to(3.0, 'EXECUTE')]
    assert transitions_agree(rep + again, [*rec, replace(again[0], t=2.505), replace(again[1], t=3.005)])
    assert not transitions_agree(rep + again, [*rec, replace(again[0], t=2.505), replace(again[1], t=2.9)])
    assert [t.as_json() for t in recorded_transitions([(1, 'A'), (2, 'A'), (3_000_000_000, 'B')])] == [
        {'t': 1e-9, 'from': '', 'to': 'A'},
        {'t': 3.0, 'from': 'A', 'to': 'B'},
    ]


def test_topic_names_are_the_nodes() -> None:
    from folder_line import interfaces
    from folder_line.ros.topics import joint_states_topic

    for node in interfaces.JOINT_NODES:
        topic = joint_states_topic(node)
        assert interfaces.joint_states_node(topic) == node
    assert interfaces.joint_states_node('/line/events') is None
    assert interfaces.joint_states_node('/line//joint_states') is None


def test_supervisor_defaults_are_the_nodes() -> None:
    """SUPERVISOR_DEFAULTS mirrors the live node's parameter defaults and the run's rate."""
    from folder_line.config.run_config import RunConfig
    from folder_line.ros.nodes.supervisor import Supervisor

    specs = {spec.name: spec.default for spec in Supervisor.EXTRA_SPECS}
    mirrored = {k: v for k, v in SUPERVISOR_DEFAULTS.items() if k != 'rate'}
    assert mirrored == {k: specs[k] for k in mirrored}
    assert SUPERVISOR_DEFAULTS['rate'] == RunConfig().rate


# --------------------------------------------------------------------------- CLI, boundary, event text


def test_cli_analyze(
    folder_recorded: tuple[Path, AnalysisResult], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from folder_line.cli.main import main

    run, result = folder_recorded
    out = tmp_path / 'cli'
    assert main(['analyze', str(run), '--out', str(out), '--csv']) == 0
    printed = capsys.readouterr().out
    assert 'scene folder: 2.000 s of line time, 27 cycles, 26 sheets counted, 0 violations' in printed
    assert (out / 'report.md').is_file() and len(list((out / 'csv').glob('*.csv'))) == len(result.recording.bag.topics)
    for argv in (
        ['analyze', str(tmp_path / 'missing')],
        ['analyze', str(tmp_path)],
        ['analyze', str(out / 'report.md')],
    ):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.count('\n') == 1 and err.startswith('folder-line: error: RUN_DIR|BAG='), err


def test_analysis_needs_no_ros(folder_recorded: tuple[Path, AnalysisResult], tmp_path: Path) -> None:
    run, _ = folder_recorded
    code = (
        'from folder_line.analysis import analyze\n'
        f'print(len(analyze({str(run / "bag")!r}, {str(tmp_path)!r}).figures))'
    )
    assert ros_modules_loaded(code) == ('3', [])


@given(
    kind=st.sampled_from(EVENT_KINDS),
    sheet=st.integers(-1, 2**62),
    cycle=st.integers(-1, 2**62),
    value=st.floats(allow_nan=False, allow_infinity=False),
)
def test_event_source_round_trip(kind: str, sheet: int, cycle: int, value: float) -> None:
    assert parse_event_source(event_source(kind, sheet, cycle, value)) == (kind, sheet, cycle, value)


def test_event_source_rejects_other_text() -> None:
    for bad in (
        'hold',
        'knife_contact sheet=1 cycle=2',
        'nonsense sheet=1 cycle=2 value=0.0',
        'at_stops sheet=1 cycle=2 value=abc',
        'at_stops sheet=x cycle=2 value=1.0',
    ):
        with pytest.raises(ValueError, match='not an event source'):
            parse_event_source(bad)
