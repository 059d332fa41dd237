"""``property_scatter`` — per-sheet scatter of restitution and friction (F).

Source: issue #13, item 5 ("scatter in friction and restitution"). Paper and ink
vary from signature to signature, and so do their bounce off the front stops and
their grip on the feed belt.

Model
-----
Signature k (id in feed order) gets its own restitution and friction::

    e_k  = clip(e  (1 + s_e  z_k), 0, E_MAX)        (stop_bounce's e)
    mu_k = clip(mu (1 + s_mu y_k), 0, MU_MAX)       (feed_slip's mu)

``s_e``, ``s_mu`` relative standard deviations in [0, 1/3), ``z_k``, ``y_k`` standard
normal clipped at ±3 (so ``1 + s z > 0``: a factor in (0, 2)), each from its own
stream of the scene seed (``folder.property_scatter.e``, ``.mu``), one per signature in
order: signature k's draws depend only on (seed, k). The clips keep the physical
range of each parameter: ``e < 1`` (a bounce loses energy) and ``mu <= 10``. The
summary's figures "at V_tr" stay those of the nominal ``e`` and ``mu``; the events and
constraints use each signature's own.

A non-zero ``s_e`` needs ``stop_bounce`` in the scene, a non-zero ``s_mu`` needs
``feed_slip`` (:func:`check_listed`): a scatter of something the scene does not
simulate would do nothing, which is refused rather than ignored. The delivery's
friction is not scattered (its carriages are not per sheet in the model).
"""

from __future__ import annotations

from collections.abc import Container
from dataclasses import dataclass

import numpy as np

from folder_line.core.numerics.rng import stream
from folder_line.core.numerics.validate import check_fields, within
from folder_line.errors import ParameterError

__all__ = [
    'E_MAX',
    'MU_MAX',
    'Params',
    'check_listed',
    'factors',
    'factors_from',
    'friction',
    'friction_from',
    'restitution',
    'restitution_from',
]

#: largest restitution a draw may take
E_MAX = 0.999
#: largest friction coefficient a draw may take (feed_slip's range)
MU_MAX = 10.0
#: the standard normal variates are clipped at this many σ
TRUNCATE = 3.0


@dataclass(frozen=True)
class Params:
    """Relative scatter of restitution and friction.

    Attributes
    ----------
    e_sigma : float
        Relative standard deviation of ``stop_bounce``'s ``e``, in [0, 1/3).
    mu_sigma : float
        Relative standard deviation of ``feed_slip``'s ``mu``, in [0, 1/3).
    """

    e_sigma: float
    mu_sigma: float

    def __post_init__(self) -> None:
        rel = within(0.0, 1.0 / TRUNCATE, hi_open=True)
        check_fields(self, 'effects.property_scatter', e_sigma=rel, mu_sigma=rel)


def check_listed(params: Params, effects: Container[str]) -> None:
    """Refuse a scatter of an effect the scene does not list (it would do nothing)."""
    for key, effect in (('e_sigma', 'stop_bounce'), ('mu_sigma', 'feed_slip')):
        if getattr(params, key) > 0.0 and effect not in effects:
            raise ParameterError(
                f'effects.property_scatter.{key}',
                getattr(params, key),
                f'scatters {effect}, which the scene does not list: list it or set 0',
            )


def factors(sigma: float, seed: int, quantity: str, n: int) -> np.ndarray:
    """Factors ``1 + σ z_k`` of signatures k = 0 .. n-1 (z clipped at ±3) for ``quantity`` ('e' or 'mu')."""
    z = stream(seed, f'folder.property_scatter.{quantity}').standard_normal(n)
    return 1.0 + sigma * np.clip(z, -TRUNCATE, TRUNCATE)


def factors_from(sigma: float, rng: np.random.Generator, n: int) -> np.ndarray:
    """The next ``n`` factors of :func:`factors` from the stream ``rng``."""
    return 1.0 + sigma * np.clip(rng.standard_normal(n), -TRUNCATE, TRUNCATE)


def restitution_from(params: Params, e: float, rng: np.random.Generator, n: int) -> np.ndarray:
    """The next ``n`` restitutions of :func:`restitution` from the stream ``rng``."""
    return np.clip(e * factors_from(params.e_sigma, rng, n), 0.0, E_MAX)


def friction_from(params: Params, mu: float, rng: np.random.Generator, n: int) -> np.ndarray:
    """The next ``n`` friction coefficients of :func:`friction` from the stream ``rng``."""
    return np.clip(mu * factors_from(params.mu_sigma, rng, n), 0.0, MU_MAX)


def restitution(params: Params, e: float, seed: int, n: int) -> np.ndarray:
    """``e_k`` of signatures k = 0 .. n-1 (module docstring)."""
    return np.clip(e * factors(params.e_sigma, seed, 'e', n), 0.0, E_MAX)


def friction(params: Params, mu: float, seed: int, n: int) -> np.ndarray:
    """``mu_k`` of signatures k = 0 .. n-1 (module docstring)."""
    return np.clip(mu * factors(params.mu_sigma, seed, 'mu', n), 0.0, MU_MAX)
