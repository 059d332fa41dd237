"""What ``folder-line optimize`` reports: the JSON document, the verdict, the landing histograms (text, PNG)."""

from __future__ import annotations

import math
import os
from pathlib import Path

from folder_line.analysis.figures import pyplot, save_figure
from folder_line.studies.optimize import ACTIVE_TOL, CONSTRAINTS, Candidate, OptimizeResult

__all__ = ['histogram_lines', 'landing_figure', 'result_document', 'verdict']

#: width of the text histograms' bars, characters
_BAR = 28


def _cv(c: Candidate) -> str:
    cv = c.landing_cv
    return 'none' if cv is None else f'{cv:.4f}'


def _broken(c: Candidate) -> list[str]:
    return [k for k, v in c.constraints.items() if v < 0.0] + ([] if c.summary is not None else ['not simulated'])


def _spill_room(c: Candidate, walls: tuple[float, float] | None) -> str:
    """How close the leaves of ``c`` land to the walls (how near the no-spill constraint is), as text."""
    x = c.landing.x if c.landing is not None else None
    if walls is None or x is None:
        return ''
    return (
        f'; leaves land {1e3 * (x.min - walls[0]):.0f} mm from the left wall and '
        f'{1e3 * (walls[1] - x.max):.0f} mm from the right one'
    )


def verdict(result: OptimizeResult, walls: tuple[float, float] | None = None) -> str:
    """One paragraph: what was found, and, if the start was not beaten, the evidence.

    ``walls``: the container's ``x_left``, ``x_right`` (m), to say how near the leaves land to them.
    """
    r = result
    ev = r.evaluations
    tried = (
        f'{ev["candidates"]} candidates, {ev["geometry_ok"]} met the geometric constraints, '
        f'{ev["simulated"]} simulated, {ev["spill_or_damage"]} of those spilled or damaged a leaf'
    )
    active = ', '.join(r.active()) or 'none of the geometric ones'
    bounded = r.at_bounds()
    if bounded:
        active += f'; at a bound: {", ".join(bounded)} (wider bounds may do better)'
    if not r.start.feasible:
        head = f'the start geometry breaks {", ".join(_broken(r.start))}; '
        if r.best is r.start:
            return head + f'no feasible geometry was found within the bounds ({tried}).'
        return head + f'best feasible landing cv {_cv(r.best)} ({tried}); constraints active at the best: {active}.'
    if r.improved:
        cs, cb = r.start.landing_cv, r.best.landing_cv
        assert cs is not None and cb is not None
        return (
            f'landing cv {cs:.4f} -> {cb:.4f} ({100.0 * (cb - cs) / cs:+.1f} %) ({tried}); '
            f'constraints active at the best: {active}{_spill_room(r.best, walls)}.'
        )
    return (
        f'the start geometry could not be beaten under the constraints: no feasible candidate had a landing cv '
        f'below {_cv(r.start)} ({tried}); constraints active at the start: '
        f'{", ".join(r.active(r.start)) or "none of the geometric ones"}{_spill_room(r.start, walls)}.'
    )


def _candidate(c: Candidate) -> dict[str, object]:
    lay, landing = c.layup, c.landing
    return {
        'values': c.values,
        'landing_cv': c.landing_cv,
        'feasible': c.feasible,
        'leaves': None if lay is None else lay.leaves,
        'leaves_landed': None if lay is None else lay.leaves_landed,
        'leaves_spilled': None if lay is None else lay.leaves_spilled,
        'leaves_damaged': None if lay is None else lay.leaves_damaged,
        'landing_x': None if landing is None or landing.x is None else landing.x.as_json(),
        'constraints': c.constraints,
        'transmission_deg': c.transmission_deg,
        'landing_histogram': None if landing is None else landing.histogram.as_json(),
    }


def result_document(
    result: OptimizeResult, scene_file: str | None = None, walls: tuple[float, float] | None = None
) -> dict[str, object]:
    """The JSON-ready record of an optimisation (``optimize.json``); ``walls`` as for :func:`verdict`."""
    r, s = result, result.settings
    return {
        'scene': r.scene_name,
        'scene_file': scene_file,
        'objective': 'layup.landing_cv (minimised)',
        'duration_s': s.duration,
        'min_transmission_deg': s.min_transmission_deg,
        'bounds': {f'layup.{b.key}': [b.lo, b.hi] for b in r.bounds},
        'constraint_units': CONSTRAINTS,
        'active_tolerance': ACTIVE_TOL,
        'start': _candidate(r.start),
        'best': _candidate(r.best),
        'improved': r.improved,
        'active_constraints': r.active(),
        'at_bounds': r.at_bounds(),
        'evaluations': r.evaluations,
        'optimizer': {
            'method': 'scipy.optimize.differential_evolution',
            'message': r.message,
            'generations': r.nit,
            'objective_evaluations': r.nfev,
            'maxiter': s.maxiter,
            'popsize': s.popsize,
            'tol': s.tol,
            'seed': s.seed,
            'seconds': r.seconds,
        },
        'verdict': verdict(r, walls),
    }


def histogram_lines(result: OptimizeResult) -> list[str]:
    """The landing histograms before and after, side by side, as text lines (same bins, same scale)."""
    lb, la = result.start.landing, result.best.landing
    if lb is None or la is None:
        return ['no landing histogram (the start was not simulated)']
    before, after, edges = lb.histogram.counts, la.histogram.counts, lb.histogram.edges
    top = max(max(before), max(after), 1)
    before_head = f'before (cv {_cv(result.start)})'
    lines = [f'{"landing x":<20}{before_head:<{_BAR + 9}}after (cv {_cv(result.best)})']
    for i, (b, a) in enumerate(zip(before, after, strict=True)):
        bar_b = '#' * round(_BAR * b / top)
        bar_a = '#' * round(_BAR * a / top)
        lines.append(f'  {edges[i]:+.3f}..{edges[i + 1]:+.3f} m  {bar_b:<{_BAR}} {b:>5}   {bar_a:<{_BAR}} {a:>5}')
    return lines


def landing_figure(result: OptimizeResult, path: str | os.PathLike[str], walls: tuple[float, float]) -> Path:
    """``landing.png``: the landing histograms before and after over the container, walls marked.

    Parameters
    ----------
    result : OptimizeResult
    path : path-like
        The PNG, written atomically.
    walls : (float, float)
        The container's inner walls ``x_left``, ``x_right``, m.
    """
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(8.0, 4.2))
    for cand, label, colour in ((result.start, 'before', 'tab:grey'), (result.best, 'after', 'tab:blue')):
        if cand.landing is None:
            continue
        edges, counts = cand.landing.histogram.edges, cand.landing.histogram.counts
        ax.stairs(
            counts,
            edges,
            label=f'{label}: cv {_cv(cand)}',
            color=colour,
            linewidth=1.8,
            fill=label == 'before',
            alpha=0.45 if label == 'before' else 1.0,
        )
        mean = sum(counts) / len(counts)
        if math.isfinite(mean):
            ax.axhline(mean, color=colour, linestyle=':', linewidth=1.0)
    for x in walls:
        ax.axvline(x, color='k', linewidth=2.0)
    ax.text(walls[0], 0.98, ' wall', transform=ax.get_xaxis_transform(), va='top', ha='left')
    ax.text(walls[1], 0.98, 'wall ', transform=ax.get_xaxis_transform(), va='top', ha='right')
    span = walls[1] - walls[0]
    ax.set_xlim(walls[0] - 0.05 * span, walls[1] + 0.05 * span)
    ax.set_xlabel('landing x across the container, m')
    ax.set_ylabel('leaves per bin')
    ax.set_title(f'layup landing, {result.settings.duration:g} s (dotted: the mean an even layup would have)')
    ax.legend(loc='lower center')
    fig.tight_layout()
    return save_figure(fig, path)
