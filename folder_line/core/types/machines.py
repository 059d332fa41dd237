"""Parameters of the line's machine sections that are not a mechanism of their own.

Each is a frozen dataclass with no defaults (defaults live in ``config/<kind>.yaml``)
validated on construction; errors name the key as ``<section>.<field>``.
"""

from __future__ import annotations

from dataclasses import dataclass

from folder_line.core.limits import DURATION, LINEAR_SPEED, MACHINE_LENGTH, SHEET_INTERVAL
from folder_line.core.numerics.validate import in_range, non_negative, positive
from folder_line.errors import ParameterError

__all__ = ['ChainParams', 'ContainerParams', 'FeedTransporterParams', 'StreamParams']


@dataclass(frozen=True)
class ContainerParams:
    """L: the container the leaves are laid into (project frame, m).

    Attributes
    ----------
    x_left, x_right : float
        Inner walls, m, in [-1000, 1000] (x_left < x_right).
    y_floor : float
        Floor height, m, in [-1000, 1000] (below both chute exits).
    bins : int
        Bins of the landing histogram across the width, a whole number in [2, 10000].
    """

    x_left: float
    x_right: float
    y_floor: float
    bins: int

    def __post_init__(self) -> None:
        for name in ('x_left', 'x_right', 'y_floor'):
            object.__setattr__(self, name, in_range(f'container.{name}', getattr(self, name), -1e3, 1e3))
        if self.x_right <= self.x_left:
            raise ParameterError('container.x_right', self.x_right, f'must be > container.x_left = {self.x_left!r}')
        if isinstance(self.bins, bool) or not isinstance(self.bins, int) or not 2 <= self.bins <= 10_000:
            raise ParameterError('container.bins', self.bins, 'must be a whole number in [2, 10000]')

    @property
    def width(self) -> float:
        """Inner width, m."""
        return self.x_right - self.x_left


@dataclass(frozen=True)
class FeedTransporterParams:
    """F: the 2nd (feed) transporter.

    Attributes
    ----------
    V_tr : float
        Belt speed at nominal line speed, m/s (> 0).
    """

    V_tr: float

    def __post_init__(self) -> None:
        object.__setattr__(self, 'V_tr', LINEAR_SPEED.check('feed_transporter.V_tr', self.V_tr))


@dataclass(frozen=True)
class ChainParams:
    """D: the delivery chain that carries the folded signature to the pile.

    One carriage passes the delivery stroke per machine cycle T, so the chain speed is
    ``v_A = pitch / T``.

    Attributes
    ----------
    x_max : float
        Length of one section (deceleration or acceleration) of the stroke, m, in [1e-4, 100].
    pitch : float
        Chain length between two carriages, m (> 0). A scene refuses more than 100 carriages on the
        stroke at once, and a chain speed ``pitch / T`` outside :data:`~folder_line.core.limits.LINEAR_SPEED`
        (:func:`folder_line.core.mechanisms.chain.schedule`).
    L_transfer : float
        Chain travel from taking the signature at the folding rollers to the start of
        the stroke, m (>= 0).
    """

    x_max: float
    pitch: float
    L_transfer: float

    def __post_init__(self) -> None:
        object.__setattr__(self, 'x_max', MACHINE_LENGTH.check('delivery_chain.x_max', self.x_max))
        object.__setattr__(self, 'pitch', positive('delivery_chain.pitch', self.pitch))
        object.__setattr__(self, 'L_transfer', non_negative('delivery_chain.L_transfer', self.L_transfer))


@dataclass(frozen=True)
class StreamParams:
    """The stream of sheets (F: one signature per knife cycle) or leaves (L).

    Attributes
    ----------
    interval : float
        L: mean time between two leaves entering the chutes (they alternate between
        transporter 3 and 4), s (> 0). F ignores it: one signature per cycle T.
    jitter : float
        L: uniform random spread of each arrival, as a fraction of ``interval``, in
        [0, 1); drawn from the scene's seed. F ignores it (a late signature is a fault).
    phase : float
        Delay of every arrival after its nominal time, s, in [0, 1e7] (the longest line time,
        :data:`folder_line.core.limits.DURATION`): L, of the first leaf;
        F, of the handover after the feed window opens.
    thickness : float
        Thickness of one counted sheet as it lies stacked, m, in (0, 0.1]: F with D, a
        folded signature on the delivery's pile; otherwise a leaf on the container
        floor. The sheet counter's table sinks by it per sheet
        (:mod:`folder_line.core.mechanisms.pile`).
    """

    interval: float
    jitter: float
    phase: float
    thickness: float

    def __post_init__(self) -> None:
        object.__setattr__(self, 'interval', SHEET_INTERVAL.check('sheets.interval', self.interval))
        object.__setattr__(self, 'jitter', in_range('sheets.jitter', self.jitter, 0.0, 1.0, hi_open=True))
        object.__setattr__(self, 'phase', in_range('sheets.phase', self.phase, 0.0, DURATION.hi))
        object.__setattr__(self, 'thickness', in_range('sheets.thickness', self.thickness, 0.0, 0.1, lo_open=True))
