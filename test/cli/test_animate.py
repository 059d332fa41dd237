"""``folder-line animate`` and ``analyze --animate``: frame counts decoded independently, overlays, bad input."""

from __future__ import annotations

import itertools
import os
from pathlib import Path

import imageio_ffmpeg
import numpy as np
import pytest

from folder_line.analysis.animation import (
    MAX_FRAMES,
    Flag,
    Timeline,
    TimeScale,
    batch_run,
    encode,
    frame_count,
    recorded_run,
)
from folder_line.analysis.recording import read_recording
from folder_line.cli.main import main
from folder_line.config.scenes import scene_mapping
from folder_line.core.line.model import simulate
from folder_line.core.line.scene import parse_scene
from folder_line.core.line.tuning import Tuning

#: small and quick: 2 s of line at 10 frames/s, 2 video s per line s -> 40 frames of 160x96
FAST = ['--fps', '10', '--slowdown', '2', '--size', '160x96']
#: the folder fed at the printing speed: feed_window violated from cycle 0 on, held at once
LATE = ['--scene', 'folder', '--set', 'feed_transporter.V_tr=5.8333']


def _code(argv: list[str]) -> int | str | None:
    """``main``'s exit code, a usage error's too (argparse exits)."""
    try:
        return main(argv)
    except SystemExit as exc:
        return exc.code


def _decoded(path: Path) -> list[np.ndarray]:
    """Every frame of a video as ffmpeg decodes it (imageio-ffmpeg's reader, not our writer)."""
    gen = imageio_ffmpeg.read_frames(str(path))
    meta = next(gen)
    w, h = meta['size']
    return [np.frombuffer(f, dtype=np.uint8).reshape(h, w, 3) for f in gen]


def test_the_frame_count_formula() -> None:
    assert frame_count(2.0, 25.0, 10.0) == 500  # 2 x 25 x 10 is whole: no frame lost to rounding
    assert frame_count(0.072, 25.0, 10.0) == 18
    scale = TimeScale(1.0, 2.0, 25.0, 10.0)
    assert scale.dt == pytest.approx(0.004)
    times = scale.times()
    assert times.size == 500 and times[0] == 1.0 and times[-1] == pytest.approx(2.996)


@pytest.mark.parametrize('ext', ['mp4', 'gif'])
def test_two_seconds_of_line_have_the_expected_frames(
    ext: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / f'line.{ext}'
    assert main(['animate', '--scene', 'line', '--duration', '2', *FAST, '--out', str(out)]) == 0
    expected = 2 * 10 * 2
    assert imageio_ffmpeg.count_frames_and_secs(str(out)) == (expected, pytest.approx(4.0))
    frames = _decoded(out)
    assert len(frames) == expected
    assert frames[0].shape == (96, 160, 3)
    moving = [not np.array_equal(a, b) for a, b in itertools.pairwise(frames)]
    assert sum(moving) >= expected - 2  # the machine moves (and the time in the overlay changes) every frame
    text = capsys.readouterr()
    assert f'wrote {out} ({expected} frames, 160x96' in text.out
    assert 'of line time' in text.err  # the progress bar
    assert [p.name for p in tmp_path.iterdir()] == [out.name]  # no temporary file left


def test_the_overlay_says_what_the_supervisor_did() -> None:
    scene = parse_scene(scene_mapping('folder', {'feed_transporter.V_tr': 5.8333}))
    scale = TimeScale(0.0, 1.0, 25.0, 10.0)
    shown = batch_run(scene, scale)
    # the first knife contact judges cycle 0 late: hold, the drive brakes, HELD at standstill
    assert [s for _, s in shown.states] == ['STARTING', 'EXECUTE', 'HOLDING', 'HELD']
    t_hold = shown.states[2][0]
    first = shown.timeline.text(t_hold)
    assert first.state == 'HOLDING'
    assert first.cycle == 'knife cycle 0'
    assert any(v.startswith('feed_window -14.59') and v.endswith('ms (cycle 0)') for v in first.violations)
    assert shown.timeline.text(t_hold - 1e-6).violations == ()
    held = shown.timeline.text(shown.states[3][0] + 0.01)
    assert held.state == 'HELD' and held.violations == () and held.count == len(shown.flags) > 0
    assert shown.timeline.text(0.0).time == 't = 0.000 s'
    assert shown.timeline.text(0.0).cycle == 'before knife cycle 0'


def test_a_tuning_is_animated_as_simulate_runs_it() -> None:
    """``animate --tune``: the supervisor holds at the first cycle simulate says is violated under the change."""
    scene = parse_scene(scene_mapping('folder', {}))
    tuning = Tuning(0.5, 'feed_transporter.V_tr', 6.0)
    shown = batch_run(scene, TimeScale(0.0, 1.5, 25.0, 10.0), tunings=[tuning])
    assert [s for _, s in shown.states] == ['STARTING', 'EXECUTE', 'HOLDING', 'HELD']
    assert tuning in shown.model.commands
    batch = simulate(scene, 1.5, sample_rate=0.0, commands=[tuning])
    first = min((int(c.cycle[c.violated][0]), c.name) for c in batch.constraints if c.violated.any())
    assert (shown.flags[0].index, shown.flags[0].constraint) == first
    assert not batch_run(scene, TimeScale(0.0, 1.5, 25.0, 10.0)).flags  # without it, nothing is violated


def test_a_violation_stays_for_a_second_of_video_or_its_cycle() -> None:
    flags = [Flag(1.0, 'rebound', 7, -0.0012, 'm'), Flag(1.0, 'chute_speed', 3, -0.25, 'm/s')]
    timeline = Timeline(lambda t: int(t), lambda t: float(int(t) + 1), 'crank turn', [(0.0, 'EXECUTE')], flags, 10.0)
    assert timeline.text(1.05).violations == ('rebound -1.2000 mm (cycle 7)', 'chute_speed -0.2500 m/s (leaf 3)')
    assert timeline.text(1.99).violations != ()  # to the end of its cycle (longer than 0.1 s of line = 1 s of video)
    after = timeline.text(2.0)
    assert after.violations == () and after.count == 2 and after.cycle == 'crank turn 2'


@pytest.mark.parametrize(
    ('args', 'option'),
    [
        (['--out', 'x.avi'], "--out='x.avi': extension '.avi'"),
        (['--out', 'noext'], "--out='noext': no extension"),
        (['--out', '.'], "--out='.': is a directory"),
        (['--out', 'missing/x.mp4'], "--out='missing/x.mp4': its folder 'missing' does not exist"),
        (['--out', 'x.mp4', '--duration', '0'], "--duration='0'"),
        (['--out', 'x.mp4', '--duration', '-2'], "--duration='-2'"),
        (['--out', 'x.mp4', '--duration', '41'], '--duration=41.0: 41 s of line time at --fps 25 and --slowdown 10 is'),
        (['--out', 'x.mp4', '--from', '9999999.5'], '--from=9999999.5'),
        (['--out', 'x.mp4', '--from', '1e9'], "--from='1e9'"),
        (['--out', 'x.gif', '--size', '161x96'], "--size='161x96'"),
        (['--out', 'x.gif', '--fps', '120'], "--fps='120'"),
        (['--out', 'x.gif', '--slowdown', 'nan'], "--slowdown='nan'"),
        (['--out', 'x.gif', '--set', 'feed_transporter.V_tr=-1'], 'feed_transporter.V_tr'),
    ],
)
def test_bad_input_is_one_line_exit_2_and_nothing_written(
    args: list[str], option: str, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    assert _code(['animate', '--scene', 'folder', *args]) == 2
    text = capsys.readouterr()
    (line,) = text.err.strip().splitlines()
    assert line.startswith('folder-line') and 'error: ' in line and option in line, line
    assert text.out == ''
    assert list(tmp_path.iterdir()) == []


def test_the_frame_cap_is_said_with_the_longest_span(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    assert main(['animate', '--duration', '500', '--fps', '1', '--slowdown', '100', '--out', str(tmp_path / 'x.mp4')])
    err = capsys.readouterr().err
    assert f'is 50000 frames (frames = floor(duration x fps x slowdown)); at most {MAX_FRAMES}' in err
    assert 'at most 100 s of line time at these settings' in err


def test_a_failed_encoding_leaves_the_old_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    out = tmp_path / 'x.mp4'
    out.write_bytes(b'the old video')

    def refuse(self: encode.VideoWriter, frame: np.ndarray) -> None:
        raise OSError(28, 'No space left on device')

    monkeypatch.setattr(encode.VideoWriter, 'write', refuse)
    assert main(['animate', *FAST, '--duration', '0.5', '--out', str(out)]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line == f"folder-line: error: --out='{out}': cannot write: ffmpeg: [Errno 28] No space left on device"
    assert out.read_bytes() == b'the old video'
    assert [p.name for p in tmp_path.iterdir()] == ['x.mp4']


def test_a_symlink_to_a_file_gets_the_video_and_stays_a_link(tmp_path: Path) -> None:
    real, link = tmp_path / 'real.gif', tmp_path / 'link.gif'
    real.write_bytes(b'old')
    link.symlink_to(real)
    assert main(['animate', *FAST, '--duration', '0.5', '--out', str(link)]) == 0
    assert link.is_symlink() and real.read_bytes()[:6] == b'GIF89a'
    assert imageio_ffmpeg.count_frames_and_secs(str(real))[0] == 10


def test_analyze_animates_the_recorded_run_in_its_window(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag, video = tmp_path / 'bag', tmp_path / 'run.mp4'
    assert main(['simulate', *LATE, '--duration', '1', '--bag', str(bag)]) == 0
    argv = ['analyze', str(bag), '--out', str(tmp_path / 'analysis'), '--animate', str(video)]
    assert main([*argv, *FAST, '--from', '0.2', '--to', '0.8']) == 0
    assert 'wrote ' + str(video) + ' (12 frames' in capsys.readouterr().out  # 0.6 s x 10 frames/s x 2
    assert imageio_ffmpeg.count_frames_and_secs(str(video))[0] == 12
    assert (tmp_path / 'analysis' / 'report.md').is_file()
    # the recorded states and violations are the batch model's, to the ns of the bag's times
    rec = read_recording(bag)
    scene = parse_scene(scene_mapping('folder', {'feed_transporter.V_tr': 5.8333}))
    scale = TimeScale(0.0, 1.0, 10.0, 2.0)
    recorded, batch = recorded_run(rec, scale), batch_run(scene, scale)
    assert [s for _, s in recorded.states] == [s for _, s in batch.states][1:]  # the bag shows EXECUTE at 0
    assert recorded.model.commands == pytest.approx(batch.model.commands)
    assert [(f.constraint, f.index) for f in recorded.flags] == [
        (f.constraint, f.index) for f in sorted(batch.flags, key=lambda f: (f.t, f.constraint))
    ]
    for t in (0.0, 0.1, 0.5, 0.9):
        assert recorded.timeline.text(t).cycle == batch.timeline.text(t).cycle


@pytest.mark.parametrize(
    ('args', 'option'),
    [
        (['--fps', '10'], '--fps=10.0: shapes the video; give --animate FILE too'),
        (['--animate', 'x.webm'], "--animate='x.webm': extension '.webm'"),
        (['--animate', 'x.mp4', '--from', '0.495', '--to', '0.5', '--fps', '1', '--slowdown', '1'], '--to='),
        (['--animate', 'x.mp4', '--fps', '60', '--slowdown', '10000'], "--from='0..1 s': 1 s of line time at"),
    ],
)
def test_analyze_refuses_a_bad_animation_before_writing(
    args: list[str], option: str, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    bag = tmp_path / 'bag'
    assert main(['simulate', *LATE, '--duration', '1', '--bag', str(bag)]) == 0
    capsys.readouterr()
    monkeypatch.chdir(tmp_path)
    assert _code(['analyze', str(bag), '--out', 'analysis', *args]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert 'error: ' in line and option in line, line
    assert sorted(os.listdir(tmp_path)) == ['bag']
