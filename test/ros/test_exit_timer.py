"""The C timer that ends a process whose interpreter is stuck in a call that holds the GIL."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

REPO = str(Path(__file__).resolve().parents[2])

_STUCK = """
import re, sys, threading
sys.path.insert(0, {repo!r})
from folder_line.ros.exit_timer import arm_exit
threading.Timer(0.05, lambda: print('a Python thread ran', flush=True)).start()
cancel = arm_exit(0.5, 7)
assert cancel is not None
if {cancelled!r}:
    cancel()
    import time
    time.sleep(1.0)
    sys.exit(0)
re.match(r'(a+)+$', 'a' * 60 + 'b')  # backtracks for ages, holding the GIL throughout
print('the match returned', flush=True)
"""


def run(cancelled: bool) -> subprocess.CompletedProcess[str]:
    code = _STUCK.format(repo=REPO, cancelled=cancelled)
    return subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, timeout=60)


def test_the_timer_ends_a_process_held_in_a_c_call_with_the_code_given() -> None:
    proc = run(cancelled=False)
    assert proc.returncode == 7, (proc.returncode, proc.stdout, proc.stderr)
    # the GIL was held all along: neither the Python timer nor the rest of the script ran
    assert proc.stdout == '', proc.stdout


def test_a_cancelled_timer_does_nothing() -> None:
    proc = run(cancelled=True)
    assert proc.returncode == 0, (proc.returncode, proc.stderr)
    assert proc.stdout == 'a Python thread ran\n'
