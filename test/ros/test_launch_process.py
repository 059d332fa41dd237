"""Node processes as ``ros2 launch`` runs them: stopped at any moment they exit 0, silently; they die with the launch.

launch starts each node's executable (``folder_line.ros.entry``) and stops it with SIGINT,
then SIGTERM after its ``sigterm_timeout``; a Ctrl-C in its terminal reaches each node twice
(the terminal's SIGINT and launch's). Every test here starts real processes on this test
process's ROS domain, sends the signals as launch does, and checks the exit code, that
stderr has no ``Traceback`` nor ``KeyboardInterrupt``, and that no process is left (by pid).
A moment is reached by waiting for what marks it (a file the child writes, a signal handler in
``/proc``, the node's parameter service), never by sleeping.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import pytest
from rclpy.node import Node
from rclpy.parameter_client import AsyncParameterClient
from rclpy.task import Future

from folder_line.ros.entry import PARENT_PID_ENV, die_with_parent
from folder_line.ros.runtime import STOP_GRACE, run_node

from ._node_process import NodeProcess, assert_clean_exit, catches, executable, send, start, unique_name, wait_until

if TYPE_CHECKING:
    from .conftest import Ros

LONG = 60.0  # s a child would block for: a test that passes ends it long before


@pytest.fixture
def started() -> Iterator[list[NodeProcess]]:
    """The processes a test starts; each is ended (SIGKILL) if the test leaves it running."""
    procs: list[NodeProcess] = []
    yield procs
    for proc in procs:
        proc.close()


def _spinning(ros: Ros, name: str, proc: NodeProcess) -> None:
    """Wait until node ``name`` in ``proc`` answers on its parameter service: built and spinning."""
    client = AsyncParameterClient(ros.node(f'probe_of_{name}'), name)
    assert ros.spin_until(lambda: client.services_are_ready() or proc.proc.poll() is not None, timeout=60.0)
    assert proc.proc.poll() is None, proc.err()


# --------------------------------------------------------------------------- the executables' imports


_SLOW_IMPORT = """
import sys
sys.path.insert(0, {where!r})
import folder_line.ros.entry as entry

entry.NODE_MODULES['slow_node'] = 'slow_node'  # a node module whose import takes {long} s
sys.exit(entry.run('slow_node'))
"""

_SLOW_MODULE = """
import pathlib
import time

pathlib.Path({mark!r}).write_text('importing')
time.sleep({long})


def main():
    return 7
"""


@pytest.mark.parametrize('signum', [signal.SIGINT, signal.SIGTERM], ids=['SIGINT', 'SIGTERM'])
def test_a_stop_during_the_imports_exits_0_at_once(
    node_env: dict[str, str], tmp_path: Path, started: list[NodeProcess], signum: signal.Signals
) -> None:
    mark = tmp_path / 'importing'
    (tmp_path / 'slow_node.py').write_text(_SLOW_MODULE.format(mark=str(mark), long=LONG))
    code = _SLOW_IMPORT.format(where=str(tmp_path), long=LONG)
    started.append(proc := start([sys.executable, '-c', code], node_env, tmp_path))
    wait_until(mark.exists, 60.0, 'the node module being imported')
    send(proc, signum)
    assert_clean_exit(proc, 0, timeout=LONG / 2)  # not the import's end: that would be code 7
    assert proc.err() == '' and proc.out() == ''


@pytest.mark.parametrize('signum', [signal.SIGINT, signal.SIGTERM], ids=['SIGINT', 'SIGTERM'])
def test_a_real_node_stopped_while_it_starts_exits_0(
    node_env: dict[str, str], tmp_path: Path, started: list[NodeProcess], signum: signal.Signals
) -> None:
    """The signal comes as soon as the executable handles it (the interpreter's own SIGINT handler
    is there from its start: the entry point's SIGTERM handler marks the moment): during the node
    module's imports, or whatever the node does by then; it exits 0 with no traceback."""
    started.append(proc := start(executable('crank_drive'), node_env, tmp_path))
    wait_until(lambda: catches(proc.pid, signal.SIGTERM) or proc.proc.poll() is not None, 60.0, 'the stop handler')
    send(proc, signum)
    assert_clean_exit(proc, 0)


# --------------------------------------------------------------------------- a spinning node


@pytest.mark.parametrize(
    'signums',
    [
        (signal.SIGINT,),
        (signal.SIGTERM,),
        (signal.SIGINT, signal.SIGINT),  # Ctrl-C in launch's terminal: from the terminal and from launch
        (signal.SIGINT, signal.SIGTERM),  # launch's SIGTERM after its SIGINT
    ],
    ids=['SIGINT', 'SIGTERM', 'SIGINT-SIGINT', 'SIGINT-SIGTERM'],
)
def test_a_spinning_node_stopped_as_launch_stops_it_exits_0(
    ros: Ros, node_env: dict[str, str], tmp_path: Path, started: list[NodeProcess], signums: tuple[signal.Signals, ...]
) -> None:
    name = unique_name('crank_drive')
    command = [*executable('crank_drive'), '--ros-args', '-r', f'__node:={name}', '-p', 'rate:=200']
    started.append(proc := start(command, node_env, tmp_path))
    _spinning(ros, name, proc)
    send(proc, *signums)
    assert_clean_exit(proc, 0)


_CHILD = '''
import os
import signal
import sys
import time
from pathlib import Path

from rclpy.node import Node
from rclpy.task import Future

from folder_line.ros.runtime import run_node

MARK = Path({mark!r})


def work(seconds):
    """Python code that runs for ``seconds`` (a long computation: signal handlers run between its bytecodes)."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        time.sleep(0.001)


class Building(Node):
    """Its constructor takes {long} s."""

    NODE_NAME = 'building'

    def __init__(self):
        super().__init__(self.NODE_NAME)
        MARK.write_text('building')
        work({long})


class Stuck(Node):
    """Its first timer callback takes {long} s; asks for exit code {code}."""

    NODE_NAME = 'stuck'

    def __init__(self):
        super().__init__(self.NODE_NAME)
        self.create_timer(0.01, self.tick)

    def tick(self):
        MARK.write_text('in a callback')
        work({long})

    def exit_code(self):
        return {code}


class Done(Node):
    """Done at once; asks for exit code {code}."""

    NODE_NAME = 'done'

    def __init__(self):
        super().__init__(self.NODE_NAME)
        self.done = Future()
        self.done.set_result(True)

    def exit_code(self):
        return {code}


code = run_node({node})
if {late}:  # stop requests after run_node returned: the process is exiting
    os.kill(os.getpid(), signal.SIGINT)
    os.kill(os.getpid(), signal.SIGTERM)
    time.sleep(0.1)  # the interpreter runs pending Python handlers in this time
MARK.write_text('exiting')
sys.exit(code)
'''


def _child(tmp_path: Path, node: str, code: int = 0, late: bool = False) -> tuple[list[str], Path]:
    mark = tmp_path / 'mark'
    text = _CHILD.format(mark=str(mark), long=LONG, node=node, code=code, late=late)
    return [sys.executable, '-c', text], mark


@pytest.mark.parametrize('code', [0, 3])
def test_sigterm_after_sigint_ends_a_node_stuck_in_a_callback(
    node_env: dict[str, str], tmp_path: Path, started: list[NodeProcess], code: int
) -> None:
    """A node that cannot stop on SIGINT (its callback does not return) exits at once on launch's
    SIGTERM, STOP_GRACE s later, with its exit code and one line on stderr."""
    command, mark = _child(tmp_path, 'Stuck', code=code)
    started.append(proc := start(command, node_env, tmp_path))
    wait_until(mark.exists, 60.0, 'the long callback')
    send(proc, signal.SIGINT, signal.SIGTERM)
    assert_clean_exit(proc, code, timeout=LONG / 2)
    said = f'stuck: a callback still ran {STOP_GRACE:g} s after SIGTERM repeated the stop request; exiting at once'
    assert proc.err().count(said) == 1, proc.err()  # (the middleware may log lines of its own)
    assert mark.read_text() == 'in a callback'  # it did not get to the end of the script


def test_a_node_stopped_while_it_is_built_exits_0(
    node_env: dict[str, str], tmp_path: Path, started: list[NodeProcess]
) -> None:
    """launch's SIGINT, then its SIGTERM, while the constructor runs: the build is cut short, 0.

    (Two SIGTERMs sent at once may reach Python as one: a signal pending twice is delivered once.)"""
    command, mark = _child(tmp_path, 'Building')
    started.append(proc := start(command, node_env, tmp_path))
    wait_until(mark.exists, 60.0, 'the node being built')
    send(proc, signal.SIGINT, signal.SIGTERM)
    assert_clean_exit(proc, 0, timeout=LONG / 2)
    assert mark.read_text() == 'exiting'


@pytest.mark.parametrize('code', [0, 3])
def test_a_stop_request_while_the_process_exits_keeps_its_exit_code(
    node_env: dict[str, str], tmp_path: Path, started: list[NodeProcess], code: int
) -> None:
    """launch signals every node still running when the clock exits, nodes that are exiting too:
    the process exits with its own code (the node's ``exit_code()``), not killed by the signal."""
    command, mark = _child(tmp_path, 'Done', code=code, late=True)
    started.append(proc := start(command, node_env, tmp_path))
    assert_clean_exit(proc, code)
    assert mark.read_text() == 'exiting'


class _Coded(Node):
    NODE_NAME = 'coded'

    def __init__(self) -> None:
        super().__init__(self.NODE_NAME)
        self.done: Future[bool] = Future()
        self.done.set_result(True)

    def exit_code(self) -> int:
        return 4


def test_run_node_asks_the_node_for_its_exit_code_by_default() -> None:
    assert run_node(_Coded, args=[]) == 4
    assert run_node(_Coded, args=[], exit_code=lambda node: 0) == 0  # the callable given wins


# --------------------------------------------------------------------------- the parent's death


_STAND_IN = """
import os
import subprocess
import sys
import time

# stands for ros2 launch: starts the node asking it to die with this process, then waits
with open(sys.argv[1], 'wb') as out, open(sys.argv[2], 'wb') as err:
    node = subprocess.Popen(sys.argv[3:], env=dict(os.environ, {env}=str(os.getpid())), stdout=out, stderr=err)
print(node.pid, flush=True)
time.sleep({long})
"""

_HARNESS = """
import ctypes
import os
import signal
import subprocess
import sys
import time

# a subreaper: the orphaned node becomes this process's child, whose exit status it can read
assert ctypes.CDLL(None, use_errno=True).prctl(36, 1, 0, 0, 0) == 0  # PR_SET_CHILD_SUBREAPER
stand_in = subprocess.Popen([sys.executable, '-c', {stand_in!r}, *sys.argv[1:]], stdout=subprocess.PIPE, text=True)
node = int(stand_in.stdout.readline())
print(node, flush=True)
sys.stdin.readline()  # the test says when
os.kill(stand_in.pid, signal.SIGKILL)
stand_in.wait()
deadline = time.monotonic() + {long}
while True:
    pid, status = os.waitpid(node, os.WNOHANG)
    if pid:
        print(os.waitstatus_to_exitcode(status), flush=True)
        break
    if time.monotonic() > deadline:
        os.kill(node, signal.SIGKILL)
        os.waitpid(node, 0)
        print('still running', flush=True)
        break
    time.sleep(0.01)
"""


@pytest.mark.skipif(not sys.platform.startswith('linux'), reason='PR_SET_PDEATHSIG is Linux')
@pytest.mark.parametrize('moment', ['starting', 'spinning'])
def test_a_node_dies_with_the_launch_that_started_it(
    ros: Ros, node_env: dict[str, str], tmp_path: Path, moment: str
) -> None:
    """``ros2 launch`` killed (SIGKILL): its node gets SIGTERM from the kernel and exits 0, nothing left."""
    stand_in = _STAND_IN.format(env=PARENT_PID_ENV, long=LONG)
    name = unique_name('crank_drive')
    harness = subprocess.Popen(
        [sys.executable, '-c', _HARNESS.format(stand_in=stand_in, long=LONG), str(tmp_path / 'node.out'),
         str(tmp_path / 'node.err'), *executable('crank_drive'), '--ros-args', '-r', f'__node:={name}'],
        env=node_env, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
    )  # fmt: skip
    assert harness.stdin is not None and harness.stdout is not None
    node = int(harness.stdout.readline())
    try:
        if moment == 'starting':
            wait_until(lambda: catches(node, signal.SIGTERM), 60.0, 'the stop handler')
        else:
            client = AsyncParameterClient(ros.node('probe_of_crank_drive'), name)
            assert ros.spin_until(client.services_are_ready, timeout=60.0)
        harness.stdin.write('go\n')
        harness.stdin.flush()
        result = harness.stdout.readline().strip()
        assert harness.wait(timeout=60.0) == 0
    finally:
        if harness.poll() is None:
            harness.kill()
            harness.wait()
    err = (tmp_path / 'node.err').read_text(errors='replace')
    assert result == '0', err
    assert 'Traceback' not in err and 'KeyboardInterrupt' not in err, err
    assert not os.path.exists(f'/proc/{node}')


def test_a_node_whose_launch_is_already_gone_exits_0_at_once(
    node_env: dict[str, str], tmp_path: Path, started: list[NodeProcess]
) -> None:
    """The launch died before the node asked to die with it (the kernel would not tell it then)."""
    gone = subprocess.Popen([sys.executable, '-c', 'pass'])
    gone.wait()
    env = dict(node_env, **{PARENT_PID_ENV: str(gone.pid)})
    started.append(proc := start(executable('crank_drive'), env, tmp_path))
    assert_clean_exit(proc, 0, timeout=30.0)
    assert proc.err() == ''


def test_die_with_parent_asks_only_when_told_and_takes_the_request_out_of_the_environment(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert die_with_parent({}) is False
    env = {PARENT_PID_ENV: 'launch'}
    assert die_with_parent(env) is False and env == {}
    assert capsys.readouterr().err == f"ignoring {PARENT_PID_ENV}='launch': not a process id\n"


def test_the_entry_module_loads_neither_rclpy_nor_numpy(node_env: dict[str, str]) -> None:
    code = 'import json, sys, folder_line.ros.entry\nprint(json.dumps(sorted({"numpy", "rclpy"} & set(sys.modules))))'
    out = subprocess.run([sys.executable, '-c', code], env=node_env, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert json.loads(out.stdout) == []
