"""The ``folder-line`` command: thin verbs over the core and the report.

Each verb lives in its own module (:mod:`folder_line.cli.simulate`, :mod:`folder_line.cli.run`, ...),
whose ``add_parser`` adds its options and sets ``func`` (the verb's body) and ``output_option`` (the
option naming its output, for an error raised where that is not known) as the parser's defaults; this
module builds the top-level parser from them, runs ``args.func(args)`` and turns its errors into one line.

Every bad input ends in one line on stderr naming the parameter and its value,
and exit code 2; nothing is left half-written. Output targets are checked before any
work (:mod:`folder_line.files.atomic`): a file target must be a regular file or missing (a
symbolic link to a regular file is followed, never replaced), an output folder must be a
folder, and it is locked for the verb's duration so that a second process writing into
it is refused.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
from collections.abc import Callable, Mapping, Sequence
from typing import NoReturn

from folder_line.cli import (
    analyze,
    animate,
    bag,
    bench,
    kinematics,
    layout,
    monitor_verb,
    operator,
    optimize,
    profile,
    report,
    run,
    scenes,
    simulate,
    solve,
    sweep,
    tune,
)
from folder_line.cli.exits import EXIT_BROKEN_PIPE, EXIT_USAGE, LINE_CHARS, print_error
from folder_line.cli.verb_options import Subparsers
from folder_line.errors import FolderLineError, OutputError, path_repr, shorten

__all__ = ['build_parser', 'main', 'verbs']

#: each verb module's ``add_parser``, in the order ``folder-line --help`` lists the verbs
_VERBS: tuple[Callable[[Subparsers], object], ...] = (
    kinematics.add_parser,
    simulate.add_parser,
    scenes.add_parser,
    layout.add_parser,
    profile.add_parser,
    run.add_parser,
    monitor_verb.add_parser,
    operator.add_parsers,
    tune.add_parser,
    bag.add_parser,
    report.add_parser,
    analyze.add_parser,
    bench.add_parser,
    sweep.add_parser,
    solve.add_parser,
    optimize.add_parser,
    animate.add_parser,
)


class _Parser(argparse.ArgumentParser):
    """``argparse`` whose usage errors are one line too (values cut, a pointer to ``--help``)."""

    def error(self, message: str) -> NoReturn:
        words = (shorten(w) for w in message.split())  # a value given on the command line is one word
        text = shorten(' '.join(words), LINE_CHARS)
        self.exit(EXIT_USAGE, f'{self.prog}: error: {text} (see {self.prog} --help)\n')


def build_parser() -> argparse.ArgumentParser:
    """The ``folder-line`` argument parser: every verb and option, with its range checks."""
    return _parser_and_verbs()[0]


def verbs() -> tuple[str, ...]:
    """The verbs ``folder-line`` takes, in the order ``folder-line --help`` lists them."""
    return tuple(_parser_and_verbs()[1])


def _parser_and_verbs() -> tuple[argparse.ArgumentParser, Mapping[str, argparse.ArgumentParser]]:
    """The parser, and its verbs' parsers by name."""
    parser = _Parser(prog='folder-line', description='Simulate the folding/layup line.')
    sub = parser.add_subparsers(dest='verb', required=True, metavar='VERB')
    for add_parser in _VERBS:
        add_parser(sub)
    return parser, sub.choices


#: argument -> how the command line names it, for an OS error on a path it gave
_PATH_ARGUMENTS = {
    'scene': '--scene',
    'params': '--params',
    'json': '--json',
    'csv': '--csv',
    'out': '--out',
    'bag': '--bag',
    'path': 'RUN_DIR|BAG',
    'animate': '--animate',
    'dir': 'DIR',
}


def _os_error_text(args: argparse.Namespace, exc: OSError) -> str:
    """One line for an OS error: the argument that named the path (the one it is, or lies under), the path
    and the OS reason; a write without a path is the verb's output's."""
    reason = exc.strerror or str(exc)
    if exc.filename is None:
        return f'{args.output_option}: {reason}'
    path = str(exc.filename)
    label = ''
    for attr, option in _PATH_ARGUMENTS.items():
        given = getattr(args, attr, None)
        if isinstance(given, str) and given and (path == given or path.startswith(given.rstrip('/') + '/')):
            label = f'{option}: '
            break
    return f'{label}{path_repr(path)}: {reason}'


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``folder-line``; returns the process exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        code: int = args.func(args)
    except OutputError as exc:
        print_error(str(exc.with_option(args.output_option)))
        return EXIT_USAGE
    except FolderLineError as exc:
        print_error(str(exc))
        return EXIT_USAGE
    except BrokenPipeError:  # the reader of stdout went away (`| head`): nothing to say, and no one to say it to
        with contextlib.suppress(OSError):
            sys.stdout = open(os.devnull, 'w')  # noqa: SIM115 - the interpreter flushes it at exit
        return EXIT_BROKEN_PIPE
    except OSError as exc:  # the OS refused to open, read or write a path deep inside a verb
        print_error(_os_error_text(args, exc))
        return EXIT_USAGE
    except KeyboardInterrupt:
        return 130
    return code


if __name__ == '__main__':
    sys.exit(main())
