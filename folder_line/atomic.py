"""Atomic CSV output: a table is written whole or not at all."""

from __future__ import annotations

import csv
import os
import tempfile
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

__all__ = ['write_csv_atomic']


def write_csv_atomic(path: str | os.PathLike[str], columns: Mapping[str, Sequence[object] | np.ndarray]) -> Path:
    """Write equal-length columns to ``path`` with a header row.

    The file is written to a temporary name in the same directory and renamed
    into place, so a failure (or a kill) never leaves a half-written CSV.
    Floats are written with ``repr`` precision (round-trip exact).

    Parameters
    ----------
    path : path-like
        Destination; its directory is created if missing.
    columns : mapping of str to sequence
        Column name -> values; all of the same length.
    """
    dest = Path(path)
    names = list(columns)
    lengths = {len(columns[n]) for n in names}
    if len(lengths) > 1:
        msg = f'columns of unequal length: {dict((n, len(columns[n])) for n in names)}'
        raise ValueError(msg)
    dest.parent.mkdir(parents=True, exist_ok=True)
    cols = [np.asarray(columns[n]).tolist() for n in names]
    fd, tmp = tempfile.mkstemp(prefix=f'.{dest.name}.', suffix='.tmp', dir=dest.parent)
    try:
        with os.fdopen(fd, 'w', newline='', encoding='utf-8') as fh:
            writer = csv.writer(fh)
            writer.writerow(names)
            writer.writerows(zip(*cols))
        os.replace(tmp, dest)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return dest
