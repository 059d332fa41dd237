"""Test side of the probes: processes in the test hosts whose output lines are collected, UDP senders and
receivers, the environment of ROS nodes in the test hosts."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ros import _line_runs

from .netns import Host, Network

PYTHON = sys.executable
PROBE = Path(__file__).with_name('udp_probe.py')
PORT = 47000  # the receivers' UDP port
REPO = Path(__file__).resolve().parents[2]


def wait_until(predicate: Callable[[], bool], timeout: float, interval: float = 0.005) -> bool:
    """:func:`ros._line_runs.wait_until`, polled every 5 ms: the probes time repairs of a few ms."""
    return _line_runs.wait_until(predicate, timeout, interval)


class Lines:
    """The stdout lines of a process (text mode), collected by a thread as they come.

    ``on_line`` (optional) is called with each line in that thread, under the lock that
    :meth:`wait_for` holds while it evaluates its predicate.
    """

    def __init__(self, proc: subprocess.Popen[str], on_line: Callable[[str], None] | None = None) -> None:
        assert proc.stdout is not None, 'start it with stdout=subprocess.PIPE, text=True'
        self.proc = proc
        self._lines: list[str] = []
        self._on_line = on_line
        self.lock = threading.Condition()
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            with self.lock:
                self._lines.append(line.rstrip('\n'))
                if self._on_line is not None:
                    self._on_line(self._lines[-1])
                self.lock.notify_all()

    @property
    def lines(self) -> list[str]:
        """Every line so far (a copy)."""
        with self.lock:
            return list(self._lines)

    def wait_for(self, predicate: Callable[[list[str]], bool], timeout: float, interval: float = 0.01) -> bool:
        """Wait until ``predicate(lines)`` holds or ``timeout`` s have passed; its last value.

        The predicate runs under the lock, at most once per ``interval`` s (cheap for the probes).
        """
        deadline = time.monotonic() + timeout
        with self.lock:
            while not predicate(self._lines):
                left = deadline - time.monotonic()
                if left <= 0.0:
                    return predicate(self._lines)
                self.lock.wait(min(left, 0.1))  # a new line, or a look at a process that ended
                self.lock.release()
                try:
                    time.sleep(interval)  # let lines gather: the predicate may be costly
                finally:
                    self.lock.acquire()
            return True


@dataclass(frozen=True)
class Datagram:
    """One datagram a receiver got."""

    seq: int
    size: int
    intact: bool
    delay_ns: int  # one way, sender's send call to receiver's recv call


class Receiver:
    """``udp_probe.py recv`` in ``host`` on :data:`PORT` (joined to ``group``), started and ready."""

    def __init__(self, host: Host, group: str | None = None, port: int = PORT) -> None:
        argv = [PYTHON, str(PROBE), 'recv', '--port', str(port), *(('--group', group) if group else ())]
        self.host = host
        self._got: dict[int, Datagram] = {}
        self._order: list[int] = []  # sequence numbers as they arrived
        self.proc: subprocess.Popen[str] = host.popen(
            argv, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, bufsize=1
        )
        self.out = Lines(self.proc, on_line=self._parse)
        if not self.out.wait_for(lambda lines: 'ready' in lines, timeout=20.0):
            raise RuntimeError(f'the receiver in {host.name} did not start: {self.out.lines}')

    def _parse(self, line: str) -> None:
        if line.startswith('rx '):
            seq, size, intact, delay = (int(w) for w in line.split()[1:])
            self._got[seq] = Datagram(seq, size, bool(intact), delay)
            self._order.append(seq)

    def datagrams(self, first: int = 0, end: int | None = None) -> dict[int, Datagram]:
        """Datagrams received so far with ``first <= seq < end``, by sequence number."""
        with self.out.lock:
            return {s: d for s, d in self._got.items() if s >= first and (end is None or s < end)}

    def arrival_order(self) -> list[int]:
        """Sequence numbers in the order they arrived."""
        with self.out.lock:
            return list(self._order)

    def wait_for_seq(self, seq: int, timeout: float = 10.0) -> bool:
        """Wait until datagram ``seq`` has arrived."""
        return self.out.wait_for(lambda _: seq in self._got, timeout)

    def wait_for_count(self, first: int, end: int, timeout: float = 10.0) -> bool:
        """Wait until every datagram ``first .. end - 1`` has arrived."""
        return self.out.wait_for(lambda _: all(s in self._got for s in range(first, end)), timeout)


def send(
    host: Host, to: str, count: int, *, start: int = 0, size: int = 64, rate: float = 0.0, port: int = PORT
) -> None:
    """Send datagrams ``start .. start + count - 1`` from ``host`` to ``to`` (an address), to its end."""
    argv = [PYTHON, str(PROBE), 'send', '--to', f'{to}:{port}', '--count', str(count), '--start', str(start)]
    argv += ['--size', str(size), '--rate', str(rate)]
    proc: subprocess.Popen[Any] = host.popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    out, err = proc.communicate(timeout=60.0)
    assert proc.returncode == 0 and out.strip() == f'sent {count}', (proc.returncode, out, err)


def flush(net: Network, sender: Host, receiver: Receiver, marker: int) -> None:
    """Make sure whatever ``sender`` sent before has arrived at ``receiver`` or is gone for good.

    Waits until the switch holds no delayed frame, clears every impairment, then sends
    datagram ``marker`` and waits for it: it follows the same path behind the others.
    """
    net.wait_idle()
    net.clear()
    send(sender, receiver.host.address, 1, start=marker)
    assert receiver.wait_for_seq(marker), f'marker {marker} did not arrive'


def domain_id() -> int:
    """A ROS domain in 1..101 from this process's pid, never the one of its environment (``ROS_DOMAIN_ID``)."""
    domain = 1 + (os.getpid() + 37) % 101
    return domain % 101 + 1 if str(domain) == os.environ.get('ROS_DOMAIN_ID') else domain


def ros_environment(workdir: Path, domain: int, base: Mapping[str, str] = os.environ) -> dict[str, str]:
    """Environment of a node in a test host: its own domain, discovery on the subnet, UDPv4 only.

    ROS logs go to ``workdir`` (not ``~/.ros``).
    """
    env = {k: v for k, v in base.items() if k not in ('ROS_STATIC_PEERS', 'ROS_LOCALHOST_ONLY')}
    env.update(
        ROS_DOMAIN_ID=str(domain),
        ROS_AUTOMATIC_DISCOVERY_RANGE='SUBNET',
        RMW_IMPLEMENTATION='rmw_fastrtps_cpp',
        FASTDDS_BUILTIN_TRANSPORTS='UDPv4',
        ROS_LOG_DIR=str(workdir / 'ros_log'),
        ROS_HOME=str(workdir / 'ros_home'),
        PYTHONPATH=os.pathsep.join(p for p in (str(REPO), base.get('PYTHONPATH', '')) if p),
        PYTHONUNBUFFERED='1',
        RCUTILS_COLORIZED_OUTPUT='0',
    )
    return env
