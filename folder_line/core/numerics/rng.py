"""Seeded, independent random streams: same scene + same seed -> same draws, bit for bit."""

from __future__ import annotations

import zlib

import numpy as np

__all__ = ['stream']


def stream(seed: int, name: str) -> np.random.Generator:
    """A PCG64 generator for the named stream of a scene's seed.

    Streams with different names are independent, and adding a stream (or an effect)
    does not change the draws of the others.
    """
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence([int(seed), zlib.crc32(name.encode())])))
