"""With arrival jitter, ``analyze``'s margin histograms show a spread (no DDS: a recording made from the batch model).

The analysis judges a run's recorded events with the core's constraint code
(:func:`folder_line.analysis.replay.evaluate`) and bins each constraint's margins for
``margins.png`` as the windows pass (``figures.margin_bars``). Fed the batch model's events of
the folder, the feed-window margins fall in one bar without jitter (every cycle is identical)
and spread over many bins with it.
"""

from __future__ import annotations

import copy

import numpy as np
import pytest

from folder_line.analysis import figures
from folder_line.analysis.recording import Recording
from folder_line.analysis.replay import evaluate
from folder_line.config.scenes import scene_mapping
from folder_line.core.line.model import simulate
from folder_line.core.line.scene import parse_scene

from ._events_only import events_recording

DURATION = 6.0


def _recording(sigma: float | None) -> Recording:
    data = copy.deepcopy(scene_mapping('folder'))
    if sigma is not None:
        data['effects']['arrival_jitter'] = {'distribution': 'normal', 'sigma': sigma}
    scene = parse_scene(data)
    result = simulate(scene, DURATION)
    return events_recording(scene, result.events, DURATION)


def _occupied_bins(sigma: float | None) -> int:
    rec = _recording(sigma)
    ev = evaluate(rec)
    fw = ev.margins['feed_window']
    edges, passed, violated = figures.margin_bars(fw)
    counts = passed + violated
    assert counts.sum() == fw.tally.evaluations > 70
    # the bars of every margin at once, binned directly, are the streamed ones
    judged = simulate(rec.scene, DURATION, sample_rate=0.0).constraint('feed_window').margin
    assert fw.histogram.low == judged.min() and fw.histogram.high == judged.max()
    if edges.size > 2:  # a margin within one bin of the streamed grid of a bar's edge may be counted beside it
        direct, _ = np.histogram(judged, bins=edges)
        width = 2.0**fw.histogram.exponent
        near = np.min(np.abs(judged[:, None] - edges[None, 1:-1]), axis=1) < width
        assert np.abs(direct - counts).sum() <= 2 * int(np.count_nonzero(near))
    return int(np.count_nonzero(counts))


def test_without_jitter_the_margins_are_one_bar() -> None:
    assert _occupied_bins(None) == 1


@pytest.mark.parametrize('sigma', [0.5, 1.0])
def test_with_jitter_the_margins_spread(sigma: float) -> None:
    assert _occupied_bins(sigma) >= 10
