"""``folder-line simulate --plots DIR``: the figures of ``analyze`` from the batch model, without ROS.

The batch run is written as the bag a live lockstep run would record
(:func:`folder_line.bag.batch.write_batch_bag`, into a temporary folder unless ``--bag``
names one) and that bag is drawn by the very code ``analyze`` uses
(:func:`folder_line.analysis.recording.read_recording`,
:func:`folder_line.analysis.replay.evaluate`,
:func:`folder_line.analysis.figures.draw_figures`). So ``simulate --plots`` draws what
``analyze`` of that run would draw, pixel for pixel (``test/cli/test_plots.py``).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

from folder_line.analysis.figure_data import GANTT_CYCLES
from folder_line.analysis.figures import FIGURES, draw_figures
from folder_line.analysis.recording import read_recording
from folder_line.analysis.replay import evaluate
from folder_line.bag.batch import write_batch_bag
from folder_line.core.line.scene import Scene
from folder_line.core.line.tuning import Tuning
from folder_line.files.atomic import check_output_dir, claim_output_dir

__all__ = ['OPTION', 'check_plots', 'write_plots']

#: the option naming the folder
OPTION = '--plots'


def check_plots(path: str) -> None:
    """Refuse a ``--plots`` folder before any work: not a folder, or holding something other than the figures."""
    check_output_dir(path, OPTION, files=tuple(FIGURES))


def write_plots(
    args: argparse.Namespace, scene: Scene, bag: str | None = None, tunings: Sequence[Tuning] = ()
) -> dict[str, Path]:
    """Draw ``analyze``'s figures of ``scene`` over ``args.duration`` into ``args.plots``; print each file.

    Parameters
    ----------
    args : argparse.Namespace
        ``plots`` (the folder), ``duration``, ``scene`` and ``overrides``.
    scene : Scene
        The scene, parsed.
    bag : str, optional
        A bag of this run already written (``simulate --bag``); else one is written to a
        temporary folder and removed.
    tunings : sequence of Tuning
        The run's ``--tune`` changes.

    Returns
    -------
    dict of str to Path
        Figure name -> file written.

    Raises
    ------
    folder_line.errors.OutputError
        The folder cannot be claimed.
    folder_line.errors.ParameterError
        ``--duration`` is not a whole number of ticks.
    """
    with tempfile.TemporaryDirectory(prefix='folder-line-plots-') as tmp:
        if bag is None:
            bag = str(Path(tmp) / 'bag')
            # the figures draw no markers
            write_batch_bag(bag, scene, args.duration, tunings=tunings, marker_rate=0.0)
        rec = read_recording(bag)
        ev = evaluate(rec)
        with claim_output_dir(args.plots, OPTION, files=tuple(FIGURES)) as out:
            figures = draw_figures(rec, ev, out, GANTT_CYCLES)
    for path in figures.values():
        print(f'wrote {path}', file=sys.stdout)
    return figures
