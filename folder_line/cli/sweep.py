"""``folder-line sweep``: metrics over a grid of scene-key values, on Dask; ``sweep.csv``, ``.json``, ``.png``."""

from __future__ import annotations

import argparse
import sys

import numpy as np

from folder_line.cli.study_options import (
    add_cluster_arguments,
    add_samples_argument,
    add_scene_arguments,
    cluster_from,
    command_text,
    scheduler_reached,
    source_from,
)
from folder_line.cli.verb_options import Subparsers
from folder_line.core.line.margin_text import format_margin, margin_constraint
from folder_line.files.atomic import claim_output_dir, write_csv_atomic, write_json_atomic
from folder_line.studies.grid import parse_vary
from folder_line.studies.points import OK
from folder_line.studies.sweep import SweepResult, plan_sweep, run_sweep, sweep_columns, sweep_document
from folder_line.studies.sweep_plot import plot_sweep, plotted_keys

__all__ = ['FILES', 'add_parser', 'run']

#: what a sweep writes into ``--out``
FILES = ('sweep.csv', 'sweep.json', 'sweep.png')


def add_parser(subparsers: Subparsers) -> argparse.ArgumentParser:
    """Add the ``sweep`` verb to ``folder-line``'s sub-parsers."""
    parser: argparse.ArgumentParser = subparsers.add_parser(
        'sweep', help='metrics of a scene over a grid of key values (curves or a heat map), on Dask'
    )
    add_scene_arguments(parser, 2.0, per='at every point')
    parser.add_argument(
        '--vary',
        action='append',
        required=True,
        metavar='KEY=START:STOP:N',
        help='a scene key and N linearly spaced values, both ends included (repeatable: the grid is the product)',
    )
    parser.add_argument(
        '--metric',
        action='append',
        default=[],
        metavar='M',
        help='a metric of simulate --json by dotted path or unique suffix (repeatable; '
        'default: every constraint margin and violations.count)',
    )
    parser.add_argument('--out', default='out/sweep', metavar='DIR', help='output directory (default ./out/sweep)')
    add_samples_argument(parser, 'per point (the metrics are then means over them)')
    add_cluster_arguments(parser)
    parser.set_defaults(func=run, output_option='--out')
    return parser


def _print_summary(result: SweepResult) -> None:
    plan = result.plan
    print(
        f'sweep of scene {plan.scene!r}: {len(plan.points)} points over {", ".join(plan.keys)}, '
        f'{plan.duration:g} s of line time each; {result.refused} refused by the model'
    )
    ok = [i for i, r in enumerate(result.results) if r.status == OK]
    for m, metric in enumerate(plan.metrics):
        values = np.array([np.nan if result.results[i].values[m] is None else result.results[i].values[m] for i in ok])
        unit = plan.units[metric]
        if values.size == 0 or np.isnan(values).all():
            print(f'  {metric}: no value')
            continue
        lo, hi = int(np.nanargmin(values)), int(np.nanargmax(values))
        at = {ok[lo]: '', ok[hi]: ''}
        for i in at:
            at[i] = ', '.join(f'{k}={plan.points[i][k]:.6g}' for k in plan.keys)
        span = _range_text(metric, unit, values[lo], values[hi])
        print(f'  {metric}: {span}  (min at {at[ok[lo]]}; max at {at[ok[hi]]})')


def _range_text(metric: str, unit: str, lo: float, hi: float) -> str:
    """``lo to hi unit``; a margin in its unit of the text (ms, mm, ...: as on sweep.png)."""
    name = margin_constraint(metric)
    if name:
        low, high = format_margin(lo, unit, name), format_margin(hi, unit, name)
        return f'{low} at every point' if low == high else f'{low} to {high}'
    return f'{lo:.6g} to {hi:.6g} {unit}'.rstrip()


def run(args: argparse.Namespace) -> int:
    """Run ``folder-line sweep``; returns the exit code."""
    varies = [parse_vary(v) for v in args.vary]
    cluster = cluster_from(args)
    with claim_output_dir(args.out, '--out', FILES) as out:  # before any work: the results need a place
        plan = plan_sweep(source_from(args), varies, args.metric, args.duration, args.samples)
        with scheduler_reached(cluster):
            result = run_sweep(plan, cluster, progress=sys.stderr)
        command = command_text(
            'sweep',
            args,
            (
                ('--scene', 'scene'),
                ('--vary', 'vary'),
                ('--metric', 'metric'),
                ('--samples', 'samples'),
                ('--set', 'overrides'),
                ('--duration', 'duration'),
                ('--out', 'out'),
            ),
        )
        before = {p.name for p in out.iterdir()}
        try:
            written = [write_csv_atomic(out / FILES[0], sweep_columns(result))]
            png = plot_sweep(result, out / FILES[2])
            files = [FILES[0], FILES[1]] + ([FILES[2]] if png is not None else [])
            written.append(write_json_atomic(out / FILES[1], sweep_document(result, command, files)))
        except OSError:  # a full disk part way: the files this run added go (the claim removes a folder it made)
            for name in FILES:
                if name not in before:
                    (out / name).unlink(missing_ok=True)
            raise
        if png is not None:
            written.append(png)
        _print_summary(result)
        for path in written:
            print(f'wrote {path}')
        if png is None:
            print('no sweep.png: a curve needs one key with several values, a heat map two')
        elif len(plotted_keys(result)) == 2 and len(plan.metrics) > 1:
            print(f'sweep.png maps the first metric, {plan.metrics[0]}; the others are in sweep.csv')
    return 0
