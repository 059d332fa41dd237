"""Output that never destroys: files written whole or not at all, targets checked, folders claimed.

- A file target that exists must be a regular file. A FIFO, a device, a socket or a
  directory is refused (:class:`~folder_line.errors.OutputError`) before anything is
  written. A **symbolic link is followed** when it points at a regular file: the new
  content is written next to the link's final target and renamed over that target, so
  the link stays a link. A dangling link, or one that points at anything else, is refused;
  a link itself is never replaced.
- A file is written to a temporary file in its directory and renamed into place; on any
  failure the temporary file and any folder created for it are removed, and the OS
  reason (``strerror``) is raised as an ``OutputError`` naming the path.
- An output folder is claimed by :func:`claim_output_dir` with ``flock(LOCK_EX | LOCK_NB)``
  on the folder itself (nothing is created inside it), so that two ``folder-line``
  processes never write into the same folder: the second is refused at once.
"""

from __future__ import annotations

import contextlib
import csv
import errno
import fcntl
import io
import json
import os
import stat
import tempfile
from collections.abc import Iterable, Iterator, Mapping, Sequence
from pathlib import Path

import numpy as np

from folder_line.errors import OutputError

__all__ = [
    'check_output_dir',
    'check_output_file',
    'claim_output_dir',
    'describe_path',
    'file_kind',
    'write_bytes_atomic',
    'write_chunks_atomic',
    'write_csv_atomic',
    'write_json_atomic',
    'write_text_atomic',
    'written_by_name',
]

_umask = os.umask(0)
os.umask(_umask)
_MODE = 0o666 & ~_umask

#: the lock file used only where a folder itself cannot be locked (``flock`` on a directory
#: is refused by some network file systems)
LOCK_FILE = '.folder-line.lock'


def file_kind(mode: int) -> str:
    """``'a FIFO'``, ``'a directory'``, ``'a regular file'``... of an ``st_mode``."""
    for test, name in (
        (stat.S_ISDIR, 'a directory'),
        (stat.S_ISFIFO, 'a FIFO'),
        (stat.S_ISCHR, 'a character device'),
        (stat.S_ISBLK, 'a block device'),
        (stat.S_ISSOCK, 'a socket'),
        (stat.S_ISREG, 'a regular file'),
    ):
        if test(mode):
            return name
    return 'a special file'


def describe_path(path: str | os.PathLike[str]) -> str:
    """What is at ``path``, for a message: ``'is a FIFO'``, ``'is a regular file'``, ``'does not exist'``..."""
    try:
        info = os.stat(path)
    except FileNotFoundError:
        return 'is a symbolic link to nothing (dangling)' if os.path.islink(path) else 'does not exist'
    except OSError as exc:
        return f'cannot be looked at: {_reason(exc)}'
    return f'is {file_kind(info.st_mode)}'


def _reason(exc: OSError) -> str:
    return exc.strerror or errno.errorcode.get(exc.errno or 0, str(exc))


def _check_ancestors(path: Path, option: str | None, target: str) -> None:
    """The nearest existing ancestor of a missing ``path`` must be a directory (we create the rest)."""
    for parent in path.parents:
        try:
            info = os.stat(parent)
        except FileNotFoundError:
            continue
        except NotADirectoryError:
            continue  # some ancestor higher up is a file: found on the way up
        except OSError as exc:
            raise OutputError(option, target, f'cannot look at {parent}: {_reason(exc)}') from None
        if not stat.S_ISDIR(info.st_mode):
            raise OutputError(option, target, f'{parent} is {file_kind(info.st_mode)}, not a directory')
        return


def check_output_file(path: str | os.PathLike[str], option: str | None = None) -> Path:
    """Where a file for ``path`` would be written; refuse a target that must not be replaced.

    Parameters
    ----------
    path : path-like
        The file to write.
    option : str, optional
        The command-line option that named it, for the message.

    Returns
    -------
    Path
        ``path`` itself, or the final target of a symbolic link to a regular file.

    Raises
    ------
    OutputError
        ``path`` is a FIFO, device, socket or directory; a dangling link or a link to one of
        those; or it lies under something that is not a directory.
    """
    dest = Path(path)
    try:
        info = os.lstat(dest)
    except (FileNotFoundError, NotADirectoryError):
        _check_ancestors(dest, option, str(path))
        return dest
    except OSError as exc:
        raise OutputError(option, str(path), _reason(exc)) from None
    if stat.S_ISLNK(info.st_mode):
        try:
            target = os.stat(dest)
        except OSError:
            raise OutputError(
                option, str(path), 'is a symbolic link to nothing (dangling); a link is never replaced'
            ) from None
        if not stat.S_ISREG(target.st_mode):
            raise OutputError(
                option, str(path), f'is a symbolic link to {file_kind(target.st_mode)}, not to a regular file'
            ) from None
        return Path(os.path.realpath(dest))
    if not stat.S_ISREG(info.st_mode):
        raise OutputError(option, str(path), f'is {file_kind(info.st_mode)}, not a regular file')
    return dest


def check_output_dir(
    path: str | os.PathLike[str], option: str | None = None, files: Iterable[str] = (), dirs: Iterable[str] = ()
) -> Path:
    """Refuse an output folder that is not one, or that holds something a verb would not overwrite.

    Parameters
    ----------
    path : path-like
        The folder (it may be missing; then its nearest existing ancestor must be a folder).
        A symbolic link to a folder is followed.
    option : str, optional
        The command-line option that named it.
    files, dirs : iterable of str
        Names inside the folder that the verb writes as files, and as folders: each must be
        missing or of that kind (:func:`check_output_file`).

    Raises
    ------
    OutputError
        Naming the offending path and what it is.
    """
    dest = Path(path)
    try:
        info = os.stat(dest)
    except (FileNotFoundError, NotADirectoryError):
        if os.path.lexists(dest):
            raise OutputError(option, str(path), 'is a symbolic link to nothing (dangling)') from None
        _check_ancestors(dest, option, str(path))
        return dest
    except OSError as exc:
        raise OutputError(option, str(path), _reason(exc)) from None
    if not stat.S_ISDIR(info.st_mode):
        raise OutputError(option, str(path), f'is {file_kind(info.st_mode)}, not a directory')
    for name in files:
        check_output_file(dest / name, option)
    for name in dirs:
        check_output_dir(dest / name, option)
    return dest


def _make_dirs(path: Path, option: str | None, target: str) -> list[Path]:
    """Create ``path`` and its missing parents; return those created, outermost first."""
    missing: list[Path] = []
    for p in (path, *path.parents):
        if os.path.isdir(p):
            break
        missing.append(p)
    created: list[Path] = []
    try:
        for p in reversed(missing):
            os.mkdir(p)
            created.append(p)
    except OSError as exc:
        _remove_dirs(created)
        raise OutputError(option, target, f'cannot create folder {exc.filename or p}: {_reason(exc)}') from None
    return created


def _remove_dirs(created: list[Path]) -> None:
    """Remove the folders of ``created`` that are still empty, innermost first."""
    for p in reversed(created):
        try:
            os.rmdir(p)
        except OSError:
            break


def _lock(fd: int, option: str | None, path: str | os.PathLike[str]) -> None:
    """Take the exclusive lock on ``fd`` at once; a folder another process holds is refused."""
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        raise OutputError(
            option,
            str(path),
            'is in use by another folder-line process; wait for it to finish or choose another folder',
        ) from None


@contextlib.contextmanager
def claim_output_dir(
    path: str | os.PathLike[str],
    option: str | None = None,
    files: Iterable[str] = (),
    dirs: Iterable[str] = (),
    create: bool = True,
) -> Iterator[Path]:
    """Check (:func:`check_output_dir`), create and lock an output folder for the ``with`` block.

    ``create=False`` claims a folder that must exist (a bag to repair): a missing one is refused.

    The lock is ``flock(LOCK_EX | LOCK_NB)`` on the folder itself (on a lock file
    :data:`LOCK_FILE` inside it where the file system refuses that); it ends with the block or
    the process. A write probe (a temporary file created and removed) finds a read-only or
    unwritable folder before any work. Folders created here and still empty at the end (the
    verb failed before writing) are removed.

    Raises
    ------
    OutputError
        Not a folder, held by another process (naming the folder), or not writable (the OS reason).
    """
    files, dirs = tuple(files), tuple(dirs)
    dest = check_output_dir(path, option, files, dirs)
    if not create and not dest.is_dir():
        raise OutputError(option, str(path), 'no such directory')
    created = _make_dirs(dest, option, str(path))
    fd = -1
    try:
        fd = os.open(dest, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
        try:
            _lock(fd, option, path)
        except OutputError:
            raise
        except OSError:  # flock on a directory not supported here: lock a file inside it
            os.close(fd)
            fd = -1
            fd = os.open(dest / LOCK_FILE, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, _MODE)
            _lock(fd, option, path)
        probe, probe_path = tempfile.mkstemp(prefix='.folder-line-probe.', dir=dest)
        os.close(probe)
        os.unlink(probe_path)
        check_output_dir(dest, option, files, dirs)  # again, now that no other folder-line can change it
    except OSError as exc:
        if fd >= 0:
            os.close(fd)
        _remove_dirs(created)
        if isinstance(exc, OutputError):
            raise
        raise OutputError(option, str(path), f'cannot write there: {_reason(exc)}') from None
    try:
        yield dest
    finally:
        os.close(fd)
        _remove_dirs(created)


def write_bytes_atomic(path: str | os.PathLike[str], data: bytes) -> Path:
    """Write ``data`` to ``path`` via a temporary file in the same directory and a rename,
    so a failure (or a kill) never leaves a half-written file; the directory is created.

    Raises
    ------
    OutputError
        The target must not be replaced (:func:`check_output_file`) or the OS refused the
        write (read-only, full, permission); nothing is left behind.
    """
    return write_chunks_atomic(path, (data,))


def write_chunks_atomic(path: str | os.PathLike[str], chunks: Iterable[bytes]) -> Path:
    """:func:`write_bytes_atomic` of the concatenated ``chunks``, written one by one as they come (a large
    file never held in memory whole).

    Raises
    ------
    OutputError
        As :func:`write_bytes_atomic`.
    """
    dest = check_output_file(path)
    created = _make_dirs(dest.parent, None, str(path))
    tmp = ''
    try:
        fd, tmp = tempfile.mkstemp(prefix=f'.{dest.name}.', suffix='.tmp', dir=dest.parent)
        with os.fdopen(fd, 'wb') as fh:
            os.fchmod(fd, _MODE)  # mkstemp makes 0600; an output is as readable as any file the user writes
            for chunk in chunks:
                fh.write(chunk)
        check_output_file(path)  # a FIFO or device put there meanwhile is not replaced either
        os.replace(tmp, dest)
    except BaseException as exc:
        if tmp:
            Path(tmp).unlink(missing_ok=True)
        _remove_dirs(created)
        if isinstance(exc, OSError) and not isinstance(exc, OutputError):
            raise OutputError(None, str(path), f'cannot write: {_reason(exc)}') from None
        raise
    return Path(path)


@contextlib.contextmanager
def written_by_name(path: str | os.PathLike[str], option: str | None = None, suffix: str = '') -> Iterator[Path]:
    """Write ``path`` through a tool that writes a file by its name (ffmpeg), never destroying.

    Yields a temporary file's path in the target's directory (``.<name>.<random>.tmp<suffix>``,
    created empty); the tool writes it. When the block ends normally the target is checked
    again and the temporary file renamed over it; when the block raises, the temporary
    file is removed. Unlike :func:`write_chunks_atomic` no folder is created: the target's
    folder must exist.

    Raises
    ------
    OutputError
        The target must not be replaced (:func:`check_output_file`), or the OS refused the
        temporary file or the rename (read-only, full, permission); nothing is left behind.
    """
    dest = check_output_file(path, option)
    tmp = ''
    try:
        fd, tmp = tempfile.mkstemp(prefix=f'.{dest.name}.', suffix=f'.tmp{suffix}', dir=dest.parent)
        os.fchmod(fd, _MODE)  # mkstemp makes 0600; an output is as readable as any file the user writes
        os.close(fd)
        yield Path(tmp)
        check_output_file(path, option)  # a FIFO or device put there meanwhile is not replaced either
        os.replace(tmp, dest)
    except BaseException as exc:
        if tmp:
            Path(tmp).unlink(missing_ok=True)
        if isinstance(exc, OSError) and not isinstance(exc, OutputError):
            raise OutputError(option, str(path), f'cannot write: {_reason(exc)}') from None
        raise


def write_text_atomic(path: str | os.PathLike[str], text: str) -> Path:
    """:func:`write_bytes_atomic` of UTF-8 text (newlines written as given)."""
    return write_bytes_atomic(path, text.encode('utf-8'))


def write_json_atomic(path: str | os.PathLike[str], document: object) -> Path:
    """Write a JSON document atomically (strict JSON: NaN or inf raise ValueError)."""
    return write_text_atomic(path, json.dumps(document, indent=2, allow_nan=False) + '\n')


def write_csv_atomic(path: str | os.PathLike[str], columns: Mapping[str, Sequence[object] | np.ndarray]) -> Path:
    """Write equal-length columns to ``path`` with a header row, atomically.

    Floats are written with ``repr`` precision (round-trip exact).

    Parameters
    ----------
    path : path-like
        Destination; its directory is created if missing.
    columns : mapping of str to sequence
        Column name -> values; all of the same length.
    """
    names = list(columns)
    lengths = {len(columns[n]) for n in names}
    if len(lengths) > 1:
        msg = f'columns of unequal length: {dict((n, len(columns[n])) for n in names)}'
        raise ValueError(msg)
    cols = [np.asarray(columns[n]).tolist() for n in names]
    buf = io.StringIO(newline='')
    writer = csv.writer(buf)
    writer.writerow(names)
    writer.writerows(zip(*cols, strict=True))
    return write_text_atomic(path, buf.getvalue())
