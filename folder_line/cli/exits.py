"""Exit codes of ``folder-line`` and its one-line error on stderr."""

from __future__ import annotations

import sys

from folder_line.errors import shorten

__all__ = [
    'EXIT_BROKEN_PIPE',
    'EXIT_NO_ANSWER',
    'EXIT_REFUSED',
    'EXIT_RUN_FAILED',
    'EXIT_USAGE',
    'LINE_CHARS',
    'print_error',
]

EXIT_USAGE = 2
EXIT_RUN_FAILED = 1
#: stdout closed under us: as a shell reports a process killed by SIGPIPE (128 + 13)
EXIT_BROKEN_PIPE = 141
#: an operator command the supervisor refused; none answered
EXIT_REFUSED = 1
EXIT_NO_ANSWER = 3
#: longest error line printed, characters (each value in it is already cut to 80)
LINE_CHARS = 2000


def print_error(text: str) -> None:
    """Print ``text`` as one line on stderr (newlines folded, cut to :data:`LINE_CHARS`)."""
    print(f'folder-line: error: {shorten(" ".join(text.split()), LINE_CHARS)}', file=sys.stderr)
