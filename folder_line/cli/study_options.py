"""Options the design-study verbs share: the scene, the line time, ``--set`` and where the work runs."""

from __future__ import annotations

import argparse
import contextlib
import shlex
from collections.abc import Iterable, Iterator

from folder_line.cli.arg_types import limited, number
from folder_line.config.scenes import InputNames, SceneMapping, parse_set, scene_mapping
from folder_line.core.limits import DURATION
from folder_line.errors import OutputError, ParameterError
from folder_line.studies.montecarlo import MARGIN_SAMPLE, MAX_SAMPLES
from folder_line.studies.runner import Cluster

__all__ = [
    'add_cluster_arguments',
    'add_samples_argument',
    'add_scene_arguments',
    'cluster_from',
    'command_text',
    'scheduler_reached',
    'source_from',
]

#: the scene loader's inputs in the command line's words
NAMES = InputNames(scene='--scene', overrides='--set')


def add_scene_arguments(
    parser: argparse.ArgumentParser, duration: float | None, scene: str = 'folder', per: str = ''
) -> None:
    """``--scene`` (default ``scene``), ``--duration`` (default ``duration``; simulated ``per`` evaluation,
    e.g. 'at every point'; None: no ``--duration``) and the repeatable ``--set``: the options of every verb
    that runs a scene."""
    each = f' {per}' if per else ''
    parser.add_argument(
        '--scene',
        default=scene,
        metavar='NAME|FILE',
        help=f'a shipped scene (folder-line scenes lists them) or a scene YAML file (default {scene})',
    )
    if duration is not None:
        parser.add_argument(
            '--duration',
            type=limited('--duration', DURATION),
            default=duration,
            metavar='S',
            help=f'line time simulated{each}, s (default {duration:g})',
        )
    parser.add_argument(
        '--set',
        dest='overrides',
        action='append',
        default=[],
        metavar='SECTION.KEY=VALUE',
        help=f'override a scene value{each}, e.g. feed_transporter.V_tr=9.5 or press.n_c=30000 '
        '(repeatable; simulate --list-keys lists the keys)',
    )


def add_cluster_arguments(parser: argparse.ArgumentParser) -> None:
    """``--workers``, ``--threads``, ``--scheduler``: where the simulations run (:class:`Cluster`)."""
    parser.add_argument(
        '--workers',
        type=number('--workers', whole=True),
        default=None,
        metavar='K',
        help='local Dask worker processes (default: one per core of this machine)',
    )
    parser.add_argument(
        '--threads',
        type=number('--threads', whole=True),
        default=1,
        metavar='T',
        help='threads per local worker (default 1)',
    )
    parser.add_argument(
        '--scheduler',
        default=None,
        metavar='ADDRESS',
        help='run on an existing Dask cluster (tcp://HOST:8786) instead of local workers',
    )


def add_samples_argument(parser: argparse.ArgumentParser, what: str) -> None:
    """``--samples N``: Monte Carlo over the scene's variation effects (:mod:`folder_line.studies.montecarlo`)."""
    parser.add_argument(
        '--samples',
        type=number('--samples', 1, MAX_SAMPLES, whole=True),
        default=None,
        metavar='N',
        help=f'Monte Carlo: N runs {what} with seeds drawn from the scene seed; per constraint the violation '
        'probability with its 95 %% interval and the margin distribution (count, mean, std, extremes exact; '
        f'quantiles of every margin, or of a uniform random sample of {MARGIN_SAMPLE} once there are more)',
    )


def cluster_from(args: argparse.Namespace) -> Cluster:
    """The :class:`Cluster` the options name (ParameterError naming a bad one)."""
    return Cluster(workers=args.workers, threads=args.threads, scheduler=args.scheduler)


@contextlib.contextmanager
def scheduler_reached(cluster: Cluster) -> Iterator[None]:
    """Name ``--scheduler`` when the cluster it gives cannot be reached (an OS error or a time-out while
    connecting), instead of the verb's output."""
    try:
        yield
    except OSError as exc:
        if cluster.scheduler is None or isinstance(exc, OutputError):
            raise
        raise ParameterError('--scheduler', cluster.scheduler, f'cannot reach it: {exc}') from None


def source_from(args: argparse.Namespace) -> SceneMapping:
    """The complete scene mapping of ``--scene`` with ``--set`` applied (not yet validated)."""
    return scene_mapping(args.scene, parse_set(args.overrides, NAMES), names=NAMES)


def command_text(verb: str, args: argparse.Namespace, options: Iterable[tuple[str, str]]) -> str:
    """The command line that reproduces a study: ``folder-line VERB`` and each ``(option, attribute)`` given."""
    words = ['folder-line', verb]
    for option, attr in options:
        value = getattr(args, attr, None)
        for item in value if isinstance(value, list) else [value]:
            if item is not None:
                words += [option, str(item)]
    return shlex.join(words)
