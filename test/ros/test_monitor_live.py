"""``folder-line monitor`` against a running line over real DDS: the ``--once`` snapshot, and the curses view in tmux.

The line (the five machine nodes and ``line_clock`` in lockstep, as ``folder-line run``
runs them in-process) spins in a thread of this process for the whole module; the
monitor runs as a separate process in the same ROS domain (``test/conftest.py``). The
monitor takes no part in the lockstep: the line runs as fast as its nodes answer, up
to rtf 1, whatever the monitor does; how fast that is depends on the machine, so the
rates shown are only required to be positive.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
import rclpy
from _ros_env import DOMAIN_ID
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter

from folder_line.ros.nodes.belt_conveyor import BeltConveyor
from folder_line.ros.nodes.crank_drive import CrankDrive
from folder_line.ros.nodes.feed_transporter import FeedTransporter
from folder_line.ros.nodes.line_clock import LineClock
from folder_line.ros.nodes.sheet_counter import SheetCounter
from folder_line.ros.nodes.supervisor import Supervisor
from folder_line.ros.topics import joint_states_topic

REPO = Path(__file__).resolve().parents[2]
JOINT_TOPICS = [joint_states_topic(n) for n in ('crank_drive', 'belt_conveyor', 'feed_transporter', 'sheet_counter')]
DURATION = 600.0  # s of sim time: longer than the module needs; the line is stopped at the end


class Line:
    """The line's nodes in a private context, spun by a thread until :meth:`stop`."""

    def __init__(self) -> None:
        self.context = Context()
        rclpy.init(context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        params = [
            Parameter('scene', value='folder'),
            Parameter('rate', value=200.0),
        ]
        # diagnostics every 0.1 s of sim time: a snapshot has some however slowly a loaded machine runs the line
        self.supervisor = Supervisor(
            parameter_overrides=[*params, Parameter('diag_rate', value=10.0)], context=self.context
        )
        self.nodes = [
            cls(parameter_overrides=params, context=self.context)
            for cls in (CrankDrive, BeltConveyor, FeedTransporter, SheetCounter)
        ]
        self.nodes += [
            self.supervisor,
            LineClock(parameter_overrides=[Parameter('duration', value=DURATION)], context=self.context),
        ]
        for node in self.nodes:
            self.executor.add_node(node)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        while not self._stop.is_set():
            self.executor.spin_once(timeout_sec=0.05)

    def wait_for(self, predicate: Callable[[], bool], timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while not predicate():
            if time.monotonic() > deadline:
                return False
            time.sleep(0.05)
        return True

    def halt(self) -> None:
        """Stop spinning (the nodes stay)."""
        self._stop.set()
        self._thread.join(timeout=10.0)
        assert not self._thread.is_alive()

    def stop(self) -> None:
        self.halt()
        self.executor.shutdown()
        for node in self.nodes:
            node.destroy_node()
        rclpy.try_shutdown(context=self.context)


@pytest.fixture(scope='module')
def line() -> Iterator[Line]:
    running = Line()
    try:
        assert running.wait_for(lambda: running.supervisor.packml.state == 'EXECUTE', timeout=30.0), (
            running.supervisor.packml.state
        )
        yield running
    finally:
        running.stop()


def monitor_cmd(*args: str) -> list[str]:
    return [sys.executable, '-m', 'folder_line.cli.main', 'monitor', *args]


# --------------------------------------------------------------------------- --once


def snapshot(node_env: dict[str, str]) -> tuple[list[str], dict[str, list[str]]]:
    """One ``--once`` snapshot: its lines, and its topic rows split into words."""
    t0 = time.monotonic()
    proc = subprocess.run(
        monitor_cmd('--once', '--window', '1.5'), env=node_env, capture_output=True, text=True, timeout=60, check=False
    )
    assert proc.returncode == 0, proc.stderr
    assert 'traceback' not in proc.stderr.lower()
    print(f'--once took {time.monotonic() - t0:.2f} s:\n{proc.stdout}')
    lines = proc.stdout.splitlines()
    return lines, {line.split()[0]: line.split() for line in lines if line.startswith('/')}


def test_once_prints_a_snapshot_of_the_running_line(line: Line, node_env: dict[str, str]) -> None:
    # the window starts at the first message, the transient-local announcement; a new process may discover
    # the line's other publishers (a few hundred endpoints) only seconds later, and on a loaded machine the
    # lockstep line may stand still for a whole window: a snapshot that saw no publisher, or no arrival in
    # its window, shows nothing to judge and is taken again (at most twice more)
    for _ in range(3):
        lines, rows = snapshot(node_env)
        if all(rows[topic][2] != '0' for topic in [*JOINT_TOPICS, '/diagnostics']) and all(
            rows[topic][1] not in ('0.0', '-') for topic in [*JOINT_TOPICS, '/clock']
        ):
            break
    assert lines[0].startswith('folder-line monitor |') and '| supervisor EXECUTE' in lines[0]
    for topic in JOINT_TOPICS:  # 200 Hz of sim time at most (rtf 1), as fast as the machine allows
        assert float(rows[topic][1]) > 0.0, rows[topic]
        assert int(rows[topic][2]) > 0
    assert float(rows['/clock'][1]) > 0.0
    # the announcement, transient-local: received once however late the monitor came
    assert rows['/line/participants'][2:] == ['1', 'lockstep', 'clock,', '5', 'participants']
    constraints = list(line.supervisor.stream.tallies.constraints.values())
    assert constraints
    shown = {'s': r'[+-]\d+\.\d{4} ms', 'm': r'[+-]\d+\.\d{4} mm', 'sheets': r'1 sheet|\d+ sheets? off'}
    for c in constraints:  # one row per constraint: level, margin and smallest margin, each in its unit
        text = next(x for x in lines if x.startswith(f'folder_line/{c.name} '))
        value = shown.get(c.unit, r'[+-][0-9.e+-]+')
        assert re.match(rf'folder_line/{c.name} +(OK|WARN|ERROR) +({value}) +({value}) +\d+/\d+', text), text


def test_once_without_a_line_says_so_and_exits_1(node_env: dict[str, str]) -> None:
    env = dict(node_env, ROS_DOMAIN_ID=str(215 + DOMAIN_ID % 18))  # nobody there
    proc = subprocess.run(
        monitor_cmd('--once', '--timeout', '1'), env=env, capture_output=True, text=True, timeout=60, check=False
    )
    assert proc.returncode == 1, proc.stderr
    assert 'waiting for the line' in proc.stdout and 'supervisor ?' in proc.stdout
    assert proc.stderr.strip().splitlines()[-1] == (
        f'folder-line: error: monitor --once: no message of the line on ROS_DOMAIN_ID={env["ROS_DOMAIN_ID"]} within '
        '--timeout 1 s: is a line running there?'
    )


# --------------------------------------------------------------------------- the curses view in tmux


class Tmux:
    """A tmux server of its own (``-L``), so the pane gets this test's environment and nothing else."""

    def __init__(self, env: dict[str, str], width: int, height: int, command: str) -> None:
        self.socket = f'folder-line-monitor-{os.getpid()}-{uuid.uuid4().hex[:8]}'
        # curses takes LINES and COLUMNS over the terminal's size (pytest-xdist's workers set 24 x 80)
        self.env = {k: v for k, v in env.items() if k not in ('LINES', 'COLUMNS')}
        self.run('new-session', '-d', '-s', 'mon', '-x', str(width), '-y', str(height), command)

    def run(self, *args: str) -> str:
        proc = subprocess.run(
            ['tmux', '-L', self.socket, '-f', os.devnull, *args],
            env=self.env,
            capture_output=True,
            text=True,
            timeout=10,
            check=False,
        )
        assert proc.returncode == 0, (args, proc.stderr)
        return proc.stdout

    def screen(self) -> str:
        return self.run('capture-pane', '-p', '-t', 'mon')

    def wait_for(self, predicate: Callable[[str], Any], timeout: float = 30.0) -> str:
        """The pane's text once ``predicate(text)`` holds; fails with the last text after ``timeout`` s."""
        deadline = time.monotonic() + timeout
        while True:
            text = self.screen()
            if predicate(text):
                return text
            if time.monotonic() > deadline:
                pytest.fail(f'timed out waiting on the pane; it shows:\n{text}')
            time.sleep(0.1)

    def kill(self) -> None:
        """Stop the server and remove its socket file."""
        subprocess.run(
            ['tmux', '-L', self.socket, 'kill-server'], env=self.env, capture_output=True, timeout=10, check=False
        )
        base = Path(self.env.get('TMUX_TMPDIR') or '/tmp') / f'tmux-{os.getuid()}'
        (base / self.socket).unlink(missing_ok=True)


def live_rows(text: str) -> bool:
    """The header, the joint_states rows with rates above zero and the constraints are on the screen."""
    rows = {w[0]: w for w in (line.split() for line in text.splitlines()) if w and w[0].startswith('/')}
    return (
        text.startswith('folder-line monitor |')
        and 'supervisor EXECUTE' in text
        and all(t in rows and rows[t][1] != '-' and float(rows[t][1]) > 0.0 for t in JOINT_TOPICS)
        and 'CONSTRAINT' in text
        and 'folder_line/feed_window' in text
    )


@pytest.fixture
def tmux_ok() -> None:
    assert shutil.which('tmux'), 'tmux is needed for the curses test (apt-get install tmux)'


@pytest.mark.parametrize('key', ['q', 'C-c'])
def test_curses_view_in_tmux_quits_cleanly(
    line: Line, node_env: dict[str, str], tmp_path: Path, key: str, tmux_ok: None
) -> None:
    err = tmp_path / 'stderr.txt'
    command = (
        f'{shlex.join(monitor_cmd("--rate", "10"))} 2>{shlex.quote(str(err))}; echo "EXIT=$?"; '
        'sleep 120'
    )  # the pane stays, to show what the terminal looks like after the monitor
    tmux = Tmux(node_env, 110, 45, command)
    try:
        t0 = time.monotonic()
        # every topic is discovered on its own (up to seconds apart under load): wait for the events too
        screen = tmux.wait_for(lambda text: live_rows(text) and 'EVENT' in text)
        print(f'live after {time.monotonic() - t0:.2f} s:\n{screen}')
        assert 'JOINT' in screen and 'EVENT' in screen
        if key == 'q':  # a terminal too small, then big enough again
            tmux.run('resize-window', '-t', 'mon', '-x', '30', '-y', '5')
            small = tmux.wait_for(lambda text: 'terminal too small' in text.replace('\n', ''))
            print(f'at 30x5:\n{small}')
            tmux.run('resize-window', '-t', 'mon', '-x', '110', '-y', '45')
            tmux.wait_for(live_rows)
        t1 = time.monotonic()
        tmux.run('send-keys', '-t', 'mon', key)
        after = tmux.wait_for(lambda text: 'EXIT=' in text, timeout=10.0)
        print(f'{key} -> exit after {time.monotonic() - t1:.2f} s; the pane then shows:\n{after!r}')
    finally:
        tmux.kill()
    assert re.search(r'^EXIT=0$', after, re.MULTILINE), after
    assert 'folder-line monitor' not in after  # the terminal is back: the view is gone with the alternate screen
    assert 'Traceback' not in err.read_text(), err.read_text()


def test_curses_view_sends_operator_commands(line: Line, node_env: dict[str, str], tmux_ok: None) -> None:
    """``h`` holds the line, ``u`` unholds it (answers on the operator row), ``x`` asks before a stop and
    any key but ``y`` cancels it, ``q`` quits."""
    tmux = Tmux(node_env, 160, 45, f'{shlex.join(monitor_cmd("--rate", "10"))}; echo "EXIT=$?"; sleep 120')
    try:
        tmux.wait_for(lambda text: live_rows(text) and 'operator keys: h hold  u unhold' in text)
        tmux.run('send-keys', '-t', 'mon', 'h')
        held = tmux.wait_for(lambda text: 'supervisor HELD' in text, timeout=60.0)
        assert 'operator: hold: accepted: hold: HOLDING, drive hold effective at ' in held, held
        tmux.run('send-keys', '-t', 'mon', 'h')  # again: refused while HELD, the reason shown
        refused = tmux.wait_for(lambda text: 'operator: hold: refused: ' in text)
        assert 'HELD' in refused.split('operator: hold: refused: ', 1)[1].splitlines()[0]
        tmux.run('send-keys', '-t', 'mon', 'u')
        tmux.wait_for(lambda text: 'operator: unhold: accepted: unhold: UNHOLDING' in text, timeout=60.0)
        tmux.wait_for(live_rows, timeout=60.0)  # EXECUTE again
        tmux.run('send-keys', '-t', 'mon', 'x')
        tmux.wait_for(lambda text: 'operator: stop the line? y: yes, any other key: no' in text)
        tmux.run('send-keys', '-t', 'mon', 'n')
        tmux.wait_for(lambda text: 'operator: stop: cancelled' in text)
        tmux.run('send-keys', '-t', 'mon', 'q')
        after = tmux.wait_for(lambda text: 'EXIT=' in text, timeout=10.0)
    finally:
        tmux.kill()
    assert re.search(r'^EXIT=0$', after, re.MULTILINE), after
    assert line.supervisor.packml.state == 'EXECUTE'


# --------------------------------------------------------------------------- the line itself


def test_the_line_ran_in_lockstep_every_tick_of_the_grid(line: Line) -> None:
    """Last in the module: the line is halted where it is; no node skipped a tick of the clock, and none is more
    than the clock's window behind the latest tick granted."""
    line.halt()
    clock = line.nodes[-1]
    assert isinstance(clock, LineClock) and clock.lost == {} and clock.current is not None
    step = 5_000_000  # 200 Hz
    window = round(clock.values['window'] * 1e9)
    assert clock.ticks == clock.current // step + 1
    for node in line.nodes[:-1]:
        done = node.lockstep.last_done
        assert clock.current - window - step <= done <= clock.current, node.get_name()
        assert node.lockstep.ticks == done // step + 1 and node.rejected == {}
    assert line.supervisor.packml.state == 'EXECUTE' and line.supervisor.logic.violations == []
