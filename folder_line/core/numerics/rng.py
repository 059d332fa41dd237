"""Seeded, independent random streams: same scene + same seed -> same draws, bit for bit."""

from __future__ import annotations

import math
import zlib

import numpy as np

__all__ = ['TRUNCATE', 'draws_from', 'standard_draws', 'stream']

#: a normal draw is clipped at this many σ
TRUNCATE = 6.0


def stream(seed: int, name: str) -> np.random.Generator:
    """A PCG64 generator for the named stream of a scene's seed.

    Streams with different names are independent, and adding a stream (or an effect)
    does not change the draws of the others.
    """
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence([int(seed), zlib.crc32(name.encode())])))


def standard_draws(distribution: str, seed: int, name: str, n: int) -> np.ndarray:
    """``n`` unit-σ variates of ``distribution`` from stream ``name`` of ``seed``, item by item.

    Item k depends only on (seed, name, k): the generators fill their output in order,
    so the first m of n draws are the m draws. Normal: clipped at ±:data:`TRUNCATE`;
    uniform: on ``[-√3, √3)``.
    """
    return draws_from(distribution, stream(seed, name), n)


def draws_from(distribution: str, rng: np.random.Generator, n: int) -> np.ndarray:
    """The next ``n`` unit-σ variates of ``distribution`` (``'normal'`` or ``'uniform'``) from ``rng``
    (:func:`standard_draws`, streamed)."""
    if distribution == 'normal':
        return np.clip(rng.standard_normal(n), -TRUNCATE, TRUNCATE)
    return (2.0 * rng.random(n) - 1.0) * math.sqrt(3.0)
