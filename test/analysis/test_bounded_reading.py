"""``read_recording`` keeps the joint states to a bounded thinning, and what the analysis computes does not change.

An hour of ``line`` is 2.9 million joint-state messages; the figures draw a few thousand.
The reader keeps a pseudo-random 1/2**k of the ticks (a hash of the stamp), the same
ticks on every node, and counts every sample with its extremes.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from folder_line.analysis import exit_speed_data
from folder_line.analysis.recording import Recording, read_recording
from folder_line.analysis.replay import evaluate
from folder_line.analysis.supervisor_replay import recorded_transitions
from folder_line.bag.metadata import segment_files
from folder_line.cli.main import main
from folder_line.interfaces import NS_PER_S, SUPERVISOR_STATE_TOPIC

CAP = 100


@pytest.fixture(scope='module')
def line_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """8 s of ``line`` (every machine and effect, four joint-state nodes at 200 Hz) from ``simulate --bag``."""
    bag = tmp_path_factory.mktemp('thin') / 'bag'
    assert main(['simulate', '--scene', 'line', '--duration', '8', '--bag', str(bag)]) == 0
    return bag


@pytest.fixture(scope='module')
def whole(line_bag: Path) -> Recording:
    return read_recording(line_bag, joint_samples=10**6)


@pytest.fixture(scope='module')
def thinned(line_bag: Path) -> Recording:
    return read_recording(line_bag, joint_samples=CAP)


def test_every_sample_is_kept_under_the_cap(whole: Recording) -> None:
    assert set(whole.joints) == {'crank_drive', 'belt_conveyor', 'feed_transporter', 'sheet_counter'}
    for j in whole.joints.values():
        assert j.fraction == 1.0 and j.count == j.t.size == 1601  # 0 .. 8 s at 200 Hz
        assert np.all(np.diff(j.t) > 0)


def _splitmix64(x: int) -> int:
    """splitmix64, written out with Python integers (the reader's is numpy's uint64 arithmetic)."""
    mask = (1 << 64) - 1
    z = (x + 0x9E3779B97F4A7C15) & mask
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & mask
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & mask
    return z ^ (z >> 31)


def test_sampling_keeps_the_same_pseudo_random_ticks_on_every_node(whole: Recording, thinned: Recording) -> None:
    fractions = {j.fraction for j in thinned.joints.values()}
    assert len(fractions) == 1
    (fraction,) = fractions
    level = round(-math.log2(fraction))
    assert level >= 1 and fraction == 0.5**level
    kept_t = None
    for node, full in whole.joints.items():
        j = thinned.joints[node]
        assert j.count == full.count and 0 < j.t.size <= CAP, node
        stamps = [round(t * NS_PER_S) for t in full.t.tolist()]
        chosen = np.array([_splitmix64(t) >> (64 - level) == 0 for t in stamps])
        np.testing.assert_array_equal(j.t, full.t[chosen])
        np.testing.assert_array_equal(j.position, full.position[chosen])
        np.testing.assert_array_equal(j.velocity, full.velocity[chosen])
        assert (j.effort is None) == (full.effort is None), node
        if j.effort is not None and full.effort is not None:
            np.testing.assert_array_equal(j.effort, full.effort[chosen])
        # the extremes are every sample's, not only the kept ones'
        for row, data in enumerate((full.position, full.velocity, full.effort)):
            if data is not None and data.size:
                np.testing.assert_array_equal(j.low[row], data.min(axis=0))
                np.testing.assert_array_equal(j.high[row], data.max(axis=0))
        if kept_t is None:
            kept_t = j.t
        np.testing.assert_array_equal(j.t, kept_t)  # every node keeps the same ticks
    # the fraction is no smaller than needed: twice it would have kept more than half the cap
    coarser = sum(_splitmix64(round(t * NS_PER_S)) >> (64 - level + 1) == 0 for t in whole.joints['crank_drive'].t)
    assert coarser > CAP // 2
    # no pattern in time: the kept ticks spread over the run, and their gaps are not one stride
    assert kept_t is not None
    assert np.unique(np.floor(kept_t / 2.0)).tolist() == [0, 1, 2, 3]  # in every quarter of the 8 s
    assert np.unique(np.round(np.diff(kept_t) * 200)).size > 10


def test_the_extent_of_a_joint(whole: Recording) -> None:
    belts = whole.joints['belt_conveyor']
    v = belts.column('chute_belts', 'velocity')
    assert belts.extent('chute_belts', 'velocity') == (float(v.min()), float(v.max()))
    with pytest.raises(KeyError, match='no joint'):
        belts.extent('nothing')


def test_the_analysis_does_not_depend_on_the_thinning(whole: Recording, thinned: Recording) -> None:
    a, b = evaluate(whole), evaluate(thinned)
    assert a.summary == b.summary
    np.testing.assert_array_equal(whole.events, thinned.events)
    data = exit_speed_data(thinned)
    assert data is not None and data['t'].size == thinned.joints['crank_drive'].t.size  # the belts' ticks matched


def test_the_states_kept_are_the_changes(line_bag: Path, whole: Recording) -> None:
    """Read independently (mcap + mcap_ros2): every state message; the recording keeps the first and each change."""
    states = []
    for path in segment_files(line_bag):
        with path.open('rb') as fh:
            reader = make_reader(fh, decoder_factories=[DecoderFactory()])
            for _, _, message, ros in reader.iter_decoded_messages(topics=[SUPERVISOR_STATE_TOPIC]):
                states.append((message.log_time, str(ros.data)))
    assert len(states) == 1601
    changes = [s for i, s in enumerate(states) if i == 0 or s[1] != states[i - 1][1]]
    assert whole.states == changes
    assert len(changes) >= 2  # STARTING, then EXECUTE
    assert recorded_transitions(whole.states) == recorded_transitions(states)


def test_joint_states_are_read_from_t_from(line_bag: Path, whole: Recording) -> None:
    late = read_recording(line_bag, t_from=5.0)
    for node, full in whole.joints.items():
        j = late.joints[node]
        assert j.count == int(np.count_nonzero(full.t >= 5.0)) and j.t[0] == 5.0, node
    assert late.events.size == whole.events.size  # the replay still needs every event


def test_the_figures_say_how_the_samples_were_thinned(whole: Recording, thinned: Recording) -> None:
    from folder_line.analysis.figures import _sampling

    assert _sampling(whole.joints['crank_drive']) == '1601 recorded samples'
    j = thinned.joints['crank_drive']
    assert (
        _sampling(j)
        == f'1601 recorded samples ({j.t.size} drawn: the ticks of a pseudo-random 1/{round(1 / j.fraction)})'
    )
