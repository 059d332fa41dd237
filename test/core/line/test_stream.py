"""The streamed line: windows cut anywhere give one window's run, bit for bit; checkpoints; bounded state.

Every shipped scene, and scenes that list every effect the line has (with the supervisor's
commands and every kind of tuning), run once in one window and again in windows of
0.013 s, of 1 s, of random lengths (and 60 s on a longer run): the events, the joint
states on a sample grid, the constraint rows and the summary are the same bytes. A
checkpoint taken at an awkward time (mid-flight, mid-ramp, mid-bounce) and restored
gives the same rest of the run, also under a command learnt after the checkpoint.
"""

from __future__ import annotations

import math
import types
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from folder_line.config.params import config_dir
from folder_line.config.scenes import list_scenes, load_scene
from folder_line.core.line.model import LineModel, run_summary
from folder_line.core.line.scene import Scene
from folder_line.core.line.stream import LineStream
from folder_line.core.line.tuning import LineCommand, Tuning
from folder_line.core.mechanisms.drive import Command
from folder_line.core.types.events import EVENT_KINDS

from .._scenes import FAULTS

#: scenes beyond the shipped ones: name -> (shipped base, effects added, effects dropped, machines changed)
EXTRA: dict[str, tuple[str, dict[str, Any], tuple[str, ...], dict[str, Any]]] = {
    'every_folder_effect': (
        'folder',
        {
            'faults': FAULTS,
            'speed_ripple': {'amplitude': 0.05, 'frequency': 3.0},
            'arrival_jitter': {'distribution': 'uniform', 'sigma': 0.3},
            'length_scatter': {'sigma': 0.2},
            'property_scatter': {'e_sigma': 0.2, 'mu_sigma': 0.1},
            'feed_slip': {'mu': 0.5, 'p': 40.0, 'm': 0.02},
        },
        (),
        {'feed_transporter': {'V_tr': 9.6}},
    ),
    'layup_faults_ripple': ('layup', {'faults': FAULTS, 'speed_ripple': {'amplitude': 0.1, 'frequency': 0.7}}, (), {}),
    'guide_friction': (
        'layup',
        {'guide_friction': {'mu': 0.5, 's0': 0.0, 'v0': 1.0, 'h': 0.002}, 'faults': FAULTS},
        ('chute_belts',),
        {},
    ),
    'guide_friction_sticks': (
        'layup',
        {'guide_friction': {'mu': 3.5, 's0': 0.1, 'v0': 0.0, 'h': 0.002}},
        ('chute_belts',),
        {},
    ),
    'line_rk4_stop': ('line', {'faults': FAULTS, 'speed_ripple': {'amplitude': 0.05, 'frequency': 2.0}}, (), {}),
}


@pytest.fixture(scope='module')
def scenes(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Scene]:
    out = {name: load_scene(name) for name in list_scenes()}
    folder = tmp_path_factory.mktemp('scenes')
    for name, (base, add, drop, machines) in EXTRA.items():
        data = yaml.safe_load((config_dir() / 'scenes' / f'{base}.yaml').read_text())
        data['name'] = name
        for key in drop:
            data['effects'].pop(key)
        data['effects'].update(add)
        data['machines'].update(machines)
        if name == 'line_rk4_stop':
            data['effects']['motor_dynamics'].update({'method': 'rk4', 'h': 0.001, 't_stop': 7.0})
        path = Path(folder) / f'{name}.yaml'
        path.write_text(yaml.safe_dump(data))
        out[name] = load_scene(str(path))
    return out


def _commands(scene: Scene) -> list[LineCommand]:
    """A hold, its unhold, a stop and a start, and every tuning the scene can take."""
    cmds: list[LineCommand] = [
        Command(2.0, 'hold'),
        Command(3.7, 'unhold'),
        Command(7.3, 'stop'),
        Command(8.1, 'start'),
    ]
    if scene.has_folder:
        cmds.append(Tuning(5.0, 'feed_transporter.V_tr', 9.5))
        if not scene.has('motor_dynamics'):
            cmds.append(Tuning(9.0, 'press.n_c', 26000.0))
    if scene.has('chute_belts'):
        cmds.append(Tuning(5.5, 'layup.v_tr', 3.1))
    cmds.append(Tuning(6.0, 'pile.t_lower', 0.05))
    return sorted(cmds, key=lambda c: c.t)


def _run(scene: Scene, cuts: Any, t_end: float, commands: list[LineCommand], rate: float = 40.0) -> dict[str, Any]:
    """Advance to every cut, then ``t_end``: every event, the samples of each window's grid, the rows, the summary."""
    stream = LineStream(scene, commands)
    grid = np.arange(int(t_end * rate) + 1) / rate
    events, rows, samples = [], {}, {}
    for cut in [*cuts, t_end]:
        if cut <= stream.t:
            continue
        t0 = stream.t
        w = stream.advance(cut)
        events.append(w.events)
        for r in w.constraints:
            rows.setdefault(r.name, []).append(r)
        g = grid[(grid > t0) & (grid <= cut)]
        if g.size:
            for unit, js in stream.sample_all(g).items():
                block = [js.position, js.velocity] + ([js.effort] if js.effort is not None else [])
                samples.setdefault(unit, []).append(np.hstack(block))
    for r in stream.finish():
        rows.setdefault(r.name, []).append(r)
    return {
        'events': np.concatenate(events),
        'rows': {
            k: tuple(np.concatenate([getattr(r, f) for r in v]) for f in ('cycle', 'margin', 't'))
            for k, v in rows.items()
        },
        'samples': {u: np.vstack(v) for u, v in samples.items()},
        'summary': stream.summary().as_json(),
    }


def _assert_same(a: dict[str, Any], b: dict[str, Any]) -> None:
    assert a['events'].tobytes() == b['events'].tobytes()
    assert a['rows'].keys() == b['rows'].keys()
    for name in a['rows']:
        for x, y in zip(a['rows'][name], b['rows'][name], strict=True):
            assert x.tobytes() == y.tobytes(), name
    assert a['samples'].keys() == b['samples'].keys()
    for unit in a['samples']:
        assert a['samples'][unit].tobytes() == b['samples'][unit].tobytes(), unit
    assert a['summary'] == b['summary']


@pytest.mark.parametrize('name', [*sorted(list_scenes()), *EXTRA])
def test_windows_cut_anywhere_give_one_windows_run_bit_for_bit(scenes: dict[str, Scene], name: str) -> None:
    scene = scenes[name]
    commands = _commands(scene)
    t_end = 10.0
    one = _run(scene, [], t_end, commands)
    kinds = {EVENT_KINDS[k] for k in np.unique(one['events']['kind'])}
    assert len(one['events']) > 100 and ('knife_contact' in kinds or 'leaf_exit' in kinds)
    rng = np.random.default_rng(len(name))
    for cuts in (np.arange(0.013, t_end, 0.013), np.arange(1.0, t_end, 1.0), np.sort(rng.uniform(0.0, t_end, 29))):
        _assert_same(one, _run(scene, cuts, t_end, commands))


def test_every_effect_and_command_kind_is_exercised(scenes: dict[str, Scene]) -> None:
    """The scenes above list every effect of the line, and the commands every kind of tuning."""
    from folder_line.core.effects import EFFECTS

    listed = {e for s in scenes.values() for e in s.effects}
    assert listed == set(EFFECTS)
    keys = {c.key for s in scenes.values() for c in _commands(s) if isinstance(c, Tuning)}
    assert keys == {'feed_transporter.V_tr', 'layup.v_tr', 'press.n_c', 'pile.t_lower'}


@pytest.mark.parametrize('name', ['folder', 'line', 'layup'])
def test_minute_long_windows_over_two_minutes(scenes: dict[str, Scene], name: str) -> None:
    scene = scenes[name]
    commands = [Command(61.5, 'hold'), Command(63.0, 'unhold')]
    _assert_same(_run(scene, [], 130.0, commands, rate=5.0), _run(scene, [60.0, 120.0], 130.0, commands, rate=5.0))


@pytest.mark.parametrize('name', ['line', 'every_folder_effect', 'guide_friction_sticks', 'layup_faults_ripple'])
def test_a_checkpoint_at_an_awkward_time_gives_the_same_rest_of_the_run(scenes: dict[str, Scene], name: str) -> None:
    """Restored at 2.0371 s (mid-ramp of the hold, signatures and leaves on their way), the run goes on as it
    went; restored under a command it did not know, it goes on as a run that knew it from the start."""
    scene = scenes[name]
    known = [Command(1.9, 'hold'), Command(3.0, 'unhold')]
    later = Command(4.4, 'stop')
    stream = LineStream(scene, known)
    stream.advance(1.0)
    stream.advance(2.0371)
    cp = stream.checkpoint()
    rest = stream.advance(6.0).events
    for _ in range(2):  # a checkpoint restores as often as asked
        stream.restore(cp)
        assert stream.t == 2.0371
        assert stream.advance(6.0).events.tobytes() == rest.tobytes()
    grid = np.linspace(2.05, 6.0, 80)
    stream.restore(cp, [*known, later])
    learnt = stream.advance(6.0).events
    upfront = LineStream(scene, [*known, later])
    upfront.advance(2.0371)
    assert learnt.tobytes() == upfront.advance(6.0).events.tobytes()
    # and so are its joint states, every unit's (the pile table's too: restored as a new object)
    got, want = stream.sample_all(grid), upfront.sample_all(grid)
    assert got.keys() == want.keys()
    for unit in want:
        assert got[unit].position.tobytes() == want[unit].position.tobytes(), unit
        assert got[unit].velocity.tobytes() == want[unit].velocity.tobytes(), unit
    assert learnt.tobytes() != rest.tobytes()  # the stop changed the line after 4.4 s
    before = learnt[learnt['t'] <= 4.4]
    assert before.tobytes() == rest[rest['t'] <= 4.4].tobytes()  # and nothing before it


def test_a_command_inside_the_lookahead_redoes_the_window(scenes: dict[str, Scene]) -> None:
    """With guide_friction the work of a window goes one step past its end; a command effective there is
    taken by redoing the window from its start, and the run is the run that knew it."""
    scene = scenes['guide_friction']
    h = scene.effect_params('guide_friction').h
    stream = LineStream(scene)
    stream.advance(1.0)
    assert stream.computed == pytest.approx(1.0 + h)
    stream.set_commands([Command(1.0 + 0.5 * h, 'hold')])
    stream.advance(3.0)
    ref = LineStream(scene, [Command(1.0 + 0.5 * h, 'hold')])
    ref.advance(1.0)
    ref.advance(3.0)
    assert stream.summary().as_json() == ref.summary().as_json()
    with pytest.raises(ValueError, match='restore a checkpoint'):
        stream.set_commands([Command(1.0 + 0.5 * h, 'hold'), Command(2.5, 'unhold')])


def test_the_summary_streamed_is_the_kept_models() -> None:
    for name in list_scenes():
        scene = load_scene(name)
        kept = LineModel(scene, 30.0).result(30.0, 0.0).summary()
        assert run_summary(scene, 30.0, window=7.3).as_json() == kept.as_json(), name


def _size(obj: Any, seen: set[int] | None = None) -> int:
    """Bytes held by ``obj``: its arrays' buffers, and a few bytes per other value, walked once each."""
    seen = set() if seen is None else seen
    if id(obj) in seen or isinstance(obj, (Scene, types.FunctionType, types.MethodType, type)):
        return 0
    seen.add(id(obj))
    if isinstance(obj, np.ndarray):
        return int(obj.nbytes)
    if isinstance(obj, dict):
        return 8 + sum(_size(k, seen) + _size(v, seen) for k, v in obj.items())
    if isinstance(obj, (list, tuple, set)):
        return 8 + sum(_size(v, seen) for v in obj)
    if hasattr(obj, '__dict__'):
        return 8 + sum(_size(v, seen) for v in vars(obj).values())
    return 8


def _carried_sizes(stream: LineStream) -> dict[str, int]:
    """The length of every array and dict a stream carries between windows, and its bytes in all."""
    out: dict[str, int] = {}
    for part, st in (('folder', stream.folder), ('layup', stream.layup)):
        if st is None:
            continue
        for key, value in vars(st.state).items():
            if isinstance(value, np.ndarray):
                out[f'{part}.{key}'] = value.size
            elif isinstance(value, dict):
                out[f'{part}.{key}'] = len(value)
    out['pile'] = stream.pile.kept
    out['bytes'] = _size(stream.checkpoint().parts) + _size(stream.drive)
    return out


@pytest.mark.parametrize(
    ('name', 'judge'),
    [('folder_faults', True), ('line', True), ('layup', True), ('folder_faults', False), ('line', False)],
)
def test_the_state_carried_does_not_grow_with_line_time(name: str, judge: bool) -> None:
    """What a stream carries from window to window is what is in the machine: the same size after 10 min
    and after an hour, judging or not (a machine node's stream does not judge; the memory benchmark
    measures the bytes: bench/bench_memory.py)."""
    scene = load_scene(name)
    stream = LineStream(scene, [Command(100.0, 'hold'), Command(103.0, 'unhold')], judge=judge)

    t = 0.0
    seen = []
    for stop in (600.0, 3600.0):
        while t < stop:
            t += 60.0
            stream.advance(t)
        seen.append(_carried_sizes(stream))
    ten, hour = seen
    for key in ten:
        if key != 'bytes':
            assert hour[key] <= max(2 * ten[key], 64), key
    # a minute of the line in flight (the window), the running sums' blocks of 4096 values, the motor's
    # start-up steps: a few megabytes at most, the same after an hour (the hour's events alone, kept, would
    # be 17 MB of the folder's)
    assert hour['bytes'] <= 1.5 * ten['bytes'] + 300_000 and hour['bytes'] < 5_000_000
    assert stream.summary().cycles > 40_000 or name == 'layup' or not judge
    assert math.isfinite(stream.t)
