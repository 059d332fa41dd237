"""Human-readable summary of a batch simulation (the ``simulate`` verb)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import IO, Any

from folder_line.core.line.margin_text import best_possible, format_margin, margin_at, margin_legend

__all__ = ['print_margins', 'print_summary']


def print_margins(min_margin: Mapping[str, Mapping[str, Any]], out: IO[str]) -> None:
    """The smallest margin of each constraint (``summary['min_margin']``), where it was judged, and a legend."""
    if not min_margin:
        return
    print('smallest margin per constraint (>= 0 passes):', file=out)
    for name, m in min_margin.items():
        best = '; best possible' if best_possible(name, m['margin']) else ''
        print(
            f'  {name:<22} {format_margin(m["margin"], m["unit"], name):>17}  at {margin_at(name, m["cycle"]):<10} '
            f'{m["violations"]} of {m["evaluations"]} violated{best}',
            file=out,
        )
    print('what the margins mean:', file=out)
    for line in margin_legend(min_margin):
        print(line, file=out)


def _print_folder(folder: dict[str, Any] | None, out: IO[str]) -> None:
    """The folder's design figures: the feed speed it needs, the knife window, the delivery's efficiency."""
    if not folder:
        return
    print(
        f'V_tr min = {folder["V_tr_min"]:.4f} m/s = {folder["V_tr_min_over_V_d"]:.4f} V_d '
        f'(V_d = {folder["V_d"]:.4f} m/s; V_tr = {folder["V_tr"]:g} m/s)',
        file=out,
    )
    print(
        f'knife window: {folder["knife_window_s"] * 1e3:.4f} ms, {folder["knife_window_deg"]:.3f} deg of crank '
        f'({folder["knife_in_deg"]:+.3f}..{folder["knife_out_deg"]:+.3f} deg)',
        file=out,
    )
    dlv = folder.get('delivery')
    if dlv:
        print(
            f'delivery: efficiency minimum {dlv["eta_min"]:.4f} at stroke position u = {dlv["eta_min_u"]:.4f} '
            f'({dlv["eta_min_travel_m"]:.4f} m of chain from the stroke start); '
            f'sprocket torque peak {dlv["sprocket_torque_peak_Nm"]:.4g} N m, '
            f'mean {dlv["sprocket_torque_mean_Nm"]:.4g} N m',
            file=out,
        )


def print_summary(summary: dict[str, Any], out: IO[str]) -> None:
    """Print the summary dict of :meth:`folder_line.core.line.model.LineResult.summary`."""
    print(
        f'scene {summary["scene"]}: {summary["duration_s"]:g} s of line time, seed {summary["seed"]}, '
        f'effects: {", ".join(summary["effects"]) or "none"}',
        file=out,
    )
    for tu in summary.get('tunings', []):
        print(f'tuned: {tu["key"]} = {tu["value"]:g} {tu["unit"]} from {tu["t"]:.9g} s (--tune)', file=out)
    print(f'cycles: {summary["cycles"]}   sheets counted: {summary["sheets_counted"]}', file=out)
    if 'v_tr_over_v_d' in summary:
        print(f'V_tr / V_d = {summary["v_tr_over_v_d"]:.4f}', file=out)
    _print_folder(summary.get('folder'), out)
    layup = summary.get('layup')
    if layup:
        print(
            f'leaves: {layup["leaves"]} entered, {layup["leaves_landed"]} landed, {layup["leaves_spilled"]} spilled, '
            f'{layup["leaves_damaged"]} damaged',
            file=out,
        )
    v = summary['violations']
    print(f'violations: {v["count"]}', file=out)
    for item in v['first']:
        name = item['constraint']
        print(
            f'  {margin_at(name, item["cycle"])}: {name} margin {format_margin(item["margin"], item["unit"], name)}',
            file=out,
        )
    print_margins(summary['min_margin'], out)
    if 'landing_cv' in summary and summary.get('landing_histogram'):
        hist = summary['landing_histogram']
        counts = hist['counts']
        top = max(counts) or 1
        print(f'landing across the container (cv {summary["landing_cv"]:.3f}):', file=out)
        edges = hist['edges']
        for i, c in enumerate(counts):
            print(f'  {edges[i]:+.3f}..{edges[i + 1]:+.3f} m {"#" * round(40 * c / top):<40} {c}', file=out)
    print('events: ' + ', '.join(f'{k} {n}' for k, n in summary['events'].items()), file=out)
