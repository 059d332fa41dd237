"""Benchmark of ``analyze``'s streaming read: ``python bench/bench_analyze.py RUN_DIR|BAG``.

Measures, in one run and side by side on the same bag:

* the floor: ``rosbags`` reading and deserializing every message once (messages/s);
* :func:`folder_line.analysis.recording.read_recording`: the one pass ``analyze`` makes,
  and its ratio to the floor;
* ``folder-line analyze`` whole (figures and report included), in a child process: wall
  time and peak RSS (``os.wait4``'s ``ru_maxrss`` of that child);
* the same with ``--to`` a tenth of the bag's line time: how peak RSS grows with the
  length of the recording (the joint states are kept to a bounded sample; the events,
  the replay's line model and the supervisor's statuses grow).

Make the bag with ``folder-line simulate --bag`` or a live ``folder-line run --rtf max``.
Prints a markdown table.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from rosbags.rosbag2 import Reader

from folder_line.analysis.recording import _resolve, read_recording
from folder_line.bag.types import typestore


def _analyze(path: str, extra: list[str]) -> tuple[float, float]:
    """(wall s, peak RSS MB) of ``folder-line analyze PATH *extra`` in a child process."""
    with tempfile.TemporaryDirectory() as out:
        env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parent.parent))
        t0 = time.perf_counter()
        proc = subprocess.Popen(
            [sys.executable, '-m', 'folder_line.cli.main', 'analyze', path, '--out', out, *extra],
            stdout=subprocess.DEVNULL,
            env=env,
        )
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        if proc.returncode != 0:
            raise subprocess.CalledProcessError(proc.returncode, proc.args)
    return wall, usage.ru_maxrss / 1024


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
    whole, rss_mb = _analyze(path, [])
    tenth, tenth_mb = _analyze(path, ['--to', f'{rec.t_end / 10:.3f}'])
    print(f'bag: {bag}, {n} messages, {rec.t_end:.6g} s of line time')
    print('| step | wall, s | messages/s | x floor |')
    print('|---|---|---|---|')
    print(f'| rosbags: deserialize every message (floor) | {floor:.2f} | {n / floor:.0f} | 1.00 |')
    print(f"| read_recording (analyze's one pass) | {one_pass:.2f} | {n / one_pass:.0f} | {one_pass / floor:.2f} |")
    print(f'| folder-line analyze (whole, child process) | {whole:.2f} | {n / whole:.0f} | {whole / floor:.2f} |')
    print(f'peak RSS of folder-line analyze: {rss_mb:.0f} MB')
    print(
        f'with --to {rec.t_end / 10:.6g} s (a tenth): {tenth:.2f} s, peak RSS {tenth_mb:.0f} MB; '
        f'growth {(rss_mb - tenth_mb) / (0.9 * rec.t_end / 3600):.0f} MB per hour of line time'
    )


if __name__ == '__main__':
    main(sys.argv[1])
