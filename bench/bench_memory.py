"""Peak memory of a batch model per knife cycle and per leaf: the figures ``check_size`` refuses by.

Run: ``.venv/bin/python bench/bench_memory.py`` (about a minute). Each scene is simulated
(``simulate``, events only, and its summary, as ``folder-line simulate`` does) in a fresh
process for two durations; the growth of the peak RSS between them, over the knife cycles
(``folder``) or leaves (``layup``) added, is the peak memory per cycle or leaf. Start-up
(imports, the interpreter) cancels out. The ``line`` scene checks the two figures
together. Compare with :data:`folder_line.core.line.model.BYTES_PER_CYCLE` and
:data:`~folder_line.core.line.model.BYTES_PER_LEAF`, which must not be below what is measured
here.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _peak(scene: str, duration: float) -> tuple[int, int, int]:
    """(peak RSS bytes, knife cycles, leaves) of one batch run in a fresh process."""
    code = """
import json, resource, sys
sys.path.insert(0, sys.argv[3])
from folder_line.interfaces import EVENT_KINDS
from folder_line.core.line.model import simulate
from folder_line.config.scenes import load_scene
scene = load_scene(sys.argv[1], {})
result = simulate(scene, float(sys.argv[2]), sample_rate=0.0)
result.summary()
kinds = result.events["kind"]
print(json.dumps({"rss": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024,
                  "cycles": int((kinds == EVENT_KINDS.index("knife_contact")).sum()),
                  "leaves": int((kinds == EVENT_KINDS.index("leaf_enter")).sum())}))
"""
    out = subprocess.run(
        [sys.executable, '-c', code, scene, repr(duration), str(REPO)], capture_output=True, text=True, check=True
    ).stdout
    d = json.loads(out)
    return d['rss'], d['cycles'], d['leaves']


def growth(scene: str, d1: float, d2: float) -> tuple[float, int, int]:
    """(peak RSS growth in bytes, cycles added, leaves added) from ``d1`` to ``d2`` s of line time."""
    r1, c1, l1 = _peak(scene, d1)
    r2, c2, l2 = _peak(scene, d2)
    return r2 - r1, c2 - c1, l2 - l1


def main() -> int:
    from folder_line.core.line.model import BYTES_PER_CYCLE, BYTES_PER_LEAF

    d1, d2 = 3600.0, 14400.0
    rss, cycles, _ = growth('folder', d1, d2)
    per_cycle = rss / cycles
    rss, _, leaves = growth('layup', d1, d2)
    per_leaf = rss / leaves
    rss, cycles_line, leaves_line = growth('line', d1, d2)
    predicted = cycles_line * BYTES_PER_CYCLE + leaves_line * BYTES_PER_LEAF
    print(
        f'peak memory per knife cycle (folder, {d1:g} -> {d2:g} s): {per_cycle:.0f} B '
        f'(BYTES_PER_CYCLE = {BYTES_PER_CYCLE})'
    )
    print(f'peak memory per leaf (layup, {d1:g} -> {d2:g} s): {per_leaf:.0f} B (BYTES_PER_LEAF = {BYTES_PER_LEAF})')
    print(
        f'line, {d1:g} -> {d2:g} s: {rss / 1e6:.0f} MB measured, {predicted / 1e6:.0f} MB from the two figures '
        f'({cycles_line} cycles, {leaves_line} leaves)'
    )
    if per_cycle > BYTES_PER_CYCLE or per_leaf > BYTES_PER_LEAF:
        print('the constants are below what is measured: raise them', file=sys.stderr)
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
