"""The line-time progress bar of ``run`` and ``simulate --bag``."""

from __future__ import annotations

import io

from folder_line.progress import LineTimeProgress


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_on_a_pipe_one_line_per_tenth() -> None:
    out = io.StringIO()
    bar = LineTimeProgress(out, 10.0, width=10)
    for k in range(101):
        bar.show(k / 10)
    bar.close()
    lines = out.getvalue().splitlines()
    assert len(lines) == 11
    assert lines[0] == '[..........]    0.00 / 10 s of line time'
    assert lines[5] == '[#####.....]    5.00 / 10 s of line time'
    assert lines[-1] == '[##########]   10.00 / 10 s of line time'


def test_on_a_terminal_redrawn_in_place_at_most_every_redraw() -> None:
    out = _Terminal()
    bar = LineTimeProgress(out, 10.0, width=10, redraw=3600.0)
    bar.show(1.0)
    bar.show(2.0)  # within the redraw period: not drawn
    bar.show(3.0, force=True)
    bar.close()
    assert out.getvalue() == ('\r[#.........]    1.00 / 10 s of line time\r[###.......]    3.00 / 10 s of line time\n')


def test_a_bar_never_drawn_leaves_no_blank_line() -> None:
    out = _Terminal()
    LineTimeProgress(out, 10.0).close()
    assert out.getvalue() == ''
