"""A node process started as ``ros2 launch`` and ``ros2 run`` start one: its executable, its own ``--ros-args``.

:func:`executable` is what setuptools writes into the node's console script (setup.py:
``import sys; from folder_line.ros.entry import NAME; sys.exit(NAME())``), run with this
interpreter; :class:`NodeProcess` keeps its stdout and stderr in files (a pipe nobody reads
could block it) and is never left running. :func:`catches` reads ``/proc`` (Linux).
"""

from __future__ import annotations

import itertools
import os
import signal
import subprocess
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path


def executable(name: str) -> list[str]:
    """The command of node ``name``'s executable, as its console script runs it."""
    code = f'import sys\nfrom folder_line.ros.entry import {name}\nsys.exit({name}())\n'
    return [sys.executable, '-c', code]


_RENAMED = itertools.count()


def unique_name(name: str) -> str:
    """A node name no other test process uses (as launch does, run it with ``-r __node:=<this>``): a test
    that talks to the node it started reaches that one, even on a ROS domain another test run shares."""
    return f'{name}_{os.getpid()}_{next(_RENAMED)}'


@dataclass
class NodeProcess:
    """A process started by :func:`start`; :meth:`close` ends it if it still runs."""

    proc: subprocess.Popen[bytes]
    stdout: Path
    stderr: Path

    @property
    def pid(self) -> int:
        return self.proc.pid

    def err(self) -> str:
        return self.stderr.read_text(errors='replace')

    def out(self) -> str:
        return self.stdout.read_text(errors='replace')

    def wait(self, timeout: float = 60.0) -> int:
        """Its exit code (it is reaped: its pid is gone)."""
        return self.proc.wait(timeout=timeout)

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()


def start(command: Sequence[str], env: Mapping[str, str], logs: Path, name: str = 'node') -> NodeProcess:
    """Start ``command`` with ``env``; stdout and stderr go to ``logs/<name>.out`` and ``.err``."""
    logs.mkdir(parents=True, exist_ok=True)
    stdout, stderr = logs / f'{name}.out', logs / f'{name}.err'
    with open(stdout, 'wb') as out, open(stderr, 'wb') as err:
        proc = subprocess.Popen(list(command), env=dict(env), stdout=out, stderr=err)
    return NodeProcess(proc, stdout, stderr)


def catches(pid: int, signum: int) -> bool:
    """Whether process ``pid`` has a handler of its own for ``signum`` (``SigCgt`` in ``/proc/<pid>/status``)."""
    try:
        status = Path(f'/proc/{pid}/status').read_text()
    except OSError:
        return False
    [mask] = [line.split()[1] for line in status.splitlines() if line.startswith('SigCgt:')]
    return bool(int(mask, 16) >> (signum - 1) & 1)


def wait_until(predicate: object, timeout: float, what: str) -> None:
    """Poll ``predicate()`` every 10 ms until true; fail naming ``what`` after ``timeout`` s."""
    assert callable(predicate)
    deadline = time.monotonic() + timeout
    while not predicate():
        assert time.monotonic() < deadline, f'{what}: not within {timeout:g} s'
        time.sleep(0.01)


def assert_clean_exit(node: NodeProcess, code: int, timeout: float = 60.0) -> None:
    """``node`` exits with ``code``, no traceback nor ``KeyboardInterrupt`` on stderr, and its pid is gone."""
    assert node.wait(timeout) == code, node.err()
    err = node.err()
    assert 'Traceback' not in err and 'KeyboardInterrupt' not in err, err
    assert not os.path.exists(f'/proc/{node.pid}'), f'pid {node.pid} left over'


def send(node: NodeProcess, *signums: signal.Signals) -> None:
    """Send ``signums`` to ``node`` in order."""
    for signum in signums:
        os.kill(node.pid, signum)
