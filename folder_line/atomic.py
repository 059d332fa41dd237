"""Atomic file output: a CSV table or a JSON document is written whole or not at all."""

from __future__ import annotations

import csv
import io
import json
import os
import tempfile
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

__all__ = ['write_bytes_atomic', 'write_csv_atomic', 'write_json_atomic', 'write_text_atomic']

_umask = os.umask(0)
os.umask(_umask)
_MODE = 0o666 & ~_umask


def write_bytes_atomic(path: str | os.PathLike[str], data: bytes) -> Path:
    """Write ``data`` to ``path`` via a temporary file in the same directory and a rename,
    so a failure (or a kill) never leaves a half-written file; the directory is created."""
    dest = Path(path)
    dest.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f'.{dest.name}.', suffix='.tmp', dir=dest.parent)
    try:
        os.fchmod(fd, _MODE)  # mkstemp makes 0600; an output is as readable as any file the user writes
        with os.fdopen(fd, 'wb') as fh:
            fh.write(data)
        os.replace(tmp, dest)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return dest


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
    writer.writerows(zip(*cols))
    return write_text_atomic(path, buf.getvalue())
