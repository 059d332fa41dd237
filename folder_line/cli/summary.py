"""Human-readable summary of a batch simulation (the ``simulate`` verb)."""

from __future__ import annotations

from typing import IO, Any

__all__ = ['print_summary']


def _fmt_margin(value: float, unit: str) -> str:
    if unit == 's':
        return f'{value * 1e3:+.4f} ms'
    if unit == '1':
        return f'{value:+.6g}'
    return f'{value:+.6g} {unit}'


def print_summary(summary: dict[str, Any], out: IO[str]) -> None:
    """Print the summary dict of :meth:`folder_line.core.line.model.LineResult.summary`."""
    print(
        f'scene {summary["scene"]}: {summary["duration_s"]:g} s of line time, seed {summary["seed"]}, '
        f'effects: {", ".join(summary["effects"]) or "none"}',
        file=out,
    )
    print(f'cycles: {summary["cycles"]}   sheets counted: {summary["sheets_counted"]}', file=out)
    if 'v_tr_over_v_d' in summary:
        print(f'V_tr / V_d = {summary["v_tr_over_v_d"]:.4f}', file=out)
    v = summary['violations']
    print(f'violations: {v["count"]}', file=out)
    for item in v['first']:
        print(
            f'  cycle {item["cycle"]}: {item["constraint"]} margin {_fmt_margin(item["margin"], item["unit"])}',
            file=out,
        )
    if summary['min_margin']:
        print('smallest margin per constraint:', file=out)
        for name, m in summary['min_margin'].items():
            print(
                f'  {name:<22} {_fmt_margin(m["margin"], m["unit"]):>18}  (cycle {m["cycle"]}, '
                f'{m["violations"]} of {m["evaluations"]} violated)',
                file=out,
            )
    if 'landing_cv' in summary and summary.get('landing_histogram'):
        hist = summary['landing_histogram']
        counts = hist['counts']
        top = max(counts) or 1
        print(f'landing across the container (cv {summary["landing_cv"]:.3f}):', file=out)
        edges = hist['edges']
        for i, c in enumerate(counts):
            print(f'  {edges[i]:+.3f}..{edges[i + 1]:+.3f} m {"#" * round(40 * c / top):<40} {c}', file=out)
    print('events: ' + ', '.join(f'{k} {n}' for k, n in summary['events'].items()), file=out)
