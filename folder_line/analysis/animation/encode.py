"""Encoding an animation: frames streamed to ffmpeg (the binary of the ``imageio-ffmpeg`` wheel).

* ``.mp4``: H.264 (``libx264``), ``yuv420p`` (what every player plays; it needs an even width and
  height, which :func:`check_size` asks for), constant frame rate, ``+faststart`` (the index at
  the front, so a browser starts playing before the whole file is in);
* ``.gif``: ffmpeg's ``palettegen`` and ``paletteuse``. One palette of 256 colours for the whole
  film, made first from :data:`PALETTE_FRAMES` frames spread over it (a palette from every frame
  would need them all at once), then every frame mapped to it with an ordered (Bayer) dither, which
  does not flicker from frame to frame, and stored as the rectangle that changed since the frame
  before (``diff_mode=rectangle``): a third of the size of a palette per frame. (Where the
  temporary folder's path cannot be written into an ffmpeg filter, each frame gets its own
  palette instead: ``stats_mode=single``, ``new=1``.) The frame delay is ``1/fps`` rounded to
  GIF's 10 ms steps.

Frames go to ffmpeg's stdin one by one (:meth:`VideoWriter.write`); nothing holds them all.
The file is written to a temporary file beside the target and renamed over it when ffmpeg has
finished (:func:`folder_line.files.atomic.written_by_name`): a failure or an interrupt leaves the
target as it was.
"""

from __future__ import annotations

import contextlib
import os
import re
import tempfile
from collections.abc import Callable, Generator, Iterable, Iterator
from pathlib import Path

import imageio_ffmpeg
import numpy as np

from folder_line.errors import OutputError, ParameterError, bounded_repr, path_repr
from folder_line.files.atomic import check_output_file, describe_path, written_by_name

__all__ = [
    'FORMATS',
    'PALETTE_FRAMES',
    'SIZE_LIMITS',
    'VideoWriter',
    'check_size',
    'check_video_target',
    'parse_size',
    'video_writer',
]

#: file extension -> ffmpeg's muxer
FORMATS = {'.mp4': 'mp4', '.gif': 'gif'}
#: smallest and largest frame width and height, px
SIZE_LIMITS = (64, 3840)
#: frames a GIF's palette is made from
PALETTE_FRAMES = 16
#: a path ffmpeg's filter syntax takes as it is (anything else would need its two levels of escaping)
_PLAIN_PATH = re.compile(r'[A-Za-z0-9/_.+-]+')


def check_video_target(path: str | os.PathLike[str], option: str) -> Path:
    """Refuse an animation target before any work: an unknown extension, a directory, a folder
    that does not exist, anything but a regular file or nothing.

    Returns
    -------
    Path
        The target (the final target of a symbolic link to a regular file).

    Raises
    ------
    ParameterError
        The extension is not one of :data:`FORMATS`.
    OutputError
        The target is a directory, its folder does not exist or is not a folder, or it is not
        a regular file (:func:`folder_line.files.atomic.check_output_file`).
    """
    p = Path(path)
    if os.path.isdir(p):
        raise OutputError(option, str(path), 'is a directory; give a file name ending in .mp4 or .gif')
    suffix = p.suffix.lower()
    if suffix not in FORMATS:
        what = f'extension {suffix!r}' if suffix else 'no extension'
        raise ParameterError(option, str(path), f'{what}: must end in .mp4 (H.264 video) or .gif')
    dest = check_output_file(p, option)
    parent = dest.parent
    if not parent.is_dir():
        what = 'does not exist' if not os.path.lexists(parent) else f'is {describe_path(parent)}, not a folder'
        raise OutputError(option, str(path), f'its folder {path_repr(parent)} {what}; create it first')
    return dest


def parse_size(text: str) -> tuple[int, int]:
    """``'1280x720'`` -> (1280, 720) (``ValueError`` naming what is wrong; :func:`check_size` applies)."""
    parts = text.lower().split('x')
    if len(parts) != 2:
        raise ValueError(f'--size={bounded_repr(text)}: must be WIDTHxHEIGHT in pixels, e.g. 1280x720')
    try:
        width, height = int(parts[0]), int(parts[1])
    except ValueError:
        raise ValueError(f'--size={bounded_repr(text)}: must be WIDTHxHEIGHT in whole pixels, e.g. 1280x720') from None
    return check_size(width, height, text)


def check_size(width: int, height: int, given: object = None) -> tuple[int, int]:
    """A frame size in :data:`SIZE_LIMITS` with an even width and height (H.264 in ``yuv420p``
    halves the colour resolution in both directions); ``ValueError`` naming ``--size`` otherwise."""
    lo, hi = SIZE_LIMITS
    shown = bounded_repr(given if given is not None else f'{width}x{height}')
    if not (lo <= width <= hi and lo <= height <= hi):
        raise ValueError(f'--size={shown}: width and height must be in [{lo}, {hi}] px')
    if width % 2 or height % 2:
        raise ValueError(f'--size={shown}: width and height must be even (H.264 video in yuv420p needs it)')
    return width, height


def _ffmpeg_options(fmt: str, palette: Path | None = None) -> dict[str, object]:
    """``imageio_ffmpeg.write_frames`` keywords of one format (a GIF with ``palette``: mapped to it)."""
    if fmt == 'mp4':
        return {
            'codec': 'libx264',
            'pix_fmt_out': 'yuv420p',
            'quality': 7,  # crf 15: line art stays sharp
            'macro_block_size': 2,  # the size is even (check_size): never rescaled
            'output_params': ['-movflags', '+faststart', '-f', 'mp4'],
        }
    if palette is not None:
        graph = f"movie='{palette}'[p];[0:v][p]paletteuse=dither=bayer:bayer_scale=5:diff_mode=rectangle"
    else:
        graph = 'split[a][b];[a]palettegen=stats_mode=single[p];[b][p]paletteuse=new=1'
    return {
        'codec': 'gif',
        'pix_fmt_out': 'pal8',
        'quality': None,
        'macro_block_size': 1,
        'output_params': ['-lavfi', graph, '-f', 'gif'],
    }


def _make_palette(path: Path, size: tuple[int, int], frames: Iterable[np.ndarray]) -> None:
    """ffmpeg's ``palettegen`` of ``frames`` written to ``path`` (a 16x16 PNG)."""
    gen = imageio_ffmpeg.write_frames(
        str(path),
        size,
        fps=1,
        codec='png',
        pix_fmt_out='rgba',
        quality=None,
        macro_block_size=1,
        ffmpeg_log_level='error',
        output_params=['-vf', 'palettegen=max_colors=256', '-update', '1', '-f', 'image2'],
    )
    gen.send(None)
    try:
        for frame in frames:
            gen.send(np.ascontiguousarray(frame))
    finally:
        gen.close()


def _check_written(path: Path, frames: int) -> None:
    """``OSError`` unless ffmpeg left a readable video with frames at ``path``: ``write_frames`` does not
    report ffmpeg's failures (a full disk leaves an empty or headless file and a zero exit of ours)."""
    if frames == 0:
        return
    try:
        found, _ = imageio_ffmpeg.count_frames_and_secs(str(path))
    except (RuntimeError, OSError):
        found = 0
    if found == 0:
        size = path.stat().st_size if path.exists() else 0
        msg = f'wrote no readable video ({size} bytes for {frames} frames; is the disk full?)'
        raise OSError(msg)


class VideoWriter:
    """Frames in, an ``.mp4`` or ``.gif`` out (:func:`video_writer` opens and closes it).

    Parameters
    ----------
    tmp : Path
        The file ffmpeg writes (renamed into place by :func:`video_writer`).
    fmt : str
        ``mp4`` or ``gif``.
    size : (int, int)
        Width and height, px.
    fps : float
        Frames per second.
    palette : Path, optional
        A GIF's palette (:func:`_make_palette`); without one, a palette per frame.
    """

    def __init__(self, tmp: Path, fmt: str, size: tuple[int, int], fps: float, palette: Path | None = None) -> None:
        self.size = size
        self.frames = 0
        self._gen: Generator[None, np.ndarray | None, None] = imageio_ffmpeg.write_frames(
            str(tmp), size, fps=fps, ffmpeg_log_level='error', **_ffmpeg_options(fmt, palette)
        )
        self._gen.send(None)  # starts ffmpeg

    def write(self, frame: np.ndarray) -> None:
        """One frame: ``(height, width, 3)`` uint8 RGB."""
        w, h = self.size
        if frame.shape != (h, w, 3) or frame.dtype != np.uint8:
            msg = f'frame of shape {frame.shape} {frame.dtype}; the video is {w}x{h} RGB uint8'
            raise ValueError(msg)
        self._gen.send(np.ascontiguousarray(frame))
        self.frames += 1

    def close(self) -> None:
        """Let ffmpeg finish the file (waits for it)."""
        self._gen.close()


@contextlib.contextmanager
def video_writer(
    path: str | os.PathLike[str],
    option: str,
    size: tuple[int, int],
    fps: float,
    palette_frames: Callable[[], Iterable[np.ndarray]] | None = None,
) -> Iterator[VideoWriter]:
    """A :class:`VideoWriter` of ``path`` (``.mp4`` or ``.gif``): written beside it, renamed over it when the
    block ends and ffmpeg has finished; on an exception (ffmpeg's too) nothing is left behind.

    Parameters
    ----------
    path : path-like
        The target; ``option`` names it in errors.
    size : (int, int)
        Width and height, px.
    fps : float
        Frames per second.
    palette_frames : callable, optional
        For a GIF: gives the frames its one palette is made from (:data:`PALETTE_FRAMES` spread over
        the film); without it, a palette per frame.

    Raises
    ------
    OutputError
        The target is refused (:func:`check_video_target`), or ffmpeg or the OS could not write it
        (the reason from ffmpeg, e.g. a full disk).
    """
    dest = check_video_target(path, option)
    fmt = FORMATS[dest.suffix.lower()]
    with contextlib.ExitStack() as stack:
        palette = None
        if fmt == 'gif' and palette_frames is not None:
            folder = stack.enter_context(tempfile.TemporaryDirectory(prefix='folder-line-palette-'))
            if _PLAIN_PATH.fullmatch(folder):
                palette = Path(folder) / 'palette.png'
        tmp = stack.enter_context(written_by_name(path, option, suffix=dest.suffix.lower()))
        writer = None
        try:
            if palette is not None and palette_frames is not None:
                _make_palette(palette, size, palette_frames())
            writer = VideoWriter(tmp, fmt, size, fps, palette)
            yield writer
            writer.close()
            _check_written(tmp, writer.frames)
        except (RuntimeError, OSError) as exc:
            if isinstance(exc, OutputError):
                raise
            if writer is not None:
                with contextlib.suppress(Exception):
                    writer.close()
            reason = ' '.join(str(exc).split())[-300:]  # ffmpeg's own words end the message
            raise OutputError(option, str(path), f'cannot write: ffmpeg: {reason}') from None
        except BaseException:
            if writer is not None:
                with contextlib.suppress(Exception):
                    writer.close()
            raise
