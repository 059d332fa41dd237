"""Run the accuracy studies and collect their rows (``folder-line bench accuracy``)."""

from __future__ import annotations

import importlib
import platform
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import IO

from folder_line.accuracy.measure import Row
from folder_line.errors import ParameterError

__all__ = ['STUDIES', 'BenchResult', 'run_benchmark']

#: the studies, in the order they run and are reported
STUDIES = ('linkage', 'fourbar', 'motor', 'events', 'publishing')


@dataclass(frozen=True)
class BenchResult:
    """Rows of every study that ran, with how long each took.

    Attributes
    ----------
    rows : tuple of Row
    quick : bool
        The reduced knob ranges of ``--quick``.
    wall_s : dict of str to float
        Wall-clock seconds per study.
    machine : dict of str to str
        Python, platform and processor, for the record.
    """

    rows: tuple[Row, ...]
    quick: bool
    wall_s: dict[str, float] = field(default_factory=dict)
    machine: dict[str, str] = field(default_factory=dict)

    @property
    def studies(self) -> tuple[str, ...]:
        """The studies that ran, in order."""
        return tuple(s for s in STUDIES if s in self.wall_s)


def check_studies(names: Sequence[str] | None) -> tuple[str, ...]:
    """The studies to run, in their order; ``None`` or empty: all.

    Raises
    ------
    ParameterError
        An unknown study name.
    """
    if not names:
        return STUDIES
    for n in names:
        if n not in STUDIES:
            raise ParameterError('--only', n, f'unknown study; choose from {", ".join(STUDIES)}')
    return tuple(s for s in STUDIES if s in names)


def run_benchmark(
    quick: bool = False, only: Sequence[str] | None = None, stream: IO[str] | None = sys.stdout
) -> BenchResult:
    """Run the studies (all, or ``only`` those) and return their rows.

    Parameters
    ----------
    quick : bool
        Fewer knob settings and shorter spans (under a minute in all).
    only : sequence of str, optional
        Names from :data:`STUDIES`.
    stream : text stream, optional
        Progress, one line per study (None: silent).
    """
    names = check_studies(only)
    rows: list[Row] = []
    wall: dict[str, float] = {}
    for name in names:
        module = importlib.import_module(f'folder_line.accuracy.{name}')
        if stream is not None:
            print(f'{name:>10}: running ...', file=stream, flush=True)
        t0 = time.perf_counter()
        got = list(module.run(quick=quick))
        wall[name] = time.perf_counter() - t0
        bad = [r for r in got if not isinstance(r, Row) or r.study != name]
        if bad or not got:
            raise RuntimeError(f'study {name} returned no rows or foreign rows: {bad[:1]!r}')
        rows += got
        if stream is not None:
            methods = len({r.method for r in got})
            print(f'{name:>10}: {len(got)} points, {methods} methods, {wall[name]:.1f} s', file=stream, flush=True)
    machine = {
        'python': platform.python_version(),
        'platform': platform.platform(),
        'processor': platform.processor() or platform.machine(),
    }
    return BenchResult(tuple(rows), quick, wall, machine)
