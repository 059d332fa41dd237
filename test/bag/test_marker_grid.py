"""The grid of ``/line/markers`` (``round(i · 1e9 / rate)`` ns): its closed form, and the extreme rates the
range admits (a rate so low that its second point overflows draws the first only, not an ``OverflowError``)."""

from __future__ import annotations

from pathlib import Path

import pytest

from folder_line.bag.markers import marker_stamps
from folder_line.cli.main import main


@pytest.mark.parametrize('rate', [5.0, 3.0, 0.7, 1000.0])
def test_the_grid_is_its_closed_form(rate: float) -> None:
    until = 4_000_000_000
    want = [round(i * 1e9 / rate) for i in range(100_000) if round(i * 1e9 / rate) <= until]
    assert list(marker_stamps(None, until, rate)) == want
    after = want[len(want) // 2]
    assert list(marker_stamps(after, until, rate)) == [s for s in want if s > after]


@pytest.mark.parametrize('rate', [5e-324, 1e-300, 1e-9])
def test_a_rate_too_low_for_a_second_point_draws_the_first_only(rate: float) -> None:
    assert list(marker_stamps(None, 10**16, rate)) == [0]
    assert list(marker_stamps(0, 10**16, rate)) == []


def test_no_grid_at_rate_0() -> None:
    assert list(marker_stamps(None, 10**9, 0.0)) == []


def test_simulate_with_the_least_marker_rate_writes_its_bag(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = tmp_path / 'bag'
    argv = ['simulate', '--scene', 'folder', '--duration', '0.5', '--bag', str(bag), '--marker-rate', '5e-324']
    assert main(argv) == 0, capsys.readouterr().err
    assert '/line/markers' in (bag / 'metadata.yaml').read_text()
