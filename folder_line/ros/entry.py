"""Entry points of the node executables, light on purpose: a stop during a node's imports exits cleanly.

Each node executable (setup.py's ``console_scripts``: ``ros2 run folder_line crank_drive``,
``ros2 launch folder_line line.launch.py``) calls one function here, which, before it
imports the node's module (rclpy, numpy and the core: a second or more of CPU):

* makes SIGINT and SIGTERM end the process at once, with exit code 0 and nothing on stderr.
  Nothing is set up yet, so nothing needs undoing; without this, a launch that stops the line
  while a node is still importing gets a ``KeyboardInterrupt`` traceback and exit code -2.
  The node's ``main`` (:func:`folder_line.ros.runtime.run_node`) then takes the signals over.
  Only the interpreter's own start, before this module runs (some 50 ms), is not covered.
* if the process that starts the node asks for it (:data:`PARENT_PID_ENV`), has the kernel
  send the node SIGTERM, a stop request, when that process dies (Linux ``PR_SET_PDEATHSIG``):
  a ``ros2 launch`` that is killed (SIGKILL) or fails leaves no node behind. The line's launch
  file asks for it; a node started by hand outlives its shell as any process does.

This module imports nothing of the package's at load, nor rclpy or numpy (a test keeps it so).
"""

from __future__ import annotations

import contextlib
import ctypes
import importlib
import os
import signal
import sys
from collections.abc import MutableMapping

__all__ = [
    'NODE_MODULES',
    'PARENT_PID_ENV',
    'belt_conveyor',
    'crank_drive',
    'die_with_parent',
    'feed_transporter',
    'line_clock',
    'run',
    'sheet_counter',
    'supervisor',
]

PARENT_PID_ENV = 'FOLDER_LINE_PARENT_PID'
"""Environment variable: the pid of the process whose death stops the node (see :func:`die_with_parent`)."""

NODE_MODULES: dict[str, str] = {
    name: f'folder_line.ros.nodes.{name}'
    for name in ('line_clock', 'crank_drive', 'belt_conveyor', 'feed_transporter', 'sheet_counter', 'supervisor')
}
"""Node name -> the module whose ``main()`` runs it (the names of :mod:`folder_line.interfaces`, which loads numpy)."""

_EXIT_OK = 0  # folder_line.ros.runtime.EXIT_OK, not imported: runtime loads rclpy
_PR_SET_PDEATHSIG = 1  # <linux/prctl.h>


def run(name: str) -> int:
    """Run node ``name`` as this process: stop handling and parent watch, then its module's ``main()``.

    Parameters
    ----------
    name : str
        A key of :data:`NODE_MODULES`.

    Returns
    -------
    int
        The node's exit code (:func:`folder_line.ros.runtime.run_node`).
    """
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, _exit_at_once)
    die_with_parent()
    module = importlib.import_module(NODE_MODULES[name])
    return int(module.main())


def die_with_parent(environ: MutableMapping[str, str] | None = None) -> bool:
    """Have the kernel send this process SIGTERM when the process named by :data:`PARENT_PID_ENV` dies.

    The variable is taken out of the environment, so that a process this one starts does
    not inherit the request. If that process is already gone (it died before the request
    was made, when the kernel would send nothing), this process gets SIGTERM at once. If it
    is alive but not this process's parent (a launch prefix runs the node), the signal comes
    when the direct parent dies. Linux only: elsewhere nothing is asked.

    Parameters
    ----------
    environ : mutable mapping, optional
        The environment (default ``os.environ``).

    Returns
    -------
    bool
        Whether the kernel will send the signal.
    """
    env = os.environ if environ is None else environ
    text = env.pop(PARENT_PID_ENV, '')
    if not text:
        return False
    try:
        parent = int(text)
    except ValueError:
        print(f'ignoring {PARENT_PID_ENV}={text!r}: not a process id', file=sys.stderr)
        return False
    if not _parent_death_signal(signal.SIGTERM):
        return False
    if os.getppid() != parent and not _alive(parent):
        signal.raise_signal(signal.SIGTERM)  # it died before the request: the kernel sends nothing then
    return True


def line_clock() -> int:
    """Executable ``line_clock``."""
    return run('line_clock')


def crank_drive() -> int:
    """Executable ``crank_drive``."""
    return run('crank_drive')


def belt_conveyor() -> int:
    """Executable ``belt_conveyor``."""
    return run('belt_conveyor')


def feed_transporter() -> int:
    """Executable ``feed_transporter``."""
    return run('feed_transporter')


def sheet_counter() -> int:
    """Executable ``sheet_counter``."""
    return run('sheet_counter')


def supervisor() -> int:
    """Executable ``supervisor``."""
    return run('supervisor')


def _exit_at_once(signum: int, frame: object) -> None:
    with contextlib.suppress(Exception):  # a write the signal interrupted cannot be flushed (reentrant call)
        sys.stdout.flush()
        sys.stderr.flush()
    os._exit(_EXIT_OK)


def _parent_death_signal(signum: int) -> bool:
    if not sys.platform.startswith('linux'):
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return int(libc.prctl(_PR_SET_PDEATHSIG, signum, 0, 0, 0)) == 0
    except (OSError, AttributeError):
        return False


def _alive(pid: int) -> bool:
    """Whether process ``pid`` runs (Linux: a zombie, dead but not yet reaped by its parent, does not)."""
    try:
        with open(f'/proc/{pid}/stat', encoding='ascii', errors='replace') as stat:
            state = stat.read().rpartition(')')[2].split()[:1]
    except OSError:
        return False
    return state != ['Z']


if __name__ == '__main__':  # python -m folder_line.ros.entry NODE [--ros-args ...]: as the executable NODE
    if len(sys.argv) < 2 or sys.argv[1] not in NODE_MODULES:
        print(f'usage: python -m folder_line.ros.entry {{{",".join(NODE_MODULES)}}} [--ros-args ...]', file=sys.stderr)
        sys.exit(2)
    sys.exit(run(sys.argv.pop(1)))
