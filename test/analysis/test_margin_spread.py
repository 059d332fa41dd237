"""With arrival jitter, ``analyze``'s margin histograms show a spread (no DDS: a recording made from the batch model).

The analysis judges a run's recorded events with the core's constraint code
(:func:`folder_line.analysis.replay.evaluate`) and bins each constraint's margins for
``margins.png`` (``figures._margin_bins``). Fed the batch model's events of the folder,
the feed-window margins fall in one bar without jitter (every cycle is identical) and
spread over many bins with it.
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

DURATION = 6.0


def _recording(sigma: float | None) -> Recording:
    data = copy.deepcopy(scene_mapping('folder'))
    if sigma is not None:
        data['effects']['arrival_jitter'] = {'distribution': 'normal', 'sigma': sigma}
    scene = parse_scene(data)
    result = simulate(scene, DURATION)
    return Recording(
        bag=None,
        run=None,
        scene=scene,
        t_end=DURATION,
        horizon=DURATION,
        events=result.events,
        event_ns=np.round(result.events['t'] * 1e9).astype(np.int64),
        joints={},
        states=[],
        commands=(),
        sheet_count=None,
        landing_x=np.zeros(0),
        bad_events=0,
    )


def _occupied_bins(sigma: float | None) -> int:
    ev = evaluate(_recording(sigma))
    fw = next(c for c in ev.constraints if c.name == 'feed_window')
    edges = figures._margin_bins(fw.margin * 1e3, fw.unit)
    counts, _ = np.histogram(fw.margin * 1e3, bins=edges)
    assert counts.sum() == fw.margin.size > 70
    return int(np.count_nonzero(counts))


def test_without_jitter_the_margins_are_one_bar() -> None:
    assert _occupied_bins(None) == 1


@pytest.mark.parametrize('sigma', [0.5, 1.0])
def test_with_jitter_the_margins_spread(sigma: float) -> None:
    assert _occupied_bins(sigma) >= 10
