"""``folder-line simulate --bag DIR``: the bag of a live lockstep run, written from the batch model."""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from folder_line.bag.batch import check_duration, write_batch_bag
from folder_line.bag.metadata import files_text
from folder_line.config.run_config import MARKER_RATE
from folder_line.core.line.scene import Scene
from folder_line.core.line.tuning import LineCommand, Tuning, command_of
from folder_line.errors import OutputError
from folder_line.files.atomic import LOCK_FILE, claim_output_dir
from folder_line.progress import LineTimeProgress

__all__ = ['write_bag']


def write_bag(
    args: argparse.Namespace, scene: Scene, tunings: Sequence[Tuning] = ()
) -> tuple[int, tuple[LineCommand, ...]]:
    """Write ``args.bag`` for ``scene`` and ``args.duration``; print what was written.

    The folder must be missing or empty: a bag is never written over anything (checked, with the
    duration, before any work). A progress bar of the line time written, with the wall time left,
    goes to stderr.

    Returns
    -------
    (int, tuple of Command or Tuning)
        The exit code (0) and the commands the bag's supervisor issued (drive commands and the
        tunings, by effective time): the line of the bag is the line under them.

    Raises
    ------
    folder_line.errors.OutputError
        ``--bag`` is not a folder, is not empty, or is held by another process.
    folder_line.errors.ParameterError
        ``--duration`` is not a whole number of ticks.
    """
    check_duration(scene, args.duration)
    bag = Path(args.bag)
    if bag.is_dir() and any(bag.iterdir()):
        raise OutputError('--bag', str(bag), 'is a folder that is not empty; a bag is written to a new or empty one')
    t0 = time.perf_counter()
    bar = LineTimeProgress(sys.stderr, args.duration)
    try:
        with claim_output_dir(bag, '--bag'):
            try:
                result = write_batch_bag(
                    bag,
                    scene,
                    args.duration,
                    custom={
                        'folder_line.scene_arg': str(args.scene),
                        'folder_line.overrides': json.dumps(args.overrides),
                    },
                    progress=bar.show,
                    tunings=tunings,
                    marker_rate=MARKER_RATE if args.marker_rate is None else args.marker_rate,
                    max_duration_s=args.max_bag_duration or 0.0,
                    max_size=int(args.max_bag_size or 0),
                )
            except OSError as exc:  # a full disk: the folder was new or empty, and is left so
                if isinstance(exc, OutputError):
                    raise
                _empty(bag)
                raise OutputError('--bag', str(bag), f'cannot write: {exc.strerror or exc}') from None
    except OutputError as exc:  # a write refused inside the bag: name --bag, not the verb's --json
        raise exc.with_option('--bag') from None
    finally:
        bar.close()
    wall = time.perf_counter() - t0
    total = sum(result.counts.values())
    print(
        f'scene {scene.name}: {args.duration:g} s of line time, {total} messages in {wall:.1f} s '
        f'(no DDS; supervisor {result.state}, {len(result.commands)} drive commands and tunings)',
        file=sys.stdout,
    )
    for topic, n in sorted(result.counts.items()):
        print(f'  {topic:<40} {n}')
    print(f'wrote {result.path} ({files_text(result.files)})')
    return 0, tuple(command_of(t, kind) for t, kind in result.commands)


def _empty(bag: Path) -> None:
    """Remove what the bag writer left in ``bag`` (new or empty before it, and claimed): its files, never the
    claim's lock."""
    for entry in bag.iterdir():
        if entry.name != LOCK_FILE and entry.is_file():
            entry.unlink(missing_ok=True)
