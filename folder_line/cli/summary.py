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
