"""Benchmark of ``analyze``'s streaming read: ``python bench/bench_analyze.py RUN_DIR|BAG``.

Measures, in one run and side by side on the same bag:

* the floor: ``rosbags`` reading and deserializing every message once (messages/s);
* :func:`folder_line.analysis.recording.read_recording`: the one pass ``analyze`` makes,
  and its ratio to the floor;
* ``folder-line analyze`` whole (figures and report included), in a child process: wall
  time and peak RSS (``resource.getrusage(RUSAGE_CHILDREN).ru_maxrss``).

Make the bag with ``folder-line simulate --bag`` or a live ``folder-line run --rtf max``.
Prints a markdown table.
"""

from __future__ import annotations

import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from rosbags.rosbag2 import Reader  # noqa: E402

from folder_line.analysis.recording import _resolve, read_recording  # noqa: E402
from folder_line.bag.types import typestore  # noqa: E402


def main(path: str) -> None:
    bag, _ = _resolve(path)
    store = typestore()
    t0 = time.perf_counter()
    n = 0
    with Reader(bag) as reader:
        for conn, _, raw in reader.messages():
            store.deserialize_cdr(raw, conn.msgtype)
            n += 1
    floor = time.perf_counter() - t0
    t0 = time.perf_counter()
    rec = read_recording(path)
    one_pass = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as out:
        env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parent.parent))
        t0 = time.perf_counter()
        subprocess.run(
            [sys.executable, '-m', 'folder_line.cli.main', 'analyze', path, '--out', out],
            check=True,
            stdout=subprocess.DEVNULL,
            env=env,
        )
        whole = time.perf_counter() - t0
    rss_mb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    print(f'bag: {bag}, {n} messages, {rec.t_end:.6g} s of line time')
    print('| step | wall, s | messages/s | x floor |')
    print('|---|---|---|---|')
    print(f'| rosbags: deserialize every message (floor) | {floor:.2f} | {n / floor:.0f} | 1.00 |')
    print(f"| read_recording (analyze's one pass) | {one_pass:.2f} | {n / one_pass:.0f} | {one_pass / floor:.2f} |")
    print(f'| folder-line analyze (whole, child process) | {whole:.2f} | {n / whole:.0f} | {whole / floor:.2f} |')
    print(f'peak RSS of folder-line analyze: {rss_mb:.0f} MB')


if __name__ == '__main__':
    main(sys.argv[1])
