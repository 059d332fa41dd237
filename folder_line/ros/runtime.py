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
from typing import Any

import rclpy
from rclpy.duration import Duration
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException
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
        self._alarm: Any = None  # the SIGALRM handler before this one armed its own

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

    Stopping. A node that is stopped (SIGINT or SIGTERM, at any moment) exits with its
    exit code, 0 unless the node asks for another (``exit_code``), and no traceback:

    * Signals are handled synchronously, in the spinning thread: rclpy's own handlers are
      not installed (``SignalHandlerOptions.NO``); a Python handler records the request and
      the spin, which never waits longer than :data:`SPIN_PERIOD`, stops between two
      callbacks. rclpy's handlers would shut the context down from another thread while a
      callback may be using it, which ends in ``RCLError: publisher's context is invalid``
      tracebacks (about one Ctrl-C in three on a 1 kHz publisher here) and occasionally a
      crash under load. A request before ``rclpy.init`` skips it; one while the node is
      being built lets the build finish and skips the spin.
    * A repeated SIGINT is the same request: a Ctrl-C in the terminal of ``ros2 launch``
      reaches each node twice, from the terminal and from launch. A SIGTERM after a request
      (``ros2 launch`` sends it ``sigterm_timeout``, 5 s, after its SIGINT, to a node still
      running) is a request to stop now. While the node is being built it raises into the
      constructor, and the half-built node is collected. While the node spins, the process, if
      the node is its own, exits at once :data:`STOP_GRACE` s later with one line on stderr,
      unless the node's teardown has begun by then: a callback that does not return cannot be
      cut short without rclpy's executor logging the exception as a fatal error, with its
      frames. During the teardown requests are only recorded (see the watchdog below).
      Python runs signal handlers in the main thread, between bytecodes: code blocked in a C
      call (a middleware call that hangs) hears no request until it returns; SIGKILL ends it.
    * When the node runs as a process of its own (``args`` None, the main thread), SIGINT and
      SIGTERM are ignored once this returns, through the interpreter's exit: Python's default
      handlers would turn a late request (launch signals every node still running when the
      line's clock exits, nodes that are exiting too) into a death by signal, exit code -2,
      which launch reports as an ERROR. Otherwise the previous handlers are restored.
      Called from another thread, it installs no signal handler at all.

    Teardown. Destroying the node can hang inside the middleware: with both cores
    busy, one of 20 runs of ``folder-line run --processes`` (120 node stops) hung in
    ``Node.destroy_node`` (rcl's node finalisation with Fast DDS) until killed. When
    the node runs as a process of its own, its work is done by then, so a watchdog ends the
    process after ``teardown_timeout`` s (default :data:`TEARDOWN_TIMEOUT`) with one warning line on
    stderr and the exit code it would have returned; if the hang holds the GIL (no Python
    thread runs), ``faulthandler`` prints the threads' stacks 2 s later from C, and a C timer
    (:func:`folder_line.ros.exit_timer.arm_exit`) ends the process :data:`HUNG_TEARDOWN_EXIT` s
    after the timeout with the same exit code.

    Refusal. A node class with a ``refuse_start`` classmethod (the machine nodes) first judges the
    start from the command line alone (:mod:`folder_line.ros.ros_args`), before any DDS participant
    exists: a bad start is refused with its one line and exit code 2 without joining the network.
    One the command line does not show is refused by the node as it is built; its half-built node
    is then torn down under the same watchdog.

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
    watchdog: threading.Timer | None = None
    cancel_exit: Callable[[], None] | None = None

    def arm(code: int, quiet: bool = False) -> None:
        nonlocal watchdog, cancel_exit
        if teardown_timeout is None or watchdog is not None:
            return

        def expire() -> None:
            if not quiet:  # (a refused node has said all it has to say in its one line)
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
        # the middleware can hang holding the GIL, and then no Python thread runs: faulthandler's C thread
        # prints the stacks, and a C timer ends the process with its code (faulthandler's own exit is code 1)
        cancel_exit = arm_exit(teardown_timeout + HUNG_TEARDOWN_EXIT, code)
        faulthandler.dump_traceback_later(teardown_timeout + HUNG_TEARDOWN_EXIT - 0.5, exit=cancel_exit is None)

    previous: dict[signal.Signals, Any] = {}
    if in_main_thread:
        for signum in STOP_SIGNALS:
            previous[signum] = signal.signal(signum, stop.on_signal)
    try:
        if stop.is_set():
            return EXIT_OK
        try:
            use_line_profile()  # the line's Fast DDS profile, before this process's first participant
            _refuse_from_command_line(node_factory, name, sys.argv[1:] if args is None else args)
        except (FolderLineError, OSError) as err:  # a bad FOLDER_LINE_KEY, a profiles folder not private
            print(f'{name}: error: {err}', file=sys.stderr)
            return EXIT_BAD_PARAMETER
        try:
            initialised = rclpy.init(
                args=None if args is None else list(args), signal_handler_options=SignalHandlerOptions.NO
            )
        except RuntimeError as err:  # rcl's RCLError: a --ros-args rule it cannot parse
            print(f'{name}: error: {str(err).splitlines()[0]}', file=sys.stderr)
            return EXIT_BAD_PARAMETER
        with initialised:
            node = _build(node_factory, name, stop)
            if isinstance(node, int):
                arm(node, quiet=True)  # the half-built node's teardown is bounded as any other
                # it hung off the traceback, which is gone now: collect it while the context is alive
                # (finalised after rclpy's shutdown: the likely cause of a SIGSEGV seen once in CI)
                gc.collect()
                return node
            code = EXIT_OK
            stop.code = lambda: _exit_code(node, exit_code)
            try:
                stop.enter('spinning')
                _spin(node, stop)
                code = _exit_code(node, exit_code)
            finally:
                stop.enter('teardown')
                arm(code)
                _flush(node)
                node.destroy_node()
            return code
    except (KeyboardInterrupt, ExternalShutdownException, _StopNow):
        pass
    except (FolderLineError, ParameterException) as err:
        print(f'{name}: error: {err}', file=sys.stderr)
        return EXIT_BAD_PARAMETER
    finally:
        if watchdog is not None:
            watchdog.cancel()
            faulthandler.cancel_dump_traceback_later()
        if cancel_exit is not None:
            cancel_exit()
        stop.disarm()
        for signum, handler in previous.items():
            if own_process:
                signal.signal(signum, signal.SIG_IGN)
            else:
                signal.signal(signum, signal.SIG_DFL if handler is None else handler)
    return EXIT_OK


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
