"""``arrival_jitter`` — per-sheet error of the arrival position at the hand-over onto the feed transporter (F).

Source: issue #13, item 5 ("per-sheet arrival position jitter, with a distribution and
σ in mm"). The papers treat every signature alike; a real signature comes off the
folding cylinder a little early or late, which is a position error along the feed
belt at the hand-over.

Model
-----
Signature k lies ``δ_k`` further back on the feed belt than nominal when it is handed
over (``δ_k > 0``: behind, it must travel further), so it travels ``L_feed + δ_k`` to
the front stops instead of ``L_feed`` (:func:`folder_line.core.line.folder_steps.feed`).
On a constant drive without slip it arrives ``δ_k / V_tr`` later, so the feed window
margin of its cycle is the nominal margin minus ``δ_k / V_tr``, exactly; with a
margin ``m`` (s) the signature misses the window iff ``δ_k > m V_tr``, with
probability ``Φ(-m V_tr / σ)`` for a normal ``δ``.

Draws, per signature id k (0, 1, ... in feed order) from the scene seed's stream
``folder.arrival_jitter`` (:func:`folder_line.core.numerics.rng.stream`), one standard
variate per signature, taken in order: signature k's ``δ_k`` depends only on (seed,
k), never on the horizon or on other effects.

* ``normal``: ``δ = σ z``, z standard normal truncated at
  ±:data:`folder_line.core.numerics.rng.TRUNCATE` (clipped; the mass beyond, 2e-9, is
  put on the bound);
* ``uniform``: ``δ`` uniform on ``[-√3 σ, √3 σ)`` (the same σ).

Only F: the layup's leaf stream has its own timing scatter (``sheets.jitter``).
The travel must stay positive: :func:`check_travel` refuses ``σ`` with
``TRUNCATE σ >= L_feed`` (normal) or ``√3 σ >= L_feed`` (uniform).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from folder_line.core.numerics.rng import TRUNCATE, draws_from, standard_draws
from folder_line.core.numerics.validate import among, check_fields, non_negative
from folder_line.errors import ParameterError

__all__ = [
    'DISTRIBUTIONS',
    'STREAM',
    'Params',
    'check_travel',
    'draw_offsets',
    'half_width',
    'offsets_from',
]

#: the distributions of δ
DISTRIBUTIONS = ('normal', 'uniform')
#: name of the seeded stream
STREAM = 'folder.arrival_jitter'


@dataclass(frozen=True)
class Params:
    """Arrival position error at the hand-over.

    Attributes
    ----------
    distribution : {'normal', 'uniform'}
        Shape of δ.
    sigma : float
        Standard deviation of δ, mm (>= 0; 0: every signature nominal).
    """

    distribution: str
    sigma: float

    def __post_init__(self) -> None:
        check_fields(self, 'effects.arrival_jitter', distribution=among(DISTRIBUTIONS), sigma=non_negative)


def half_width(params: Params) -> float:
    """Largest ``|δ|`` a draw can have, mm (``TRUNCATE σ`` normal, ``√3 σ`` uniform)."""
    return (TRUNCATE if params.distribution == 'normal' else math.sqrt(3.0)) * params.sigma


def check_travel(params: Params, L_feed: float) -> None:
    """Refuse a σ whose largest draw would reach the stops at the hand-over (``L_feed`` in m)."""
    if half_width(params) * 1e-3 >= L_feed:
        raise ParameterError(
            'effects.arrival_jitter.sigma',
            params.sigma,
            f'the largest offset {half_width(params):g} mm must be below the feed travel {L_feed * 1e3:g} mm',
        )


def offsets_from(params: Params, rng: np.random.Generator, n: int) -> np.ndarray:
    """The next ``n`` offsets of :func:`draw_offsets` from the stream ``rng``, m."""
    return draws_from(params.distribution, rng, n) * (params.sigma * 1e-3)


def draw_offsets(params: Params, seed: int, n: int) -> np.ndarray:
    """Position error ``δ_k`` of signatures k = 0 .. n-1, m (positive: further back).

    Parameters
    ----------
    params : Params
        Distribution and σ (mm).
    seed : int
        The scene seed.
    n : int
        Signatures (>= 0).

    Returns
    -------
    ndarray, shape (n,)
        m.
    """
    return standard_draws(params.distribution, seed, STREAM, n) * (params.sigma * 1e-3)
