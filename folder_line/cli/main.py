"""The ``folder-line`` command: thin verbs over the core and the report.

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
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import NoReturn

from folder_line.accuracy.bench import STUDIES, run_benchmark
from folder_line.accuracy.output import write_outputs
from folder_line.analysis.report import analyze, print_analysis
from folder_line.bag.metadata import METADATA_FILE
from folder_line.bag.reader import bag_info_lines, read_bag
from folder_line.bag.repair import repair, repairable
from folder_line.cli import animate as animate_cli
from folder_line.cli import batch as batch_cli
from folder_line.cli import keys, montecarlo, optimize, summary, tables
from folder_line.cli import layout as layout_verb
from folder_line.cli import solve as solve_verb
from folder_line.cli import sweep as sweep_verb
from folder_line.cli.arg_types import add_tune_argument, check_tunings, limited, split_limit, tuning_change
from folder_line.cli.report import REPORT_FILES, add_report_arguments, report_params, write_report
from folder_line.cli.study_options import NAMES, add_scene_arguments, source_from
from folder_line.config.run_config import BAG_DIR, MARKER_RATE, MARKER_RATES, SCENE_FILE, RunConfig, bag_of
from folder_line.config.scenes import InputNames, parse_set
from folder_line.core.limits import DURATION, LOST_TIMEOUT, RTF, Limit
from folder_line.core.line.scene import parse_scene
from folder_line.core.line.tuning import TUNABLES
from folder_line.errors import FolderLineError, OutputError, ParameterError, bounded_repr, path_repr, shorten
from folder_line.files.atomic import (
    check_output_dir,
    check_output_file,
    claim_output_dir,
    write_csv_atomic,
    write_json_atomic,
)
from folder_line.interfaces import OPERATOR_COMMANDS, TUNABLE_PARAMETERS
from folder_line.progress import LineTimeProgress

#: the option that names each verb's output, for errors raised where it is not known
_OUTPUT_OPTION = {
    'kinematics': '--csv',
    'simulate': '--json',
    'run': '--out',
    'report': '--out',
    'analyze': '--out',
    'bench': '--out',
    'bag': 'DIR',
    'optimize': '--out',
    'sweep': '--out',
    'solve': '--json',
    'scenes': 'stdout',
    'layout': '--out',
    'profile': 'stdout',
    'animate': '--out',
    **dict.fromkeys(OPERATOR_COMMANDS, 'stdout'),
    'tune': 'stdout',
}
#: longest error line printed, characters (each value in it is already cut to 80)
_LINE_CHARS = 2000

__all__ = ['build_parser', 'main', 'verbs']

EXIT_USAGE = 2
EXIT_RUN_FAILED = 1
#: stdout closed under us: as a shell reports a process killed by SIGPIPE (128 + 13)
EXIT_BROKEN_PIPE = 141
#: an operator command the supervisor refused; none answered
EXIT_REFUSED = 1
EXIT_NO_ANSWER = 3


def _samples(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'--samples={bounded_repr(text)}: must be a whole number >= 2') from None
    if n < 2 or n > 100_000_000:
        raise argparse.ArgumentTypeError(f'--samples={bounded_repr(text)}: must be in [2, 100000000]')
    return n


# the monitor's own knobs (display, not line physics)
_MONITOR_RATE = Limit('monitor refresh rate', 0.1, 60.0, 'Hz', 'a screen refresh')
_MONITOR_WINDOW = Limit('monitor rate window', 0.01, 600.0, 's', 'sim time the rates are counted over')
_MONITOR_TIMEOUT = Limit('monitor wait for the line', 0.1, 3600.0, 's', 'wall time')
_OPERATOR_TIMEOUT = Limit('operator wait for the supervisor', 0.1, 3600.0, 's', 'wall time')
# what `bag play` and `analyze --from/--to` take from a bag: line time (a week at most)
_BAG_TIME = Limit('line time in a bag', 0.0, 604800.0, 's', 'a week of line time')
_BAG_SPAN = Limit('line time to play', 1e-9, 604800.0, 's', 'a week of line time')
#: ``simulate --from``: where the output starts, line time (``--from`` + ``--duration`` within DURATION too)
_FROM = Limit('line time the output starts at (`simulate --from`)', 0.0, DURATION.hi, 's', 'a run reaches DURATION')
#: wall time ``simulate`` runs before its progress bar shows on a terminal, s: a quick run shows none
BAR_DELAY = 0.5
#: ``--rtf``: a ceiling in the RTF range, or ``max`` (0.0: as fast as the line allows)
_rtf = limited('--rtf', RTF, also='max')


class _Parser(argparse.ArgumentParser):
    """``argparse`` whose usage errors are one line too (values cut, a pointer to ``--help``)."""

    def error(self, message: str) -> NoReturn:
        words = (shorten(w) for w in message.split())  # a value given on the command line is one word
        text = shorten(' '.join(words), _LINE_CHARS)
        self.exit(EXIT_USAGE, f'{self.prog}: error: {text} (see {self.prog} --help)\n')


def _addlimited(
    parser: argparse.ArgumentParser, option: str, limit: Limit, default: float, metavar: str, help: str
) -> None:
    """``option``: a number in ``limit`` (:func:`folder_line.cli.arg_types.limited`); ``help`` gets
    `` (default ...)`` appended."""
    parser.add_argument(
        option, type=limited(option, limit), default=default, metavar=metavar, help=f'{help} (default {default:g})'
    )


def _add_out(parser: argparse.ArgumentParser, default: str) -> None:
    """``--out DIR``, the verb's output folder."""
    parser.add_argument('--out', default=default, metavar='DIR', help=f'output directory (default ./{default})')


def _add_marker_rate(parser: argparse.ArgumentParser, when: str, *, given_only: bool = False) -> None:
    """``--marker-rate HZ``: ``/line/markers`` per second of line time (the machine for RViz/Foxglove);
    ``given_only``: None unless given (the verb refuses it where it does nothing), :data:`MARKER_RATE` meant."""
    if not given_only:
        _addlimited(
            parser,
            '--marker-rate',
            MARKER_RATES,
            MARKER_RATE,
            'HZ',
            f'{when}/line/markers per second of line time, 0: none',
        )
        return
    parser.add_argument(
        '--marker-rate',
        type=limited('--marker-rate', MARKER_RATES),
        default=None,
        metavar='HZ',
        help=f'{when}/line/markers per second of line time, 0: none (default {MARKER_RATE:g})',
    )


#: bounds of --max-bag-duration (s) and --max-bag-size (bytes) when not 0
BAG_DURATION = (1e-3, 1e7)
BAG_SIZE = (1024, 10**15)


def _add_bag_split(parser: argparse.ArgumentParser, when: str) -> None:
    """``--max-bag-duration S`` and ``--max-bag-size BYTES``: split the bag, as ``ros2 bag record`` does; None
    unless given (a verb refuses them where they do nothing), 0 (one file) meant."""
    parser.add_argument(
        '--max-bag-duration',
        type=split_limit('--max-bag-duration', *BAG_DURATION, 's'),
        default=None,
        metavar='S',
        help=f'{when}start a new .mcap file every S s of line time (default 0: one file, as ros2 bag record)',
    )
    parser.add_argument(
        '--max-bag-size',
        type=split_limit('--max-bag-size', *BAG_SIZE, 'bytes', whole=True),
        default=None,
        metavar='BYTES',
        help=f'{when}start a new .mcap file once one has BYTES bytes, at its next flush (every 0.1 s of '
        'line time); with --max-bag-duration, whichever comes first (default 0: no split by size)',
    )


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

    kin = sub.add_parser('kinematics', help='table of one mechanism over a crank turn (or the delivery stroke)')
    kin.add_argument('mechanism', choices=('layup', 'knife', 'delivery'))
    kin.add_argument('--params', metavar='FILE.yaml', help='any subset of the parameters; the rest are the defaults')
    kin.add_argument('--samples', type=_samples, default=360, metavar='N', help='number of samples (default 360)')
    kin.add_argument('--csv', metavar='PATH', help='write the table as CSV (SI units, angles in rad)')

    sim = sub.add_parser(
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
    _add_marker_rate(sim, 'with --bag: ', given_only=True)
    _add_bag_split(sim, 'with --bag: ')
    montecarlo.add_arguments(sim)
    sub.add_parser('scenes', help='list the shipped scenes with their machines, effects and descriptions')
    layout_verb.add_arguments(sub.add_parser('layout', help=layout_verb.HELP))
    sub.add_parser(
        'profile',
        help="print the path of the line's Fast DDS profile for FOLDER_LINE_KEY (writing it if needed), for ros2 "
        'tools that must reach a closed line: FASTDDS_DEFAULT_PROFILES_FILE=$(folder-line profile) ros2 param set ...',
    )

    run = sub.add_parser('run', help='run the line as ROS 2 nodes over DDS for a while, then report')
    add_scene_arguments(run, 20.0)
    run.add_argument(
        '--rtf',
        type=_rtf,
        default=1.0,
        metavar='X|max',
        help='real-time factor ceiling (default 1); max: as fast as the slowest node allows',
    )
    run.add_argument(
        '--clock',
        choices=('lockstep', 'wall'),
        default='lockstep',
        help='lockstep: sim time waits for every node, the answer never depends on load (default); '
        'wall: paced by the wall clock for hardware in the loop, late ticks counted',
    )
    _addlimited(
        run,
        '--lost-timeout',
        LOST_TIMEOUT,
        3.0,
        'S',
        'wall time a tick waits for a node before the node is declared lost',
    )
    _add_out(run, 'out')
    where = run.add_mutually_exclusive_group()
    where.add_argument('--processes', action='store_true', help='one process per node, as a launch file would')
    where.add_argument(
        '--external-nodes',
        action='store_true',
        help='the machine nodes run elsewhere (each on its own host): start only line_clock and the recorder '
        'here, print the command for each node, and wait for them',
    )
    _add_marker_rate(run, '')
    _add_bag_split(run, '')

    mon = sub.add_parser('monitor', help='live terminal view of the running line (q or Ctrl-C quits)')
    _addlimited(mon, '--rate', _MONITOR_RATE, 4.0, 'HZ', 'screen refreshes per second')
    mon.add_argument(
        '--once',
        action='store_true',
        help='print one plain-text snapshot after collecting for the rate window, then exit',
    )
    _addlimited(mon, '--window', _MONITOR_WINDOW, 2.0, 'S', 'window of the topic rates, s of wall time')
    _addlimited(mon, '--timeout', _MONITOR_TIMEOUT, 10.0, 'S', 'with --once: longest wait for the first message, s')

    for command in OPERATOR_COMMANDS:
        op = sub.add_parser(
            command,
            help=f'operator command: {command} the running line (its supervisor, on this ROS domain)',
            description=(
                f"Call the supervisor's {command} service (std_srvs/Trigger) on the current ROS domain and print "
                'its answer. Exit 0: accepted; 1: refused (the reason is printed); 3: no supervisor answered.'
            ),
        )
        _addlimited(op, '--timeout', _OPERATOR_TIMEOUT, 5.0, 'S', 'longest wait for the service, then its answer, s')

    tune = sub.add_parser(
        'tune',
        help='operator tuning: change a setting of the running line at its next machine cycle boundary',
        description=(
            'Set the node parameter that tunes KEY on the current ROS domain, as `ros2 param set` would '
            f'({", ".join(f"/{n} {p}" for n, ps in TUNABLE_PARAMETERS.items() for p in ps)}); the supervisor '
            'times the change at the next machine cycle boundary and records it. Exit 0: accepted; 1: refused '
            '(the reason is printed); 3: the node did not answer. `simulate --tune T:KEY=VALUE` runs the same '
            'change in the batch model.'
        ),
    )
    tune.add_argument('change', type=tuning_change, metavar='KEY=VALUE', help=f'KEY one of {", ".join(TUNABLES)}')
    _addlimited(tune, '--timeout', _OPERATOR_TIMEOUT, 5.0, 'S', 'longest wait for the node, then its answer, s')

    bag = sub.add_parser('bag', help='rosbag2 bags of a run: info, play, repair')
    bag_sub = bag.add_subparsers(dest='bag_verb', required=True, metavar='BAG_VERB')
    bag_info = bag_sub.add_parser('info', help='topics, counts, line time and custom data of a bag')
    bag_info.add_argument('dir', metavar='DIR', help='a run folder (e.g. out) or its bag folder (out/bag)')
    play = bag_sub.add_parser(
        'play', help='republish a bag on its topics with /clock, as the line published it (Ctrl-C stops)'
    )
    play.add_argument('dir', metavar='DIR', help='a run folder (e.g. out) or its bag folder (out/bag)')
    play.add_argument(
        '--rtf',
        type=_rtf,
        default=1.0,
        metavar='X|max',
        help='line seconds per wall second (default 1); max: no pacing',
    )
    play.add_argument(
        '--start', type=limited('--start', _BAG_TIME), default=0.0, metavar='S', help="begin S s after the bag's start"
    )
    play.add_argument(
        '--duration', type=limited('--duration', _BAG_SPAN), metavar='S', help='play S s of line time (default: all)'
    )
    play.add_argument('--topics', nargs='+', default=[], metavar='T', help='only these topics (/clock always)')
    play.add_argument('--loop', action='store_true', help='play the window again and again until Ctrl-C')
    bag_repair = bag_sub.add_parser(
        'repair', help='rebuild metadata.yaml from the MCAP files present, salvaging an unfinished last file'
    )
    bag_repair.add_argument('dir', metavar='DIR', help='a run folder (e.g. out) or its bag folder (out/bag)')

    rep = sub.add_parser('report', help='kinematics, efficiency and cyclogram report of the defaults, with plots')
    _add_out(rep, 'out')
    add_report_arguments(rep)

    ana = sub.add_parser('analyze', help='replay analysis of a recorded run: report.md and plots (no ROS needed)')
    ana.add_argument('path', metavar='RUN_DIR|BAG', help='a run directory (run.json, bag/) or a bag directory')
    ana.add_argument('--out', metavar='DIR', help='output directory (default RUN_DIR/analysis)')
    ana.add_argument('--csv', action='store_true', help='also write one CSV per topic to DIR/csv/')
    ana.add_argument(
        '--from', dest='t_from', type=limited('--from', _BAG_TIME), metavar='S', help='analyse line time from S s on'
    )
    ana.add_argument(
        '--to', dest='t_to', type=limited('--to', _BAG_TIME), metavar='S', help='analyse line time up to S s'
    )
    ana.add_argument(
        '--animate',
        metavar='FILE.mp4|FILE.gif',
        help='also write a video of the recorded run over the window --from .. --to (its recorded states and '
        'violations written on it; see folder-line animate --help for the time scale)',
    )
    animate_cli.add_animation_options(ana, defaults=False)

    bench = sub.add_parser('bench', help='benchmarks: what accuracy costs in CPU time')
    bench_sub = bench.add_subparsers(dest='bench_verb', required=True, metavar='BENCH_VERB')
    acc = bench_sub.add_parser(
        'accuracy',
        help='error against CPU time per simulated second for every accuracy knob: CSV, markdown, Pareto plot',
    )
    _add_out(acc, 'out/accuracy')
    acc.add_argument('--quick', action='store_true', help='fewer knob settings, shorter spans (under a minute)')
    acc.add_argument(
        '--only',
        action='append',
        metavar='STUDY',
        default=[],
        choices=STUDIES,
        help=f'run only this study (repeatable): {", ".join(STUDIES)}',
    )
    sweep_verb.add_parser(sub)
    solve_verb.add_parser(sub)
    optimize.add_parser(sub)
    animate_cli.add_parser(sub)
    return parser, sub.choices


def _cmd_bench(args: argparse.Namespace) -> int:
    files = ('accuracy.csv', 'accuracy.md', 'accuracy.png', 'accuracy.json')
    with claim_output_dir(args.out, '--out', files) as out:  # before any work: the results need a place
        result = run_benchmark(quick=args.quick, only=args.only, stream=sys.stdout)
        command = (
            'folder-line bench accuracy'
            + (' --quick' if args.quick else '')
            + ''.join(f' --only {s}' for s in args.only)
        )
        for path in write_outputs(result, out, command):
            print(f'wrote {path}')
    return 0


def _cmd_kinematics(args: argparse.Namespace) -> int:
    if args.csv:
        check_output_file(args.csv, '--csv')
    table = tables.kinematics_table(args.mechanism, args.params, args.samples)
    tables.print_summary(args.mechanism, table, sys.stdout)
    if args.csv:
        dest = write_csv_atomic(args.csv, table)
        print(f'wrote {dest} ({args.samples} rows, {len(table)} columns)')
    return 0


def _progress_bar(end: float) -> LineTimeProgress | None:
    """The line-time bar of a streamed run to ``end`` s, on stderr if it is a terminal (None otherwise)."""
    if not sys.stderr.isatty():
        return None
    bar = LineTimeProgress(sys.stderr, end, delay=BAR_DELAY)
    bar.show(0.0)  # the clock of the estimate starts here (nothing is drawn before BAR_DELAY)
    return bar


def _cmd_simulate(args: argparse.Namespace) -> int:
    start = args.start
    listing = '--list-keys' if args.list_keys else '--list-metrics' if args.list_metrics else None
    if args.samples is not None and listing is not None:
        raise ParameterError('--samples', args.samples, f'runs a Monte Carlo; {listing} lists and runs nothing')
    if start is not None:
        if args.list_keys:
            raise ParameterError('--from', start, 'starts the output of a run; --list-keys lists and runs nothing')
        if args.bag is not None:
            raise ParameterError(
                '--from', start, 'not with --bag: a bag is written from line time 0, as a live run records it'
            )
        if args.samples is not None:
            raise ParameterError('--from', start, 'not with --samples: a Monte Carlo sample runs from line time 0')
        summary.check_window(start, args.duration)
    if args.json:
        check_output_file(args.json, '--json')
    if args.bag is not None and args.samples is not None:
        raise ParameterError('--samples', args.samples, 'runs a Monte Carlo; --bag writes one run')
    if args.plots is not None:
        if args.samples is not None:
            raise ParameterError('--samples', args.samples, 'runs a Monte Carlo; --plots draws one run')
        if listing is not None:
            raise ParameterError('--plots', args.plots, f'draws a run; {listing} lists and runs nothing')
        import folder_line.cli.plots as plots  # the figures' modules and matplotlib: only --plots

        plots.check_plots(args.plots)
    if args.tune and args.samples is not None:
        raise ParameterError('--samples', args.samples, 'runs a Monte Carlo; --tune changes one run')
    if args.marker_rate is not None and args.bag is None:
        raise ParameterError('--marker-rate', args.marker_rate, 'draws the machine into a bag: only with --bag')
    for option, value in (('--max-bag-duration', args.max_bag_duration), ('--max-bag-size', args.max_bag_size)):
        if value is not None and args.bag is None:
            raise ParameterError(option, value, 'splits a bag: only with --bag')
    if args.samples is None:
        for option, value, default in (
            ('--workers', args.workers, None),
            ('--threads', args.threads, 1),
            ('--scheduler', args.scheduler, None),
        ):
            if value != default:
                raise ParameterError(option, value, 'runs the samples of a Monte Carlo: only with --samples')
    data = source_from(args)
    if args.samples is not None:
        return montecarlo.simulate_samples(args, data)
    scene = parse_scene(data)
    end = (start or 0.0) + args.duration
    tunings = check_tunings(scene, args.tune, end)
    if args.bag is not None:
        code, issued = batch_cli.write_bag(args, scene, tunings)
        if args.plots is not None:  # the line of the bag: under the commands its supervisor issued
            bar = _progress_bar(end)
            try:
                figures, _ = plots.collect(
                    scene, args.duration, commands=issued, progress=None if bar is None else bar.show
                )
            finally:
                if bar is not None:
                    bar.close()
            plots.write_figures(args.plots, figures)
        return code
    if args.list_keys:
        keys.print_keys(data, sys.stdout)
        return 0
    bar = _progress_bar(end)
    try:
        progress = None if bar is None else bar.show
        if args.plots is not None:  # one streamed run for the summary and the figures
            figures, result_summary = plots.collect(
                scene, args.duration, start=start, commands=tunings, progress=progress
            )
        else:
            result_summary = summary.line_summary(
                scene, args.duration, start=start, commands=tunings, progress=progress
            )
        if bar is not None:
            bar.show(end, force=True)
    finally:
        if bar is not None:
            bar.close()
    if tunings:
        result_summary['tunings'] = [
            {'t': tu.t, 'key': tu.key, 'value': tu.value, 'unit': TUNABLES[tu.key].unit} for tu in tunings
        ]
    if args.list_metrics:
        keys.print_metrics(result_summary, sys.stdout)
        return 0
    summary.print_summary(result_summary, sys.stdout)
    if args.json:
        dest = write_json_atomic(args.json, result_summary)
        print(f'wrote {dest}')
    if args.plots is not None:
        plots.write_figures(args.plots, figures)
    return 0


def _cmd_run(args: argparse.Namespace) -> int:
    if args.clock == 'wall' and args.rtf == 0.0:
        print(
            "folder-line: error: --rtf='max': needs --clock lockstep (the wall clock paces a wall run)", file=sys.stderr
        )
        return EXIT_USAGE
    cfg = RunConfig(
        scene=args.scene,
        duration=args.duration,
        overrides=tuple(args.overrides),
        rtf=args.rtf,
        out=Path(args.out),
        processes=args.processes,
        external=args.external_nodes,
        clock=args.clock,
        lost_timeout=args.lost_timeout,
        marker_rate=args.marker_rate,
        max_bag_duration=args.max_bag_duration or 0.0,
        max_bag_size=int(args.max_bag_size or 0),
    )
    from folder_line.ros import run as ros_run  # loads rclpy: only the run and monitor verbs need DDS

    with claim_output_dir(cfg.out, '--out', files=('run.json', SCENE_FILE), dirs=(BAG_DIR, 'logs')):
        result = ros_run.run_line(cfg, sys.stdout, NAMES)
    ros_run.print_run_summary(result.summary, cfg.out, sys.stdout)
    verdict = result.summary['outcome']
    if not verdict['ok']:
        print(f'folder-line: run failed: {verdict["message"]}', file=sys.stderr)
        return EXIT_RUN_FAILED
    return 0


def _cmd_monitor(args: argparse.Namespace) -> int:
    from folder_line.cli.monitor import run_monitor  # loads rclpy: only this verb needs DDS

    return run_monitor(rate=args.rate, once=args.once, window=args.window, timeout=args.timeout)


def _key_hint() -> str:
    """Which line key this process has: a closed line answers only a caller with its own."""
    from folder_line.ros.line_key import KEY_VARIABLE

    if os.environ.get(KEY_VARIABLE, '').strip():
        return f'with this {KEY_VARIABLE}'
    return f'and open? A line started by folder-line run is closed: give its {KEY_VARIABLE}'


def _cmd_operator(args: argparse.Namespace) -> int:
    from folder_line.ros.operator import call_command  # loads rclpy: only the verbs that use DDS need it

    answer = call_command(args.verb, timeout=args.timeout)
    if answer is None:
        domain = os.environ.get('ROS_DOMAIN_ID', '0') or '0'
        _error(
            f'{args.verb}: no supervisor answered /line/supervisor/{args.verb} on ROS domain {domain} within '
            f'{args.timeout:g} s (is the line running, on this domain, {_key_hint()}?)'
        )
        return EXIT_NO_ANSWER
    print(f'{args.verb}: {"accepted" if answer.accepted else "refused"}: {answer.message}')
    return 0 if answer.accepted else EXIT_REFUSED


def _cmd_tune(args: argparse.Namespace) -> int:
    from folder_line.ros.operator import call_tune, tunable_parameter  # loads rclpy: only the verbs that use DDS

    key, value = args.change
    answer = call_tune(key, value, timeout=args.timeout)
    if answer is None:
        domain = os.environ.get('ROS_DOMAIN_ID', '0') or '0'
        node, _ = tunable_parameter(key)
        _error(
            f'tune: node /{node} did not answer on ROS domain {domain} within {args.timeout:g} s '
            f'(is the line running, on this domain, {_key_hint()}?)'
        )
        return EXIT_NO_ANSWER
    print(f'tune: {"accepted" if answer.accepted else "refused"}: {answer.message}')
    return 0 if answer.accepted else EXIT_REFUSED


def _cmd_bag(args: argparse.Namespace) -> int:
    args.dir = str(bag_of(args.dir))  # a run folder stands for its bag
    if args.bag_verb == 'repair':
        bag = Path(args.dir)
        check_output_dir(bag, 'DIR', files=(METADATA_FILE,))  # before any claim touches a folder
        if bag.is_dir():
            repairable(bag)  # a folder that is no bag is refused before the claim's write probe goes into it
        with contextlib.ExitStack() as claims:  # the bag, and the run folder holding it: a run may be writing
            if bag.is_dir() and bag.resolve().name == BAG_DIR:
                claims.enter_context(claim_output_dir(bag.resolve().parent, 'DIR', create=False))
            claims.enter_context(claim_output_dir(bag, 'DIR', files=(METADATA_FILE,), create=False))
            result = repair(args.dir)
        print(f'repaired {args.dir}: {result.describe()}')
        print(f'wrote {result.metadata}')
        return 0
    if args.bag_verb == 'play':
        from folder_line.ros import player  # loads rclpy: only the verbs that use DDS need it

        played = player.play_bag(
            args.dir,
            rtf=args.rtf,
            start=args.start,
            duration=args.duration,
            topics=args.topics,
            loop=args.loop,
            stream=sys.stdout,
        )
        total = sum(played.published.values())
        how = 'stopped by Ctrl-C' if played.interrupted else 'done'
        print(
            f'{how}: {total} messages on {len(played.published)} topics, {played.passes} pass(es), '
            f'line time {played.line_time:.9g} s in {played.wall_time:.3f} s of wall time'
        )
        return 0
    for line in bag_info_lines(read_bag(args.dir)):
        print(line)
    return 0


def _cmd_report(args: argparse.Namespace) -> int:
    params = report_params(args.params, parse_set(args.overrides, InputNames(scene='--params', overrides='--set')))
    with claim_output_dir(args.out, '--out', REPORT_FILES) as out:
        write_report(out, sys.stdout, params)
    return 0


def _cmd_profile(args: argparse.Namespace) -> int:
    from folder_line.ros.dds_profile import line_partition, use_line_profile
    from folder_line.ros.line_key import KEY_VARIABLE

    env = dict(os.environ)
    if not env.get(KEY_VARIABLE, '').strip():
        _error(f'{KEY_VARIABLE} is not set: give the key of the line (folder-line run prints it)')
        return EXIT_USAGE
    env.pop('FASTDDS_DEFAULT_PROFILES_FILE', None)  # the line's own, not the one this shell may name
    env.pop('FASTRTPS_DEFAULT_PROFILES_FILE', None)
    path = use_line_profile(env)
    if path is None or line_partition(env) is None:
        _error(f'RMW_IMPLEMENTATION={env.get("RMW_IMPLEMENTATION")}: the line key needs rmw_fastrtps_cpp')
        return EXIT_USAGE
    print(path)
    return 0


def _cmd_scenes(args: argparse.Namespace) -> int:
    keys.print_scenes(sys.stdout)
    return 0


def _cmd_analyze(args: argparse.Namespace) -> int:
    animate_cli.check_animation_options(args)  # before any work: the video's target and options
    result = analyze(
        args.path,
        args.out,
        csv=args.csv,
        t_from=args.t_from,
        t_to=args.t_to,
        before_writing=lambda rec: animate_cli.check_recording_window(args, rec),
    )
    print_analysis(result, sys.stdout)
    if args.animate is not None:
        animate_cli.animate_recording(args, result.recording)
    return 0


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
        return f'{_OUTPUT_OPTION[args.verb]}: {reason}'
    path = str(exc.filename)
    label = ''
    for attr, option in _PATH_ARGUMENTS.items():
        given = getattr(args, attr, None)
        if isinstance(given, str) and given and (path == given or path.startswith(given.rstrip('/') + '/')):
            label = f'{option}: '
            break
    return f'{label}{path_repr(path)}: {reason}'


def _error(text: str) -> None:
    """Print ``text`` as one line on stderr (newlines folded, cut to :data:`_LINE_CHARS`)."""
    print(f'folder-line: error: {shorten(" ".join(text.split()), _LINE_CHARS)}', file=sys.stderr)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``folder-line``; returns the process exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    handler = {
        'kinematics': _cmd_kinematics,
        'simulate': _cmd_simulate,
        'run': _cmd_run,
        'monitor': _cmd_monitor,
        'report': _cmd_report,
        'bag': _cmd_bag,
        'analyze': _cmd_analyze,
        'bench': _cmd_bench,
        'optimize': optimize.run,
        'sweep': sweep_verb.run,
        'solve': solve_verb.run,
        'scenes': _cmd_scenes,
        'layout': layout_verb.run,
        'profile': _cmd_profile,
        'animate': animate_cli.run,
        **dict.fromkeys(OPERATOR_COMMANDS, _cmd_operator),
        'tune': _cmd_tune,
    }[args.verb]
    try:
        return handler(args)
    except OutputError as exc:
        _error(str(exc.with_option(_OUTPUT_OPTION[args.verb])))
        return EXIT_USAGE
    except FolderLineError as exc:
        _error(str(exc))
        return EXIT_USAGE
    except BrokenPipeError:  # the reader of stdout went away (`| head`): nothing to say, and no one to say it to
        with contextlib.suppress(OSError):
            sys.stdout = open(os.devnull, 'w')  # noqa: SIM115 - the interpreter flushes it at exit
        return EXIT_BROKEN_PIPE
    except OSError as exc:  # the OS refused to open, read or write a path deep inside a verb
        _error(_os_error_text(args, exc))
        return EXIT_USAGE
    except KeyboardInterrupt:
        return 130


if __name__ == '__main__':
    sys.exit(main())
