"""The report of the default configuration: the papers' published results next to
what the model computes, the three mechanisms' tables as CSV, and plots.

This is what ``make run`` shows (``folder-line report --out DIR``). ``--params FILE`` (a YAML mapping of
the sections ``layup``, ``knife``, ``cyclogram``, ``delivery`` and ``press`` to any of their keys) and
``--set SECTION.KEY=VALUE`` (as for a scene, ``press.n_c=30000`` included) redo it at other values
(:func:`report_params`); the report then starts with the values it was given.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, TYPE_CHECKING, TypedDict

import numpy as np

from folder_line.analysis.colours import PHASE_COLOURS, QUANTITY_COLOURS
from folder_line.analysis.figures import pyplot, save_figure
from folder_line.analysis.paper_curves import exit_speed_curves, stroke_curves
from folder_line.cli.tables import kinematics_table
from folder_line.cli.verb_options import Subparsers, add_out
from folder_line.config.params import KINDS, load_container, load_params, read_yaml_mapping
from folder_line.config.scenes import InputNames, parse_set, set_press
from folder_line.core.line.scene import MachineParams, check_press_speed
from folder_line.core.mechanisms import cyclogram, delivery, knife, layup, layup_reach
from folder_line.core.types.machines import ContainerParams
from folder_line.errors import ParameterError
from folder_line.files.atomic import claim_output_dir, write_csv_atomic, write_text_atomic

if TYPE_CHECKING:  # matplotlib is imported when a figure is drawn (folder_line.analysis.figures.pyplot)
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = [
    'REPORT_FILES',
    'Check',
    'ReportParams',
    'add_parser',
    'add_report_arguments',
    'delivery_figure',
    'layup_geometry_figure',
    'layup_speeds_figure',
    'published_checks',
    'report_params',
    'run',
    'write_report',
]

#: the files :func:`write_report` writes into its folder
REPORT_FILES = (
    'report.md',
    'layup.csv',
    'knife.csv',
    'delivery.csv',
    'layup_speeds.png',
    'layup_geometry.png',
    'knife_cyclogram.png',
    'delivery_efficiency.png',
)

PAPER_V_TR = 0.230 / 0.025  # m/s, paper 001 eq. (5): 230 mm in 0.025 s


@dataclass(frozen=True)
class Check:
    """One published figure against the model."""

    paper: str
    quantity: str
    published: str
    model: str
    agrees: bool


class PaperParams(TypedDict):
    """The parameters the papers' figures are recomputed from (:func:`published_checks`)."""

    layup: layup.LayupParams
    knife: knife.KnifeParams
    delivery: delivery.DeliveryParams
    cyclogram: cyclogram.CyclogramParams


@dataclass(frozen=True)
class ReportParams:
    """What the report is computed from, and what was given to change the defaults.

    Attributes
    ----------
    params : PaperParams
        The validated parameters of the four mechanisms.
    given : tuple of str
        ``KEY=VALUE`` of every value given (``--params`` file first, then ``--set``), in order; empty for
        the defaults.
    """

    params: PaperParams
    given: tuple[str, ...] = field(default=())
    container: ContainerParams = field(default_factory=load_container)


def _file_values(path: str | None) -> list[tuple[str, object]]:
    """``--params FILE``: section -> mapping of key: value, flattened to (``section.key``, value) in file order."""
    if path is None:
        return []
    out: list[tuple[str, object]] = []
    for section, values in read_yaml_mapping(Path(path), '--params').items():
        if not isinstance(values, Mapping):
            raise ParameterError(f'{section}', values, 'must be a mapping of key: value')
        out += [(f'{section}.{k}', v) for k, v in values.items()]
    return out


def report_params(path: str | None = None, overrides: Mapping[str, object] | None = None) -> ReportParams:
    """The report's parameters: the defaults, then a ``--params`` file's values, then the ``--set`` overrides.

    Parameters
    ----------
    path : str, optional
        YAML file mapping report sections (``layup``, ``knife``, ``cyclogram``, ``delivery``, ``container``,
        ``press``)
        to any subset of their keys.
    overrides : mapping, optional
        ``{'press.n_c': 30000, 'delivery.f_A': 0.2}`` as from ``--set``.

    Raises
    ------
    ParameterError
        Naming the key and value: an unknown section or key, a value out of range, a knife speed that is
        not twice the cylinder's.
    """
    given = [*_file_values(path), *(overrides or {}).items()]
    sections: dict[str, dict[str, object]] = {kind: {} for kind in (*KINDS, 'container')}
    for key, value in given:
        head, sep, name = key.partition('.')
        if head == 'press':
            set_press(sections, key, value, 'the report')
        elif not sep or head not in sections or not name or '.' in name:
            raise ParameterError(
                key,
                value,
                f'must be SECTION.KEY with a section of the report ({", ".join(KINDS)}, container) or press.n_c',
            )
        else:
            sections[head][name] = value
    p: PaperParams = {  # built in the order of KINDS: the first refused value is reported
        'layup': load_params('layup', overrides=sections['layup']),
        'knife': load_params('knife', overrides=sections['knife']),
        'delivery': load_params('delivery', overrides=sections['delivery']),
        'cyclogram': load_params('cyclogram', overrides=sections['cyclogram']),
    }
    check_press_speed(p['knife'].n_k, p['cyclogram'].n_c)
    container = load_container(sections['container'])  # drawn under the six-bar in layup_geometry.png
    return ReportParams(p, tuple(f'{k}={v}' for k, v in given), container)


def add_report_arguments(parser: argparse.ArgumentParser) -> None:
    """``--params FILE`` and the repeatable ``--set`` of the ``report`` verb."""
    parser.add_argument(
        '--params',
        metavar='FILE.yaml',
        help='values to report at instead of the defaults: '
        '{layup|knife|cyclogram|delivery|container|press: {key: value}}',
    )
    parser.add_argument(
        '--set',
        dest='overrides',
        action='append',
        default=[],
        metavar='SECTION.KEY=VALUE',
        help='override a value, e.g. press.n_c=30000 (cylinder and knife) or delivery.f_A=0.2 (repeatable)',
    )


def add_parser(subparsers: Subparsers) -> argparse.ArgumentParser:
    """Add the ``report`` verb to ``folder-line``'s sub-parsers."""
    rep: argparse.ArgumentParser = subparsers.add_parser(
        'report', help='kinematics, efficiency and cyclogram report of the defaults, with plots'
    )
    add_out(rep, 'out')
    add_report_arguments(rep)
    rep.set_defaults(func=run, output_option='--out')
    return rep


def run(args: argparse.Namespace) -> int:
    """Write the report at the values given into ``--out`` (claimed for the duration)."""
    params = report_params(args.params, parse_set(args.overrides, InputNames(scene='--params', overrides='--set')))
    with claim_output_dir(args.out, '--out', REPORT_FILES) as out:
        write_report(out, sys.stdout, params)
    return 0


def _defaults() -> PaperParams:
    return report_params().params


def published_checks(p: PaperParams | None = None) -> list[Check]:
    """The papers' published results, recomputed from the parameters ``p`` (defaults if None)."""
    p = p or _defaults()
    lay, kn, dl, cy = p['layup'], p['knife'], p['delivery'], p['cyclogram']
    checks: list[Check] = []

    # D: efficiency (paper 002, Fig. 2)
    ev = delivery.evaluate(dl, np.linspace(0.0, 1.0, 20001))
    eta_end, eta_const = float(ev.eta[-1]), float(ev.eta[0])
    checks.append(
        Check(
            'D',
            'eta at the decel/accel boundary (xi = 1), lowest of the section',
            '0.69',
            f'{eta_end:.4f} (min {ev.eta.min():.4f})',
            abs(eta_end - 0.69) < 0.005 and ev.eta.min() == eta_end,
        )
    )
    checks.append(
        Check('D', 'eta at constant carriage speed (xi = 0)', '0.98', f'{eta_const:.4f}', 0.98 <= eta_const < 0.99)
    )

    # F: cyclogram (paper 001)
    tm = cyclogram.cycle_timing(cy, kn)
    checks.append(
        Check(
            'F',
            'printing speed V_d, D = 267.38 mm at 25000 rev/h',
            '5.83 m/s',
            f'{tm.V_d:.4f} m/s',
            abs(tm.V_d - 5.83) < 0.005,
        )
    )
    checks.append(Check('F', 'cycle T at 50000 rev/h', '0.072 s', f'{tm.T:.6f} s', abs(tm.T - 0.072) < 1e-12))
    checks.append(
        Check(
            'F',
            'folding + knife exit (knife window)',
            '0.03 s',
            f'{tm.t_knife:.5f} s',
            abs(tm.t_knife - 0.03) < 0.03 * 0.005,
        )
    )
    checks.append(
        Check(
            'F',
            'feed time with the 10 % reserve',
            '0.025 s',
            f'{tm.t_allowed:.5f} s',
            abs(tm.t_allowed - 0.025) < 0.025 * 0.015,
        )
    )
    checks.append(
        Check(
            'F',
            'minimum 2nd-transporter speed V_tr',
            '~9.2 m/s',
            f'{tm.V_tr_min:.3f} m/s',
            abs(tm.V_tr_min - 9.2) < 9.2 * 0.015,
        )
    )
    checks.append(Check('F', 'V_tr / V_d', '~1.6', f'{tm.ratio_min:.3f}', abs(tm.ratio_min - 1.6) < 0.03))

    # L: exit speeds (paper 000, Figs. 4-5)
    ext = layup_reach.swing_extremes(lay)
    v_ext = max(max(abs(e.point.vC), abs(e.point.vE)) for e in ext)
    checks.append(Check('L', 'v_C, v_E at both swing extremes', '0', f'{v_ext:.2e} m/s', v_ext < 1e-9))
    st = layup.LayupModel(lay).arrays(2.0 * math.pi * np.arange(100_000) / 100_000, accelerations=False)
    va_min = float(min(st.vaC.min(), st.vaE.min()))
    checks.append(
        Check(
            'L',
            f'min absolute exit speed with belts at v_tr = {lay.v_tr:g} m/s',
            f'>= {lay.v_tr:g} m/s',
            f'{va_min:.6f} m/s',
            va_min >= lay.v_tr,
        )
    )
    return checks


def layup_speeds_figure(lay: layup.LayupParams) -> Figure:
    """The figure of ``layup_speeds.png``: the exit speeds without and with belts (paper L, figs. 4-5)."""
    plt = pyplot()
    fig: Figure
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(9, 7), sharex=True)
    exit_speed_curves(ax1, ax2, lay, lay.v_tr)
    ax1.set_ylabel('swing speed, m/s')
    ax1.set_title('L: exit speeds without belts (paper Fig. 4): zero at the swing extremes')
    ax1.legend(loc='upper left', fontsize=8)
    ax2.set_ylabel('absolute exit speed, m/s')
    ax2.set_xlabel('crank angle $\\varphi$, deg')
    ax2.set_title(f'L: with belts at $v_{{tr}}$ = {lay.v_tr:g} m/s (paper Fig. 5): never below $v_{{tr}}$')
    ax2.legend(loc='center right', fontsize=8)
    fig.tight_layout()
    return fig


def _container(ax: Axes, cont: ContainerParams, top: float) -> None:
    """The container's inner walls (from the floor up to ``top``, m) and floor, labelled with their values."""
    xs = (cont.x_left, cont.x_left, cont.x_right, cont.x_right)
    ys = (top, cont.y_floor, cont.y_floor, top)
    ax.plot(
        xs,
        ys,
        color='tab:brown',
        lw=3,
        solid_capstyle='butt',
        label=f'container: walls x = {cont.x_left:g}, {cont.x_right:g} m; floor y = {cont.y_floor:g} m',
    )
    for x, text, dx, ha in ((cont.x_left, 'x_left', 6, 'left'), (cont.x_right, 'x_right', -6, 'right')):
        ax.annotate(f'{text} = {x:g}', (x, cont.y_floor), textcoords='offset points', xytext=(dx, 5), ha=ha)
    ax.annotate(
        f'floor y_floor = {cont.y_floor:g}',
        (0.5 * (cont.x_left + cont.x_right), cont.y_floor),
        textcoords='offset points',
        xytext=(0, 5),
        ha='center',
    )


def layup_geometry_figure(lay: layup.LayupParams, cont: ContainerParams) -> Figure:
    """The figure of ``layup_geometry.png``: the six-bar at both swing extremes over the container.

    Parameters
    ----------
    lay : LayupParams
        The six-bar, m.
    cont : ContainerParams
        The container in the six-bar's frame, m: its walls are drawn from the floor up to
        the highest point of the exits' paths (the model has no wall height).
    """
    plt = pyplot()
    ext = layup_reach.swing_extremes(lay)
    st = layup.LayupModel(lay).arrays(np.linspace(0.0, 2.0 * math.pi, 721), accelerations=False)
    fig: Figure
    fig, ax = plt.subplots(figsize=(7.5, 8))
    ax.plot(st.xC, st.yC, color=QUANTITY_COLOURS['vC'], lw=2, label='path of exit C')
    ax.plot(st.xE, st.yE, color=QUANTITY_COLOURS['vE'], lw=2, label='path of exit E')
    o1 = (lay.a, lay.b)
    for e, style in zip(ext, ('-', '--'), strict=True):
        s1 = layup.LayupModel(lay).arrays(np.array([e.phi]), accelerations=False)
        pts = {k: (float(getattr(s1, 'x' + k)[0]), float(getattr(s1, 'y' + k)[0])) for k in 'ABCE'}
        chain = [o1, pts['A'], pts['B'], (0.0, 0.0), pts['C'], pts['E'], (lay.O2O3, 0.0)]
        ax.plot(
            *zip(*chain, strict=True),
            style,
            color='k',
            marker='o',
            ms=4,
            lw=1,
            label=f'{e.kind} dead centre, phi = {math.degrees(e.phi):.1f} deg',
        )
    for name, xy in (('O1', o1), ('O2', (0.0, 0.0)), ('O3', (lay.O2O3, 0.0))):
        ax.annotate(name, xy, textcoords='offset points', xytext=(5, 5))
    _container(ax, cont, float(max(st.yC.max(), st.yE.max())))
    ax.set_aspect('equal')
    ax.set_xlabel('x, m')
    ax.set_ylabel('y, m')
    ax.set_title('L: six-bar at both swing extremes, over the container')
    ax.set_ylim(min(cont.y_floor, float(min(st.yC.min(), st.yE.min()))) - 0.1, 0.45)
    ax.legend(loc='upper right', fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def _plot_layup(lay: layup.LayupParams, cont: ContainerParams, out: Path) -> list[Path]:
    return [
        save_figure(layup_speeds_figure(lay), out / 'layup_speeds.png'),
        save_figure(layup_geometry_figure(lay, cont), out / 'layup_geometry.png'),
    ]


def _plot_knife(kn: knife.KnifeParams, cy: cyclogram.CyclogramParams, out: Path) -> Path:
    plt = pyplot()

    tm = cyclogram.cycle_timing(cy, kn)
    t = np.linspace(tm.knife.t_in, tm.knife.t_in + tm.T, 1001)
    ks = knife.state_at_time(kn, t)
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(9, 6.5), sharex=True, gridspec_kw={'height_ratios': [2, 1.3]})
    ms = 1e3 * (t - tm.knife.t_in)
    ax1.plot(ms, ks.s * 1e3, label='knife height s')
    ax1.axhline(kn.s_clear * 1e3, color='r', ls='--', lw=1, label=f's_clear = {kn.s_clear * 1e3:.1f} mm')
    ax1.fill_between(
        ms,
        kn.s_min * 1e3,
        kn.s_max * 1e3,
        where=ks.occupies,
        color='r',
        alpha=0.12,
        label=f'knife window {tm.t_knife * 1e3:.2f} ms',
    )
    ax1.set_ylabel('s, mm')
    ax1.set_title(f'F: crank-slider knife at {kn.n_k:g} rev/h (T = {tm.T * 1e3:.1f} ms)')
    ax1.legend(loc='upper right', fontsize=8)
    for ph in tm.timeline:
        a, b = 1e3 * (ph.t_start - tm.knife.t_in), 1e3 * (ph.t_end - tm.knife.t_in)
        ax2.barh(3, b - a, left=a, color=PHASE_COLOURS[ph.name], alpha=0.6)
        ax2.text((a + b) / 2, 3, f'{ph.name}\n{(b - a):.1f} ms', ha='center', va='center', fontsize=8)
    feed0 = 1e3 * (tm.knife.t_out - tm.knife.t_in)
    cases = (('V_tr = V_d', tm.V_d), ('paper V_tr', PAPER_V_TR), ('model V_tr,min', tm.V_tr_min))
    for row, (_label, v) in enumerate(cases):
        t_feed = 1e3 * cy.L_feed / v
        ok = tm.feed_margin(v) >= -1e-12  # V_tr,min itself passes, up to rounding
        ax2.barh(row, t_feed, left=feed0, color='tab:green' if ok else 'tab:orange', alpha=0.8)
        ax2.text(1.0, row, f'{v:.2f} m/s: {t_feed:.1f} ms, {"fits" if ok else "late"}', va='center', fontsize=8)
    ax2.set_yticks(range(len(cases) + 1), [c[0] for c in cases] + ['cyclogram'])
    ax2.axvline(feed0 + 1e3 * tm.t_allowed, color='k', ls=':', lw=1)
    ax2.set_xlabel('time from knife entry, ms')
    ax2.set_title('cyclogram (paper Figs. 1-2); dotted: end of the feed window less the 10 % reserve', fontsize=9)
    ax2.set_xlim(0, 1e3 * tm.T)
    fig.tight_layout()
    return save_figure(fig, out / 'knife_cyclogram.png')


def delivery_figure(dl: delivery.DeliveryParams) -> Figure:
    """The figure of ``delivery_efficiency.png``: efficiency and carriage speed along the stroke (paper D, fig. 2)."""
    plt = pyplot()
    fig: Figure
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(9, 7), sharex=True)
    stroke_curves(ax1, ax2, dl, ('paper_mirror', 'geometric'))
    ax1.set_ylabel('instantaneous efficiency')
    ax1.set_title(
        f'D: efficiency along the stroke (paper Fig. 2), Lambda = {dl.Lambda:g}, '
        f'alpha_m = {dl.alpha_m_deg:g} deg, {dl.law}'
    )
    ax1.legend(fontsize=8, loc='lower left')
    ax2.set_ylabel('carriage speed ratio K_v')
    ax2.set_xlabel('stroke position u (deceleration section 0..1, acceleration section 1..2)')
    ax2.legend(fontsize=8)
    fig.tight_layout()
    return fig


def _plot_delivery(dl: delivery.DeliveryParams, out: Path) -> Path:
    return save_figure(delivery_figure(dl), out / 'delivery_efficiency.png')


def write_report(out: Path, stream: IO[str], inputs: ReportParams | None = None) -> list[Path]:
    """Print the report and write ``report.md``, CSV tables and PNG plots to ``out``.

    ``inputs``: the parameters (:func:`report_params`); default the defaults.
    """
    inputs = inputs or report_params()
    p = inputs.params
    out.mkdir(parents=True, exist_ok=True)
    checks = published_checks(p)
    tm = cyclogram.cycle_timing(p['cyclogram'], p['knife'])
    sw = layup_reach.sweep(p['layup'])
    k_u, k_min = delivery.stroke_minimum(p['delivery'], 'K_v')

    lines = ['# folder_line: the default configuration against the papers', '']
    if inputs.given:
        lines = [
            '# folder_line: the papers against the model at other values',
            '',
            'Values given (the rest are the defaults; a paper figure at the defaults may then not agree):',
            '',
            *(f'- `{g}`' for g in inputs.given),
            '',
        ]
    lines += [
        '| mech. | quantity | paper | model | agrees |',
        '|---|---|---|---|---|',
    ]
    lines += [
        f'| {c.paper} | {c.quantity} | {c.published} | {c.model} | {"yes" if c.agrees else "NO"} |' for c in checks
    ]
    lines += [
        '',
        '## Derived figures',
        '',
        f'- L: exits sweep x = {sw.xC[0]:.3f}..{sw.xC[1]:.3f} m (C) and {sw.xE[0]:.3f}..{sw.xE[1]:.3f} m (E).',
        f'- F: knife window {tm.t_knife * 1e3:.3f} ms, dwell {tm.t_dwell * 1e3:.2f} ms, '
        f'feed window {tm.t_fw * 1e3:.3f} ms, allowed feed time {tm.t_allowed * 1e3:.3f} ms; '
        f'feed margin at V_tr = V_d: {tm.feed_margin(tm.V_d) * 1e3:.3f} ms, '
        f"at the paper's {PAPER_V_TR:.1f} m/s: {tm.feed_margin(PAPER_V_TR) * 1e3:.3f} ms.",
        f'- F: minimum feed speed V_tr = {tm.V_tr_min:.4f} m/s = {tm.ratio_min:.4f} V_d '
        f'(V_d = {tm.V_d:.4f} m/s, cylinder {p["cyclogram"].n_c:g} rev/h, knife {p["knife"].n_k:g} rev/h).',
        f'- D: slowest carriage K_v = {k_min:.4f} at stroke position u = {k_u:.4f} (geometric return section).',
    ]

    written = [out / 'report.md']
    mechanisms: dict[str, MachineParams] = {'layup': p['layup'], 'knife': p['knife'], 'delivery': p['delivery']}
    for mech, mp in mechanisms.items():
        written.append(
            write_csv_atomic(out / f'{mech}.csv', kinematics_table(mech, None, 360 if mech != 'delivery' else 101, mp))
        )
    written += _plot_layup(p['layup'], inputs.container, out)
    written.append(_plot_knife(p['knife'], p['cyclogram'], out))
    written.append(_plot_delivery(p['delivery'], out))
    plots = [f'![{w.stem}]({w.name})' for w in written if w.suffix == '.png']
    # the plots are images of report.md; the console lists the files written instead (no empty heading)
    write_text_atomic(out / 'report.md', '\n'.join(lines + (['', '## Plots', '', *plots] if plots else [])) + '\n')

    for line in lines:
        print(line, file=stream)
    print('', file=stream)
    print(f'{sum(c.agrees for c in checks)} of {len(checks)} published results reproduced.', file=stream)
    print(f'Wrote {len(written)} files to {out.resolve()}:', file=stream)
    for w in written:
        print(f'  {w.name}', file=stream)
    return written
