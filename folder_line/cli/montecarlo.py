"""``folder-line simulate --samples N``: Monte Carlo of a scene's variation effects on Dask.

The options (:func:`add_arguments`) and the verb (:func:`simulate_samples`): the output is
checked and the scene merged and validated before any work, the samples run on a Dask
cluster (:func:`folder_line.studies.montecarlo.monte_carlo`), a per-constraint table goes
to stdout (:func:`print_table`) and the aggregate to ``--json``.
"""

from __future__ import annotations

import argparse
import sys
from typing import IO

from folder_line.cli.study_options import add_cluster_arguments, add_samples_argument, cluster_from, scheduler_reached
from folder_line.config.scenes import SceneMapping
from folder_line.core.line.margin_text import format_margin, margin_legend
from folder_line.files.atomic import write_json_atomic
from folder_line.studies.montecarlo import monte_carlo
from folder_line.studies.montecarlo_figures import EVERY_MARGIN, MonteCarloResult

__all__ = ['add_arguments', 'print_table', 'simulate_samples']


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``--samples N`` and the cluster options, on ``simulate``."""
    add_samples_argument(parser, 'of --duration each (--json: the aggregate)')
    add_cluster_arguments(parser)


def print_table(result: MonteCarloResult, out: IO[str]) -> None:
    """Per constraint: violation probability per cycle with its interval, runs violated, margin quantiles."""
    agg = result.aggregate
    print(
        f'scene {result.scene}: {agg.samples} samples of {result.duration_s:g} s (scene seed '
        f'{result.seed}); intervals: {agg.interval}',
        file=out,
    )
    head = f'  {"constraint":<22} {"p per cycle":>11} {"95 % interval":>23} {"runs violated":>14}'
    print(head + f' {"margin 1 %":>18} {"median":>18} {"99 %":>18}', file=out)
    for name, c in agg.constraints.items():
        pc, pr, m = c.p_cycle, c.p_run, c.margin
        p = '-' if pc.p is None else f'{pc.p:.4g}'
        lo, hi = pc.ci95
        interval = f'[{lo:.4g}, {hi:.4g}]'
        runs = f'{pr.k}/{pr.n}'
        row = f'  {name:<22} {p:>11} {interval:>23} {runs:>14}'
        if m.count:
            q = m.quantiles
            row += ''.join(f' {format_margin(q[k], c.unit, name):>18}' for k in ('0.01', '0.5', '0.99'))
        print(row, file=out)
    sampled = [n for n, c in agg.constraints.items() if c.margin.method != EVERY_MARGIN]
    if sampled:
        kept = agg.constraints[sampled[0]].margin.kept
        print(
            f'  margin quantiles of {", ".join(sampled)}: of a uniform random sample of {kept} margins '
            '(p, runs, mean, std and extremes: of every margin)',
            file=out,
        )
    print('what the margins mean (>= 0 passes):', file=out)
    for line in margin_legend(agg.constraints):
        print(line, file=out)


def simulate_samples(args: argparse.Namespace, source: SceneMapping) -> int:
    """``simulate --samples N`` of the merged scene ``source`` (``--json`` already checked): run, print, write."""
    cluster = cluster_from(args)
    with scheduler_reached(cluster):
        result = monte_carlo(source, args.duration, args.samples, cluster, progress=sys.stderr)
    print_table(result, sys.stdout)
    if args.json:
        dest = write_json_atomic(args.json, result.as_json())
        print(f'wrote {dest}')
    return 0
