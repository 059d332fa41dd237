"""Run many independent simulations on ``dask.distributed``, in order, with a progress bar.

Sweeps and Monte Carlo samples are independent tasks: :func:`run_tasks` maps a
top-level (picklable) function over them on a Dask cluster and returns the results in
the order of the tasks, whatever order they finish in. By default a ``LocalCluster``
of worker processes uses every core of this machine; ``scheduler`` sends the tasks to
an existing cluster instead (``dask scheduler`` on one machine, ``dask worker ADDRESS``
on each of the others: docs/studies.md, "Several machines"). Every task carries everything it
depends on (the scene, its seed), so a result never depends on the number of workers
or on the order they run in.
"""

from __future__ import annotations

import logging
import os
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import IO, TypeVar

from folder_line.errors import ParameterError

__all__ = ['LOCAL_DASK_CONFIG', 'Cluster', 'for_each_result', 'run_tasks']

T = TypeVar('T')
R = TypeVar('R')

#: most local worker processes or threads per worker
_MAX_WORKERS = 512
#: width of the progress bar, characters
_BAR = 30
#: Dask settings of a local cluster. Dask's default sets ``MALLOC_TRIM_THRESHOLD_`` in its workers, which
#: turns off glibc's dynamic mmap threshold: every large numpy array is then mapped and unmapped anew, and a
#: simulation runs about 2x slower than in this process (``bench/bench_studies.py``). The one-thread BLAS
#: settings stay (the workers are processes), and the statistical profiler (a 10 ms sampling thread) is off.
LOCAL_DASK_CONFIG = {
    'distributed.nanny.pre-spawn-environ': {'OMP_NUM_THREADS': 1, 'MKL_NUM_THREADS': 1, 'OPENBLAS_NUM_THREADS': 1},
    'distributed.worker.profile.enabled': False,
}


@dataclass(frozen=True)
class Cluster:
    """Where the tasks run.

    Attributes
    ----------
    workers : int or None
        Local worker processes (None: one per core of this machine). Ignored with ``scheduler``.
    threads : int
        Threads per local worker process (1: the simulations are CPU-bound Python).
    scheduler : str or None
        Address of an existing Dask scheduler (``tcp://host:8786``): the tasks run on its workers.
    """

    workers: int | None = None
    threads: int = 1
    scheduler: str | None = None

    def __post_init__(self) -> None:
        for name in ('workers', 'threads'):
            value = getattr(self, name)
            if value is None and name == 'workers':
                continue
            if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= _MAX_WORKERS:
                raise ParameterError(f'--{name}', value, f'must be a whole number in [1, {_MAX_WORKERS}]')
        if self.scheduler is not None:
            _check_address(self.scheduler)

    @property
    def local_workers(self) -> int:
        """Worker processes of the local cluster."""
        return self.workers if self.workers is not None else max(1, os.cpu_count() or 1)


def _check_address(address: str) -> None:
    """Refuse a scheduler address Dask could not connect to by its form alone (ParameterError naming
    ``--scheduler``): an unknown scheme, or a TCP/TLS address without a port."""
    from distributed.comm.addressing import parse_address, parse_host_port
    from distributed.comm.registry import get_backend

    try:
        scheme, location = parse_address(address.strip())
        get_backend(scheme)
        if scheme in ('tcp', 'tls'):
            parse_host_port(location)
    except ValueError as exc:
        raise ParameterError('--scheduler', address, f'not a scheduler address ({exc}); e.g. tcp://host:8786') from None


class _Progress:
    """A one-line progress bar on a terminal (redrawn in place), or a closing line elsewhere."""

    def __init__(self, stream: IO[str] | None, label: str, total: int) -> None:
        self.stream, self.label, self.total = stream, label, total
        self.tty = bool(stream is not None and hasattr(stream, 'isatty') and stream.isatty())
        self.start = time.monotonic()
        self.done = 0

    def step(self) -> None:
        self.done += 1
        if self.stream is None or not self.tty:
            return
        filled = round(_BAR * self.done / max(self.total, 1))
        self.stream.write(
            f'\r{self.label} [{"#" * filled}{"." * (_BAR - filled)}] {self.done}/{self.total}'
            f'  {time.monotonic() - self.start:.1f} s'
        )
        self.stream.flush()

    def close(self) -> None:
        if self.stream is None:
            return
        if self.tty:
            self.stream.write('\n')
        self.stream.write(f'{self.label}: {self.done} of {self.total} done in {time.monotonic() - self.start:.1f} s\n')
        self.stream.flush()


def for_each_result(
    fn: Callable[[T], R],
    tasks: Sequence[T],
    cluster: Cluster,
    on_result: Callable[[int, R], None],
    *,
    label: str = 'tasks',
    progress: IO[str] | None = sys.stderr,
) -> None:
    """``on_result(i, fn(tasks[i]))`` for every task as it completes on a Dask cluster, in any order.

    Each result is handed over and dropped at once, so a caller that pools them (a Monte Carlo)
    holds what it pools, not every result.

    Parameters
    ----------
    fn : callable
        A module-level function (pickled to the workers).
    tasks : sequence
        Its arguments, one per task (picklable).
    cluster : Cluster
        A local cluster's size, or an existing scheduler's address.
    on_result : callable
        Called with the task's index and its result, in the order they complete.
    label : str
        Names the tasks on the progress bar.
    progress : text stream or None
        Where the progress bar goes (None: nowhere).

    Raises
    ------
    Exception
        The first exception a task raised, re-raised here with its own type and message.
    """
    import dask
    from dask.distributed import Client, LocalCluster, as_completed

    bar = _Progress(progress, label, len(tasks))
    if not tasks:
        bar.close()
        return
    local: LocalCluster | None = None
    if cluster.scheduler is None:
        with dask.config.set(LOCAL_DASK_CONFIG):
            local = LocalCluster(
                n_workers=min(cluster.local_workers, len(tasks)),  # a process per task at most
                threads_per_worker=cluster.threads,
                processes=True,
                dashboard_address=':0',  # None still binds the web server to 8787 (a warning if taken): any port
                silence_logs=logging.CRITICAL,  # a task's exception is raised here, not logged there
            )
    try:
        with Client(local if local is not None else cluster.scheduler) as client:
            futures = client.map(fn, list(tasks), pure=False)
            index = {f.key: i for i, f in enumerate(futures)}
            for future in as_completed(futures):
                on_result(index[future.key], future.result())  # a task's exception is raised here
                future.release()
                bar.step()
    finally:
        if local is not None:
            local.close()
    bar.close()


def run_tasks(
    fn: Callable[[T], R],
    tasks: Sequence[T],
    cluster: Cluster,
    *,
    label: str = 'tasks',
    progress: IO[str] | None = sys.stderr,
) -> list[R]:
    """``[fn(t) for t in tasks]``, computed on a Dask cluster (:func:`for_each_result`).

    Parameters
    ----------
    fn : callable
        A module-level function (pickled to the workers).
    tasks : sequence
        Its arguments, one per task (picklable).
    cluster : Cluster
        A local cluster's size, or an existing scheduler's address.
    label : str
        Names the tasks on the progress bar.
    progress : text stream or None
        Where the progress bar goes (None: nowhere).

    Returns
    -------
    list
        The results, in the order of ``tasks``.

    Raises
    ------
    Exception
        The first exception a task raised, re-raised here with its own type and message.
    """
    results: dict[int, R] = {}

    def keep(i: int, result: R) -> None:
        results[i] = result

    for_each_result(fn, tasks, cluster, keep, label=label, progress=progress)
    return [results[i] for i in range(len(tasks))]
