"""The process side of a node: ``run_node`` (init, spin, stop, teardown, exit code) and the line's executor.

A node module of the line ends with::

    def main(args: list[str] | None = None) -> int:
        return run_node(MyNode, args)

:func:`run_node` returns :data:`EXIT_OK` or, when the node refuses its parameters,
:data:`EXIT_BAD_PARAMETER`; :func:`events_executor` is the executor every in-process
line (``folder-line run``, the benchmarks) spins its nodes with.
"""

from __future__ import annotations

import faulthandler
import gc
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any

import rclpy
from rclpy._rclpy_pybind11 import RCLError
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException
from rclpy.experimental.events_executor import EventsExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from rclpy.task import Future

from folder_line.errors import FolderLineError

__all__ = [
    'EXIT_BAD_PARAMETER',
    'EXIT_OK',
    'LINGER',
    'SPIN_PERIOD',
    'TEARDOWN_TIMEOUT',
    'events_executor',
    'run_node',
]

EXIT_OK = 0
"""Exit code of a node that stopped on request or finished."""

EXIT_BAD_PARAMETER = 2
"""Exit code of a node that refused its parameters (one line on stderr names the parameter and value)."""

SPIN_PERIOD = 0.1
"""Longest wall time, s, that :func:`run_node` waits before it looks at a stop request."""

LINGER = 0.2
"""Wall time, s, that :func:`run_node` keeps a node that is ``done`` alive before destroying it, so
that subscribers in other processes still get its last messages."""

TEARDOWN_TIMEOUT = 5.0
"""Wall time, s, that a node process allows the middleware to tear the node down (see :func:`run_node`)."""


def run_node(
    node_factory: Callable[[], Node],
    args: Sequence[str] | None = None,
    *,
    teardown_timeout: float | None = None,
    exit_code: Callable[[Node], int] | None = None,
) -> int:
    """Body of a node's ``main(args=None)``: init, spin, clean up, exit code.

    The node is built by ``node_factory()`` in the default context and spun by a
    events executor (:func:`events_executor`) until SIGINT or SIGTERM, until the context is shut
    down from elsewhere, or, if the node has a ``done`` attribute holding an
    ``rclpy.task.Future``, until that future completes (a node that finishes on its
    own, like ``line_clock`` with a ``duration``) and :data:`LINGER` s more.

    Signals are handled synchronously, in the spinning thread: rclpy's own
    handlers are not installed (``SignalHandlerOptions.NO``); a Python handler only
    records the request and the spin, which never waits longer than
    :data:`SPIN_PERIOD`, stops between two callbacks. rclpy's handlers would shut
    the context down from another thread while a callback may be using it, which
    ends in ``RCLError: publisher's context is invalid`` tracebacks (about one
    Ctrl-C in three on a 1 kHz publisher here) and occasionally a crash under load.
    A second SIGINT while stopping raises ``KeyboardInterrupt``, still caught.
    Called from another thread, it installs no signal handler at all.

    Teardown. Destroying the node can hang inside the middleware: with both cores
    busy, one of 20 runs of ``folder-line run --processes`` (120 node stops) hung in
    ``Node.destroy_node`` (rcl's node finalisation with Fast DDS) until killed. When
    the node runs as a process of its own (``args`` from ``sys.argv``, the main
    thread), its work is done by then, so a watchdog ends the process after
    ``teardown_timeout`` s (default :data:`TEARDOWN_TIMEOUT`) with one warning line on
    stderr and the exit code it would have returned; if the hang holds the GIL (no Python
    thread runs), ``faulthandler`` ends it 2 s later from C, with the threads' stacks and
    exit code 1.

    Parameters
    ----------
    node_factory : callable
        Usually the node class; called with no arguments.
    args : sequence of str, optional
        Command line for ``rclpy.init`` (``None``: ``sys.argv``).
    teardown_timeout : float, optional
        Seconds allowed for the teardown before the process exits anyway; default
        :data:`TEARDOWN_TIMEOUT` for a process's own node (``args`` None, main thread),
        else no watchdog (a test calling this must not lose its process).
    exit_code : callable, optional
        ``exit_code(node)``: the exit code of a node that ran (default 0), e.g. non-zero
        when ``line_clock`` lost a participant.

    Returns
    -------
    int
        :data:`EXIT_OK` (0) on a stop request or completion; :data:`EXIT_BAD_PARAMETER`
        (2) when the node refuses its parameters, after one line on stderr naming
        the parameter and value.
    """
    name = getattr(node_factory, 'NODE_NAME', getattr(node_factory, '__name__', 'node'))
    stop = threading.Event()

    def on_signal(signum: int, frame: object) -> None:
        if stop.is_set() and signum == signal.SIGINT:
            raise KeyboardInterrupt
        stop.set()

    in_main_thread = threading.current_thread() is threading.main_thread()
    if teardown_timeout is None and args is None and in_main_thread:
        teardown_timeout = TEARDOWN_TIMEOUT
    watchdog: threading.Timer | None = None

    def arm(code: int) -> None:
        nonlocal watchdog
        if teardown_timeout is None or watchdog is not None:
            return

        def expire() -> None:
            print(
                f'{name}: the middleware did not finish tearing the node down in {teardown_timeout:g} s; '
                'exiting anyway (the node had stopped)',
                file=sys.stderr,
                flush=True,
            )
            sys.stdout.flush()
            os._exit(code)

        watchdog = threading.Timer(teardown_timeout, expire)
        watchdog.daemon = True
        watchdog.start()
        # the middleware can hang holding the GIL (a peer process stopped while it holds a shared-memory lock),
        # and then no Python thread runs: faulthandler's C thread ends the process all the same, with the stacks
        faulthandler.dump_traceback_later(teardown_timeout + 2.0, exit=True)

    previous: dict[signal.Signals, Any] = {}
    if in_main_thread:
        for signum in (signal.SIGINT, signal.SIGTERM):
            previous[signum] = signal.signal(signum, on_signal)
    try:
        with rclpy.init(args=None if args is None else list(args), signal_handler_options=SignalHandlerOptions.NO):
            refused: str | None
            try:
                node = node_factory()
            except (FolderLineError, ParameterException) as err:
                refused = f'{name}: error: {err}'
            else:
                refused = None
            if refused is not None:
                # the half-built node hangs off the traceback, which is gone now: collect it while the
                # context is alive (finalised after rclpy's shutdown: the likely cause of a SIGSEGV seen once in CI)
                gc.collect()
                print(refused, file=sys.stderr)
                return EXIT_BAD_PARAMETER
            code = EXIT_OK
            try:
                _spin(node, stop)
                code = EXIT_OK if exit_code is None else exit_code(node)
            finally:
                arm(code)
                node.destroy_node()
            return code
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (FolderLineError, ParameterException) as err:
        print(f'{name}: error: {err}', file=sys.stderr)
        return EXIT_BAD_PARAMETER
    except RCLError as err:  # e.g. a --ros-args rule rcl cannot parse
        print(f'{name}: error: {str(err).splitlines()[0]}', file=sys.stderr)
        return EXIT_BAD_PARAMETER
    finally:
        if watchdog is not None:
            watchdog.cancel()
            faulthandler.cancel_dump_traceback_later()
        for signum, handler in previous.items():
            signal.signal(signum, signal.SIG_DFL if handler is None else handler)
    return EXIT_OK


def events_executor(context: Any) -> Any:
    """An ``rclpy.experimental.EventsExecutor`` for ``context``: the line's executor.

    It costs a third of ``SingleThreadedExecutor``'s CPU per message here (``bench/bench_nodes.py``).
    Its constructor enables ``faulthandler`` on ``sys.stderr``, which fails where ``sys.stderr`` has
    no file descriptor (a captured stream, a notebook): the process's own stderr is used then.
    """
    try:
        sys.stderr.fileno()
    except (AttributeError, OSError, ValueError):
        saved, sys.stderr = sys.stderr, sys.__stderr__
        try:
            return EventsExecutor(context=context)
        finally:
            sys.stderr = saved
    return EventsExecutor(context=context)


def _spin(node: Node, stop: threading.Event) -> None:
    done = getattr(node, 'done', None)
    if not isinstance(done, Future):
        done = None
    executor = events_executor(node.context)
    try:
        executor.add_node(node)
        while not stop.is_set() and node.context.ok() and not (done is not None and done.done()):
            executor.spin_once(timeout_sec=SPIN_PERIOD)
        if done is not None and done.done():
            # a subscriber in another process reads the last messages out of this process's
            # shared memory (Fast DDS), which goes with it: linger before the node is destroyed
            deadline = time.monotonic() + LINGER
            while not stop.is_set() and node.context.ok() and time.monotonic() < deadline:
                executor.spin_once(timeout_sec=min(SPIN_PERIOD, max(deadline - time.monotonic(), 0.0)))
    finally:
        executor.shutdown()
