"""A progress bar of line time, for the verbs that take long: ``run`` and ``simulate --bag``."""

from __future__ import annotations

import time
from typing import IO

__all__ = ['LineTimeProgress']


class LineTimeProgress:
    """``[####....]  t / total s of line time``: redrawn in place on a terminal (at most every
    ``redraw`` s of wall time), one line per tenth of ``total`` on a pipe or a file.

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

    def show(self, t: float, *, force: bool = False) -> None:
        """Draw the line time reached, ``t`` s (on a terminal now if ``force``: the last drawing)."""
        fraction = min(max(t / self.total, 0.0), 1.0)
        done = int(self.width * fraction)
        line = f'[{"#" * done}{"." * (self.width - done)}] {t:7.2f} / {self.total:g} s of line time'
        if self.tty:
            now = time.monotonic()
            if now - self.drawn < self.redraw and not force:
                return
            self.drawn = now
            self.stream.write('\r' + line)
        elif int(10 * fraction) > self.tenths:
            self.tenths = int(10 * fraction)
            self.stream.write(line + '\n')
        else:
            return
        self.stream.flush()

    def close(self) -> None:
        """End the bar's line on a terminal (if it was drawn)."""
        if self.tty and self.drawn > -float('inf'):
            self.stream.write('\n')
            self.stream.flush()
