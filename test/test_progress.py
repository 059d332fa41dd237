"""The line-time progress bar of ``run``, ``simulate`` and ``simulate --bag``: line time done, wall time left."""

from __future__ import annotations

import io
import os
import select
from pathlib import Path

import pytest

from folder_line.progress import CLEAR_LINE, ESTIMATE_AFTER, LineTimeProgress, logs_above, wall_text


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


class _Clock:
    """A wall clock a test sets: ``clock.now`` s."""

    def __init__(self, now: float = 100.0) -> None:
        self.now = now

    def __call__(self) -> float:
        return self.now


def test_on_a_pipe_one_line_per_tenth() -> None:
    out = io.StringIO()
    bar = LineTimeProgress(out, 10.0, width=10, clock=_Clock())  # the wall clock stands still: no estimate
    for k in range(101):
        bar.show(k / 10)
    bar.close()
    lines = out.getvalue().splitlines()
    assert len(lines) == 11
    assert lines[0] == '[..........]    0.00 / 10 s of line time'
    assert lines[5] == '[#####.....]    5.00 / 10 s of line time'
    assert lines[-1] == '[##########]   10.00 / 10 s of line time, done in 0 s'


def test_the_wall_time_left_is_the_pace_since_the_line_moved_times_what_is_left() -> None:
    """3600 s of line time; the line stands at 0 for 30 s of start-up (not its pace), then runs 60 line s per
    wall s: at 1200 s of line time, 20 s after it moved, 2400 line s are left, 40 s of wall time."""
    clock = _Clock(0.0)
    out = io.StringIO()
    bar = LineTimeProgress(out, 3600.0, width=10, clock=clock)
    bar.show(0.0)
    clock.now = 30.0
    bar.show(0.0)  # still starting: the estimate starts here
    clock.now = 30.0 + ESTIMATE_AFTER / 2
    bar.show(60.0 * ESTIMATE_AFTER / 2)  # too soon to tell: a tenth not reached, nothing drawn on a pipe
    clock.now = 50.0
    bar.show(1200.0)
    clock.now = 90.0
    bar.show(3600.0)
    lines = out.getvalue().splitlines()
    assert lines == [
        '[..........]    0.00 / 3600 s of line time',
        '[###.......] 1200.00 / 3600 s of line time, 40 s left',
        '[##########] 3600.00 / 3600 s of line time, done in 1 min 30 s',
    ]
    assert bar.left(1200.0, 50.0) == pytest.approx(40.0)
    assert bar.left(1200.0, 30.0 + ESTIMATE_AFTER / 2) is None  # moved for less than ESTIMATE_AFTER


@pytest.mark.parametrize(
    ('seconds', 'text'),
    [(0.4, '0 s'), (42.0, '42 s'), (59.6, '1 min 00 s'), (185.0, '3 min 05 s'), (7620.0, '2 h 07 min')],
)
def test_wall_times_read_as_a_person_says_them(seconds: float, text: str) -> None:
    assert wall_text(seconds) == text


def test_on_a_terminal_a_shorter_estimate_covers_the_longer_one() -> None:
    clock = _Clock(0.0)
    out = _Terminal()
    bar = LineTimeProgress(out, 1000.0, width=10, redraw=0.0, clock=clock)
    bar.show(0.0)
    clock.now = 10.0
    bar.show(100.0)  # 0.1 wall s per line s: 90 s left
    clock.now = 91.0
    bar.show(999.0)  # 0.1 s left
    longer = '[#.........]  100.00 / 1000 s of line time, 1 min 30 s left'
    assert _screen(out.getvalue()) == ['[#########.]  999.00 / 1000 s of line time, 0 s left'.ljust(len(longer))]


def test_a_delayed_bar_shows_nothing_for_a_quick_run() -> None:
    clock = _Clock(0.0)
    out = _Terminal()
    bar = LineTimeProgress(out, 10.0, width=10, redraw=0.0, delay=0.5, clock=clock)
    bar.show(0.0)
    clock.now = 0.3
    bar.show(10.0, force=True)
    bar.close()
    assert out.getvalue() == ''
    slow = _Terminal()
    bar = LineTimeProgress(slow, 10.0, width=10, redraw=0.0, delay=0.5, clock=clock)
    clock.now = 1.0
    bar.show(5.0)
    bar.close()
    assert _screen(slow.getvalue()) == ['[#####.....]    5.00 / 10 s of line time']


def test_on_a_terminal_redrawn_in_place_at_most_every_redraw() -> None:
    out = _Terminal()
    bar = LineTimeProgress(out, 10.0, width=10, redraw=3600.0, clock=_Clock())
    bar.show(1.0)
    bar.show(2.0)  # within the redraw period: not drawn
    bar.show(3.0, force=True)
    bar.close()
    assert out.getvalue() == ('\r[#.........]    1.00 / 10 s of line time\r[###.......]    3.00 / 10 s of line time\n')


def test_a_bar_never_drawn_leaves_no_blank_line() -> None:
    out = _Terminal()
    LineTimeProgress(out, 10.0).close()
    assert out.getvalue() == ''


def test_a_log_line_clears_the_bar_and_the_bar_comes_back_below_it() -> None:
    out = _Terminal()
    bar = LineTimeProgress(out, 10.0, width=10, redraw=0.0, clock=_Clock())
    bar.show(2.0)
    bar.log('[WARN] [supervisor]: feed_window violated in cycle 3')
    bar.show(3.0)
    bar.close()
    assert out.getvalue() == (
        '\r[##........]    2.00 / 10 s of line time'
        + CLEAR_LINE
        + '[WARN] [supervisor]: feed_window violated in cycle 3\n'
        + '\r[##........]    2.00 / 10 s of line time'
        + '\r[###.......]    3.00 / 10 s of line time\n'
    )
    # what the terminal shows: every line whole, the log line on its own line above the bar
    assert _screen(out.getvalue()) == [
        '[WARN] [supervisor]: feed_window violated in cycle 3',
        '[###.......]    3.00 / 10 s of line time',
    ]


def test_a_log_line_to_another_stream_of_the_same_terminal() -> None:
    """The bar on stdout, the logs on stderr (``run``): each is flushed before the other writes."""
    screen: list[str] = []

    class Shared(_Terminal):
        def flush(self) -> None:
            screen.append(self.getvalue())
            self.seek(0)
            self.truncate()

    bar_out, log_out = Shared(), Shared()
    bar = LineTimeProgress(bar_out, 10.0, width=10, redraw=0.0, clock=_Clock())
    bar.show(5.0)
    bar.log('WARN one', log_out)
    assert _screen(''.join(screen)) == ['WARN one', '[#####.....]    5.00 / 10 s of line time']


def test_without_a_bar_on_screen_a_log_line_is_just_written() -> None:
    out = _Terminal()
    bar = LineTimeProgress(out, 10.0, width=10, clock=_Clock())
    bar.log('before the bar')
    bar.show(1.0, force=True)
    bar.close()
    bar.log('after the bar')
    assert _screen(out.getvalue()) == ['before the bar', '[#.........]    1.00 / 10 s of line time', 'after the bar']
    pipe = io.StringIO()
    piped = LineTimeProgress(pipe, 10.0, width=10, clock=_Clock())
    piped.show(1.0)
    piped.log('WARN on a pipe')
    assert pipe.getvalue() == '[#.........]    1.00 / 10 s of line time\nWARN on a pipe\n'


def _read_all(master: int) -> str:
    chunks = []
    while select.select([master], [], [], 0)[0]:
        chunks.append(os.read(master, 65536))
    return b''.join(chunks).decode().replace('\r\n', '\n')


def _bar_at(t: float) -> tuple[_Terminal, LineTimeProgress]:
    """A bar of 10 s on a fake terminal stream, drawn at ``t``."""
    out = _Terminal()
    bar = LineTimeProgress(out, 10.0, width=10, redraw=0.0, clock=_Clock())
    bar.show(t)
    return out, bar


def test_logs_above_takes_what_c_code_writes_to_the_descriptor() -> None:
    """A pseudo-terminal stands for the user's: bytes written to its descriptor (as rcutils writes
    a node's WARN) come out on it whole, and the bar (a fake terminal stream) is cleared and redrawn."""
    master, slave = os.openpty()
    try:
        out, bar = _bar_at(4.0)
        with logs_above(bar, slave):
            os.write(slave, b'[WARN] [feed]: late sheet\n[ERROR] [supervisor]: ')
            os.write(slave, b'hold\n')
            bar.show(6.0)
            os.write(slave, b'no newline at the end')
        bar.close()
        assert _read_all(master) == '[WARN] [feed]: late sheet\n[ERROR] [supervisor]: hold\nno newline at the end\n'
        drawn = out.getvalue()
        assert drawn.count(CLEAR_LINE) == 3 and drawn.endswith('[######....]    6.00 / 10 s of line time\n')
        os.write(slave, b'after\n')  # restored: straight to the terminal again
        assert _read_all(master) == 'after\n' and out.getvalue() == drawn
    finally:
        os.close(master)
        os.close(slave)


def test_logs_above_leaves_a_descriptor_that_is_not_a_terminal_alone(tmp_path: Path) -> None:
    fd = os.open(tmp_path / 'log', os.O_WRONLY | os.O_CREAT)
    try:
        out, bar = _bar_at(1.0)
        with logs_above(bar, fd):
            os.write(fd, b'WARN to a file\n')
        assert (tmp_path / 'log').read_text() == 'WARN to a file\n'
        assert CLEAR_LINE not in out.getvalue()
    finally:
        os.close(fd)


def test_a_node_loggers_warn_comes_out_whole_above_the_bar() -> None:
    """What ``run`` meets: an rclpy logger's WARN, written by rcutils (C) to fd 2, on the bar's terminal."""
    import rclpy.logging

    master, slave = os.openpty()
    saved = os.dup(2)
    os.dup2(slave, 2)
    try:
        out = _Terminal()
        bar = LineTimeProgress(out, 10.0, width=10, redraw=0.0, clock=_Clock())
        bar.show(4.0)
        with logs_above(bar):
            rclpy.logging.get_logger('feed_transporter').warning('late sheet in cycle 13')
        bar.show(5.0)
        bar.close()
        shown = _read_all(master)
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(master)
        os.close(slave)
    assert '[feed_transporter]: late sheet in cycle 13' in shown and shown.count('\n') == 1 and shown.endswith('\n')
    assert out.getvalue().count(CLEAR_LINE) == 1  # the bar was cleared for it, then drawn again


def _screen(text: str) -> list[str]:
    """The lines a terminal shows for ``text``: '\\r' returns to the line's start, CLEAR_LINE erases it."""
    lines, line, col = [], [], 0
    i = 0
    while i < len(text):
        if text.startswith(CLEAR_LINE, i):
            line, col = [], 0
            i += len(CLEAR_LINE)
            continue
        ch = text[i]
        if ch == '\r':
            col = 0
        elif ch == '\n':
            lines.append(''.join(line))
            line, col = [], 0
        else:
            if col < len(line):
                line[col] = ch
            else:
                line.append(ch)
            col += 1
        i += 1
    if line:
        lines.append(''.join(line))
    return lines
