"""Benchmark of ``simulate --bag`` against its floor: ``python bench/bench_bag.py [SECONDS] [SCENE]``.

Measures, in one run (default one hour of the ``folder`` scene at 200 Hz):

* ``folder-line simulate --scene SCENE --duration SECONDS --bag DIR`` as a process: wall
  time and peak RSS (the batch model, the supervisor's logic and the writing, everything);
* the floor: the ``rosbags`` writer (``rosbags.rosbag2.Writer``, MCAP storage) serialising the
  same messages (``Typestore.serialize_cdr``) and writing them, no model. The messages are
  read back from the bag just written and deserialized, a batch at a time, outside the
  timing; only serialize + write (and the writer's close) are timed.

Prints both, their ratio and the messages per second. Everything is written under a
temporary folder that is removed at the end.
"""

from __future__ import annotations

import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from rosbags.rosbag2 import Reader, StoragePlugin, Writer  # noqa: E402

from folder_line.bag.types import typestore  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
BATCH = 20_000  # messages deserialized (untimed) before they are serialized and written (timed)


def simulate_bag(seconds: float, scene: str, out: Path) -> tuple[float, float]:
    """Wall time (s) and peak RSS (MiB) of ``folder-line simulate --bag`` as a child process."""
    env = {**os.environ, 'PYTHONPATH': str(REPO)}
    cmd = [sys.executable, '-m', 'folder_line.cli.main', 'simulate', '--scene', scene]
    cmd += ['--duration', f'{seconds:g}', '--bag', str(out)]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, cwd=REPO, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f'simulate --bag failed ({proc.returncode}):\n{proc.stderr}')
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    return wall, peak


def floor(bag: Path, out: Path) -> tuple[float, int]:
    """Seconds the rosbags writer takes to serialize and write every message of ``bag``; and their number."""
    store = typestore()
    timed = 0.0
    n = 0
    with Reader(bag) as reader:
        writer = Writer(out, version=9, storage_plugin=StoragePlugin.MCAP)
        writer.open()
        conns: dict[int, Any] = {}
        t0 = time.perf_counter()
        for c in reader.connections:
            conns[c.id] = writer.add_connection(c.topic, c.msgtype, typestore=store)
        timed += time.perf_counter() - t0
        batch: list[tuple[Any, int, Any, str]] = []

        def write_batch() -> float:
            t = time.perf_counter()
            for conn, stamp, msg, msgtype in batch:
                writer.write(conn, stamp, store.serialize_cdr(msg, msgtype))
            batch.clear()
            return time.perf_counter() - t

        for conn, stamp, raw in reader.messages():
            batch.append((conns[conn.id], stamp, store.deserialize_cdr(raw, conn.msgtype), conn.msgtype))
            n += 1
            if len(batch) >= BATCH:
                timed += write_batch()
        timed += write_batch()
        t0 = time.perf_counter()
        writer.close()
        timed += time.perf_counter() - t0
    return timed, n


def main(argv: list[str]) -> None:
    seconds = float(argv[0]) if argv else 3600.0
    scene = argv[1] if len(argv) > 1 else 'folder'
    with tempfile.TemporaryDirectory(prefix='bench_bag_') as tmp:
        ours, peak = simulate_bag(seconds, scene, Path(tmp) / 'batch')
        size = sum(p.stat().st_size for p in (Path(tmp) / 'batch').iterdir()) / 2**20
        base, n = floor(Path(tmp) / 'batch', Path(tmp) / 'floor')
    print(f'{seconds:g} s of {scene} at 200 Hz: {n} messages, bag {size:.0f} MiB')
    print('| what | wall s | messages/s |')
    print('|---|---:|---:|')
    print(f'| `simulate --bag` (model, supervisor, writing; peak RSS {peak:.0f} MiB) | {ours:.1f} | {n / ours:,.0f} |')
    print(f'| floor: rosbags writer, serialize + write only | {base:.1f} | {n / base:,.0f} |')
    print(f'ratio simulate --bag / floor: {ours / base:.2f}')


if __name__ == '__main__':
    main(sys.argv[1:])
