"""``folder-line monitor``: a live terminal view of the running line.

Two halves, as in ``ros2bag``'s api/verb split: the view
(:class:`folder_line.cli.monitor_view.MonitorState`, pure, tested with no ROS graph) and
the subscriptions that feed it (:func:`folder_line.ros.monitor.monitor_session`). This
module joins them: :func:`run_monitor` either prints one plain-text snapshot
(``--once``) or runs a ``curses`` screen redrawn at ``--rate`` Hz until ``q`` or
Ctrl-C (exit code 0 either way, the terminal restored). In the live view the keys of
:data:`folder_line.cli.operator_keys.OPERATOR_KEYS` send the supervisor's operator
commands (``x`` stop and ``a`` abort ask ``y`` first); the answer shows on the
operator row.

The monitor costs about an eighth of a core while following the ~1500 messages/s of
the ``folder`` line at rtf 1.
"""

from __future__ import annotations

import contextlib
import curses
import os
import shutil
import sys
import time
from collections.abc import Sequence
from typing import IO

from folder_line.cli.monitor_view import MIN_WIDTH, WINDOW, MonitorState
from folder_line.cli.operator_keys import OperatorKeys
from folder_line.ros.monitor import BATCH, KEY_PERIOD, MonitorSession, monitor_session
from folder_line.ros.recorder import LINE_TOPICS

__all__ = ['run_monitor']


def run_monitor(
    rate: float = 4.0,
    once: bool = False,
    window: float = WINDOW,
    timeout: float = 10.0,
    stream: IO[str] | None = None,
    argv: Sequence[str] | None = None,
) -> int:
    """Body of ``folder-line monitor``.

    Parameters
    ----------
    rate : float, optional
        Screen refreshes per second (curses view).
    once : bool, optional
        Print one plain-text snapshot to ``stream`` and return: wait up to
        ``timeout`` s for the first message, then collect for ``window`` s.
    window : float, optional
        Window of the rates, s of wall time.
    timeout : float, optional
        With ``once``: longest wait for the first message, s (the snapshot then says
        that nothing arrived).
    stream : file, optional
        Where the snapshot goes (default ``sys.stdout``).
    argv : sequence of str, optional
        ``rclpy.init`` arguments (default none).

    Returns
    -------
    int
        0 after ``q``, Ctrl-C or the snapshot; 1 after a snapshot in which nothing of the line
        arrived (a line on stderr says so); 2 when the curses view has no terminal to draw on (a
        line on stderr says to use ``--once``).
    """
    stream = sys.stdout if stream is None else stream
    if not once and not (sys.stdin.isatty() and sys.stdout.isatty()):
        print(
            'folder-line: error: monitor: stdin and stdout must be a terminal for the live view; '
            'use --once for a plain-text snapshot',
            file=sys.stderr,
        )
        return 2
    state = MonitorState(LINE_TOPICS, window=window)
    try:
        with monitor_session(state.ingest, argv) as session:
            if not once:
                return _curses_view(session, state, rate)
            session.collect(timeout, window)
            width = shutil.get_terminal_size((120, 50)).columns if stream.isatty() else 160
            stream.write('\n'.join(state.render(max(width, MIN_WIDTH), None, time.time())) + '\n')
            stream.flush()
            if state.last_wall is None:
                domain = os.environ.get('ROS_DOMAIN_ID', '0') or '0'
                print(
                    f'folder-line: error: monitor --once: no message of the line on ROS_DOMAIN_ID={domain} within '
                    f'--timeout {timeout:g} s: is a line running there?',
                    file=sys.stderr,
                )
                return 1
    except KeyboardInterrupt:  # a second Ctrl-C while stopping
        pass
    return 0


def _key(session: MonitorSession, operator: OperatorKeys, key: str) -> None:
    """An operator key: send its command (after a confirmation for stop and abort), show the answer."""
    command = operator.press(key)
    if command is None:
        return

    def on_answer(accepted: bool, message: str) -> None:
        operator.answer(command, accepted, message)

    if session.command(command, on_answer):
        operator.sent(command)
    else:
        operator.no_service(command)


def _read_keys(stdscr: curses.window, session: MonitorSession, operator: OperatorKeys) -> bool | None:
    """Take the keys typed since the last look: None on ``q`` (quit, unless a command waits for its
    confirmation), else whether the view must be drawn again (a key taken, or the terminal resized)."""
    redraw = False
    while True:
        key = stdscr.getch()
        if key == -1:
            return redraw
        if key in (ord('q'), ord('Q')) and operator.pending is None:
            return None
        if key == curses.KEY_RESIZE:
            redraw = True
        elif 0 <= key < 256:
            _key(session, operator, chr(key))
            redraw = True


def _curses_view(session: MonitorSession, state: MonitorState, rate: float) -> int:
    operator = state.operator = OperatorKeys(keyed=bool(os.environ.get('FOLDER_LINE_KEY', '').strip()))

    def loop(stdscr: curses.window) -> int:
        with contextlib.suppress(curses.error):  # a terminal that cannot hide the cursor
            curses.curs_set(0)
        stdscr.nodelay(True)
        styles = {
            'header': curses.A_REVERSE,
            'title': curses.A_BOLD,
            'alert': curses.A_BOLD | curses.A_STANDOUT,
            '': curses.A_NORMAL,
        }
        period = 1.0 / rate
        next_draw = next_key = 0.0
        while not session.stopped:
            now = time.monotonic()
            if now >= next_key:
                next_key = now + KEY_PERIOD
                keys = _read_keys(stdscr, session, operator)
                if keys is None:
                    return 0
                if keys:
                    next_draw = 0.0
            if now >= next_draw:
                next_draw = now + period
                _draw(stdscr, state, styles, time.time())  # the clock of the reception times
            session.drain(KEY_PERIOD)
            time.sleep(max(min(BATCH, next_key - time.monotonic(), next_draw - time.monotonic()), 0.0))
        return 0

    try:
        return curses.wrapper(loop)
    except curses.error as err:  # no usable terminal (TERM unset or unknown ...)
        print(f'folder-line: error: monitor: cannot use the terminal: {err}', file=sys.stderr)
        return 2


def _draw(stdscr: curses.window, state: MonitorState, styles: dict[str, int], now: float) -> None:
    height, width = stdscr.getmaxyx()
    stdscr.erase()
    for y, (text, style) in enumerate(state.render_styled(width, height, now)[:height]):
        attr = styles.get(style, curses.A_NORMAL)
        try:
            try:
                stdscr.addnstr(y, 0, text, width, attr)
            except UnicodeEncodeError:  # a terminal whose encoding lacks a character of a message
                stdscr.addnstr(y, 0, text.encode('ascii', 'replace').decode('ascii'), width, attr)
        except curses.error:  # writing the bottom-right cell moves the cursor off the screen: harmless
            pass
    stdscr.refresh()
