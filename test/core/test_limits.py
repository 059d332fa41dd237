"""One set of limits (issue 11): the CLI, the scene loader and the node parameters share each range.

Each check takes its bounds from :mod:`folder_line.core.limits`, so a test that moved a bound in
one place only fails here: the ends are accepted, a step beyond either end, a subnormal, NaN and
inf are refused with the key, the value and the range.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from folder_line.cli import main as cli
from folder_line.cli import summary as summary_cli
from folder_line.config.run_config import RunConfig, clock_parameters, node_parameters
from folder_line.config.scenes import load_scene
from folder_line.core import limits as L
from folder_line.core.line.line_summary import LineSummary
from folder_line.core.line.model import LineModel, run_summary
from folder_line.errors import ParameterError
from folder_line.interfaces import KNOWN_PARTICIPANTS, MACHINE_NODES
from folder_line.ros.nodes.line_clock import SPECS as CLOCK_SPECS
from folder_line.ros.nodes.machine import MACHINE_SPECS

LIMITS_PAGE = Path(__file__).resolve().parents[2] / 'docs' / 'limits.md'


def _beyond(limit: L.Limit) -> list[float]:
    """Values just outside ``limit`` and absurd ones."""
    out = [math.nextafter(limit.hi, math.inf), limit.hi * 10.0, 1e308, math.nan, math.inf, -math.inf]
    out += [math.nextafter(limit.lo, -math.inf), -1.0]
    if limit.lo > 0.0:
        out += [5e-324, 1e-300]
    return out


# --------------------------------------------------------------------------- command line

_OPTIONS = [
    (['simulate', '--duration'], L.DURATION),
    (['run', '--duration'], L.DURATION),
    (['run', '--rtf'], L.RTF),
    (['run', '--lost-timeout'], L.LOST_TIMEOUT),
]


@pytest.mark.parametrize(('words', 'limit'), _OPTIONS, ids=lambda x: ' '.join(x) if isinstance(x, list) else '')
def test_cli_options_take_the_range_of_their_limit(
    words: list[str], limit: L.Limit, capsys: pytest.CaptureFixture[str]
) -> None:
    parser = cli.build_parser()
    option = words[-1].lstrip('-').replace('-', '_')
    verb, flag = words
    for value in (limit.lo, limit.hi):
        assert getattr(parser.parse_args([verb, f'{flag}={value!r}']), option) == value
    for value in _beyond(limit):
        with pytest.raises(SystemExit) as info:
            parser.parse_args([verb, f'{flag}={value!r}'])
        assert info.value.code == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and f'{words[-1]}=' in err and f'must be in {limit.text()}' in err, err


def test_rtf_max_is_no_ceiling() -> None:
    assert cli.build_parser().parse_args(['run', '--rtf', 'max']).rtf == 0.0


# --------------------------------------------------------------------------- nodes


def _bounds(specs: tuple, name: str) -> tuple[float, float]:
    spec = next(s for s in specs if s.name == name)
    return spec.bounds


def test_node_parameters_take_the_same_ranges() -> None:
    assert all(s.name != 'horizon' for s in MACHINE_SPECS)  # the line is streamed: no model horizon to size
    assert _bounds(MACHINE_SPECS, 'rate') == L.TICK_RATE.bounds
    assert _bounds(MACHINE_SPECS, 'lost_timeout') == L.LOST_TIMEOUT.bounds
    assert _bounds(CLOCK_SPECS, 'rate') == L.TICK_RATE.bounds
    assert _bounds(CLOCK_SPECS, 'lost_timeout') == L.LOST_TIMEOUT.bounds
    assert _bounds(CLOCK_SPECS, 'duration') == (0.0, L.DURATION.hi)  # 0: until interrupted
    assert _bounds(CLOCK_SPECS, 'rtf') == (0.0, L.RTF.hi)  # 0: no ceiling; (0, lo) refused by the node


@pytest.mark.parametrize('duration', [L.DURATION.lo, L.DURATION.hi])
def test_the_shortest_and_longest_runs_give_their_nodes_parameters_they_accept(duration: float) -> None:
    """No memory limit: the longest run's clock takes its duration, and no machine node is sized for it."""
    cfg = RunConfig(scene='folder', duration=duration)
    lo, hi = _bounds(CLOCK_SPECS, 'duration')
    assert lo <= clock_parameters(cfg, KNOWN_PARTICIPANTS)['duration'] == duration <= hi
    for node in MACHINE_NODES:
        params = node_parameters(cfg, node)
        assert 'horizon' not in params
        assert L.TICK_RATE.lo <= params['rate'] <= L.TICK_RATE.hi


# --------------------------------------------------------------------------- scene keys

_SCENE_KEYS = [
    ('folder', 'knife.n_k', L.KNIFE_SPEED),
    ('folder', 'cyclogram.n_c', L.CYLINDER_SPEED),
    ('folder', 'feed_transporter.V_tr', L.LINEAR_SPEED),
    ('layup', 'sheets.interval', L.SHEET_INTERVAL),  # the folder takes one signature per cycle: inert there
    ('layup', 'layup.n_kr', L.CRANK_SPEED),
    ('layup', 'layup.v_tr', L.LINEAR_SPEED),
    ('folder', 'sample_rate', L.SAMPLE_RATE),
]


#: the knife turns twice per cylinder turn: a speed loads with its partner at the matching value
_PARTNER = {
    'knife.n_k': lambda v: {'cyclogram.n_c': v / 2.0},
    'cyclogram.n_c': lambda v: {'knife.n_k': 2.0 * v},
}


def _NONE(value: float) -> dict[str, float]:
    return {}


@pytest.mark.parametrize(('scene', 'key', 'limit'), _SCENE_KEYS, ids=[k for _, k, _ in _SCENE_KEYS])
def test_scene_keys_take_the_range_of_their_limit(scene: str, key: str, limit: L.Limit) -> None:
    for value in (limit.lo, limit.hi):
        load_scene(scene, {key: value, **_PARTNER.get(key, _NONE)(value)})  # both ends load
    for value in _beyond(limit):
        if key == 'layup.v_tr' and value == -1.0:
            continue  # negative: refused as 'must be >= 0' (0 is a belt-less chute)
        with pytest.raises(ParameterError) as info:
            load_scene(scene, {key: value})
        assert info.value.key == key
        if math.isfinite(value) and not (key == 'layup.v_tr' and value < 0.0):
            assert info.value.reason == f'must be in {limit.text()}', info.value.reason


def test_a_belt_less_chute_is_still_a_speed_of_0() -> None:
    assert load_scene('layup', {'layup.v_tr': 0.0}).machine('layup').v_tr == 0.0
    with pytest.raises(ParameterError, match=r'must be in \[0.001, 1000\] m/s'):
        load_scene('layup', {'layup.v_tr': 5e-324})


def test_the_cli_refuses_an_absurd_speed_in_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    for value in ('1e-300', '1e308', '5e-324'):
        assert cli.main(['simulate', '--duration', '1', '--set', f'knife.n_k={value}']) == 2
        err = capsys.readouterr().err.strip()
        assert err == f'folder-line: error: knife.n_k={float(value)!r}: must be in [2, 200000] rev/h', err


def test_the_batch_model_and_simulate_use_the_same_ranges() -> None:
    """The kept model, the streamed summary and simulate's window take line time in DURATION, said in seconds."""
    scene = load_scene('folder', {})
    beyond = math.nextafter(L.DURATION.hi, math.inf)
    with pytest.raises(ParameterError, match=r'horizon=.*must be in \[0.001, 10000000\] s'):
        LineModel(scene, beyond)
    with pytest.raises(ParameterError, match='horizon=5e-324'):
        LineModel(scene, 5e-324)
    with pytest.raises(ParameterError, match=r'duration=.*must be in \[0.001, 10000000\] s'):
        run_summary(scene, beyond)
    with pytest.raises(
        ParameterError, match=r'--from=.* = 10000001 s of line time; .* at most 10000000 s \(116 days\)'
    ):
        summary_cli.check_window(L.DURATION.hi - 1.0, 2.0)


def test_the_longest_duration_is_simulated_not_refused(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """No memory refusal any more (no check_size, no cycle cap): simulate hands the longest run to the stream.
    The streamed summary itself is stubbed here (116 days of line time take hours)."""
    asked: list[tuple[float, float | None]] = []

    def streamed(scene: object, duration: float, *, start: float | None = None, **kwargs: object) -> LineSummary:
        asked.append((duration, start))
        return run_summary(load_scene('folder', {}), 0.01)

    monkeypatch.setattr(summary_cli, 'line_summary', streamed)
    assert cli.main(['simulate', '--scene', 'folder', '--duration', f'{L.DURATION.hi!r}']) == 0
    assert cli.main(['simulate', '--scene', 'folder', '--from', '5e6', '--duration', '5e6']) == 0
    assert asked == [(L.DURATION.hi, None), (5e6, 5e6)]
    assert capsys.readouterr().err == ''


@pytest.mark.parametrize('value', ['-1', '-5e-324', '1e7', 'nan', 'inf', 'soon'])
def test_from_is_a_line_time_in_the_run_refused_in_one_line(value: str, capsys: pytest.CaptureFixture[str]) -> None:
    """``--from``: [0, 1e7] s, and --from + --duration within the longest run (1e7 s), said as line time."""
    with pytest.raises(SystemExit) as info:  # the parser's refusals exit, the verb's return
        raise SystemExit(cli.main(['simulate', '--scene', 'folder', f'--from={value}', '--duration', '1']))
    assert info.value.code == 2
    (err,) = capsys.readouterr().err.strip().splitlines()
    assert err.startswith('folder-line') and '--from=' in err, err
    assert 'must be' in err or '10000001 s of line time; a run reaches at most 10000000 s' in err, err


def test_the_limits_page_lists_every_limit() -> None:
    """docs/limits.md has a row for every limit, with its range as the refusals print it."""
    text = LIMITS_PAGE.read_text(encoding='utf-8')
    for limit in L.LIMITS.values():
        assert f'| {limit.what} | {limit.text()} |' in text, limit.what
