"""A line whose ``line_clock`` dies: every node says so within ``lost_timeout`` plus a few seconds, keeps
saying it at a bounded rate, and its process exits non-zero when stopped (the line did not end)."""

from __future__ import annotations

import contextlib
import signal
import subprocess
import sys
import time
from pathlib import Path

from folder_line.interfaces import MACHINE_NODES
from folder_line.ros.lockstep import WAIT_REPORT
from folder_line.ros.nodes.machine import EXIT_LOST

from ._line_runs import wait_until

REPO = Path(__file__).resolve().parents[2]
LOST_TIMEOUT = 1.0
SILENT = 'line_clock silent for'


def start(name: str, env: dict[str, str], log: Path, *params: str) -> subprocess.Popen[bytes]:
    cmd = [sys.executable, '-m', f'folder_line.ros.nodes.{name}', '--ros-args']
    for p in params:
        cmd += ['-p', p]
    with open(log, 'wb') as f:
        return subprocess.Popen(cmd, env=env, cwd=REPO, stdout=subprocess.DEVNULL, stderr=f)


def test_a_killed_clock_is_named_by_every_node(node_env: dict[str, str], tmp_path: Path) -> None:
    common = ("scene:='folder'", f'lost_timeout:={LOST_TIMEOUT!r}')
    logs = {name: tmp_path / f'{name}.log' for name in (*MACHINE_NODES, 'line_clock')}
    nodes = {name: start(name, node_env, logs[name], *common) for name in MACHINE_NODES}
    clock = start(
        'line_clock', node_env, logs['line_clock'], 'duration:=60.0', 'rtf:=1.0', f'lost_timeout:={LOST_TIMEOUT!r}'
    )
    try:
        assert wait_until(lambda: 'sim time runs' in logs['line_clock'].read_text(), timeout=120.0), logs[
            'line_clock'
        ].read_text()
        time.sleep(0.5)
        clock.send_signal(signal.SIGKILL)
        killed = time.monotonic()
        clock.wait(timeout=10)

        def all_named() -> bool:
            return all(SILENT in logs[n].read_text() for n in MACHINE_NODES)

        assert wait_until(all_named, timeout=LOST_TIMEOUT + 10.0), {
            n: logs[n].read_text()[-500:] for n in MACHINE_NODES
        }
        named = time.monotonic() - killed
        assert named < LOST_TIMEOUT + 5.0  # within the limit plus a few seconds (a heartbeat, the report)
        # and it keeps saying so, at a bounded rate: a second report after WAIT_REPORT s, not a flood
        assert wait_until(
            lambda: all(logs[n].read_text().count(SILENT) >= 2 for n in MACHINE_NODES), timeout=WAIT_REPORT + 5
        )
        for name in MACHINE_NODES:
            count = logs[name].read_text().count(SILENT)
            assert count <= 2 + (time.monotonic() - killed) / WAIT_REPORT, (name, count)
    finally:
        for proc in nodes.values():
            if proc.poll() is None:
                proc.send_signal(signal.SIGINT)
        codes = {}
        for name, proc in nodes.items():
            with contextlib.suppress(subprocess.TimeoutExpired):
                proc.wait(timeout=20)
            if proc.poll() is None:
                proc.kill()
                proc.wait()
            codes[name] = proc.returncode
        if clock.poll() is None:
            clock.kill()
            clock.wait()
    # stopped by SIGINT with the line unfinished: non-zero, and no traceback
    assert codes == dict.fromkeys(MACHINE_NODES, EXIT_LOST), codes
    for name in MACHINE_NODES:
        assert 'Traceback' not in logs[name].read_text(), logs[name].read_text()[-2000:]
