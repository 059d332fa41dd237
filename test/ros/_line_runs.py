"""What the tests of ``folder-line run`` share: the run as a process, its bag read independently, /proc.

* :func:`start_run` starts ``python -m folder_line.cli.main run ...`` with the test's environment
  plus a unique tag variable, stdout and stderr to files (a pipe nobody reads could block it);
  :func:`wait_for_line_time` waits for its progress output to reach a line time.
* :func:`read_bag_mcap` reads a run's bag with the independent reader (``mcap`` and
  ``mcap-ros2-support``, decoding from the schema text in each file; not ``folder_line.bag``),
  per topic and publishing node, in order; :func:`plain` makes a message comparable.
* :func:`assert_bag_is_model` compares a bag with the batch model, tick by tick.
* :func:`children`, :func:`tagged` and :func:`line_processes` find processes through ``/proc`` (Linux).
"""

from __future__ import annotations

import contextlib
import os
import re
import signal
import subprocess
import sys
import time
import uuid
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace
from typing import TYPE_CHECKING, Any

from _ros_env import node_environment
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from std_msgs.msg import String

from folder_line.interfaces import SUPERVISOR_STATE_TOPIC
from folder_line.ros.nodes.supervisor import STATE_QOS

if TYPE_CHECKING:
    from folder_line.core.line.model import LineModel

REPO = Path(__file__).resolve().parents[2]
TAG = 'FOLDER_LINE_TEST_TAG'
_PROGRESS = re.compile(r'(\d+\.\d+) / \S+ s of line time')


@dataclass
class RunProcess:
    """A ``folder-line run`` started by :func:`start_run`."""

    proc: subprocess.Popen[bytes]
    out: Path
    stdout: Path
    stderr: Path
    tag: str
    started: int  # clock ticks since boot (:func:`start_time`)

    @property
    def pid(self) -> int:
        return self.proc.pid

    def line_time(self) -> float:
        """The latest line time its progress output shows (-1 before the first)."""
        found = _PROGRESS.findall(self.stdout.read_text(errors='replace'))
        return float(found[-1]) if found else -1.0

    def wait(self, timeout: float) -> int:
        """Its exit code; kills it (and fails) after ``timeout`` s."""
        try:
            return self.proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
            raise AssertionError(f'folder-line run did not end within {timeout:g} s; stderr:\n{self.text()}') from None

    def stop(self) -> None:
        """End it if it still runs: SIGTERM (it closes its bag and ends its nodes), SIGKILL after 60 s.

        (A killed run leaves its DDS endpoints in the other participants' discovery until their lease
        expires, and the next run on the domain would take them for another line.)
        """
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=60)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()

    def text(self) -> str:
        """stdout and stderr so far, for assertion messages."""
        return self.stdout.read_text(errors='replace') + self.stderr.read_text(errors='replace')

    def error_lines(self) -> list[str]:
        """The ``folder-line: ...`` lines of its stderr (the node logs are the rest)."""
        return [
            line for line in self.stderr.read_text(errors='replace').splitlines() if line.startswith('folder-line:')
        ]


def start_run(env: dict[str, str], out: Path, *args: str, logs: Path | None = None) -> RunProcess:
    """``python -m folder_line.cli.main run --out OUT ARGS`` in ``env`` with a unique :data:`TAG`."""
    tag = uuid.uuid4().hex
    logs = logs or out.parent
    logs.mkdir(parents=True, exist_ok=True)
    stdout, stderr = logs / f'{out.name}.stdout', logs / f'{out.name}.stderr'
    with open(stdout, 'wb') as so, open(stderr, 'wb') as se:
        proc = subprocess.Popen(
            [sys.executable, '-m', 'folder_line.cli.main', 'run', '--out', str(out), *args],
            env={**env, TAG: tag},
            cwd=REPO,
            stdout=so,
            stderr=se,
        )
    return RunProcess(proc, out, stdout, stderr, tag, start_time(proc.pid))


def wait_until(predicate: Callable[[], bool], timeout: float, period: float = 0.05) -> bool:
    """Poll ``predicate`` until true or ``timeout`` s of wall time pass; return it."""
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            return predicate()
        time.sleep(period)
    return True


def wait_for_line_time(run: RunProcess, t: float, timeout: float = 90.0) -> None:
    """Wait until ``run`` shows line time ``>= t`` (and is still running)."""
    ok = wait_until(lambda: run.line_time() >= t or run.proc.poll() is not None, timeout)
    assert ok and run.proc.poll() is None, f'line time {run.line_time()} (exit {run.proc.poll()}):\n{run.text()}'


# --------------------------------------------------------------------------- /proc


def children(pid: int) -> list[int]:
    """Direct children of ``pid`` (``/proc/<pid>/task/*/children``)."""
    out: list[int] = []
    for task in Path(f'/proc/{pid}/task').glob('*'):
        with contextlib.suppress(OSError):
            out += [int(c) for c in (task / 'children').read_text().split()]
    return out


def cmdline(pid: int) -> list[str]:
    """Arguments of process ``pid`` ([] if it is gone)."""
    try:
        return Path(f'/proc/{pid}/cmdline').read_bytes().decode(errors='replace').split('\0')
    except OSError:
        return []


def child_node(pid: int, node: str) -> int:
    """The child of ``pid`` that runs node ``node`` (``-m folder_line.ros.entry <node>``)."""
    found = [c for c in children(pid) if _runs_node(cmdline(c), node)]
    assert len(found) == 1, {c: cmdline(c) for c in children(pid)}
    return found[0]


def state(pid: int) -> str:
    """The state letter of ``pid`` (R, S, T, Z ...; '' if it is gone)."""
    try:
        text = Path(f'/proc/{pid}/stat').read_text()
    except OSError:
        return ''
    return text.rsplit(')', 1)[1].split()[0]


def tagged(tag: str) -> dict[int, list[str]]:
    """Every live process (not a zombie) whose environment has :data:`TAG` = ``tag``, with its arguments."""
    needle = f'{TAG}={tag}'.encode()
    found = {}
    for entry in Path('/proc').iterdir():
        if not entry.name.isdigit():
            continue
        try:
            environ = (entry / 'environ').read_bytes()
        except OSError:
            continue
        if needle in environ.split(b'\0') and state(int(entry.name)) not in ('Z', 'X', ''):
            found[int(entry.name)] = cmdline(int(entry.name))
    return found


def start_time(pid: int) -> int:
    """When ``pid`` started, in clock ticks since boot (``/proc/<pid>/stat`` field 22; -1 if it is gone)."""
    try:
        return int(Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()[19])
    except (OSError, IndexError, ValueError):
        return -1


def _runs_node(args: list[str], node: str) -> bool:
    """Whether a command line runs ``node`` (``-m folder_line.ros.entry <node>`` or ``...ros.nodes.<node>``)."""
    if f'folder_line.ros.nodes.{node}' in args:
        return True
    return any(a == 'folder_line.ros.entry' and args[i + 1 : i + 2] == [node] for i, a in enumerate(args))


def line_processes(out: Path, domain: int, since: int) -> dict[int, list[str]]:
    """Live processes started at ``since`` (clock ticks, :func:`start_time`) or later whose arguments name
    ``out`` or run ``folder_line.ros.nodes`` with ``ROS_DOMAIN_ID=domain`` (older ones are not the run's)."""
    found = {}
    for entry in Path('/proc').iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        args = cmdline(int(entry.name))
        text = ' '.join(args)
        if state(int(entry.name)) in ('Z', 'X', '') or start_time(int(entry.name)) < since:
            continue
        if str(out) in text:
            found[int(entry.name)] = args
        elif 'folder_line.ros.nodes.' in text or 'folder_line.ros.entry' in text:
            try:
                environ = (entry / 'environ').read_bytes().split(b'\0')
            except OSError:
                continue
            if f'ROS_DOMAIN_ID={domain}'.encode() in environ:
                found[int(entry.name)] = args
    return found


# --------------------------------------------------------------------------- bags


def plain(obj: Any) -> Any:
    """An mcap_ros2 message as nested tuples of (field, value); sequences as tuples."""
    if isinstance(obj, SimpleNamespace) and hasattr(obj, '__slots__'):
        return (type(obj).__name__, tuple((k, plain(getattr(obj, k))) for k in obj.__slots__ if not k.startswith('_')))
    if isinstance(obj, (list, tuple)):
        return tuple(plain(x) for x in obj)
    return obj


@dataclass(frozen=True)
class Record:
    """One message of a bag as the mcap reader gives it (no wall time: the bag has none)."""

    log_ns: int
    publish_ns: int
    msg: Any  # the decoded mcap_ros2 message

    @property
    def value(self) -> Any:
        return plain(self.msg)


def read_bag_mcap(bag: Path, topics: Sequence[str] | None = None) -> dict[tuple[str, str], list[Record]]:
    """Every message of the bag, per (topic, ``header.frame_id`` or ''), in file order.

    Every segment must be a finished MCAP file (summary and footer) of the ``ros2`` profile.
    """
    files = sorted(bag.glob('*.mcap'), key=lambda p: int(p.stem.rsplit('_', 1)[1]))
    assert files, f'no .mcap file in {bag}'
    out: dict[tuple[str, str], list[Record]] = {}
    for path in files:
        with path.open('rb') as fh:
            reader = make_reader(fh, decoder_factories=[DecoderFactory()])
            assert reader.get_header().profile == 'ros2'
            assert reader.get_summary() is not None, f'{path}: not finished'
            for _, channel, message, ros in reader.iter_decoded_messages(topics=topics, log_time_order=False):
                header = getattr(ros, 'header', None)
                key = (channel.topic, '' if header is None else header.frame_id)
                out.setdefault(key, []).append(Record(message.log_time, message.publish_time, ros))
    return out


def stamp_ns(msg: Any) -> int:
    """``header.stamp`` of a decoded message, ns."""
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


def statuses(records: dict[tuple[str, str], list[Record]], name: str) -> list[tuple[int, dict[str, str], Any]]:
    """Every ``/diagnostics`` status called ``name``: (log time, key/values, status), in bag order."""
    found = []
    for (topic, _), recs in records.items():
        if topic != '/diagnostics':
            continue
        for rec in recs:
            for st in rec.msg.status:
                if st.name == name:
                    found.append((rec.log_ns, {kv.key: kv.value for kv in st.values}, st))
    return sorted(found, key=lambda x: x[0])


# --------------------------------------------------------------------------- the batch model


def assert_bag_is_model(
    records: dict[tuple[str, str], list[Record]],
    scene_name: str,
    duration: float,
    rate: float = 200.0,
    rejected: bool = False,
) -> None:
    """The line's messages in ``records`` are the batch model of the scene, tick by tick.

    Exactly one tick per ``1/rate`` s of line time from 0 to ``duration`` on ``/clock`` and on
    every joint-state, count, rate and state topic, each logged at its tick; joint states
    equal ``LineModel(scene, duration + 1.0).sample(node, t)`` to 1e-9 (the horizon ``run`` gives
    the nodes); the events are the model's events up to ``duration``, once each, at their
    model time (nearest ns) and value, published in the tick that contains them; the counts are
    the model's counted events; the supervisor is in EXECUTE (after STARTING, if it starts) and stays there
    and commands nothing, and no diagnostic status is above OK (but the rejected inputs', if
    ``rejected``). Records of other publishers (a fuzzer's) are not looked at, nor, if ``rejected``,
    events under a node's name that the node cannot have published.
    """

    from folder_line.config.scenes import load_scene
    from folder_line.core.line.model import LineModel

    ns = 1_000_000_000
    step = round(ns / rate)
    n_ticks = round(duration * rate) + 1
    ticks = [k * step for k in range(n_ticks)]
    model = LineModel(load_scene(scene_name), duration + 1.0)

    clock = records[('/clock', '')]
    assert [r.msg.clock.sec * ns + r.msg.clock.nanosec for r in clock] == ticks
    assert [r.log_ns for r in clock] == ticks

    _assert_joint_states_are_model(records, model, ticks)
    _assert_events_are_model(records, model, ticks, duration, rejected)
    _assert_count_is_model(records, model, ticks)
    _assert_supervisor_quiet(records, n_ticks, duration, rejected)


def _assert_joint_states_are_model(
    records: dict[tuple[str, str], list[Record]], model: LineModel, ticks: list[int]
) -> None:
    """Every node's joint states at each tick are the model's (:func:`assert_bag_is_model`)."""
    import numpy as np

    from folder_line.interfaces import MACHINE_NODES, NODE_OF_UNIT

    ns = 1_000_000_000
    nodes = {NODE_OF_UNIT[unit]: (unit, joints) for unit, joints in model.units.items()}
    assert set(nodes) <= set(MACHINE_NODES) and nodes
    for node, (unit, joints) in nodes.items():
        recs = records[(f'/line/{node}/joint_states', node)]
        stamps = [stamp_ns(r.msg) for r in recs]
        assert stamps == ticks, (node, len(stamps), len(ticks))
        assert [r.log_ns for r in recs] == ticks and [r.publish_ns for r in recs] == ticks, node
        assert all(tuple(r.msg.name) == joints for r in recs), node
        expect = model.sample(unit, np.array(stamps) / ns)
        np.testing.assert_allclose([r.msg.position for r in recs], expect.position, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose([r.msg.velocity for r in recs], expect.velocity, rtol=1e-9, atol=1e-9)
        if expect.effort is None:
            assert all(len(r.msg.effort) == 0 for r in recs), node
        else:
            np.testing.assert_allclose([r.msg.effort for r in recs], expect.effort, rtol=1e-9, atol=1e-9)


def _assert_events_are_model(
    records: dict[tuple[str, str], list[Record]], model: LineModel, ticks: list[int], duration: float, rejected: bool
) -> None:
    """The events are the model's, once each, in the tick that contains them (:func:`assert_bag_is_model`)."""
    from folder_line.interfaces import EVENT_KINDS, EVENT_OWNER, MACHINE_NODES, parse_event_source

    ns = 1_000_000_000
    step = ticks[1] - ticks[0]
    got = []
    for node in MACHINE_NODES:
        for r in records.get(('/line/events', node), []):
            try:
                kind, sheet, cycle, value = parse_event_source(r.msg.source)
            except ValueError:
                kind = ''
            if EVENT_OWNER.get(kind) != node:  # not the node's: a fuzzer's, with the node's name
                assert rejected, (node, r.msg.source)
                continue
            t_ns = r.msg.time_ref.sec * ns + r.msg.time_ref.nanosec
            tick = stamp_ns(r.msg)
            assert r.log_ns == tick and tick in ticks, (node, kind, tick)
            assert tick - step - 1 <= t_ns <= tick + 1 or tick == 0, (node, kind, t_ns, tick)  # (t - step, t]
            got.append((kind, sheet, cycle, t_ns, value))
    table = model.events[model.events['t'] <= duration]
    expect_rows = sorted(
        (EVENT_KINDS[r['kind']], int(r['sheet']), int(r['cycle']), round(float(r['t']) * ns), float(r['value']))
        for r in table
    )
    assert sorted(got) == expect_rows
    assert len(got) > 100


def _assert_count_is_model(records: dict[tuple[str, str], list[Record]], model: LineModel, ticks: list[int]) -> None:
    """The count at each tick is the model's counted events so far; a rate at each tick."""
    import numpy as np

    from folder_line.core.mechanisms.pile import counted_event
    from folder_line.interfaces import EVENT_KINDS

    ns = 1_000_000_000
    counted = model.events[model.events['kind'] == EVENT_KINDS.index(counted_event(model.scene.has_delivery))]['t']
    count = records[('/line/sheet_counter/count', '')]
    assert [r.log_ns for r in count] == ticks
    assert [r.msg.data for r in count] == [int(np.count_nonzero(counted <= t / ns)) for t in ticks]
    assert count[-1].msg.data > 0
    assert [r.log_ns for r in records[('/line/sheet_counter/rate', '')]] == ticks


def _assert_supervisor_quiet(
    records: dict[tuple[str, str], list[Record]], n_ticks: int, duration: float, rejected: bool
) -> None:
    """The supervisor is in EXECUTE after STARTING, commands nothing and reports nothing above OK."""
    from folder_line.interfaces import COMMAND_KINDS

    ns = 1_000_000_000
    states = [r.msg.data for r in records[('/line/supervisor/state', '')]]
    assert len(states) == n_ticks and states[-1] == 'EXECUTE'
    first = states.index('EXECUTE')
    assert set(states[:first]) <= {'STARTING'} and set(states[first:]) == {'EXECUTE'}
    commands = records.get(('/line/supervisor/commands', 'supervisor'), [])
    assert not (commands and not rejected) and not [r for r in commands if r.msg.source in COMMAND_KINDS]
    diags = records[('/diagnostics', 'supervisor')]
    assert [stamp_ns(r.msg) for r in diags] == [k * ns for k in range(int(duration) + 1)]
    assert [r.log_ns for r in diags] == [stamp_ns(r.msg) for r in diags]
    for r in diags:  # no constraint ever violated, no input rejected
        assert all(st.level == 0 or (rejected and st.name == 'folder_line/supervisor/inputs') for st in r.msg.status), [
            (st.name, st.level, st.message) for st in r.msg.status
        ]


@contextlib.contextmanager
def line_with_states(ros: Any, out: Path, duration: float, scene: str = 'folder') -> Iterator[LiveLine]:
    """A ``folder-line run`` of ``scene`` at rtf 1 into ``out`` (stderr piped), and the supervisor's state
    as a listener in ``ros`` hears it; the run is killed on the way out if it still runs."""
    proc = subprocess.Popen(
        [
            sys.executable,
            '-m',
            'folder_line.cli.main',
            'run',
            '--scene',
            scene,
            '--duration',
            str(duration),
            '--rtf',
            '1',
            '--out',
            str(out),
        ],
        env=node_environment(),
        cwd=REPO,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        listener = ros.node(f'line_listener_{uuid.uuid4().hex[:6]}')
        yield LiveLine(proc, ros.subscribe(listener, String, SUPERVISOR_STATE_TOPIC, STATE_QOS))
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()


@dataclass
class LiveLine:
    """A run of :func:`line_with_states`: the process and the states heard."""

    proc: subprocess.Popen[str]
    states: Any

    def state(self) -> str:
        """The latest state heard ('' before the first)."""
        return str(self.states.messages[-1].data) if self.states.messages else ''


def run_under_attack(script: str, env: dict[str, str], tmp_path: Path, duration: float) -> tuple[Any, dict[str, Any]]:
    """A folder run of ``duration`` s at rtf 1, in this process, while the attacker ``test/ros/<script>``
    runs in a process of its own with ``env``: once it is ready (``REPORT.ready``) until the run ends
    (``REPORT.stop``). Returns the run's result and the attacker's JSON report (its exit code 0)."""
    import io
    import json

    from folder_line.config.run_config import RunConfig
    from folder_line.ros.run import run_line

    report = tmp_path / f'{Path(script).stem}.json'
    log = tmp_path / f'{Path(script).stem}.log'
    with open(log, 'wb') as fh:
        attacker = subprocess.Popen(
            [sys.executable, str(Path(__file__).with_name(script)), str(report)],
            env=env,
            stdout=fh,
            stderr=subprocess.STDOUT,
        )
    try:
        assert wait_until(lambda: report.with_suffix('.ready').exists() or attacker.poll() is not None, 120)
        assert attacker.poll() is None, log.read_text()
        cfg = RunConfig(scene='folder', duration=duration, rtf=1.0, out=tmp_path / 'attacked')
        result = run_line(cfg, io.StringIO())
    finally:
        report.with_suffix('.stop').touch()
        attacker.wait(timeout=60)
    assert attacker.returncode == 0, log.read_text()
    return result, json.loads(report.read_text())
