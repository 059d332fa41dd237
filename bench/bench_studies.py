"""Cost of the design studies: Dask against a plain loop, and what Monte Carlo accuracy costs.

Measured side by side in one run:

1. **Fan-out overhead.** The same tasks (one hour of ``folder_jitter`` each) run as a
   plain in-process loop (the floor: no Dask at all), then through
   :func:`folder_line.studies.runner.run_tasks` on a ``LocalCluster`` of 1 and of 2 worker
   processes, and once more with Dask's default worker environment (its
   ``MALLOC_TRIM_THRESHOLD_``, which :data:`folder_line.studies.runner.LOCAL_DASK_CONFIG`
   leaves out). The cluster's start-up (paid once per verb) is timed apart from the tasks;
   the tasks' ratio to the floor says what Dask costs on one worker and what a second
   core gains.
2. **Monte Carlo accuracy against time.** ``simulate --samples N`` for growing N: the 95 %
   interval of the feed-window violation probability narrows as 1/sqrt(N) while the time
   grows as N.

Run: ``.venv/bin/python bench/bench_studies.py`` (``--quick``: fewer tasks and samples).
"""

from __future__ import annotations

import argparse
import logging
import os
import platform
import time

import dask
from dask.distributed import LocalCluster

from folder_line.config.scenes import scene_mapping
from folder_line.studies.montecarlo import SampleTask, aggregate, run_sample
from folder_line.studies.runner import LOCAL_DASK_CONFIG, Cluster, run_tasks


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument('--quick', action='store_true', help='fewer tasks and samples')
    args = ap.parse_args()
    tasks_n = 16
    duration = 600.0 if args.quick else 3600.0  # an hour of line, ~0.3 s a task
    source = scene_mapping('folder_jitter')
    tasks = [SampleTask(source=source, duration=duration, index=i) for i in range(tasks_n)]
    print(
        f'python {platform.python_version()}, {os.cpu_count()} cores; {tasks_n} tasks of {duration:g} s '
        f'of folder_jitter line time\n'
    )

    t0 = time.perf_counter()
    floor = [run_sample(t) for t in tasks]
    t_floor = time.perf_counter() - t0
    print('| how | cluster start, s | tasks, s | tasks: ratio to the loop |')
    print('|---|---:|---:|---:|')
    print(f'| plain loop in this process (floor) | - | {t_floor:.2f} | 1.00 |')
    runs = [(1, LOCAL_DASK_CONFIG, ''), (2, LOCAL_DASK_CONFIG, ''), (1, {}, ", Dask's default worker environment")]
    for workers, config, note in runs:
        t0 = time.perf_counter()
        with (
            dask.config.set(config),
            LocalCluster(
                n_workers=workers,
                threads_per_worker=1,
                processes=True,
                dashboard_address=':0',
                silence_logs=logging.CRITICAL,
            ) as cluster,
        ):
            t_start = time.perf_counter() - t0
            t0 = time.perf_counter()
            got = run_tasks(run_sample, tasks, Cluster(scheduler=cluster.scheduler_address), progress=None)
            wall = time.perf_counter() - t0
        same = aggregate(got) == aggregate(floor)
        print(
            f'| Dask LocalCluster, {workers} worker process{"es" if workers > 1 else ""}{note} | {t_start:.2f} '
            f'| {wall:.2f} | {wall / t_floor:.2f}{"" if same else "  RESULTS DIFFER"} |'
        )

    print('\nMonte Carlo on 2 workers: the feed-window violation probability per cycle and its 95 % interval\n')
    print('| samples | p per cycle | interval width | wall, s |')
    print('|---:|---:|---:|---:|')
    for n in (10, 40, 160) if args.quick else (10, 40, 160, 640):
        sample_tasks = [SampleTask(source=source, duration=5.0, index=i) for i in range(n)]
        t0 = time.perf_counter()
        result = aggregate(run_tasks(run_sample, sample_tasks, Cluster(workers=2), progress=None))
        wall = time.perf_counter() - t0
        p = result['constraints']['feed_window']['p_cycle']
        lo, hi = p['ci95']
        print(f'| {n} | {p["p"]:.4f} | {hi - lo:.4f} | {wall:.2f} |')


if __name__ == '__main__':
    main()
