"""A progress bar of line time, for the verbs that take long: ``run`` and ``simulate --bag``.

On a terminal the bar is redrawn in place with ``\\r``; a log line written meanwhile (the
WARN lines of rclpy nodes, which rcutils writes straight to file descriptor 2) would land in
the middle of it. :meth:`LineTimeProgress.log` clears the bar, writes the line and draws the
bar again below it; :func:`logs_above` sends everything written to a file descriptor through
it while a run spins, so a log line is never torn.
"""

from __future__ import annotations

import os
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import IO

__all__ = ['CLEAR_LINE', 'LineTimeProgress', 'logs_above']

#: back to the start of the line and erase it (ANSI "erase in line")
CLEAR_LINE = '\r\x1b[K'


class LineTimeProgress:
    """``[####....]  t / total s of line time``: redrawn in place on a terminal (at most every
    ``redraw`` s of wall time), one line per tenth of ``total`` on a pipe or a file.

    Safe to use from two threads (the loop that draws, a thread that logs: :func:`logs_above`).

    Parameters
    ----------
    stream : text stream
        Where to draw (stderr for ``simulate --bag``, whose stdout is the result).
    total : float
        Line time of the whole run, s (> 0).
    width : int
        Characters of the bar.
    redraw : float
        Least wall time between two drawings on a terminal, s.
    """

    def __init__(self, stream: IO[str], total: float, width: int = 40, redraw: float = 0.1) -> None:
        self.stream, self.total, self.width, self.redraw = stream, total, width, redraw
        self.tty = hasattr(stream, 'isatty') and stream.isatty()
        self.tenths = -1
        self.drawn = -float('inf')
        self.shown = ''  # the bar on the terminal's last line now ('' when none is)
        self._lock = threading.Lock()

    def _line(self, t: float) -> str:
        fraction = min(max(t / self.total, 0.0), 1.0)
        done = int(self.width * fraction)
        return f'[{"#" * done}{"." * (self.width - done)}] {t:7.2f} / {self.total:g} s of line time'

    def show(self, t: float, *, force: bool = False) -> None:
        """Draw the line time reached, ``t`` s (on a terminal now if ``force``: the last drawing)."""
        with self._lock:
            line = self._line(t)
            if self.tty:
                now = time.monotonic()
                if now - self.drawn < self.redraw and not force:
                    return
                self.drawn = now
                self.stream.write('\r' + line)
                self.shown = line
            else:
                fraction = min(max(t / self.total, 0.0), 1.0)
                if int(10 * fraction) <= self.tenths:
                    return
                self.tenths = int(10 * fraction)
                self.stream.write(line + '\n')
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
