"""Cost of the batch line simulation: 1 h of the folder scene, growth with duration,
and the price of each effect, all measured side by side in one run.

Run: ``.venv/bin/python bench/bench_line.py`` (``--quick`` for a short run).
"""

from __future__ import annotations

import argparse
import platform
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from folder_line.config.scenes import scene_mapping
from folder_line.core.line.model import simulate
from folder_line.core.line.scene import Scene, parse_scene


def best_of(fn: Callable[[], Any], repeat: int) -> float:
    best = float('inf')
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def variant(name: str, effects: list[str], overrides: dict[str, Any] | None = None) -> Scene:
    """Scene ``name`` with exactly ``effects`` (parameters taken from the ``line`` scene)."""
    line = scene_mapping('line')
    data = scene_mapping(name, overrides)
    data['effects'] = {e: line['effects'][e] for e in effects}
    return parse_scene(data)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument('--quick', action='store_true', help='shorter durations, fewer repeats')
    args = ap.parse_args()
    hour = 360.0 if args.quick else 3600.0
    rep = 1 if args.quick else 3
    print(f'python {platform.python_version()}, numpy {np.__version__}; best of {rep}; durations in line time\n')

    folder = variant('folder', ['stop_bounce', 'chain_friction'])
    t_hour = best_of(lambda: simulate(folder, hour, sample_rate=0.0), rep)
    print(
        f'folder scene, {hour:g} s of line time ({hour / 0.072:.0f} cycles), exact events: {t_hour:.3f} s '
        f'(target for 3600 s: <= 2 s)\n'
    )

    print('| duration, s | events only, s | per 1000 cycles, ms | with 200 Hz samples, s |')
    print('|---:|---:|---:|---:|')
    for d in [36.0, 360.0] if args.quick else [36.0, 360.0, 3600.0, 36000.0]:
        te = best_of(lambda d=d: simulate(folder, d, sample_rate=0.0), rep)
        ts = best_of(lambda d=d: simulate(folder, d, sample_rate=200.0), rep) if d <= 3600.0 else float('nan')
        ts_text = f'{ts:.3f}' if ts == ts else '—'
        print(f'| {d:g} | {te:.3f} | {1e3 * te / (d / 0.072) * 1000:.3f} | {ts_text} |')

    d = 360.0 if args.quick else 3600.0
    print(f'\nEach effect added, {d:g} s of line time (ratio: to the scene without effects, same run):\n')
    print('| scene | effects | events only, s | ratio | 200 Hz samples, s | ratio |')
    print('|---|---|---:|---:|---:|---:|')
    steps = [
        ('folder', [], None),
        ('folder', ['stop_bounce'], None),
        ('folder', ['stop_bounce', 'chain_friction'], None),
        ('folder', ['stop_bounce', 'chain_friction', 'feed_slip'], {'feed_transporter.V_tr': 9.6}),
        ('folder', ['stop_bounce', 'chain_friction', 'feed_slip', 'faults'], {'feed_transporter.V_tr': 9.6}),
        ('folder', ['stop_bounce', 'chain_friction', 'feed_slip', 'motor_dynamics'], {'feed_transporter.V_tr': 9.6}),
        ('layup', [], None),
        ('layup', ['chute_belts'], None),
        ('layup', ['chute_belts', 'leaf_flight'], None),
        ('layup', ['chute_belts', 'leaf_flight', 'leaf_damage'], None),
        ('layup', ['guide_friction', 'leaf_flight', 'leaf_damage'], None),
    ]
    base: dict[str, tuple[float, float]] = {}
    faults_params = {
        'p_missing': 0.001,
        'p_double': 0.001,
        'p_late': 0.001,
        'late_delay': 0.001,
        'p_slowdown': 0.0001,
        'slowdown_factor': 0.9,
        'slowdown_duration': 0.5,
    }
    guide = {'mu': 0.5, 's0': 0.0, 'v0': 1.0, 'h': 0.002}
    for name, effects, over in steps:
        line = scene_mapping('line')
        line['effects']['faults'] = faults_params
        line['effects']['guide_friction'] = guide
        data = scene_mapping(name, over)
        data['effects'] = {e: line['effects'][e] for e in effects}
        scene = parse_scene(data)
        dd = d if 'guide_friction' not in effects else d / 10.0
        te = best_of(lambda scene=scene, dd=dd: simulate(scene, dd, sample_rate=0.0), rep)
        ts = best_of(lambda scene=scene, dd=dd: simulate(scene, dd, sample_rate=200.0), rep)
        if not effects:
            base[name] = (te, ts)
        scale = d / dd
        b = base[name]
        print(
            f'| {name} | {", ".join(effects) or "none"}{"" if scale == 1 else f" (timed over {dd:g} s, scaled)"} '
            f'| {te * scale:.3f} | {te * scale / b[0]:.2f} | {ts * scale:.3f} | {ts * scale / b[1]:.2f} |'
        )

    no_cf = variant('folder', ['stop_bounce'])
    t_without = best_of(lambda: simulate(no_cf, d, sample_rate=200.0), rep)
    t_with = best_of(lambda: simulate(folder, d, sample_rate=200.0), rep)
    print(
        f'\nNot listing chain_friction (200 Hz samples, {d:g} s): {t_without:.3f} s vs {t_with:.3f} s listed: '
        f'{t_with / t_without:.2f} x faster without.'
    )


if __name__ == '__main__':
    main()
