"""``folder-line solve``: the value of one scene key where a condition on a metric starts to hold.

``--find feed_transporter.V_tr --where 'min_margin_s.feed_window>=0'`` answers "what is the
slowest feed transporter that still feeds in time?" in two steps:

1. **Bracket.** A coarse scan of ``scan`` evenly spaced values over ``[lo, hi]`` (run as one
   Dask batch, :func:`folder_line.studies.runner.run_tasks`). Points the model refuses are
   skipped. The first pair of neighbouring evaluated values where the condition changes
   (fails -> holds or holds -> fails) is the bracket; none in the range is an error naming the
   range and the metric at its ends.
2. **Refine.** :func:`scipy.optimize.brentq` inside that bracket, in this process, to the
   absolute tolerance ``tol`` in the key's unit, on the signed distance to the condition
   (``metric - threshold`` for ``>``/``>=``, ``threshold - metric`` for ``<``/``<=``) whose sign
   is the condition's truth (where the distance is 0 but the condition fails, as for ``> 0``,
   it counts as a tiny negative). The bracket's ends are the scan's values, not simulated
   again. On a continuous metric (a margin) brentq converges super-linearly to the zero; on a
   step (a count) its bisection steps still close the bracket on the jump. Either way the
   answer is within ``tol`` of where the condition changes.

The default range is ``[x0 / 2, 2 x0]`` around the scene's own value ``x0`` of the key
(``x0 != 0``); ``--between`` gives any other. The scan stays inside it; values the model
refuses (outside a key's physical limits, :mod:`folder_line.core.limits`) are skipped.
"""

from __future__ import annotations

import itertools
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import IO

import numpy as np

from folder_line.config.scenes import apply_overrides
from folder_line.core.line.metric_units import metric_unit
from folder_line.core.line.metrics import flatten_metrics, resolve_metric
from folder_line.errors import FolderLineError, ParameterError
from folder_line.studies.keys import check_key, key_unit, scene_value
from folder_line.studies.points import OK, PointTask, evaluate_point, simulate_summary
from folder_line.studies.runner import Cluster, run_tasks

__all__ = ['DEFAULT_SCAN', 'Condition', 'SolveResult', 'parse_condition', 'solve_boundary']

#: values of the bracketing scan by default
DEFAULT_SCAN = 9
#: default tolerance, as a fraction of the range's width
DEFAULT_TOL_FRACTION = 1e-6
#: most refinement steps (brentq's maxiter)
MAX_ITER = 200
#: the sign given to a distance of exactly 0 where the condition fails (``> 0`` at 0)
_TINY = 1e-300

_CONDITION = re.compile(r'^\s*(?P<metric>[A-Za-z_][\w.]*)\s*(?P<op>>=|<=|>|<)\s*(?P<number>\S+)\s*$')


@dataclass(frozen=True)
class Condition:
    """``METRIC OP NUMBER``: a metric compared with a threshold.

    Attributes
    ----------
    metric : str
        Metric path or unique suffix (resolved against the scene's summary).
    op : str
        ``>=``, ``>``, ``<=`` or ``<``.
    threshold : float
        In the metric's unit.
    """

    metric: str
    op: str
    threshold: float

    @property
    def text(self) -> str:
        """``'min_margin_s.feed_window>=0'``."""
        return f'{self.metric}{self.op}{self.threshold:g}'

    def distance(self, value: float) -> float:
        """Signed distance of ``value`` to the threshold, positive on the side where the condition holds."""
        return value - self.threshold if self.op.startswith('>') else self.threshold - value

    def holds(self, value: float) -> bool:
        """The condition at ``value`` (in the metric's unit)."""
        d = self.distance(value)
        return d >= 0.0 if self.op.endswith('=') else d > 0.0


def parse_condition(text: str, option: str = '--where') -> Condition:
    """``'min_margin_s.feed_window>=0'`` -> :class:`Condition` (ParameterError naming ``option`` otherwise)."""
    match = _CONDITION.match(text)
    if match is None:
        raise ParameterError(option, text, "must be METRIC OP NUMBER with OP one of >=, >, <=, <, e.g. 'V_tr_min<=10'")
    try:
        threshold = float(match['number'])
    except ValueError:
        raise ParameterError(option, text, f'{match["number"]!r} is not a number') from None
    if not math.isfinite(threshold):
        raise ParameterError(option, text, 'the threshold must be a finite number')
    return Condition(match['metric'], match['op'], threshold)


@dataclass(frozen=True)
class SolveResult:
    """Where the condition starts to hold.

    Attributes
    ----------
    key : str
        The key solved for.
    unit : str
        Its unit ('' if not known).
    condition : Condition
        The condition, its metric resolved to a path.
    metric_unit : str
        Unit of the metric.
    value : float
        The boundary value of the key, within ``tolerance`` of where the condition changes.
    tolerance : float
        Absolute, in the key's unit.
    holds : str
        ``'above'``: the condition holds just above ``value`` (fails below); ``'below'``: the reverse.
    bracket : tuple of float
        The scan's bracket ``(a, b)``, a < b.
    between : tuple of float
        The range scanned.
    scan : tuple of (float, float or None)
        The scan's values of the key and the metric there (None: refused by the model).
    evaluations : int
        Simulations run: the scene's own point, the scan and the refinement.
    """

    key: str
    unit: str
    condition: Condition
    metric_unit: str
    value: float
    tolerance: float
    holds: str
    bracket: tuple[float, float]
    between: tuple[float, float]
    scan: tuple[tuple[float, float | None], ...]
    evaluations: int

    def document(self) -> dict[str, object]:
        """The JSON of ``--json``."""
        return {
            'value': self.value,
            'tolerance': self.tolerance,
            'key': self.key,
            'unit': self.unit,
            'condition': self.condition.text,
            'metric': self.condition.metric,
            'metric_unit': self.metric_unit,
            'holds': self.holds,
            'bracket': list(self.bracket),
            'between': list(self.between),
            'scan': [{'value': x, 'metric': m} for x, m in self.scan],
            'evaluations': self.evaluations,
            'method': 'scan, then scipy.optimize.brentq on the signed distance to the condition',
        }


def _default_range(source: Mapping[str, object], key: str) -> tuple[float, float]:
    x0 = scene_value(source, key)
    if isinstance(x0, bool) or not isinstance(x0, int | float) or x0 == 0 or not math.isfinite(x0):
        raise ParameterError(
            '--between', None, f'needed: the scene value of {key} is {x0!r}, no range [x0/2, 2 x0] around it'
        )
    a, b = 0.5 * float(x0), 2.0 * float(x0)
    return (min(a, b), max(a, b))


def _fmt(value: float | None) -> str:
    return 'refused' if value is None else f'{value:.6g}'


def _bracket(
    evaluated: list[tuple[float, float]], cond: Condition, key: str, between: tuple[float, float], scan: int
) -> tuple[tuple[float, float], str]:
    """The first pair of neighbours of the scan ``evaluated`` ((value of ``key``, metric)) across which
    ``cond`` changes, and whether it holds ``'above'`` or ``'below'`` it; ``ParameterError`` naming
    ``--between`` when there is none."""
    for (xa, va), (xb, vb) in itertools.pairwise(evaluated):
        if cond.holds(va) != cond.holds(vb):
            return (xa, xb), ('above' if cond.holds(vb) else 'below')
    path = cond.metric
    ends = (
        f'{path} = {_fmt(evaluated[0][1])} at {evaluated[0][0]:.6g} and {_fmt(evaluated[-1][1])} at '
        f'{evaluated[-1][0]:.6g}'
        if evaluated
        else 'the model refused every value'
    )
    where = 'everywhere' if evaluated and cond.holds(evaluated[0][1]) else 'nowhere'
    lo, hi = between
    raise ParameterError(
        '--between',
        f'{lo:.6g}:{hi:.6g}',
        f'{cond.text} holds {where} in the range of {key} ({scan} values scanned): {ends}; no boundary to find'
        if evaluated
        else f'no boundary of {cond.text} in the range of {key}: {ends}',
    )


class _SignedDistance:
    """The function whose root :func:`solve_boundary` finds: the condition's distance, positive where it
    holds, at a value of the key; each value simulated once (``known`` seeds it), counted in :attr:`count`."""

    def __init__(
        self, source: Mapping[str, object], key: str, duration: float, cond: Condition, known: dict[float, float]
    ) -> None:
        self.source = source
        self.key = key
        self.duration = duration
        self.cond = cond
        self.known = known
        self.count = 0

    def __call__(self, x: float) -> float:
        got = self.known.get(x)
        if got is None:
            self.count += 1
            path = self.cond.metric
            try:
                summary = simulate_summary(apply_overrides(self.source, {self.key: x}), self.duration)
                got = flatten_metrics(summary.as_json()).get(path)
            except FolderLineError as exc:
                raise ParameterError(self.key, x, f'refused by the model while refining the boundary: {exc}') from None
            if got is None:
                raise ParameterError(self.key, x, f'the summary has no {path} here')
            self.known[x] = got
        d = self.cond.distance(got)
        ok = self.cond.holds(got)
        return d if (d > 0.0) == ok and d != 0.0 else (_TINY if ok else -_TINY)


def solve_boundary(
    source: Mapping[str, object],
    key: str,
    condition: Condition,
    duration: float,
    cluster: Cluster,
    *,
    between: tuple[float, float] | None = None,
    tol: float | None = None,
    scan: int = DEFAULT_SCAN,
    progress: IO[str] | None = None,
) -> SolveResult:
    """Find the value of ``key`` where ``condition`` starts to hold.

    Parameters
    ----------
    source : mapping
        The complete scene mapping (``--set`` applied).
    key : str
        The scene key to solve for (``--find``).
    condition : Condition
        ``METRIC OP NUMBER`` (``--where``); the metric is resolved against the scene's summary.
    duration : float
        Line time per evaluation, s.
    cluster : Cluster
        Where the scan runs.
    between : (float, float), optional
        The range, in the key's unit; default ``[x0/2, 2 x0]`` around the scene's value x0.
    tol : float, optional
        Absolute tolerance on the answer, in the key's unit (> 0); default 1e-6 of the range's width.
    scan : int
        Values of the bracketing scan (>= 2).
    progress : text stream, optional
        The scan's progress bar.

    Returns
    -------
    SolveResult

    Raises
    ------
    ParameterError
        An unknown key or metric; no change of the condition in the range (naming the range and the
        metric at its ends); a point of the refinement the model refuses.
    """
    check_key(source, key, '--find')
    flat = flatten_metrics(summary := simulate_summary(source, duration).as_json())
    path = resolve_metric(condition.metric, list(flat), '--where')
    cond = Condition(path, condition.op, condition.threshold)
    lo, hi = between if between is not None else _default_range(source, key)
    width = hi - lo
    tolerance = DEFAULT_TOL_FRACTION * width if tol is None else tol
    if not (math.isfinite(tolerance) and 0.0 < tolerance < width):
        raise ParameterError('--tol', tol, f'must be > 0 and below the range width {width:.6g}')
    if not 2 <= scan <= 10_000:
        raise ParameterError('--scan', scan, 'must be a whole number in [2, 10000]')
    xs = [float(x) for x in np.linspace(lo, hi, scan)]
    tasks = [PointTask(source, ((key, x),), duration, (path,)) for x in xs]
    results = run_tasks(evaluate_point, tasks, cluster, label='solve scan', progress=progress)
    values = [r.values[0] if r.status == OK else None for r in results]
    scanned = tuple(zip(xs, values, strict=True))
    evaluated = [(x, v) for x, v in scanned if v is not None]
    bracket, holds = _bracket(evaluated, cond, key, (lo, hi), scan)
    # the metric by the exact value of the key: the scan's values seed it, so brentq's first two
    # calls (the bracket's ends) are not simulated again
    signed = _SignedDistance(source, key, duration, cond, dict(evaluated))

    from scipy.optimize import brentq

    value = float(brentq(signed, bracket[0], bracket[1], xtol=tolerance, maxiter=MAX_ITER))
    return SolveResult(
        key=key,
        unit=key_unit(source, key),
        condition=cond,
        metric_unit=metric_unit(path, summary),
        value=value,
        tolerance=tolerance,
        holds=holds,
        bracket=bracket,
        between=(lo, hi),
        scan=scanned,
        evaluations=1 + len(xs) + signed.count,
    )
