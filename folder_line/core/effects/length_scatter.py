"""``length_scatter`` — per-sheet scatter of the signature's length (F).

Source: issue #13, item 5 ("per-sheet length scatter"). Cut and folded signatures
are not all equally long.

Where the length enters
-----------------------
The folding cylinder lets go of the signature's **trailing** edge at a fixed phase
(the hand-over, ``sheet_handover``), so the signature's position on the feed belt
is fixed by its tail: a signature ``ΔL_k`` longer than nominal has its leading edge
``ΔL_k`` further on, and travels ``L_feed - ΔL_k`` to the front stops
(:func:`folder_line.core.line.folder_steps.feed`). A longer signature therefore
arrives ``ΔL_k / V_tr`` earlier on a constant drive without slip (its feed-window
margin grows by exactly that), a shorter one later. With ``arrival_jitter`` as well
the travel is ``L_feed + δ_k - ΔL_k``. Only F: the layup model has no leaf length.

Draws: ``ΔL_k = σ z_k``, z standard normal clipped at ±6, one per signature id k in
feed order from the scene seed's stream ``folder.length_scatter``: signature k's
length depends only on (seed, k).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from folder_line.core.numerics.rng import TRUNCATE, draws_from, standard_draws
from folder_line.core.numerics.validate import check_fields, non_negative
from folder_line.errors import ParameterError

__all__ = ['STREAM', 'Params', 'check_travel', 'draw_excess', 'excess_from']

#: name of the seeded stream
STREAM = 'folder.length_scatter'


@dataclass(frozen=True)
class Params:
    """Length scatter of the signatures.

    Attributes
    ----------
    sigma : float
        Standard deviation of the length, mm (>= 0).
    """

    sigma: float

    def __post_init__(self) -> None:
        check_fields(self, 'effects.length_scatter', sigma=non_negative)


def check_travel(params: Params, L_feed: float) -> None:
    """Refuse a σ whose longest signature would be at the stops at the hand-over (``L_feed`` in m)."""
    if TRUNCATE * params.sigma * 1e-3 >= L_feed:
        raise ParameterError(
            'effects.length_scatter.sigma',
            params.sigma,
            f'the largest excess {TRUNCATE * params.sigma:g} mm must be below the feed travel {L_feed * 1e3:g} mm',
        )


def draw_excess(params: Params, seed: int, n: int) -> np.ndarray:
    """Length excess ``ΔL_k`` over nominal of signatures k = 0 .. n-1, m (positive: longer)."""
    return standard_draws('normal', seed, STREAM, n) * (params.sigma * 1e-3)


def excess_from(params: Params, rng: np.random.Generator, n: int) -> np.ndarray:
    """The next ``n`` excesses of :func:`draw_excess` from the stream ``rng``, m."""
    return draws_from('normal', rng, n) * (params.sigma * 1e-3)
