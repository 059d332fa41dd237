"""``folder-line animate`` and ``analyze --animate``: the line as a video, without ROS.

``animate`` draws the streamed line of a scene (:func:`folder_line.analysis.animation.batch_run`: the
supervisor in the loop, as ``run`` and ``simulate --bag`` run it); ``analyze --animate`` a recorded
run, with the states and violations it recorded
(:func:`folder_line.analysis.animation.recorded_run`). Both draw the core's scenery
(:class:`folder_line.core.line.scenery.Scenery`) frame by frame as the line is advanced window by
window, from a fast-forward to ``--from`` (:func:`folder_line.analysis.animation.render`), and show a
progress bar of line time on stderr. Neither keeps the line's history: memory does not grow with
``--from`` or ``--duration``.
Every target and number is checked before any work; a refusal is one line naming the option and
its value, exit code 2, and nothing is written.
"""

from __future__ import annotations

import argparse
import sys
from typing import IO

from folder_line.analysis.animation import (
    DEFAULT_FPS,
    DEFAULT_SLOWDOWN,
    FPS,
    MAX_FRAMES,
    SLOWDOWN,
    AnimatedRun,
    Animation,
    TimeScale,
    check_video_target,
    parse_size,
    recorded_run,
    render,
    scale_note,
)
from folder_line.analysis.animation import batch_run as batch_animation
from folder_line.analysis.recording import Recording
from folder_line.cli.arg_types import add_tune_argument, check_tunings, limited
from folder_line.cli.study_options import add_scene_arguments, source_from
from folder_line.cli.verb_options import Subparsers
from folder_line.core.limits import DURATION, Limit
from folder_line.core.line.scene import parse_scene
from folder_line.errors import ParameterError
from folder_line.progress import LineTimeProgress

__all__ = [
    'ANIMATION_OPTIONS',
    'DEFAULT_SIZE',
    'add_animation_options',
    'add_parser',
    'animate_recording',
    'check_animation_options',
    'check_recording_window',
    'run',
]

#: frame size, px, default
DEFAULT_SIZE = (1280, 720)
#: the options that shape a video (``analyze`` refuses them without ``--animate``)
ANIMATION_OPTIONS = (('--fps', 'fps'), ('--slowdown', 'slowdown'), ('--size', 'size'))
_FROM = Limit('line time of the first frame', 0.0, DURATION.hi, 's', 'a run of the longest duration')

FRAMES_HELP = (
    'Time scale: the video runs --slowdown times slower than the line (default 10: a 72 ms knife cycle '
    'lasts 0.72 s), at --fps frames per second (default 25). Frame i shows line time FROM + i*dt with '
    'dt = 1/(fps*slowdown), i = 0 .. N-1, N = floor(DURATION*fps*slowdown) frames (2 s at the defaults: '
    f'500 frames, 20 s of video); at most {MAX_FRAMES} frames. A --slowdown below 1 speeds the line up.'
)


def _size(text: str) -> tuple[int, int]:
    try:
        return parse_size(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def add_animation_options(parser: argparse.ArgumentParser, *, defaults: bool = True) -> None:
    """``--fps``, ``--slowdown``, ``--size`` (without ``defaults``: None when not given, for ``analyze``)."""
    fps, slow, size = (DEFAULT_FPS, DEFAULT_SLOWDOWN, DEFAULT_SIZE) if defaults else (None, None, None)
    parser.add_argument(
        '--fps',
        type=limited('--fps', FPS),
        default=fps,
        metavar='F',
        help=f'video frames per second, in {FPS.text()} (default {DEFAULT_FPS:g})',
    )
    parser.add_argument(
        '--slowdown',
        type=limited('--slowdown', SLOWDOWN),
        default=slow,
        metavar='X',
        help=f'video seconds per line second, in {SLOWDOWN.text()} (default {DEFAULT_SLOWDOWN:g}; below 1 faster)',
    )
    parser.add_argument(
        '--size',
        type=_size,
        default=size,
        metavar='WxH',
        help=f'frame width and height in px, both even (default {DEFAULT_SIZE[0]}x{DEFAULT_SIZE[1]})',
    )


def add_parser(subparsers: Subparsers) -> argparse.ArgumentParser:
    """Add the ``animate`` verb to ``folder-line``'s sub-parsers."""
    p: argparse.ArgumentParser = subparsers.add_parser(
        'animate',
        help='video of the line (mp4 or gif) from the streamed line, with time, cycle, PackML state, violations',
        description=(
            'Draw the line seen from the side (x along the line, z up, metres) from the streamed line of a scene, '
            'with the supervisor in the loop as `run` and `simulate --bag` run it (no ROS), and encode it with the '
            'ffmpeg of imageio-ffmpeg: .mp4 (H.264) or .gif. Each frame shows the line time, the machine cycle, '
            'the PackML state and the constraint violations as they are decided. ' + FRAMES_HELP
        ),
        epilog=(
            'Example: folder-line animate --scene line --duration 2 --out line.mp4 (500 frames, 20 s of video). '
            'A recorded run: folder-line analyze RUN_DIR --animate run.mp4 [--from S] [--to S].'
        ),
    )
    add_scene_arguments(p, 2.0)
    add_tune_argument(p)
    p.add_argument(
        '--from',
        dest='t_from',
        type=limited('--from', _FROM),
        default=0.0,
        metavar='S',
        help=(
            'line time of the first frame, s (default 0); the run is simulated from 0 to FROM + DURATION (the '
            'supervisor in the loop), then the frames are drawn from a fast-forward to FROM'
        ),
    )
    p.add_argument('--out', required=True, metavar='FILE.mp4|FILE.gif', help='the video to write')
    add_animation_options(p)
    p.set_defaults(func=run, output_option='--out')
    return p


def _report(anim: Animation, scale: TimeScale, stream: IO[str]) -> None:
    w, h = anim.size
    print(
        f'wrote {anim.path} ({anim.frames} frames, {w}x{h}, {anim.video_s:g} s of video at {scale.fps:g} frames/s: '
        f'line time {scale.t_from:g} to {scale.t_end:g} s, {scale.slowdown:g} video s per line s; '
        f'drawn and encoded in {anim.wall_s:.1f} s)',
        file=stream,
    )


def _render(shown: AnimatedRun, scale: TimeScale, out: str, option: str, size: tuple[int, int]) -> Animation:
    bar = LineTimeProgress(sys.stderr, scale.duration)
    try:
        return render(
            shown.model,
            shown.timeline,
            scale,
            out,
            option,
            size,
            title=shown.title,
            note=scale_note(scale),
            until=shown.until,
            progress=bar.show,
        )
    finally:
        bar.close()


def run(args: argparse.Namespace) -> int:
    """``folder-line animate``: check everything, simulate, draw, encode; print what was written."""
    check_video_target(args.out, '--out')
    if args.t_from + args.duration > DURATION.hi:
        raise ParameterError(
            '--from', args.t_from, f'--from + --duration must be at most {DURATION.hi:g} s, the longest run'
        )
    scale = TimeScale(args.t_from, args.duration, args.fps, args.slowdown)
    scale.check('--duration', args.duration)
    scene = parse_scene(source_from(args))
    tunings = check_tunings(scene, args.tune, args.t_from + args.duration)
    shown = batch_animation(scene, scale, tunings)
    _report(_render(shown, scale, args.out, '--out', args.size), scale, sys.stdout)
    return 0


def check_animation_options(args: argparse.Namespace) -> None:
    """``analyze``: ``--fps``, ``--slowdown``, ``--size`` need ``--animate``; the target is checked at once.

    Raises
    ------
    ParameterError, OutputError
    """
    if args.animate is None:
        for option, attr in ANIMATION_OPTIONS:
            if getattr(args, attr) is not None:
                raise ParameterError(option, getattr(args, attr), 'shapes the video; give --animate FILE too')
        return
    check_video_target(args.animate, '--animate')


def _scale(args: argparse.Namespace, t_from: float, t_end: float) -> TimeScale:
    return TimeScale(
        t_from,
        t_end - t_from,
        DEFAULT_FPS if args.fps is None else args.fps,
        DEFAULT_SLOWDOWN if args.slowdown is None else args.slowdown,
    )


def check_recording_window(args: argparse.Namespace, rec: Recording) -> None:
    """``analyze --animate``: the window ``--from .. --to`` (or the bag's end) must make 1 to MAX_FRAMES frames;
    checked after the bag is read, before anything is written.

    Raises
    ------
    ParameterError
        Naming ``--to`` if it was given, else ``--from``, and the window.
    """
    if args.animate is None:
        return
    t_from = args.t_from or 0.0
    if t_from >= rec.t_end:
        return  # analyze refuses it, naming --from
    option = '--to' if args.t_to is not None else '--from'
    _scale(args, t_from, rec.t_end).check(option, f'{t_from:g}..{rec.t_end:.9g} s')


def animate_recording(args: argparse.Namespace, rec: Recording) -> Animation:
    """``analyze --animate``: the recorded run from ``--from`` (default 0) to ``--to`` (default its end)."""
    t_from = args.t_from or 0.0
    scale = _scale(args, t_from, rec.t_end)
    size = DEFAULT_SIZE if args.size is None else args.size
    anim = _render(recorded_run(rec, scale), scale, args.animate, '--animate', size)
    _report(anim, scale, sys.stdout)
    return anim
