"""Optimise the layup geometry: the most even layup (smallest ``landing_cv``) under the design constraints.

The design variables are link lengths of the layup six-bar (any of :data:`LINK_KEYS`), each
within bounds. A candidate is judged in two stages, cheapest first:

1. geometry (no simulation, about a millisecond): loop O1-A-B-O2 a Grashof crank-rocker,
   both loops assembled over the whole crank turn with a transmission angle of at least
   ``min_transmission`` (:mod:`folder_line.core.mechanisms.layup_design`), both chute exits
   inside the container walls and above its floor over the whole swing;
2. only a geometry that passes is simulated (:func:`folder_line.core.line.model.run_summary` of
   the scene with the candidate's values, streamed in memory that does not grow with the line
   time): no leaf may spill over a wall or be damaged, and the objective is the summary's
   ``layup.landing_cv``.

The optimiser is :func:`scipy.optimize.differential_evolution`, seeded (a run is
deterministic), started from a population that holds the scene's own geometry (so the best
found is never worse than the start when the start is feasible), with the geometric
constraints as a ``NonlinearConstraint`` (scipy evaluates the objective only where they all
hold) and the simulated one as a penalty (a spilled or damaged leaf costs more than any
landing CV can). No polishing: the objective is a histogram statistic, piecewise constant
in the geometry, with no useful gradient.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import IO, TYPE_CHECKING, NamedTuple

import numpy as np

from folder_line.config.scenes import SceneMapping, apply_overrides
from folder_line.core.line.layup_figures import Landing, LayupFigures
from folder_line.core.line.line_summary import LineSummary
from folder_line.core.line.model import run_summary
from folder_line.core.line.scene import Scene, parse_scene
from folder_line.core.mechanisms.layup import LayupParams
from folder_line.core.mechanisms.layup_design import crank_rocker_margin, exit_clearance, transmission_check
from folder_line.core.numerics.validate import build
from folder_line.errors import FolderLineError, ParameterError
from folder_line.studies.grid import parse_bounds

if TYPE_CHECKING:
    from scipy.optimize import OptimizeResult as ScipyResult

__all__ = [
    'CONSTRAINTS',
    'DEFAULT_KEYS',
    'DEFAULT_SPAN',
    'LINK_KEYS',
    'Bound',
    'Candidate',
    'OptimizeResult',
    'OptimizeSettings',
    'check_scene',
    'default_bounds',
    'evaluate',
    'optimize_layup',
    'parse_design_vary',
]

#: the layup's dimensions a study may vary (m); n_kr and v_tr are speeds, not geometry
LINK_KEYS = ('R_kr', 'a', 'b', 'l2', 'O2B', 'l3', 'l4', 'l5', 'O2O3')
#: varied when no ``--vary`` is given: the links of both loops and the chute pivots' distance
DEFAULT_KEYS = ('R_kr', 'l2', 'O2B', 'l3', 'l4', 'l5', 'O2O3')
#: default bounds: the scene's value ± this fraction of it
DEFAULT_SPAN = 0.15
#: objective of a simulated geometry that spills or damages a leaf (CV of 31 bins is at most sqrt(30))
PENALTY = 10.0
#: names of the constraints, all margins >= 0 where met, with their units
CONSTRAINTS: dict[str, str] = {
    'crank_rocker': 'm',
    'assembly': '1',
    'transmission_deg': 'deg',
    'exits_left': 'm',
    'exits_right': 'm',
    'exits_floor': 'm',
    'no_spill_or_damage': 'leaves',
}
#: a margin this close to 0 (in its unit) counts as an active constraint at the optimum
ACTIVE_TOL: dict[str, float] = {
    'crank_rocker': 1e-3,
    'assembly': 1e-3,
    'transmission_deg': 0.5,
    'exits_left': 5e-3,
    'exits_right': 5e-3,
    'exits_floor': 5e-3,
}


@dataclass(frozen=True)
class Bound:
    """Bounds of one design variable: ``layup.<key>`` in ``[lo, hi]``, m."""

    key: str
    lo: float
    hi: float


#: what one ``--vary`` of optimize is, for the messages
_VARY_FORM = 'layup.KEY=LO:HI, e.g. layup.l4=0.55:0.70'


def parse_design_vary(items: Sequence[str], option: str = '--vary') -> tuple[Bound, ...]:
    """``['layup.l4=0.55:0.7', ...]`` -> bounds, each key once.

    Raises
    ------
    ParameterError
        Naming ``option`` and the item: not ``layup.KEY=LO:HI``, a key not in :data:`LINK_KEYS`,
        a key given twice, LO:HI refused by :func:`folder_line.studies.grid.parse_bounds`, or a
        non-positive bound of a length (all but ``a``, ``b``).
    """
    out: list[Bound] = []
    for item in items:
        key, sep, rng = item.partition('=')
        section, dot, name = key.strip().partition('.')
        if not (sep and dot) or section != 'layup':
            raise ParameterError(option, item, f'must be {_VARY_FORM}')
        if name not in LINK_KEYS:
            raise ParameterError(option, item, f'{name!r} is not a link of the layup; one of {", ".join(LINK_KEYS)}')
        if any(b.key == name for b in out):
            raise ParameterError(option, item, f'layup.{name} is given twice')
        lo, hi = parse_bounds(rng, option, item=item, form=_VARY_FORM)
        if name not in ('a', 'b') and lo <= 0.0:
            raise ParameterError(option, item, f'a length must stay > 0 (LO = {lo:g})')
        out.append(Bound(name, lo, hi))
    return tuple(out)


def default_bounds(
    layup: Mapping[str, float], keys: Sequence[str] = DEFAULT_KEYS, span: float = DEFAULT_SPAN
) -> tuple[Bound, ...]:
    """Bounds ``value · (1 ± span)`` around the scene's own values of ``keys``.

    Parameters
    ----------
    layup : mapping
        The scene's ``layup`` section (merged with the defaults), m.
    keys : sequence of str
        Keys of :data:`LINK_KEYS`.
    span : float
        Relative half-width (0.15: ±15 %).
    """
    out = []
    for key in keys:
        v = float(layup[key])
        lo, hi = sorted((v * (1.0 - span), v * (1.0 + span)))
        out.append(Bound(key, lo, hi))
    return tuple(out)


@dataclass(frozen=True)
class OptimizeSettings:
    """How to optimise.

    Attributes
    ----------
    min_transmission_deg : float
        Smallest transmission angle ``min(μ, 180° − μ)`` allowed in either loop over the turn, deg.
    duration : float
        Line time simulated per candidate, s.
    seed : int
        Seed of the optimiser (the scene keeps its own seed for the leaf stream).
    maxiter : int
        Generations of differential evolution.
    popsize : int
        Population size per design variable (scipy's ``popsize``).
    tol : float
        scipy's relative convergence tolerance on the population's objective spread.
    """

    min_transmission_deg: float = 40.0
    duration: float = 600.0
    seed: int = 1
    maxiter: int = 80
    popsize: int = 12
    tol: float = 0.01

    def __post_init__(self) -> None:
        if not 0.0 < self.min_transmission_deg < 90.0:
            raise ParameterError('--min-transmission', self.min_transmission_deg, 'must be in (0, 90) deg')
        for name, lo in (('maxiter', 0), ('popsize', 1)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= 100_000:
                raise ParameterError(f'--{name}', v, f'must be a whole number in [{lo}, 100000]')
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or not 0 <= self.seed < 2**32:
            raise ParameterError('--seed', self.seed, 'must be a whole number in [0, 2**32)')


class _Dims(NamedTuple):
    """Unvalidated six-bar dimensions (m) of a candidate, for the geometric checks."""

    R_kr: float
    a: float
    b: float
    l2: float
    O2B: float
    l3: float
    l4: float
    l5: float
    O2O3: float


@dataclass(frozen=True)
class Candidate:
    """One judged geometry.

    Attributes
    ----------
    values : dict of str to float
        The varied keys' values, m.
    constraints : dict of str to float
        Margin of each constraint of :data:`CONSTRAINTS` (>= 0: met) that was evaluated; the
        simulated one only for a geometry that passed the others.
    transmission_deg : dict of str to float or None
        Smallest transmission angle of ``loop1`` and ``loop2`` over the turn, deg (None: does not close).
    geometry_ok : bool
        Every geometric constraint holds.
    summary : LineSummary or None
        The simulation summary (None: not simulated).
    """

    values: dict[str, float]
    constraints: dict[str, float]
    transmission_deg: dict[str, float | None]
    geometry_ok: bool
    summary: LineSummary | None = field(default=None, repr=False)

    @property
    def layup(self) -> LayupFigures | None:
        """The layup's figures of the simulation (None: not simulated)."""
        return None if self.summary is None else _layup_of(self.summary)

    @property
    def landing(self) -> Landing | None:
        """Where the leaves of the simulation landed (None: not simulated, or no ``leaf_flight``)."""
        return None if self.layup is None else self.layup.landing

    @property
    def landing_cv(self) -> float | None:
        """``layup.landing_cv`` of the simulation (None: not simulated or nothing landed)."""
        cv = None if self.landing is None else self.landing.histogram.cv
        return None if cv is None else float(cv)

    @property
    def feasible(self) -> bool:
        """Every constraint holds (the geometry and the simulation) and leaves landed."""
        return (
            self.geometry_ok and self.constraints.get('no_spill_or_damage', -1.0) >= 0.0 and self.landing_cv is not None
        )

    @property
    def objective(self) -> float:
        """What is minimised: the landing CV if feasible, else more than any CV (inf: not simulated)."""
        if not self.geometry_ok or self.summary is None:
            return math.inf
        cv = self.landing_cv
        if self.feasible and cv is not None:  # feasible includes a landing CV; said again for the type
            return cv
        lay = _layup_of(self.summary)
        return float(
            PENALTY
            + (lay.leaves_spilled + lay.leaves_damaged) / max(lay.leaves, 1)
            + (1.0 if self.landing_cv is None else 0.0)
        )


def _layup_of(summary: LineSummary) -> LayupFigures:
    """The layup's figures of a summary (KeyError: the scene has no layup)."""
    if summary.layup is None:
        raise KeyError('layup')
    return summary.layup


def _layup_section(mapping: SceneMapping, values: Mapping[str, float]) -> dict[str, float]:
    section = dict(mapping['machines']['layup'])
    section.update(values)
    return section


#: what :func:`_geometry` finds: the geometric margins, the transmission angles, whether all margins hold
_Geometry = tuple[dict[str, float], dict[str, float | None], bool]


def _geometry(mapping: SceneMapping, values: Mapping[str, float], mu_min: float) -> _Geometry:
    """The geometric margins of a candidate (cheap, no simulation), its transmission angles, and whether all hold."""
    section = _layup_section(mapping, values)
    try:
        dims = _Dims(*(float(section[k]) for k in LINK_KEYS))
    except (TypeError, ValueError):
        raise ParameterError('layup', {k: section.get(k) for k in LINK_KEYS}, 'dimensions must be numbers') from None
    out = {'crank_rocker': crank_rocker_margin(math.hypot(dims.a, dims.b), dims.R_kr, dims.l2, dims.O2B)}
    tc = transmission_check(dims)
    worst = max(tc.worst_cos1, tc.worst_cos2)
    out['assembly'] = 1.0 - worst if math.isfinite(worst) else -1e3
    mu1, mu2 = tc.mu1, tc.mu2
    angles = {'loop1': None if mu1 is None else math.degrees(mu1), 'loop2': None if mu2 is None else math.degrees(mu2)}
    # in degrees where both loops close, else continued below 0 by the cosine's excess (monotone, continuous)
    out['transmission_deg'] = (
        math.degrees(math.acos(worst)) - math.degrees(mu_min)
        if worst <= 1.0
        else -math.degrees(mu_min) - (min(worst, 1e3) - 1.0)
    )
    exits: tuple[float, ...] = (-1.0, -1.0, -1.0)
    if out['crank_rocker'] > 0.0 and out['transmission_deg'] >= 0.0:
        try:
            params = build(LayupParams, section, 'layup', 'layup parameter')
        except FolderLineError:  # within the toggle tolerance of LayupParams: refused there too
            out['assembly'] = min(out['assembly'], -1e-12)
        else:
            cont = mapping['machines']['container']
            exits = tuple(exit_clearance(params, float(cont['x_left']), float(cont['x_right']), float(cont['y_floor'])))
    out.update(zip(('exits_left', 'exits_right', 'exits_floor'), exits, strict=True))
    return out, angles, all(v >= 0.0 for v in out.values())


def evaluate(
    mapping: SceneMapping,
    values: Mapping[str, float],
    settings: OptimizeSettings,
    *,
    scene: Scene | None = None,
    geometry: _Geometry | None = None,
) -> Candidate:
    """Judge one geometry: the cheap geometric constraints, then, only if they all hold, a simulation.

    Parameters
    ----------
    mapping : mapping
        The complete scene mapping (:func:`folder_line.config.scenes.scene_mapping`), with a
        ``layup`` and a ``container`` machine and the ``leaf_flight`` effect.
    values : mapping of str to float
        ``{key: value}`` of :data:`LINK_KEYS` replacing the scene's, m.
    settings : OptimizeSettings
        The transmission angle required and the line time simulated.
    scene : Scene, optional
        ``mapping`` with ``values`` applied, parsed (None: parsed here if simulated).
    geometry : tuple, optional
        What the geometric checks found for ``values`` already (None: checked here).

    Returns
    -------
    Candidate
    """
    if geometry is None:
        geometry = _geometry(mapping, values, math.radians(settings.min_transmission_deg))
    cons, angles, ok = geometry
    constraints = dict(cons)  # the simulated constraint is added to a copy
    summary = None
    if ok:
        if scene is None:
            scene = parse_scene(apply_overrides(mapping, {f'layup.{k}': v for k, v in values.items()}))
        summary = run_summary(scene, settings.duration)
        lay = _layup_of(summary)
        constraints['no_spill_or_damage'] = -float(lay.leaves_spilled + lay.leaves_damaged)
    return Candidate(dict(values), constraints, dict(angles), ok, summary)


@dataclass(frozen=True)
class OptimizeResult:
    """What :func:`optimize_layup` found.

    Attributes
    ----------
    scene_name : str
        The name of the scene optimised.
    bounds : tuple of Bound
    settings : OptimizeSettings
    start, best : Candidate
        The scene's own geometry and the best feasible one found (``start`` if none beats it).
    scene : Scene
        The scene with the best geometry (validated).
    mapping : dict
        Its complete mapping (what ``scene.yaml`` holds).
    evaluations : dict of str to int
        ``candidates`` judged, ``geometry_ok`` of them, ``simulated``, ``spill_or_damage``
        (simulated but a leaf spilled or was damaged).
    message : str
        The optimiser's own message.
    nit, nfev : int
        scipy's generations and objective evaluations.
    seconds : float
        Wall time of the optimisation, s.
    """

    scene_name: str
    bounds: tuple[Bound, ...]
    settings: OptimizeSettings
    start: Candidate
    best: Candidate
    scene: Scene
    mapping: SceneMapping
    evaluations: dict[str, int]
    message: str
    nit: int
    nfev: int
    seconds: float

    @property
    def improved(self) -> bool:
        """The best geometry has a smaller landing CV than the start (or the start was infeasible)."""
        return self.best.values != self.start.values and (
            not self.start.feasible or self.best.objective < self.start.objective
        )

    def at_bounds(self, rel: float = 0.005) -> list[str]:
        """``layup.KEY=lo`` / ``=hi`` for each design variable of ``best`` within ``rel`` of its bound range
        from a bound (the bounds, not the constraints, stopped it there)."""
        out = []
        for b in self.bounds:
            v, tol = self.best.values[b.key], rel * (b.hi - b.lo)
            if v - b.lo <= tol:
                out.append(f'layup.{b.key}=lo')
            elif b.hi - v <= tol:
                out.append(f'layup.{b.key}=hi')
        return out

    def active(self, candidate: Candidate | None = None) -> list[str]:
        """Geometric constraints within :data:`ACTIVE_TOL` of their bound at ``candidate`` (default ``best``)."""
        c = self.best if candidate is None else candidate
        return [k for k, tol in ACTIVE_TOL.items() if k in c.constraints and c.constraints[k] <= tol]


def check_scene(mapping: SceneMapping) -> Scene:
    """Validate the scene an optimisation starts from; returns it parsed.

    Raises
    ------
    ParameterError
        The scene has no ``layup`` or ``container`` machine or does not list ``leaf_flight`` (no
        leaf lands, there is no ``landing_cv``), or any error of
        :func:`folder_line.core.line.scene.parse_scene`.
    """
    machines = mapping.get('machines', {})
    if 'layup' not in machines or 'container' not in machines or 'leaf_flight' not in mapping.get('effects', {}):
        raise ParameterError(
            '--scene',
            mapping.get('name'),
            'needs the layup and container machines and the leaf_flight effect (else no leaf lands: no landing_cv)',
        )
    return parse_scene(mapping)


def optimize_layup(
    mapping: SceneMapping,
    bounds: Sequence[Bound],
    settings: OptimizeSettings = OptimizeSettings(),
    *,
    scene: Scene | None = None,
    progress: IO[str] | None = None,
    clock: Callable[[], float] = time.monotonic,
) -> OptimizeResult:
    """Minimise ``layup.landing_cv`` over the geometry within ``bounds`` under the design constraints.

    Parameters
    ----------
    mapping : mapping
        The complete scene mapping (``--set`` applied), with ``layup``, ``container`` and ``leaf_flight``.
    bounds : sequence of Bound
        The design variables, each once.
    settings : OptimizeSettings
    scene : Scene, optional
        ``mapping`` as :func:`check_scene` returns it, if the caller checked it already (None: checked here).
    progress : text stream, optional
        Where one line per generation goes (best CV so far).
    clock : callable
        Wall clock for the reported time, s.

    Returns
    -------
    OptimizeResult

    Raises
    ------
    ParameterError
        The scene lands no leaves, or a bound is not a link of the layup.
    """
    if scene is None:
        scene = check_scene(mapping)  # the start must be a valid scene: its own errors first
    keys = [b.key for b in bounds]
    if not keys:
        raise ParameterError('--vary', [], 'needs at least one layup.KEY=LO:HI')
    lows, highs = np.array([b.lo for b in bounds]), np.array([b.hi for b in bounds])
    layup = mapping['machines']['layup']
    x_start = np.array([float(layup[k]) for k in keys])
    start = evaluate(mapping, dict(zip(keys, x_start.tolist(), strict=True)), settings, scene=scene)
    search = _Search(mapping, keys, settings, progress)

    from scipy.optimize import NonlinearConstraint, differential_evolution

    inside = bool(np.all((x_start >= lows) & (x_start <= highs)))
    t0 = clock()
    res = differential_evolution(
        search.objective,
        list(zip(lows, highs, strict=True)),
        maxiter=settings.maxiter,
        popsize=settings.popsize,
        tol=settings.tol,
        rng=np.random.default_rng(settings.seed),
        polish=False,
        init='latinhypercube',
        x0=x_start if inside else None,
        constraints=NonlinearConstraint(search.geometry, 0.0, np.inf),
        callback=search.report,
        updating='immediate',
    )
    seconds = clock() - t0
    found = search.seen.get(tuple(float(v) for v in res.x))
    best = start
    if found is not None and found.feasible and (not start.feasible or found.objective < start.objective):
        best = found
    best_mapping = apply_overrides(mapping, {f'layup.{k}': v for k, v in best.values.items()})
    if best is not start:
        best_mapping['name'] = f'{mapping["name"]}_optimized'
        best_mapping['description'] = (
            f'{mapping["name"]} with the layup geometry from folder-line optimize '
            f'(landing cv {_cv_text(start)} -> {_cv_text(best)}, {settings.duration:g} s)'
        )
    return OptimizeResult(
        scene_name=str(mapping['name']),
        bounds=tuple(bounds),
        settings=settings,
        start=start,
        best=best,
        scene=scene if best is start else parse_scene(best_mapping),
        mapping=best_mapping,
        evaluations=search.counts,
        message=str(res.message),
        nit=int(res.nit),
        nfev=int(res.nfev),
        seconds=seconds,
    )


class _Search:
    """The functions :func:`optimize_layup` hands to ``differential_evolution`` (the constraint, the objective
    and the progress callback), with the candidates they have seen and what they counted."""

    def __init__(
        self, mapping: SceneMapping, keys: list[str], settings: OptimizeSettings, progress: IO[str] | None
    ) -> None:
        self.mapping = mapping
        self.keys = keys
        self.settings = settings
        self.progress = progress
        self.mu_min = math.radians(settings.min_transmission_deg)
        self.seen: dict[tuple[float, ...], Candidate] = {}
        # of the constraint function, reused by the objective
        self.geometries: dict[tuple[float, ...], _Geometry] = {}
        self.counts = {'candidates': 0, 'geometry_ok': 0, 'simulated': 0, 'spill_or_damage': 0}
        self.generation = 0

    def values_of(self, x: np.ndarray) -> dict[str, float]:
        """The design variables ``x`` by key."""
        return dict(zip(self.keys, (float(v) for v in x), strict=True))

    def geometry(self, x: np.ndarray) -> np.ndarray:
        """The geometric constraints of ``x`` (each >= 0 when met), in the order of ``ACTIVE_TOL``."""
        self.counts['candidates'] += 1
        key = tuple(float(v) for v in x)
        found = self.geometries.get(key)
        if found is None:
            found = self.geometries[key] = _geometry(self.mapping, self.values_of(x), self.mu_min)
        cons, _, ok = found
        self.counts['geometry_ok'] += ok
        return np.array([cons[k] for k in ACTIVE_TOL])

    def objective(self, x: np.ndarray) -> float:
        """The landing CV of ``x`` (a penalty where it is infeasible), each candidate simulated once."""
        key = tuple(float(v) for v in x)
        cand = self.seen.get(key)
        if cand is None:
            cand = evaluate(self.mapping, self.values_of(x), self.settings, geometry=self.geometries.get(key))
            self.seen[key] = cand
            if cand.summary is not None:
                self.counts['simulated'] += 1
                self.counts['spill_or_damage'] += cand.constraints['no_spill_or_damage'] < 0.0
        return cand.objective

    def report(self, intermediate_result: ScipyResult) -> None:
        """One line per generation on the progress stream: the best CV so far."""
        self.generation += 1
        if self.progress is not None:
            fun = float(intermediate_result.fun)
            text = f'{fun:.4f}' if fun < PENALTY else 'none feasible yet'
            self.progress.write(
                f'generation {self.generation}/{self.settings.maxiter}: best landing cv {text}  '
                f'({self.counts["simulated"]} simulated of {self.counts["candidates"]} candidates)\n'
            )
            self.progress.flush()


def _cv_text(c: Candidate) -> str:
    cv = c.landing_cv
    return 'none' if cv is None else f'{cv:.4f}'
