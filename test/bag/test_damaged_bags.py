"""Bags that tell the truth after damage: a repair names the line time lost, ``analyze`` judges nothing across it.

A bag of 6 s of line time, split every second (``--max-bag-duration 1``: seven files, each in chunks
of 0.1 s), is damaged in its third file in one of three ways: the file deleted, the file cut in half,
16 bytes of a chunk flipped. Before the repair, reading the flipped chunk is refused in one line naming the repair.
``bag repair`` then records the gap (``folder_line.gaps``; the bag is ``repaired``, never
``complete``), ``bag info`` names it, every file opens in the independent ``mcap`` reader
with its checksums checked, and ``analyze`` reports no violation, leaves the cycles around
the gap unjudged, replays the supervisor up to the gap, and finds every event it judges to be
the line model's. The undamaged bag is the control: no gap, every cycle judged.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from _ros_env import REPO, node_environment
from mcap.reader import make_reader

from folder_line.analysis.report import analyze
from folder_line.bag.gaps import KEY_GAPS, read_gaps
from folder_line.bag.metadata import KEY_COMPLETE
from folder_line.bag.reader import read_bag
from folder_line.bag.repair import repair
from folder_line.cli import main as cli
from folder_line.core.types.events import event_kind
from folder_line.interfaces import NS_PER_S

DURATION = 6.0
DAMAGED = 2  # the segment damaged: [2, 3) s of line time


def folder_line(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, '-m', 'folder_line.cli.main', *args],
        env=node_environment(),
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=300,
    )


@pytest.fixture(scope='module', params=['folder', 'line'])
def intact(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Path:
    bag = tmp_path_factory.mktemp(request.param) / 'bag'
    assert (
        cli.main(
            [
                'simulate',
                '--scene',
                request.param,
                '--duration',
                str(DURATION),
                '--bag',
                str(bag),
                '--max-bag-duration',
                '1',
            ]
        )
        == 0
    )
    return bag


def damage(bag: Path, how: str) -> tuple[int, int]:
    """Damage the third segment; the log-time span of its messages, ns."""
    (path,) = bag.glob(f'*_{DAMAGED}.mcap')
    with path.open('rb') as fh:
        stats = make_reader(fh).get_summary().statistics  # type: ignore[union-attr]
    span = (stats.message_start_time, stats.message_end_time)
    data = bytearray(path.read_bytes())
    if how == 'missing':
        path.unlink()
    elif how == 'truncated':
        path.write_bytes(data[: len(data) // 2])
    else:  # 16 bytes of the data of a chunk in the middle of the file
        at = len(data) // 3
        data[at : at + 16] = bytes(b ^ 0xFF for b in data[at : at + 16])
        path.write_bytes(data)
    return span


@pytest.mark.parametrize('how', ['missing', 'truncated', 'flipped'])
def test_a_repair_names_the_gap_and_analyze_judges_nothing_across_it(intact: Path, tmp_path: Path, how: str) -> None:
    bag = tmp_path / 'bag'
    shutil.copytree(intact, bag)
    first, last = damage(bag, how)

    if how == 'flipped':  # before the repair: refused in one line, no traceback
        refused = folder_line('analyze', str(bag), '--out', str(tmp_path / 'refused'))
        assert refused.returncode == 2 and 'Traceback' not in refused.stderr, refused.stderr
        (line,) = refused.stderr.strip().splitlines()
        assert 'checksum' in line and f'folder-line bag repair {bag}' in line, line
        assert not (tmp_path / 'refused' / 'report.md').exists()

    repaired = folder_line('bag', 'repair', str(bag))
    assert repaired.returncode == 0, repaired.stderr
    assert 'a gap of' in repaired.stdout, repaired.stdout
    contents = read_bag(bag)
    assert contents.custom[KEY_COMPLETE] == 'repaired'  # never "complete (closed by its writer)"
    (gap,) = contents.gaps
    assert gap.first_ns <= last and gap.last_ns >= first  # the lost messages lie in the gap
    if how == 'missing':  # the old metadata said where the file was
        assert (gap.first_ns, gap.last_ns) == (first, last)
    assert gap.first_ns >= DAMAGED * NS_PER_S and gap.last_ns < (DAMAGED + 1) * NS_PER_S
    info = folder_line('bag', 'info', str(bag))
    state = next(line for line in info.stdout.splitlines() if line.startswith('state'))
    assert f'repaired with a gap of {gap.seconds:.3f} s at {gap.first_ns / NS_PER_S:.3f} s' in state, info.stdout
    assert any(line.startswith('gap ') for line in info.stdout.splitlines())
    for path in sorted(bag.glob('*.mcap')):  # what is listed reads whole, checksums checked, independently
        with path.open('rb') as fh:
            assert sum(1 for _ in make_reader(fh, validate_crcs=True).iter_messages()) > 0

    again = folder_line('bag', 'repair', str(bag))  # a second repair keeps what the first found
    assert again.returncode == 0 and read_bag(bag).gaps == [gap]

    result = analyze(bag, out=tmp_path / 'analysis')
    s = result.summary
    assert s.violations.count == 0  # nothing invented: no missing sheet, no release never made
    assert s.unjudged and s.gaps == [gap]
    assert s.replay_matches and [t.target for t in s.transitions] == ['EXECUTE']
    assert result.events_check.agree  # every event judged is the line model's
    assert 'a repaired bag with a gap of' in result.report.read_text()
    unjudged = result.recording.unjudged
    kept = result.recording.events
    assert not set(kept['cycle'][kept['kind'] == event_kind('knife_contact')].tolist()) & set(
        unjudged.cycles.tolist()
    )  # no contact judged
    # the control: the whole bag, every cycle judged
    whole = analyze(intact, out=tmp_path / 'whole').summary
    assert whole.gaps == [] and whole.unjudged == '' and whole.violations.count == 0
    assert s.cycles == whole.cycles - unjudged.cycles.size


def test_gaps_that_are_not_gaps_are_refused_in_one_line(tmp_path: Path) -> None:
    from folder_line.errors import BagError

    for text in ('[[2, 1]]', '[[1.5, 2]]', '{"a": 1}', '[[true, 2]]', 'nope', '[[1, 2, 3]]', '[5]', '[[-1, 2]]'):
        with pytest.raises(BagError, match=KEY_GAPS):
            read_gaps({KEY_GAPS: text})
    assert read_gaps({KEY_GAPS: json.dumps([[5, 9], [1, 2], [3, 4]])})[0].first_ns == 1


def test_a_repair_names_recorded_gaps_it_cannot_read(intact: Path, tmp_path: Path) -> None:
    """Gaps in the old metadata.yaml that are not gaps are not kept, and the repair says so."""
    bag = tmp_path / 'bag'
    shutil.copytree(intact, bag)
    metadata = bag / 'metadata.yaml'
    text = metadata.read_text()
    assert '\n  custom_data:\n' in text
    metadata.write_text(text.replace('\n  custom_data:\n', f"\n  custom_data:\n    {KEY_GAPS}: '[[2, 1]]'\n", 1))
    result = repair(bag)
    assert result.gaps == [] and result.unreadable.startswith(f'custom_data {KEY_GAPS}=')
    assert 'the old gaps could not be read, and were not kept' in result.describe()
