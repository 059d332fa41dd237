"""Benchmark of the layup six-bar kinematics: ``python bench/bench_layup.py [N]``.

Measures, in one run and side by side:

* the vectorised six-bar (:meth:`LayupModel.arrays`): positions + velocities (and,
  separately, + accelerations) for N crank angles (default 1e6), in angles/s;
* the scalar pure-``math`` path (:meth:`LayupModel.point`), µs per call;
* for scale, a plain NumPy closed-form four-bar (loop O1-A-B-O2 only: B, θ3, ω3,
  written as straightforward whole-array expressions), evaluations/s.

Each figure is the best of several repeats (wall clock, ``time.perf_counter``), output
arrays freshly allocated on every call as a caller would see them. Prints a markdown table.
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from folder_line.config.params import load_params
from folder_line.core.mechanisms.layup import LayupModel, layup_point
from folder_line.core.mechanisms.layup_angles import TAU


def best_of(fn, repeats: int) -> float:
    """Smallest wall time of ``repeats`` calls, s."""
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def fourbar_numpy(
    phi: np.ndarray, R: float, a: float, b: float, l2: float, p: float, w: float
) -> tuple[np.ndarray, ...]:
    """Plain NumPy closed form of the crank-rocker O1-A-B-O2: B, θ3 and ω3 (reference for scale)."""
    c, s = np.cos(phi), np.sin(phi)
    ax = a + R * c
    ay = b + R * s
    d2 = ax * ax + ay * ay
    k1 = 0.5 + (p * p - l2 * l2) / (2.0 * d2)
    s1 = np.sqrt(((p + l2) ** 2 - d2) * (d2 - (p - l2) ** 2))
    k2 = 0.5 * s1 / d2
    bx = k1 * ax - k2 * ay
    by = k1 * ay + k2 * ax
    w3 = 2.0 * w * R * ((by - ay) * c - (bx - ax) * s) / s1
    return bx, by, np.arctan2(by, bx), w3


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and print the table; returns the exit code."""
    args = sys.argv[1:] if argv is None else argv
    n = int(float(args[0])) if args else 1_000_000
    p = load_params('layup')
    model = LayupModel(p)
    rng = np.random.default_rng(12345)
    phi = rng.uniform(0.0, TAU, n)  # [0, 2π): exercises the exact reduction
    phi_red = rng.uniform(-math.pi, math.pi, n)  # already reduced

    model.arrays(phi[:1000])  # warm up
    t_pv = best_of(lambda: model.arrays(phi, accelerations=False), 7)
    t_pv_red = best_of(lambda: model.arrays(phi_red, accelerations=False), 7)
    t_pva = best_of(lambda: model.arrays(phi, accelerations=True), 7)
    t_4bar = best_of(lambda: fourbar_numpy(phi, p.R_kr, p.a, p.b, p.l2, p.O2B, p.omega), 7)

    angles = [float(x) for x in phi[:100_000]]
    point = model.point

    def scalar_loop() -> None:
        for x in angles:
            point(x)

    def cached_loop() -> None:
        for x in angles[:20_000]:
            layup_point(p, x)

    t_point = best_of(scalar_loop, 5) / len(angles)
    t_cached = best_of(cached_loop, 5) / 20_000

    rate = n / t_pv
    rate_4 = n / t_4bar
    rows = [
        ('six-bar vectorised, positions + velocities, phi in [0, 2pi)', f'{n:.0e}', t_pv * 1e3, f'{rate:.3g} angles/s'),
        (
            'six-bar vectorised, positions + velocities, phi in [-pi, pi]',
            f'{n:.0e}',
            t_pv_red * 1e3,
            f'{n / t_pv_red:.3g} angles/s',
        ),
        ('six-bar vectorised, + accelerations', f'{n:.0e}', t_pva * 1e3, f'{n / t_pva:.3g} angles/s'),
        ('four-bar plain NumPy closed form (B, theta3, omega3)', f'{n:.0e}', t_4bar * 1e3, f'{rate_4:.3g} evals/s'),
        ('six-bar scalar LayupModel.point', '1', t_point * 1e3, f'{t_point * 1e6:.2f} us/call'),
        ('six-bar scalar layup_point (cached model)', '1', t_cached * 1e3, f'{t_cached * 1e6:.2f} us/call'),
    ]
    print(f'numpy {np.__version__}, python {sys.version.split()[0]}\n')
    print('| case | N | time per call (ms) | throughput |')
    print('|---|---:|---:|---:|')
    for name, nn, ms, thr in rows:
        print(f'| {name} | {nn} | {ms:.4g} | {thr} |')
    print(
        f'\nsix-bar / plain four-bar throughput ratio: {rate / rate_4:.2f} '
        f'(target six-bar >= 1e7 angles/s: {"met" if rate >= 1e7 else "NOT met"}; '
        f'scalar <= 5 us: {"met" if t_point <= 5e-6 else "NOT met"})'
    )
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
