"""The layup's figures in a run's summary (:class:`LayupFigures`): leaves counted, exit speeds, landings.

:meth:`folder_line.core.line.layup_stream.LayupStream.summary` makes them of the events handed
out. Each class's ``as_json()`` is its block of the ``simulate`` summary, keys in the order
written, a section of an effect the scene does not list left out.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from folder_line.core.effects.leaf_flight import Histogram
    from folder_line.core.line.running import RunningStats

__all__ = [
    'ExtremeSpeed',
    'GuideFrictionFigures',
    'Landing',
    'LandingHistogram',
    'LayupFigures',
    'LeafStats',
    'PhaseSpeeds',
    'SwingSpeed',
]


@dataclass(frozen=True)
class LeafStats:
    """Count, mean, minimum and maximum of a figure over the leaves (in its unit)."""

    leaves: int
    mean: float
    min: float
    max: float

    @classmethod
    def of(cls, stats: RunningStats) -> LeafStats | None:
        """The figures of ``stats`` (None if nothing was added)."""
        if not stats.count:
            return None
        return cls(stats.count, float(stats.sum.value / stats.count), stats.low, stats.high)

    def as_json(self) -> dict[str, object]:
        """``{'leaves', 'mean', 'min', 'max'}``."""
        return {'leaves': self.leaves, 'mean': self.mean, 'min': self.min, 'max': self.max}


@dataclass(frozen=True)
class ExtremeSpeed:
    """The exit speeds near a rocker dead centre.

    Attributes
    ----------
    phi : float
        The crank angle of the dead centre, rad.
    window_deg : float
        The crank angles around it counted, deg.
    exit_speed : LeafStats or None
        The absolute exit speeds there, m/s (None: no leaf exited there).
    """

    phi: float
    window_deg: float
    exit_speed: LeafStats | None

    def as_json(self) -> dict[str, object]:
        """``{'phi', 'window_deg', 'exit_speed'}``."""
        speed = None if self.exit_speed is None else self.exit_speed.as_json()
        return {'phi': self.phi, 'window_deg': self.window_deg, 'exit_speed': speed}


@dataclass(frozen=True)
class PhaseSpeeds:
    """The mean exit speed per bin of exit crank angle: ``edges_deg`` (deg), ``mean`` (m/s, None where empty)."""

    edges_deg: list[float]
    mean: list[float | None]

    def as_json(self) -> dict[str, object]:
        """``{'edges_deg', 'mean'}``."""
        return {'edges_deg': list(self.edges_deg), 'mean': list(self.mean)}


@dataclass(frozen=True)
class SwingSpeed:
    """The chute exits' swing speed over a crank turn, smallest and largest, m/s."""

    min: float
    max: float

    def as_json(self) -> dict[str, object]:
        """``{'min', 'max'}``."""
        return {'min': self.min, 'max': self.max}


@dataclass(frozen=True)
class LandingHistogram:
    """Landings across the container: bin ``edges`` (m), ``counts``, ``cv`` of the counts (None: none landed)."""

    edges: list[float]
    counts: list[int]
    cv: float | None

    @classmethod
    def of(cls, hist: Histogram) -> LandingHistogram:
        """The histogram ``hist``, as plain numbers."""
        return cls([float(e) for e in hist.edges], [int(c) for c in hist.counts], hist.cv)

    def as_json(self) -> dict[str, object]:
        """``{'edges', 'counts'}`` (the cv is the summary's ``landing_cv``)."""
        return {'edges': list(self.edges), 'counts': list(self.counts)}


@dataclass(frozen=True)
class Landing:
    """``leaf_flight``'s figures: where the leaves landed and how many spilled over each wall.

    Attributes
    ----------
    histogram : LandingHistogram
    x : LeafStats or None
        The landing positions, m (None: none landed).
    spilled_left, spilled_right : int
    """

    histogram: LandingHistogram
    x: LeafStats | None
    spilled_left: int
    spilled_right: int

    def as_json(self) -> dict[str, object]:
        """The keys ``landing_histogram``, ``landing_cv``, ``landing_x``, ``spilled_left``, ``spilled_right``."""
        return {
            'landing_histogram': self.histogram.as_json(),
            'landing_cv': self.histogram.cv,
            'landing_x': None if self.x is None else self.x.as_json(),
            'spilled_left': self.spilled_left,
            'spilled_right': self.spilled_right,
        }


@dataclass(frozen=True)
class GuideFrictionFigures:
    """``guide_friction``'s figures: integrator steps summed over the leaves, sticks, slips, the exit
    speed along the chute (m/s; None: no leaf exited)."""

    steps: int
    sticks: int
    slips: int
    exit_speed_along: LeafStats | None

    def as_json(self) -> dict[str, object]:
        """The ``guide_friction`` block."""
        along = None if self.exit_speed_along is None else self.exit_speed_along.as_json()
        return {'steps': self.steps, 'sticks': self.sticks, 'slips': self.slips, 'exit_speed_along': along}


@dataclass(frozen=True)
class LayupFigures:
    """The layup's figures (the summary's ``layup`` block).

    Attributes
    ----------
    crank_cycles : int
        Crank turns completed.
    leaves, leaves_exited, leaves_landed, leaves_spilled, leaves_damaged : int
        Leaves entered, exited, landed, spilled, damaged.
    min_exit_speed, max_exit_speed, mean_exit_speed : float or None
        Absolute exit speeds, m/s (None: no leaf exited).
    exit_speed_at_extremes : dict of str to ExtremeSpeed
        Dead centre kind (``'extended'``, ``'folded'``) -> the exit speeds near it.
    exit_speed_by_phase : PhaseSpeeds
    swing_speed : SwingSpeed
    landing : Landing or None
        With ``leaf_flight``.
    guide_friction : GuideFrictionFigures or None
        With ``guide_friction``.
    """

    crank_cycles: int
    leaves: int
    leaves_exited: int
    leaves_landed: int
    leaves_spilled: int
    leaves_damaged: int
    min_exit_speed: float | None
    max_exit_speed: float | None
    mean_exit_speed: float | None
    exit_speed_at_extremes: dict[str, ExtremeSpeed]
    exit_speed_by_phase: PhaseSpeeds
    swing_speed: SwingSpeed
    landing: Landing | None = None
    guide_friction: GuideFrictionFigures | None = None

    def as_json(self) -> dict[str, object]:
        """The ``layup`` block."""
        out: dict[str, object] = {
            'crank_cycles': self.crank_cycles,
            'leaves': self.leaves,
            'leaves_exited': self.leaves_exited,
            'leaves_landed': self.leaves_landed,
            'leaves_spilled': self.leaves_spilled,
            'leaves_damaged': self.leaves_damaged,
            'min_exit_speed': self.min_exit_speed,
            'max_exit_speed': self.max_exit_speed,
            'mean_exit_speed': self.mean_exit_speed,
            'exit_speed_at_extremes': {k: v.as_json() for k, v in self.exit_speed_at_extremes.items()},
            'exit_speed_by_phase': self.exit_speed_by_phase.as_json(),
            'swing_speed': self.swing_speed.as_json(),
        }
        if self.landing is not None:
            out.update(self.landing.as_json())
        if self.guide_friction is not None:
            out['guide_friction'] = self.guide_friction.as_json()
        return out
