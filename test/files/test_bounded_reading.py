"""Reading is bounded (issue 11, part 2): hostile scene, parameter and bag metadata files, hostile ``--set``.

Every verb that reads a user's YAML gets each hostile file; each ends with exit code 2
and one short line naming the file (and, for a decode or parse error, the line and the
column), fast and in bounded memory, with nothing created.
"""

from __future__ import annotations

import os
import time
import tracemalloc
from collections.abc import Callable
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from folder_line.cli.main import main
from folder_line.config.scenes import SET_VALUE_CHARS
from folder_line.errors import ParameterError, bounded_repr
from folder_line.files.yamlio import MAX_ALIASES, MAX_DEPTH, TEXT_LIMIT, load_yaml

#: longest error line a hostile input may produce, characters
LINE_MAX = 400


def _bomb(levels: int, width: int = 9) -> str:
    """Billion laughs: ``width ** levels`` leaves from ``levels * width`` aliases."""
    rows = [f'l0: &l0 [{", ".join(["lol"] * width)}]']
    rows += [f'l{i}: &l{i} [{", ".join([f"*l{i - 1}"] * width)}]' for i in range(1, levels)]
    return '\n'.join(rows) + '\n'


#: name -> (file bytes, words of the error, does it name a line and column)
HOSTILE: dict[str, tuple[bytes, str, bool]] = {
    'yaml bomb': (_bomb(7, 9).encode(), 'expands to more than', True),
    'too many aliases': (
        ('a: &a 1\nb: [' + ', '.join(['*a'] * (MAX_ALIASES + 1)) + ']\n').encode(),
        f'more than {MAX_ALIASES} aliases',
        True,
    ),
    'recursive alias': (b'a: &a [1, *a]\n', 'recursive', True),
    'duplicate key': (
        b'machines:\n  knife: {}\nname: x\nmachines: {}\n',
        "duplicate key 'machines' (first at line 1)",
        True,
    ),
    'python tag': (b'name: !!python/object/apply:os.system ["echo owned"]\n', 'not allowed', True),
    'binary tag': (b'name: !!binary aGk=\n', 'not allowed', True),
    'local tag': (b'name: !mine x\n', 'not allowed', True),
    'invalid yaml': (b'machines:\n  knife: [1, 2\nname: x\n', "expected ',' or ']'", True),
    'bad indentation': (b'a: 1\n b: 2\n', 'mapping values are not allowed here', True),
    'latin-1': ('name: Gr\u00fc\u00dfe\n'.encode('latin-1'), 'not UTF-8 (byte 0xfc)', True),
    'utf-16 with bom': ('name: x\n'.encode('utf-16'), 'is UTF-16', False),
    'utf-16 without bom': ('name: x\n'.encode('utf-16-le'), 'U+0000 is not allowed', True),
    'nul character': (b'name: a\x00b\n', 'U+0000 is not allowed', True),
    'deep nesting': (b'a: ' + b'[' * 5000 + b']' * 5000 + b'\n', f'nested deeper than {MAX_DEPTH} levels', True),
    '5000-digit integer': (b'seed: ' + b'7' * 5000 + b'\n', 'integer of 5000 digits', True),
    'too large': (b'# ' + b'x' * TEXT_LIMIT + b'\n', 'at most', False),
    'two documents': (b'a: 1\n---\nb: 2\n', 'but found another document', True),
}

_LINE_COL = ', column '


def _write(path: Path, data: bytes) -> Path:
    path.write_bytes(data)
    return path


def _check_line(line: str, path: Path, words: str, positioned: bool) -> None:
    assert str(path) in line and words in line, line
    assert len(line) <= LINE_MAX, len(line)
    if positioned:
        assert ': line ' in line and _LINE_COL in line, line


def refused(argv: list[str], capsys: pytest.CaptureFixture[str], seconds: float = 5.0) -> str:
    """Exit code 2, one line, no traceback, within ``seconds``; the line."""
    t0 = time.perf_counter()
    code = main(argv)
    elapsed = time.perf_counter() - t0
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.count('\n') == 1 and err.startswith('folder-line: error: '), err
    assert 'Traceback' not in err
    assert elapsed < seconds, f'{elapsed:.1f} s'
    return err.rstrip('\n')


def _scene_verbs(out: Path) -> dict[str, Callable[[Path], list[str]]]:
    return {
        'simulate --scene': lambda f: ['simulate', '--scene', str(f), '--duration', '1', '--json', str(out / 's.json')],
        'run --scene': lambda f: ['run', '--scene', str(f), '--duration', '1', '--out', str(out)],
        'kinematics --params': lambda f: ['kinematics', 'layup', '--params', str(f), '--csv', str(out / 'k.csv')],
    }


@pytest.mark.parametrize('case', list(HOSTILE))
@pytest.mark.parametrize('verb', ['simulate --scene', 'run --scene', 'kinematics --params'])
def test_hostile_scene_and_parameter_files(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], verb: str, case: str
) -> None:
    data, words, positioned = HOSTILE[case]
    f = _write(tmp_path / 'hostile.yaml', data)
    out = tmp_path / 'out'
    line = refused(_scene_verbs(out)[verb](f), capsys)
    _check_line(line, f, words, positioned)
    assert line.startswith(f"folder-line: error: {verb.split()[1]}='{f}': "), line
    assert sorted(p.name for p in tmp_path.iterdir()) == ['hostile.yaml']  # no out/, no JSON, no CSV


@pytest.mark.parametrize('kind', ['fifo', 'directory'])
@pytest.mark.parametrize('verb', ['simulate --scene', 'kinematics --params'])
def test_a_scene_or_parameter_file_that_is_not_a_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], verb: str, kind: str
) -> None:
    f = tmp_path / 'input.yaml'
    os.mkfifo(f) if kind == 'fifo' else f.mkdir()  # a FIFO nobody writes to: reading must not wait
    line = refused(_scene_verbs(tmp_path / 'out')[verb](f), capsys)
    assert f"'{f}': is a {'FIFO' if kind == 'fifo' else 'directory'}, not a regular file" in line, line


def _bag_dir(tmp_path: Path) -> Path:
    """A real (empty) bag of the folder scene."""
    from folder_line.bag.writer import BagWriter
    from folder_line.config.scenes import scene_mapping
    from folder_line.ros.recorder import LINE_TOPICS

    source = yaml.safe_dump(scene_mapping('folder'), sort_keys=False)
    with BagWriter(tmp_path / 'run' / 'bag', scene_source=source, effects=[], scene_name='folder', topics=LINE_TOPICS):
        pass
    return tmp_path / 'run' / 'bag'


@pytest.mark.parametrize('case', [c for c in HOSTILE if c != 'too large'])
@pytest.mark.parametrize('verb', ['bag info', 'analyze'])
def test_hostile_bag_metadata(tmp_path: Path, capsys: pytest.CaptureFixture[str], verb: str, case: str) -> None:
    data, words, positioned = HOSTILE[case]
    bag = _bag_dir(tmp_path)
    meta = _write(bag / 'metadata.yaml', data)
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob('*'))
    argv = ['bag', 'info', str(bag)] if verb == 'bag info' else ['analyze', str(bag.parent)]
    line = refused(argv, capsys)
    if case == 'yaml bomb':  # the metadata's bound is larger (a long bag has many segments); still refused
        words = 'expands to more than 1000000 nodes'
        assert meta.stat().st_size < 1000
    _check_line(line, meta, words, positioned)
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob('*')) == before  # no analysis/ folder


def test_a_bomb_fails_fast_in_bounded_memory() -> None:
    text = _bomb(12, 9)  # 9 ** 12 = 2.8e11 leaves if expanded
    tracemalloc.start()
    t0 = time.perf_counter()
    with pytest.raises(ParameterError, match='expands to more than 100000 nodes'):
        load_yaml(text, '--scene', 'bomb.yaml')
    elapsed = time.perf_counter() - t0
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert elapsed < 1.0 and peak < 20e6, (elapsed, peak)


def test_a_small_bomb_inside_a_scene_value_prints_a_short_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # 9 ** 4 = 6561 leaves: under the node bound, so the scene validator meets the value and prints it
    f = _write(tmp_path / 's.yaml', (_bomb(4) + 'machines:\n  knife:\n    r_k: *l3\n').encode())
    line = refused(['simulate', '--scene', str(f), '--duration', '1'], capsys, seconds=2.0)
    assert line.startswith('folder-line: error: ') and len(line) <= LINE_MAX, line
    assert '...' in line, line


def test_plain_yaml_with_anchors_still_loads() -> None:
    text = 'base: &b {V_tr: 9.3, mu: 0.2}\nfirst: *b\nsecond: {<<: *b, mu: 0.3}\nlist: [1, 2.5, x, null, true]\n'
    assert load_yaml(text, 'x', 'x.yaml') == {
        'base': {'V_tr': 9.3, 'mu': 0.2},
        'first': {'V_tr': 9.3, 'mu': 0.2},
        'second': {'V_tr': 9.3, 'mu': 0.3},
        'list': [1, 2.5, 'x', None, True],
    }
    assert load_yaml('\ufeffa: 1\n', 'x', 'x.yaml') == {'a': 1}  # a UTF-8 byte-order mark is fine


@pytest.mark.parametrize('value', ['7' * 5000, '1' * 4301 + '.5', 'x' * 100_000, '[' * 5000])
@pytest.mark.parametrize('verb', ['simulate', 'run'])
def test_a_huge_set_value_is_one_short_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], verb: str, value: str
) -> None:
    argv = [verb, '--duration', '1', '--set', f'feed_transporter.V_tr={value}']
    argv += ['--out', str(tmp_path / 'out')] if verb == 'run' else ['--json', str(tmp_path / 's.json')]
    line = refused(argv, capsys)
    assert line.endswith(f': value is {len(value)} characters long; at most {SET_VALUE_CHARS}'), line
    assert line.startswith("folder-line: error: feed_transporter.V_tr='") and len(line) <= 200, line
    assert 'Exceeds the limit' not in line
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    'value', ['!!python/object/apply:os.system [x]', '&a [*a]', '{a: 1, a: 2}', '99e99999', '-.inf']
)
def test_odd_set_values_are_refused_by_the_scene_not_the_parser(capsys: pytest.CaptureFixture[str], value: str) -> None:
    line = refused(['simulate', '--duration', '1', '--set', f'feed_transporter.V_tr={value}'], capsys)
    assert line.startswith('folder-line: error: feed_transporter.V_tr='), line


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(key=st.text(min_size=1, max_size=300).filter(lambda k: '=' not in k and k.strip()), value=st.text(max_size=300))
def test_any_set_item_for_an_unknown_key_is_one_bounded_line(
    capsys: pytest.CaptureFixture[str], key: str, value: str
) -> None:
    line = refused(['simulate', '--duration', '1', '--set', f'zz_{key}={value}'], capsys)
    assert len(line) <= LINE_MAX, line


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.binary(max_size=400) | st.text(max_size=200).map(lambda t: t.encode('utf-8', 'surrogatepass')))
def test_any_bytes_as_a_scene_are_one_bounded_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], data: bytes
) -> None:
    f = _write(tmp_path / 'fuzz.yaml', data)
    line = refused(['simulate', '--scene', str(f), '--duration', '1'], capsys)
    assert len(line) <= LINE_MAX, line


@given(
    value=st.recursive(
        st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=1000),
        lambda inner: st.lists(inner, max_size=50) | st.dictionaries(st.text(max_size=50), inner, max_size=50),
        max_leaves=500,
    )
)
def test_bounded_repr_is_bounded(value: object) -> None:
    assert len(bounded_repr(value)) <= 80
    assert len(str(ParameterError('k' * 1000, value, 'bad'))) <= 80 + 1 + 80 + 5


@pytest.mark.parametrize(
    'argv',
    [
        ['simulate', '--duration', '9' * 5000],
        ['kinematics', 'knife', '--samples', '7' * 5000],
        ['run', '--rtf', 'x' * 5000],
        ['simulate', '--scene'],
        ['kinematics', 'gear' * 2000],
        ['simulate', '--' + 'y' * 5000],
    ],
)
def test_usage_errors_are_one_short_line(argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(argv)
    err = capsys.readouterr().err
    assert exc.value.code == 2
    assert err.count('\n') == 1 and err.startswith('folder-line') and ': error: ' in err, err
    assert len(err) <= LINE_MAX and err.rstrip().endswith('--help)'), err
