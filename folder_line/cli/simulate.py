"""``folder-line simulate``: a scene simulated with exact events, streamed in bounded memory (no ROS)."""

from __future__ import annotations

import argparse
import contextlib
import sys
from collections.abc import Iterator, Sequence
from dataclasses import replace
from typing import TYPE_CHECKING, Any

from folder_line.cli import batch as batch_cli
from folder_line.cli import keys, montecarlo, summary
from folder_line.cli.arg_types import add_tune_argument, check_tunings, limited
from folder_line.cli.study_options import add_scene_arguments, source_from
from folder_line.cli.verb_options import add_bag_split, add_marker_rate
from folder_line.core.limits import DURATION, Limit
from folder_line.core.line.line_summary import LineSummary, TuningRecord, WindowSummary
from folder_line.core.line.scene import Scene, parse_scene
from folder_line.core.line.tuning import TUNABLES, Tuning
from folder_line.errors import ParameterError
from folder_line.files.atomic import check_output_file, write_json_atomic
from folder_line.progress import LineTimeProgress

if TYPE_CHECKING:
    from folder_line.cli.plots import FigureData

__all__ = ['BAR_DELAY', 'add_parser', 'run']

#: ``simulate --from``: where the output starts, line time (``--from`` + ``--duration`` within DURATION too)
_FROM = Limit('line time the output starts at (`simulate --from`)', 0.0, DURATION.hi, 's', 'a run reaches DURATION')
#: wall time ``simulate`` runs before its progress bar shows on a terminal, s: a quick run shows none
BAR_DELAY = 0.5


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add the ``simulate`` verb to ``folder-line``'s sub-parsers."""
    sim: argparse.ArgumentParser = subparsers.add_parser(
        'simulate',
        help='simulation of a scene with exact events, streamed in bounded memory (no ROS)',
        description=(
            'Simulate a scene without ROS and print its summary. The line is streamed window by window: '
            'memory does not grow with --duration, and on a terminal a progress bar on stderr shows the line '
            'time done and the wall time left. Without --from the summary is simulate(scene, D).summary() '
            'of the batch model, bit for bit.'
        ),
    )
    add_scene_arguments(sim, 60.0)
    sim.add_argument(
        '--from',
        dest='start',
        type=limited('--from', _FROM),
        default=None,
        metavar='S',
        help='the line time the output starts at, s: the line still starts at 0 s (from standstill) and is '
        'fast-forwarded to S keeping nothing; --duration D is the span after S. The summary (--json, '
        '--list-metrics) is of the window S..S+D: the cycles, sheets, events and constraint rows the line '
        'hands out from S on (a cycle counts where it is judged), without the design figures of a run from 0; '
        '--plots draws that window; --tune times stay line times from 0. Not with --bag or --samples',
    )
    listing = sim.add_mutually_exclusive_group()
    listing.add_argument('--json', metavar='PATH', help='write the summary as JSON')
    listing.add_argument(
        '--bag',
        metavar='DIR',
        help='write the bag a live lockstep `run` of the scene would record (no DDS; a new or empty folder)',
    )
    listing.add_argument(
        '--list-keys', action='store_true', help='list every --set key of the scene: unit, value, range; then exit'
    )
    listing.add_argument(
        '--list-metrics',
        action='store_true',
        help='simulate --duration and list every metric (dotted path into the summary) with its value and unit',
    )
    sim.add_argument(
        '--plots',
        metavar='DIR',
        help="draw analyze's figures of the run (landing, cyclogram, margins, efficiency, exit speeds) into DIR, "
        'from the streamed run in bounded memory (joint states: a pseudo-random sample of the 200 Hz ticks; '
        'margins and landings: exact streamed histograms); with --bag, of the line of that bag',
    )
    add_tune_argument(sim)
    add_marker_rate(sim, 'with --bag: ', given_only=True)
    add_bag_split(sim, 'with --bag: ')
    montecarlo.add_arguments(sim)
    sim.set_defaults(func=run, output_option='--json')
    return sim


# --------------------------------------------------------------------------- the options, before any work


def _listing(args: argparse.Namespace) -> str | None:
    """The listing option given (``--list-keys``, ``--list-metrics``), if any."""
    return '--list-keys' if args.list_keys else '--list-metrics' if args.list_metrics else None


def _check_from(args: argparse.Namespace) -> None:
    """Refuse ``--from`` with what runs from line time 0 or runs nothing; its window within DURATION."""
    start = args.start
    if args.list_keys:
        raise ParameterError('--from', start, 'starts the output of a run; --list-keys lists and runs nothing')
    if args.bag is not None:
        raise ParameterError(
            '--from', start, 'not with --bag: a bag is written from line time 0, as a live run records it'
        )
    if args.samples is not None:
        raise ParameterError('--from', start, 'not with --samples: a Monte Carlo sample runs from line time 0')
    summary.check_window(start, args.duration)


def _check_plots_option(args: argparse.Namespace, listing: str | None) -> None:
    """Refuse ``--plots`` with a Monte Carlo or a listing, and a folder that cannot take the figures."""
    if args.samples is not None:
        raise ParameterError('--samples', args.samples, 'runs a Monte Carlo; --plots draws one run')
    if listing is not None:
        raise ParameterError('--plots', args.plots, f'draws a run; {listing} lists and runs nothing')
    import folder_line.cli.plots as plots  # the figures' modules and matplotlib: only --plots

    plots.check_plots(args.plots)


def _check_bag_only(args: argparse.Namespace) -> None:
    """Refuse the options of a bag (marker rate, split) without ``--bag``."""
    if args.marker_rate is not None and args.bag is None:
        raise ParameterError('--marker-rate', args.marker_rate, 'draws the machine into a bag: only with --bag')
    for option, value in (('--max-bag-duration', args.max_bag_duration), ('--max-bag-size', args.max_bag_size)):
        if value is not None and args.bag is None:
            raise ParameterError(option, value, 'splits a bag: only with --bag')


def _check_cluster_unused(args: argparse.Namespace) -> None:
    """Refuse the options of a Monte Carlo's workers without ``--samples``."""
    for option, value, default in (
        ('--workers', args.workers, None),
        ('--threads', args.threads, 1),
        ('--scheduler', args.scheduler, None),
    ):
        if value != default:
            raise ParameterError(option, value, 'runs the samples of a Monte Carlo: only with --samples')


def _check_options(args: argparse.Namespace) -> None:
    """Refuse options that do not go together, and an output target that cannot be written, before any work."""
    listing = _listing(args)
    if args.samples is not None and listing is not None:
        raise ParameterError('--samples', args.samples, f'runs a Monte Carlo; {listing} lists and runs nothing')
    if args.start is not None:
        _check_from(args)
    if args.json:
        check_output_file(args.json, '--json')
    if args.bag is not None and args.samples is not None:
        raise ParameterError('--samples', args.samples, 'runs a Monte Carlo; --bag writes one run')
    if args.plots is not None:
        _check_plots_option(args, listing)
    if args.tune and args.samples is not None:
        raise ParameterError('--samples', args.samples, 'runs a Monte Carlo; --tune changes one run')
    _check_bag_only(args)
    if args.samples is None:
        _check_cluster_unused(args)


# --------------------------------------------------------------------------- the run


def _progress_bar(end: float) -> LineTimeProgress | None:
    """The line-time bar of a streamed run to ``end`` s, on stderr if it is a terminal (None otherwise)."""
    if not sys.stderr.isatty():
        return None
    bar = LineTimeProgress(sys.stderr, end, delay=BAR_DELAY)
    bar.show(0.0)  # the clock of the estimate starts here (nothing is drawn before BAR_DELAY)
    return bar


@contextlib.contextmanager
def _progress(end: float) -> Iterator[LineTimeProgress | None]:
    """:func:`_progress_bar` for the duration of the block, closed after it."""
    bar = _progress_bar(end)
    try:
        yield bar
    finally:
        if bar is not None:
            bar.close()


def _write_bag(args: argparse.Namespace, scene: Scene, tunings: Sequence[Tuning], end: float) -> int:
    """``--bag``: write the bag of the run, and with ``--plots`` draw the line of that bag."""
    code, issued = batch_cli.write_bag(args, scene, tunings)
    if args.plots is not None:  # the line of the bag: under the commands its supervisor issued
        import folder_line.cli.plots as plots

        with _progress(end) as bar:
            figures, _ = plots.collect(
                scene, args.duration, commands=issued, progress=None if bar is None else bar.show
            )
        plots.write_figures(args.plots, figures)
    return code


def _stream(
    args: argparse.Namespace, scene: Scene, tunings: Sequence[Tuning], end: float
) -> tuple[FigureData | None, LineSummary | WindowSummary]:
    """Stream the line to ``end`` s: the figures' data (with ``--plots``, else None) and the summary."""
    figures = None
    with _progress(end) as bar:
        progress = None if bar is None else bar.show
        if args.plots is not None:  # one streamed run for the summary and the figures
            import folder_line.cli.plots as plots

            figures, result_summary = plots.collect(
                scene, args.duration, start=args.start, commands=tunings, progress=progress
            )
        else:
            result_summary = summary.line_summary(
                scene, args.duration, start=args.start, commands=tunings, progress=progress
            )
        if bar is not None:
            bar.show(end, force=True)
    return figures, result_summary


def run(args: argparse.Namespace) -> int:
    """Simulate the scene and print its summary (or its keys, its metrics, its bag, its Monte Carlo)."""
    _check_options(args)
    data = source_from(args)
    if args.samples is not None:
        return montecarlo.simulate_samples(args, data)
    scene = parse_scene(data)
    end = (args.start or 0.0) + args.duration
    tunings = check_tunings(scene, args.tune, end)
    if args.bag is not None:
        return _write_bag(args, scene, tunings, end)
    if args.list_keys:
        keys.print_keys(data, sys.stdout)
        return 0
    figures, result_summary = _stream(args, scene, tunings, end)
    if tunings:
        records = [TuningRecord(tu.t, tu.key, tu.value, TUNABLES[tu.key].unit) for tu in tunings]
        result_summary = replace(result_summary, tunings=records)
    if args.list_metrics:
        keys.print_metrics(result_summary.as_json(), sys.stdout)
        return 0
    summary.print_summary(result_summary, sys.stdout)
    if args.json:
        dest = write_json_atomic(args.json, result_summary.as_json())
        print(f'wrote {dest}')
    if figures is not None:
        import folder_line.cli.plots as plots

        plots.write_figures(args.plots, figures)
    return 0
