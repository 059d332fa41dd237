"""A progress bar of line time, for the verbs that take long: ``run``, ``simulate`` and ``simulate --bag``.

The bar shows the line time done against the run's and, once the line has moved for a
while, an estimate of the wall time left: the wall time per second of line time measured
since the line time started moving, times the line time still to go.

On a terminal the bar is redrawn in place with ``\\r``; a log line written meanwhile (the
WARN lines of rclpy nodes, which rcutils writes straight to file descriptor 2) would land in
the middle of it. :meth:`LineTimeProgress.log` clears the bar, writes the line and draws the
bar again below it; :func:`logs_above` sends everything written to a file descriptor through
it while a run spins, so a log line is never torn.
"""

from __future__ import annotations

import math
import os
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import IO

__all__ = ['CLEAR_LINE', 'ESTIMATE_AFTER', 'LineTimeProgress', 'logs_above', 'wall_text']

#: back to the start of the line and erase it (ANSI "erase in line")
CLEAR_LINE = '\r\x1b[K'
#: wall time the line time must have moved for before the time left is estimated, s
ESTIMATE_AFTER = 1.0


def wall_text(seconds: float) -> str:
    """A wall time for a person: ``'42 s'``, ``'3 min 05 s'``, ``'2 h 07 min'`` (rounded to the second)."""
    s = max(0, round(seconds))
    if s < 60:
        return f'{s} s'
    if s < 3600:
        return f'{s // 60} min {s % 60:02d} s'
    return f'{s // 3600} h {s % 3600 // 60:02d} min'


class LineTimeProgress:
    """``[####....]  t / total s of line time, 2 min 05 s left``: redrawn in place on a terminal (at most
    every ``redraw`` s of wall time), one line per tenth of ``total`` on a pipe or a file.

    The time left is estimated once the line time has moved for :data:`ESTIMATE_AFTER` s of
    wall time: the wall time taken per second of line time since it first moved (a start-up
    that does not advance the line, as the nodes' of ``run``, is not counted) times the line
    time still to go. A drawing at ``total`` says the wall time the whole took (``done in ...``).

    Safe to use from two threads (the loop that draws, a thread that logs: :func:`logs_above`).

    Parameters
    ----------
    stream : text stream
        Where to draw (stderr for ``simulate``, whose stdout is the result).
    total : float
        Line time of the whole run, s (> 0).
    width : int
        Characters of the bar.
    redraw : float
        Least wall time between two drawings on a terminal, s.
    delay : float
        Wall time before the first drawing on a terminal, s: a run done sooner shows no bar.
    clock : callable
        Wall clock, s (``time.monotonic``; a test's own).
    """

    def __init__(
        self,
        stream: IO[str],
        total: float,
        width: int = 40,
        redraw: float = 0.1,
        *,
        delay: float = 0.0,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.stream, self.total, self.width, self.redraw = stream, total, width, redraw
        self.delay, self.clock = delay, clock
        self.tty = hasattr(stream, 'isatty') and stream.isatty()
        self.tenths = -1
        self.drawn = -float('inf')
        self.shown = ''  # the bar on the terminal's last line now ('' when none is)
        self.started = clock()
        self._anchor: tuple[float, float] | None = None  # (line time, wall time) when the line last stood still
        self._lock = threading.Lock()

    def left(self, t: float, now: float) -> float | None:
        """Wall time left at line time ``t`` (s) and wall time ``now``, s; None until it can be estimated."""
        anchor = self._anchor
        if anchor is None or t <= anchor[0] or now - anchor[1] < ESTIMATE_AFTER:
            return None
        per = (now - anchor[1]) / (t - anchor[0])  # wall s per line s
        return max(self.total - t, 0.0) * per

    def _line(self, t: float, now: float) -> str:
        fraction = min(max(t / self.total, 0.0), 1.0) if self.total > 0.0 else 1.0
        done = int(self.width * fraction)
        text = f'[{"#" * done}{"." * (self.width - done)}] {t:7.2f} / {self.total:g} s of line time'
        if t >= self.total:
            return text + f', done in {wall_text(now - self.started)}'
        left = self.left(t, now)
        return text if left is None or not math.isfinite(left) else text + f', {wall_text(left)} left'

    def show(self, t: float, *, force: bool = False) -> None:
        """Draw the line time reached, ``t`` s (on a terminal now if ``force``: the last drawing)."""
        with self._lock:
            now = self.clock()
            if self._anchor is None or t <= self._anchor[0]:
                self._anchor = (t, now)  # the line has not moved yet: its start-up is not its pace
            if self.tty:
                if now - self.drawn < self.redraw and not force:
                    return
                if now - self.started < self.delay and not self.shown:
                    return
                line = self._line(t, now)
                self.drawn = now
                self.stream.write('\r' + line.ljust(len(self.shown)))  # a shorter line covers the longer one
                self.shown = line
            else:
                fraction = min(max(t / self.total, 0.0), 1.0) if self.total > 0.0 else 1.0
                if int(10 * fraction) <= self.tenths:
                    return
                self.tenths = int(10 * fraction)
                self.stream.write(self._line(t, now) + '\n')
            self.stream.flush()

    def log(self, text: str, to: IO[str] | None = None) -> None:
        """Write the line ``text`` to ``to`` (default the bar's stream) without tearing the bar.

        On a terminal with the bar showing: the bar's line is erased, the text written on it,
        and the bar drawn again on the next line. ``to`` may be another stream on the same
        terminal (stderr for the logs, the bar on stdout): each is flushed in turn.
        """
        out = self.stream if to is None else to
        with self._lock:
            if self.tty and self.shown:
                self.stream.write(CLEAR_LINE)
                self.stream.flush()
            out.write(text.rstrip('\n') + '\n')
            out.flush()
            if self.tty and self.shown:
                self.stream.write('\r' + self.shown)
                self.stream.flush()

    def close(self) -> None:
        """End the bar's line on a terminal (if it was drawn)."""
        with self._lock:
            if self.tty and self.drawn > -float('inf'):
                self.stream.write('\n')
                self.stream.flush()
            self.shown = ''


def _pump(read_fd: int, bar: LineTimeProgress, to: IO[str]) -> None:
    """Pass what arrives on ``read_fd`` to ``bar.log`` line by line, until the pipe's end (all writers closed)."""
    pending = b''
    encoding = getattr(to, 'encoding', None) or 'utf-8'
    while chunk := os.read(read_fd, 65536):
        *lines, pending = (pending + chunk).split(b'\n')
        for line in lines:
            bar.log(line.decode(encoding, errors='replace'), to)
    if pending:
        bar.log(pending.decode(encoding, errors='replace'), to)
    os.close(read_fd)


@contextmanager
def logs_above(bar: LineTimeProgress, fd: int = 2) -> Iterator[None]:
    """While inside, whatever is written to the file descriptor ``fd`` goes through :meth:`LineTimeProgress.log`.

    That includes what C code writes there (rcutils' console output of rclpy's loggers, which no
    Python handler sees): ``fd`` is pointed at a pipe that a thread reads line by line, writing each
    line to the original ``fd`` above the bar. Only when the bar is on a terminal and ``fd`` is one
    too (the two share a screen); otherwise nothing changes. On leaving, ``fd`` is restored and
    every line written before is out.

    Parameters
    ----------
    bar : LineTimeProgress
        The bar the lines must not tear.
    fd : int
        The file descriptor of the logs (2, stderr).
    """
    if not (bar.tty and os.isatty(fd)):
        yield
        return
    sys.stderr.flush()
    saved = os.dup(fd)
    read_fd, write_fd = os.pipe()
    os.set_inheritable(read_fd, False)
    to = os.fdopen(os.dup(saved), 'w', encoding='utf-8', errors='replace')
    os.dup2(write_fd, fd)
    os.close(write_fd)  # fd is now the pipe's only writer: restoring fd ends the pump
    pump = threading.Thread(target=_pump, args=(read_fd, bar, to), name='logs_above', daemon=True)
    pump.start()
    try:
        yield
    finally:
        sys.stderr.flush()
        os.dup2(saved, fd)
        os.close(saved)
        pump.join(timeout=5.0)  # at once, unless a child process kept a copy of fd
        if not pump.is_alive():
            to.close()
