"""The process side of a node: ``run_node`` (init, spin, stop, teardown, exit code) and the line's executor.

A node module of the line ends with::

    def main(args: list[str] | None = None) -> int:
        return run_node(MyNode, args)

and its executable enters through :mod:`folder_line.ros.entry`, which makes a stop during the
imports a clean exit. :func:`run_node` returns :data:`EXIT_OK`, :data:`EXIT_BAD_PARAMETER` when
the node refuses its parameters, or the code the node asks for (``exit_code``);
:func:`events_executor` is the executor every in-process line (``folder-line run``, the
benchmarks) spins its nodes with.
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
from types import FrameType
from typing import TypeAlias

import rclpy
from rclpy.duration import Duration
from rclpy.exceptions import ParameterException
from rclpy.executors import Executor, ExternalShutdownException
from rclpy.experimental.events_executor import EventsExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from rclpy.task import Future

from folder_line.errors import FolderLineError
from folder_line.ros.dds_profile import use_line_profile
from folder_line.ros.exit_timer import arm_exit
from folder_line.ros.ros_args import command_line_values

__all__ = [
    'EXIT_BAD_PARAMETER',
    'EXIT_OK',
    'HUNG_TEARDOWN_EXIT',
    'LINGER',
    'SPIN_PERIOD',
    'STOP_GRACE',
    'STOP_SIGNALS',
    'TEARDOWN_TIMEOUT',
    'SignalHandler',
    'events_executor',
    'run_node',
]

SignalHandler: TypeAlias = Callable[[int, FrameType | None], object] | int | signal.Handlers | None
"""What ``signal.signal`` returns and takes: a handler, ``SIG_DFL``/``SIG_IGN``, or None (one not set in Python)."""

EXIT_OK = 0
"""Exit code of a node that stopped on request or finished."""

EXIT_BAD_PARAMETER = 2
"""Exit code of a node that refused its parameters (one line on stderr names the parameter and value)."""

SPIN_PERIOD = 0.1
"""Longest wall time, s, that :func:`run_node` waits before it looks at a stop request."""

LINGER = 0.2
"""Wall time, s, that :func:`run_node` keeps a node that is ``done`` alive before destroying it, so
that subscribers in other processes still get its last messages."""

FLUSH_TIMEOUT = 3.0
"""Longest wall time, s, a node that finished waits for its readers to acknowledge what it published."""

TEARDOWN_TIMEOUT = 5.0
"""Wall time, s, that a node process allows the middleware to tear the node down (see :func:`run_node`)."""

HUNG_TEARDOWN_EXIT = 2.5
"""Wall time, s, after :data:`TEARDOWN_TIMEOUT` at which a C timer ends a process whose teardown hangs
holding the GIL (the stacks are printed 0.5 s before)."""

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)
"""The signals that stop a node: ``ros2 launch`` sends SIGINT, then SIGTERM after its ``sigterm_timeout`` (5 s)."""

STOP_GRACE = 1.0
"""Wall time, s, that a node process still spinning gets after a SIGTERM repeats a stop request, before it
exits at once (see :func:`run_node`)."""


class _StopNow(BaseException):
    """Raised by :func:`run_node`'s signal handler into a node being built: SIGTERM after a stop request.

    A ``BaseException``, as ``KeyboardInterrupt`` is: an ``except Exception`` does not stop it.
    """


class _StopRequests:
    """The stop requests of a node run by :func:`run_node`: its signal handler and what a repeated SIGTERM does.

    A signal handler runs between two bytecodes of the code it interrupts, which may hold any
    lock (another signal's handler in ``threading.Event.set``, a write to ``sys.stderr``): so
    nothing here takes one. The request is a plain attribute, the exit at once is a SIGALRM
    timer, and its line goes to file descriptor 2. ``phase`` is ``'start'``, ``'building'``,
    ``'spinning'`` or ``'teardown'``; ``code`` gives the exit code of a node that exits at once.
    """

    def __init__(self, name: str, own_process: bool) -> None:
        self.requested = False
        self.phase = 'start'
        self.code: Callable[[], int] = lambda: EXIT_OK
        self._name = name
        self._own_process = own_process  # only a process's own node may end the process
        self._alarm: SignalHandler = None  # the SIGALRM handler before this one armed its own

    def is_set(self) -> bool:
        """Whether a stop was requested."""
        return self.requested

    def enter(self, phase: str) -> None:
        """The node is now in ``phase``; the teardown cancels an exit at once (its own watchdog bounds it)."""
        self.phase = phase
        if phase == 'teardown':
            self.disarm()

    def disarm(self) -> None:
        """Cancel an exit at once and restore the SIGALRM handler (a no-op if none was armed)."""
        if self._alarm is not None:
            signal.setitimer(signal.ITIMER_REAL, 0.0)
            signal.signal(signal.SIGALRM, self._alarm)
            self._alarm = None

    def on_signal(self, signum: int, frame: object) -> None:
        """The handler of :data:`STOP_SIGNALS` (see :func:`run_node`)."""
        again = self.requested
        self.requested = True
        if not again or signum != signal.SIGTERM:
            return
        if self.phase == 'building':
            self.phase = 'start'  # raised once
            raise _StopNow
        if self.phase == 'spinning' and self._own_process and self._alarm is None:
            self._alarm = signal.signal(signal.SIGALRM, self._exit_now)
            signal.setitimer(signal.ITIMER_REAL, STOP_GRACE)

    def _exit_now(self, signum: int, frame: object) -> None:
        if self.phase != 'spinning':
            return
        try:
            code = self.code()
        except Exception:  # the node is in the middle of a callback: its state may not answer
            code = EXIT_OK
        line = (
            f'{self._name}: a callback still ran {STOP_GRACE:g} s after SIGTERM repeated the stop request; '
            'exiting at once\n'
        )
        os.write(2, line.encode())
        os._exit(code)


class _TeardownWatchdog:
    """Ends the process with its exit code when the middleware hangs tearing the node down.

    Armed once (:meth:`arm`), as the teardown begins: after ``timeout`` s a Python timer exits with the
    code; if the hang holds the GIL (no Python thread runs), ``faulthandler`` prints the stacks from C
    and a C timer ends the process :data:`HUNG_TEARDOWN_EXIT` s after the timeout with the same code
    (``faulthandler``'s own exit is code 1). ``timeout`` None: never armed.
    """

    def __init__(self, name: str, timeout: float | None) -> None:
        self.name = name
        self.timeout = timeout
        self._timer: threading.Timer | None = None
        self._cancel_exit: Callable[[], None] | None = None

    def arm(self, code: int, quiet: bool = False) -> None:
        """Start the timers for exit code ``code`` (``quiet``: without the warning line); once only."""
        timeout = self.timeout
        if timeout is None or self._timer is not None:
            return
        name = self.name

        def expire() -> None:
            if not quiet:  # (a refused node has said all it has to say in its one line)
                print(
                    f'{name}: the middleware did not finish tearing the node down in {timeout:g} s; '
                    'exiting anyway (the node had stopped)',
                    file=sys.stderr,
                    flush=True,
                )
            sys.stdout.flush()
            os._exit(code)

        self._timer = threading.Timer(timeout, expire)
        self._timer.daemon = True
        self._timer.start()
        self._cancel_exit = arm_exit(timeout + HUNG_TEARDOWN_EXIT, code)
        faulthandler.dump_traceback_later(timeout + HUNG_TEARDOWN_EXIT - 0.5, exit=self._cancel_exit is None)

    def cancel(self) -> None:
        """Stop every timer armed (the teardown finished)."""
        if self._timer is not None:
            self._timer.cancel()
            faulthandler.cancel_dump_traceback_later()
        if self._cancel_exit is not None:
            self._cancel_exit()


def run_node(
    node_factory: Callable[[], Node],
    args: Sequence[str] | None = None,
    *,
    teardown_timeout: float | None = None,
    exit_code: Callable[[Node], int] | None = None,
) -> int:
    """Body of a node's ``main(args=None)``: init, spin, clean up, exit code.

    The node is built by ``node_factory()`` in the default context and spun by an events executor
    (:func:`events_executor`) until SIGINT or SIGTERM, until the context is shut down from elsewhere, or,
    if the node has a ``done`` attribute holding an ``rclpy.task.Future``, until that future completes
    and :data:`LINGER` s more. The manual's "How a node ends" says what a stop, a repeated stop and a
    hung teardown do; in short:

    * signals are handled in the spinning thread, between two callbacks (rclpy's handlers are not
      installed); a SIGTERM after a request stops the node :data:`STOP_GRACE` s later at the latest;
    * a node running as a process of its own (``args`` None, the main thread) ignores SIGINT and SIGTERM
      once this returns, so a late request from ``ros2 launch`` cannot turn its exit into a death by signal;
    * its teardown is bounded: after ``teardown_timeout`` s a watchdog ends the process with the code it
      would have returned, a C timer (:func:`folder_line.ros.exit_timer.arm_exit`) even when the hang holds
      the GIL;
    * a node class with a ``refuse_start`` classmethod judges its command line before any DDS
      participant exists (:mod:`folder_line.ros.ros_args`): a bad start is one line and exit code 2.

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
        ``exit_code(node)``: the exit code of a node that was built, asked once its spin is
        over, whether it finished or was stopped, e.g. non-zero when ``line_clock`` lost a
        participant. Default: ``node.exit_code()`` if the node has such a method, else 0.

    Returns
    -------
    int
        :data:`EXIT_OK` (0) on a stop request or completion, unless ``exit_code`` says
        otherwise; :data:`EXIT_BAD_PARAMETER` (2) when the node refuses its parameters,
        after one line on stderr naming the parameter and value.
    """
    name = getattr(node_factory, 'NODE_NAME', getattr(node_factory, '__name__', 'node'))
    in_main_thread = threading.current_thread() is threading.main_thread()
    own_process = args is None and in_main_thread
    stop = _StopRequests(name, own_process)
    if teardown_timeout is None and own_process:
        teardown_timeout = TEARDOWN_TIMEOUT
    watchdog = _TeardownWatchdog(name, teardown_timeout)

    previous: dict[signal.Signals, SignalHandler] = {}
    if in_main_thread:
        for signum in STOP_SIGNALS:
            previous[signum] = signal.signal(signum, stop.on_signal)
    try:
        if stop.is_set():
            return EXIT_OK
        initialised = _init(node_factory, name, args)
        if isinstance(initialised, int):
            return initialised
        with initialised:
            node = _build(node_factory, name, stop)
            if isinstance(node, int):
                watchdog.arm(node, quiet=True)  # the half-built node's teardown is bounded as any other
                # it hung off the traceback, which is gone now: collect it while the context is alive
                # (finalised after rclpy's shutdown: the likely cause of a SIGSEGV seen once in CI)
                gc.collect()
                return node
            return _spin_and_tear_down(node, stop, watchdog, exit_code)
    except (KeyboardInterrupt, ExternalShutdownException, _StopNow):
        pass
    except (FolderLineError, ParameterException) as err:
        print(f'{name}: error: {err}', file=sys.stderr)
        return EXIT_BAD_PARAMETER
    finally:
        watchdog.cancel()
        stop.disarm()
        _restore_signals(previous, own_process)
    return EXIT_OK


def _restore_signals(previous: dict[signal.Signals, SignalHandler], own_process: bool) -> None:
    """Put back the handlers ``previous`` replaced; a node's own process ignores the stop signals instead
    (a late request from launch must not turn its exit into a death by signal)."""
    for signum, handler in previous.items():
        if own_process:
            signal.signal(signum, signal.SIG_IGN)
        else:
            signal.signal(signum, signal.SIG_DFL if handler is None else handler)


def _init(node_factory: Callable[[], Node], name: str, args: Sequence[str] | None) -> rclpy.InitContextManager | int:
    """Judge the start from the command line, then ``rclpy.init``: the initialised context manager, or
    :data:`EXIT_BAD_PARAMETER` after one line on stderr."""
    try:
        use_line_profile()  # the line's Fast DDS profile, before this process's first participant
        _refuse_from_command_line(node_factory, name, sys.argv[1:] if args is None else args)
    except (FolderLineError, OSError) as err:  # a bad FOLDER_LINE_KEY, a profiles folder not private
        print(f'{name}: error: {err}', file=sys.stderr)
        return EXIT_BAD_PARAMETER
    try:
        return rclpy.init(args=None if args is None else list(args), signal_handler_options=SignalHandlerOptions.NO)
    except RuntimeError as err:  # rcl's RCLError: a --ros-args rule it cannot parse
        print(f'{name}: error: {str(err).splitlines()[0]}', file=sys.stderr)
        return EXIT_BAD_PARAMETER


def _spin_and_tear_down(
    node: Node, stop: _StopRequests, watchdog: _TeardownWatchdog, exit_code: Callable[[Node], int] | None
) -> int:
    """Spin ``node`` until it is stopped or done, then tear it down under ``watchdog``; its exit code."""
    code = EXIT_OK
    stop.code = lambda: _exit_code(node, exit_code)
    try:
        stop.enter('spinning')
        _spin(node, stop)
        code = _exit_code(node, exit_code)
    finally:
        stop.enter('teardown')
        watchdog.arm(code)
        _flush(node)
        node.destroy_node()
    return code


def _flush(node: Node) -> None:
    """A node that finished (its ``done`` future completed) waits, at most :data:`FLUSH_TIMEOUT` s, until every
    reader has acknowledged what it published: a sample lost on the way is repaired before the writer goes."""
    done = getattr(node, 'done', None)
    if not (isinstance(done, Future) and done.done()):
        return
    deadline = time.monotonic() + FLUSH_TIMEOUT
    for publisher in node.publishers:
        left = deadline - time.monotonic()
        if left <= 0.0 or not publisher.wait_for_all_acked(Duration(nanoseconds=int(left * 1e9))):
            return


def _refuse_from_command_line(node_factory: Callable[[], Node], name: str, args: Sequence[str]) -> None:
    """Raise what the node would refuse its start for, read from ``args`` alone, before any DDS participant
    exists (:mod:`folder_line.ros.ros_args`; a node class with a ``refuse_start`` classmethod). A start
    refused later, by the node, makes and tears down a participant: under a storm of discovery that
    teardown now and then crashes inside Fast DDS."""
    refuse = getattr(node_factory, 'refuse_start', None)
    if refuse is None:
        return
    given = command_line_values(args, name)
    if given is not None:
        refuse(given)


def _build(node_factory: Callable[[], Node], name: str, stop: _StopRequests) -> Node | int:
    """The node, or the exit code of one not built: refused (one line on stderr), or stopped while being built."""
    try:
        stop.enter('building')
        try:
            return node_factory()
        finally:
            stop.enter('start')
    except (FolderLineError, ParameterException) as err:
        refused: str | None = f'{name}: error: {err}'
    except _StopNow:
        refused = None
    if refused is not None:
        print(refused, file=sys.stderr, flush=True)  # first: whatever the teardown of the half-built node does
    return EXIT_OK if refused is None else EXIT_BAD_PARAMETER


def _exit_code(node: Node, exit_code: Callable[[Node], int] | None) -> int:
    if exit_code is not None:
        return int(exit_code(node))
    own = getattr(node, 'exit_code', None)
    return int(own()) if callable(own) else EXIT_OK


def events_executor(context: rclpy.Context) -> Executor:
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


def _spin(node: Node, stop: _StopRequests) -> None:
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
