"""Outputs of ``folder-line bench accuracy``: CSV, markdown, the Pareto plot and a JSON record.

Everything is computed before the first file is written, and every file is written
atomically (:mod:`folder_line.files.atomic`): a failed run leaves the output directory as it was.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from folder_line.accuracy.bench import BenchResult
from folder_line.accuracy.measure import COLUMNS, Row
from folder_line.accuracy.pareto import EqualErrorRatio, cheapest, curves, equal_error_ratio, pareto_front
from folder_line.analysis.figures import DPI, pyplot
from folder_line.files.atomic import write_bytes_atomic, write_json_atomic, write_text_atomic

__all__ = ['COMPARISONS', 'TARGETS', 'comparisons', 'markdown', 'pareto_png', 'write_outputs']

#: error targets of the "cheapest setting" table, in each quantity's unit
TARGETS = (1e-3, 1e-6, 1e-9, 1e-12)

#: (study, folder_line's method, the general-purpose method) compared at equal error
COMPARISONS: tuple[tuple[str, str, str], ...] = (
    ('fourbar', 'closed form (folder_line)', 'solve_ivp RK45'),
    ('fourbar', 'closed form (folder_line)', 'solve_ivp DOP853'),
    ('fourbar', 'closed form (folder_line)', 'solve_ivp LSODA'),
    *tuple(
        ('motor', f'{a} (folder_line) [{case}]', f'solve_ivp {b} [{case}]')
        for case in ('start-up, no load', 'with chain load')
        for a, b in (('DOPRI5', 'RK45'), ('DOPRI5', 'DOP853'), ('RK4', 'DOP853'))
    ),
)


def _g(x: float) -> str:
    if x == 0.0:
        return '0'
    if x == int(x) and 1.0 <= abs(x) < 1e7:
        return str(int(x))
    return f'{x:.3g}'


def _panels(rows: Sequence[Row]) -> list[tuple[str, str, str]]:
    seen: list[tuple[str, str, str]] = []
    for r in rows:
        key = (r.study, r.quantity, r.unit)
        if key not in seen:
            seen.append(key)
    return seen


def comparisons(rows: Sequence[Row]) -> list[EqualErrorRatio]:
    """The :data:`COMPARISONS` whose methods both have rows, measured at equal error."""
    have = {(r.study, r.method) for r in rows}
    return [
        equal_error_ratio([r for r in rows if r.study == s], s, a, b)
        for s, a, b in COMPARISONS
        if (s, a) in have and (s, b) in have
    ]


def markdown(result: BenchResult, command: str) -> str:
    """The benchmark as markdown: cheapest settings per target error, ratios at equal error, every row."""
    rows = list(result.rows)
    total = sum(result.wall_s.values())
    out = [
        f'# Accuracy against CPU time{" (quick)" if result.quick else ""}',
        '',
        (
            f'`{command}` — {total:.0f} s wall in all; Python {result.machine.get("python", "?")}, '
            f'{result.machine.get("platform", "?")}.'
        ),
        '',
        (
            'error: largest absolute error over the simulated span against a checked reference; '
            'CPU: `time.process_time` seconds per simulated second (best of 3 batches).'
        ),
        '',
        '## Cheapest measured setting for an error target',
        '',
        '| study | quantity | ' + ' | '.join(f'≤ {t:g}' for t in TARGETS) + ' |',
        '|---|---|' + '---|' * len(TARGETS),
    ]
    for study, quantity, unit in _panels(rows):
        cells = []
        for t in TARGETS:
            ch = cheapest(rows, study, t, quantity=quantity).row
            cells.append(
                '—' if ch is None else f'{ch.method}, {ch.knob} = {_g(ch.value)}: {_g(ch.cpu_s_per_sim_s)} s/s'
            )
        out.append(f'| {study} | {quantity} ({unit}) | ' + ' | '.join(cells) + ' |')
    ratios = comparisons(rows)
    if ratios:
        out += [
            '',
            '## General-purpose integrator against folder_line, at equal error',
            '',
            (
                "ratio = CPU of the general method / CPU of folder_line's at the same error (> 1: folder_line "
                "is cheaper); the error is folder_line's best, or the general method's best if it never "
                'gets there.'
            ),
            '',
            '| study | folder_line | general | error | CPU folder_line (s/s) | CPU general (s/s) | ratio |',
            '|---|---|---|---:|---:|---:|---:|',
        ]
        study_of = {(a, b): s for s, a, b in COMPARISONS}
        for q in ratios:
            mark = '' if q.reached else " (the general method's best)"
            out.append(
                f'| {study_of[(q.method_a, q.method_b)]} | {q.method_a} | {q.method_b} | {_g(q.error)}{mark} '
                f'| {_g(q.cpu_a)} | {_g(q.cpu_b)} | {q.ratio:.3g} |'
            )
    out += ['', '## Every point', '']
    for (study, method), curve in curves(rows).items():
        r0 = curve[0]
        out += [
            f'### {study}: {method}',
            '',
            f'{r0.quantity}, error in {r0.unit}; reference: {r0.reference}',
            '',
            f'| {r0.knob} | error ({r0.unit}) | CPU s per sim s | on the Pareto front |',
            '|---:|---:|---:|:---:|',
        ]
        front = set(map(id, pareto_front(r for r in rows if r.study == study and r.quantity == r0.quantity)))
        for r in sorted(curve, key=lambda r: r.value):
            out.append(f'| {_g(r.value)} | {_g(r.error)} | {_g(r.cpu_s_per_sim_s)} | {"●" if id(r) in front else ""} |')
        out.append('')
    out += ['## Wall time per study', '', '| study | s |', '|---|---:|']
    out += [f'| {s} | {w:.1f} |' for s, w in result.wall_s.items()]
    return '\n'.join(out) + '\n'


def pareto_png(rows: Sequence[Row]) -> bytes:
    """The log-log Pareto plot, one panel per (study, quantity), one curve per method, as PNG bytes.

    Exact results (error 0) are drawn on the panel's floor, a decade below its least
    non-zero error, with an open marker.
    """
    from matplotlib import ticker  # matplotlib loads on use (pyplot() picks the back end first)

    plt = pyplot()
    panels = _panels(rows)
    ncol = min(3, len(panels))
    nrow = math.ceil(len(panels) / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(5.2 * ncol, 4.2 * nrow), squeeze=False)
    for ax, (study, quantity, unit) in zip(axes.flat, panels, strict=False):
        sel = [r for r in rows if r.study == study and r.quantity == quantity]
        positive = [r.error for r in sel if r.error > 0.0]
        floor = min(positive) / 10.0 if positive else 1e-16
        for (_, method), curve in curves(sel).items():
            curve = sorted(curve, key=lambda r: r.value)
            x = [r.cpu_s_per_sim_s for r in curve]
            y = [max(r.error, floor) for r in curve]
            (line,) = ax.loglog(x, y, marker='o', ms=4, lw=1.2, label=method)
            for r, xi, yi in zip(curve, x, y, strict=True):
                if r.error == 0.0:
                    ax.plot([xi], [yi], marker='o', ms=7, mfc='none', mec=line.get_color())
            for r, xi, yi in ((curve[0], x[0], y[0]), (curve[-1], x[-1], y[-1])):
                ax.annotate(
                    f'{r.knob}={_g(r.value)}',
                    (xi, yi),
                    fontsize=6,
                    xytext=(3, 3),
                    textcoords='offset points',
                    color=line.get_color(),
                )
        ax.set_title(f'{study}: {quantity}', fontsize=10)
        ax.set_xlabel('CPU s per simulated s')
        ax.set_ylabel(f'max error ({unit})')
        ax.grid(True, which='major', alpha=0.3)
        ax.xaxis.set_minor_formatter(ticker.NullFormatter())  # a panel spanning < 1 decade would print them
        ax.legend(fontsize=7, loc='best')
    for ax in list(axes.flat)[len(panels) :]:
        ax.axis('off')
    fig.suptitle('What accuracy costs: error against CPU time (down-left is better)', fontsize=12)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format='png', dpi=DPI)
    plt.close(fig)
    return buf.getvalue()


def _csv_text(rows: Sequence[Row]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator='\n')
    w.writerow(COLUMNS)
    for r in rows:
        w.writerow([repr(v) if isinstance(v, float) else v for v in (getattr(r, c) for c in COLUMNS)])
    return buf.getvalue()


def write_outputs(result: BenchResult, out: Path, command: str) -> list[Path]:
    """Write ``accuracy.csv``, ``accuracy.md``, ``accuracy.png`` and ``accuracy.json`` to ``out``.

    All four are rendered first, then written atomically.
    """
    rows = list(result.rows)
    csv_text = _csv_text(rows)
    md = markdown(result, command)
    png = pareto_png(rows)
    record: dict[str, Any] = {
        'command': command,
        'quick': result.quick,
        'machine': result.machine,
        'wall_s': result.wall_s,
        'comparisons': [vars(q) | {} for q in comparisons(rows)],
        'rows': [r.as_dict() for r in rows],
    }
    return [
        write_text_atomic(out / 'accuracy.csv', csv_text),
        write_text_atomic(out / 'accuracy.md', md),
        write_bytes_atomic(out / 'accuracy.png', png),
        write_json_atomic(out / 'accuracy.json', record),
    ]
