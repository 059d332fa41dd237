"""Hosts in network namespaces, joined by a user-space switch that impairs their links (for tests).

::

    with Network(['a', 'b'], workdir) as net:
        net.set('a', delay_ms=5.0, jitter_ms=2.0, loss=0.01)
        server = net['b'].popen([sys.executable, 'server.py'])
        net.cut('a')  # partition a; net.cut('a', False) heals it
        print(net.counters()['a'].rx)

Each host is a network namespace of its own with ``lo`` up and one link, ``eth0``
(address ``SUBNET.<i+1>/24``, hosts in the order given), the end of a veth pair whose
other end is port ``sw<i>`` of the switch (``switch.c``, built here with gcc), which runs
in a namespace of its own. Hosts have no default route: only their /24 and a multicast
route (``224.0.0.0/4 dev eth0``, for DDS discovery), so every packet stays inside the
namespaces made here. ``eth0`` sends no segmentation-offloaded frames (``gso_max_segs
1``: the switch cannot forward frames larger than the MTU) and has no IPv6 address.

Impairments (:meth:`Network.set`, :meth:`Network.cut`) belong to a host's link and apply
to the frames it sends and to those sent to it: see ``switch.c``. Namespaces are named
``<PREFIX><pid>n<k>-<host>`` (``--switch`` for the switch): parallel runs never collide,
and :func:`cleanup_leftovers` removes those of processes that are gone. Needs root
(:func:`available` says why not). Nothing outside the namespaces and the work directory
is touched (``ip netns`` keeps its names in ``/run/netns``).
"""

from __future__ import annotations

import contextlib
import ctypes
import hashlib
import itertools
import os
import re
import select
import shutil
import signal
import subprocess
import threading
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from functools import cache
from pathlib import Path
from types import TracebackType
from typing import IO, Any

__all__ = [
    'PREFIX',
    'SUBNET',
    'Host',
    'Network',
    'NetworkError',
    'PortCounters',
    'available',
    'build_switch',
    'cleanup_leftovers',
]

SOURCE = Path(__file__).with_name('switch.c')
CFLAGS = ('-std=c11', '-O2', '-Wall', '-Wextra')
PREFIX = 'flnet'
SUBNET = '10.231.0'  # hosts are SUBNET.1, SUBNET.2, ... /24, in their own namespaces only
MULTICAST = '224.0.0.0/4'
STOP_WAIT = 3.0  # s a process is given between SIGTERM and SIGKILL
REPLY_WAIT = 10.0  # s the switch is given to answer a command
_IP = shutil.which('ip') or '/usr/sbin/ip'
_HOST_NAME = re.compile(r'[A-Za-z0-9][A-Za-z0-9_]{0,31}\Z')
_OURS = re.compile(rf'{PREFIX}(\d+)n\d+-')
_serial = itertools.count()
_PR_SET_PDEATHSIG = 1


class NetworkError(RuntimeError):
    """A namespace, link or the switch could not be made, or the switch refused a command."""


@dataclass(frozen=True)
class PortCounters:
    """Frames counted by the switch at one host's port (see ``switch.c``); ``b - a`` is the change."""

    rx: int = 0  # frames received from the host
    tx: int = 0  # frames delivered to the host
    lost: int = 0  # dropped by this port's loss, either direction
    cut: int = 0  # dropped by this port's cut, either direction
    err: int = 0  # could not be sent or queued
    kdrop: int = 0  # dropped by the kernel before the switch read them
    csum: int = 0  # partial checksums completed
    queued: int = 0  # waiting for their delay now

    def __sub__(self, other: PortCounters) -> PortCounters:
        return PortCounters(**{f.name: getattr(self, f.name) - getattr(other, f.name) for f in fields(self)})


def _ip(*args: str, netns: str | None = None, stdin: str | None = None, check: bool = True) -> str:
    """Run ``ip [-n netns] args``; its stdout, NetworkError with its stderr if it fails and ``check``."""
    cmd = [_IP, *(('-n', netns) if netns else ()), *args]
    done = subprocess.run(cmd, input=stdin, capture_output=True, text=True, timeout=30)
    if check and done.returncode != 0:
        raise NetworkError(f'{" ".join(cmd)}: {done.stderr.strip() or f"exit {done.returncode}"}')
    return done.stdout


def _die_with_parent() -> None:  # pragma: no cover - runs in the child between fork and exec
    ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)


@cache
def available() -> str | None:
    """Why namespaces joined by the switch cannot be made here (None if they can), for ``pytest.skip``."""
    if os.geteuid() != 0:
        return 'network namespaces need root'
    if not os.access(_IP, os.X_OK):
        return 'no ip (iproute2)'
    if shutil.which('gcc') is None:
        return 'no gcc to build the switch'
    name = f'{PREFIX}{os.getpid()}n{next(_serial)}-probe'
    try:
        _ip('netns', 'add', name)
    except (NetworkError, OSError, subprocess.SubprocessError) as e:
        return f'cannot make a network namespace: {e}'
    try:
        _ip('link', 'add', 'eth0', 'type', 'veth', 'peer', 'name', 'eth1', netns=name)
    except NetworkError as e:
        return f'cannot make a veth pair: {e}'
    finally:
        _ip('netns', 'del', name, check=False)
    return None


def build_switch(directory: Path) -> Path:
    """The switch built from ``switch.c`` into ``directory`` (reused while the source is unchanged)."""
    source = SOURCE.read_bytes()
    digest = hashlib.sha256(source + ' '.join(CFLAGS).encode()).hexdigest()[:12]
    binary = directory / f'switch-{digest}'
    if binary.exists():
        return binary
    directory.mkdir(parents=True, exist_ok=True)
    partial = directory / f'.switch-{digest}.{os.getpid()}'
    done = subprocess.run(['gcc', *CFLAGS, '-o', str(partial), str(SOURCE)], capture_output=True, text=True)
    if done.returncode != 0:
        raise NetworkError(f'gcc could not build the switch:\n{done.stderr}')
    os.replace(partial, binary)  # atomic: a parallel build of the same source is the same binary
    return binary


def _netns_names() -> list[str]:
    return [line.split()[0] for line in _ip('netns', 'list').splitlines() if line.strip()]


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _remove_netns(name: str) -> None:
    """Kill what still runs in namespace ``name`` (every process there is one of ours) and delete it."""
    for pid in _ip('netns', 'pids', name, check=False).split():
        with contextlib.suppress(ProcessLookupError, ValueError):
            os.kill(int(pid), signal.SIGKILL)
    _ip('netns', 'del', name)


def cleanup_leftovers() -> list[str]:
    """Delete the namespaces (and so their links) left by processes that are gone; their names."""
    removed = []
    for name in _netns_names():
        match = _OURS.match(name)
        if match and int(match[1]) != os.getpid() and not _alive(int(match[1])):
            _remove_netns(name)
            removed.append(name)
    return removed


@dataclass(frozen=True)
class Host:
    """One host: a network namespace with ``eth0`` at ``address`` on port ``port`` of the switch."""

    name: str
    netns: str
    address: str
    port: str
    network: Network

    def popen(
        self, argv: Sequence[str], *, env: Mapping[str, str] | None = None, **kwargs: Any
    ) -> subprocess.Popen[Any]:
        """Start ``argv`` in this host (``ip netns exec``), in a process group of its own.

        It is stopped with its group when the network closes, and killed if the thread that
        started it ends first (``PR_SET_PDEATHSIG``). ``kwargs`` go to :class:`subprocess.Popen`.
        """
        return self.network.popen_in(self, argv, env, kwargs)

    def run(self, argv: Sequence[str], *, timeout: float = 30.0, **kwargs: Any) -> subprocess.CompletedProcess[str]:
        """Run ``argv`` in this host to its end; its output as text."""
        cmd = [_IP, 'netns', 'exec', self.netns, *argv]
        return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, **kwargs)


class Network:
    """Hosts in namespaces of their own, linked through the impairing switch; a context manager.

    Parameters
    ----------
    hosts : sequence of str
        Host names (letters, digits, ``_``), addresses ``SUBNET.1``, ``SUBNET.2``, ... in this order.
    workdir : Path
        Where the switch is built (unless ``switch`` is given) and logs (``switch.log``).
    switch : Path, optional
        A switch already built with :func:`build_switch`.
    seed : int
        Seed of the switch's random draws (loss, jitter).
    """

    def __init__(self, hosts: Sequence[str], workdir: Path, *, switch: Path | None = None, seed: int = 1) -> None:
        if not hosts or len(set(hosts)) != len(hosts) or len(hosts) > 64:
            raise ValueError(f'hosts must be 1 to 64 distinct names: {list(hosts)}')
        bad = [h for h in hosts if not _HOST_NAME.match(h)]
        if bad:
            raise ValueError(f'host names are letters, digits and _: {bad}')
        self.workdir = workdir
        self.seed = seed
        self._switch_binary = switch
        base = f'{PREFIX}{os.getpid()}n{next(_serial)}'
        self.switch_netns = f'{base}--switch'
        self.hosts: dict[str, Host] = {
            name: Host(name, f'{base}-{name}', f'{SUBNET}.{i + 1}', f'sw{i}', self) for i, name in enumerate(hosts)
        }
        self._made: list[str] = []  # namespaces made, deleted in reverse
        self._procs: list[subprocess.Popen[Any]] = []
        self._switch: subprocess.Popen[bytes] | None = None
        self._replies = b''
        self._lock = threading.Lock()

    # ------------------------------------------------------------------ life

    def __enter__(self) -> Network:
        self.start()
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None, tb: TracebackType | None) -> None:
        self.close()

    def __getitem__(self, name: str) -> Host:
        return self.hosts[name]

    @property
    def namespaces(self) -> list[str]:
        """Every namespace of this network: the switch's, then the hosts'."""
        return [self.switch_netns, *(h.netns for h in self.hosts.values())]

    def start(self) -> None:
        """Make the namespaces and links and start the switch; on failure undo what was made."""
        try:
            cleanup_leftovers()
            self.workdir.mkdir(parents=True, exist_ok=True)
            binary = self._switch_binary or build_switch(self.workdir)
            self._add_netns(self.switch_netns)
            for host in self.hosts.values():
                self._add_host(host)
            self._start_switch(binary)
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        """Stop every process started here and the switch, delete the namespaces (and their links).

        Every step is tried; the first error is raised at the end.
        """
        errors: list[BaseException] = []
        for step in (self._stop_processes, self._stop_switch):
            try:
                step()
            except Exception as e:
                errors.append(e)
        while self._made:
            name = self._made.pop()
            try:
                _remove_netns(name)
            except Exception as e:
                errors.append(e)
        if errors:
            raise errors[0]

    def _add_netns(self, name: str) -> None:
        _ip('netns', 'add', name)
        self._made.append(name)

    def _add_host(self, host: Host) -> None:
        self._add_netns(host.netns)
        commands = [
            f'link add eth0 type veth peer name {host.port} netns {self.switch_netns}',
            'link set eth0 addrgenmode none gso_max_segs 1',
            f'addr add {host.address}/24 dev eth0',
            'link set lo up',
            'link set eth0 up',
            f'route add {MULTICAST} dev eth0',
        ]
        _ip('-batch', '-', netns=host.netns, stdin='\n'.join(commands) + '\n')
        _ip('-batch', '-', netns=self.switch_netns, stdin=f'link set {host.port} addrgenmode none up\n')

    def _start_switch(self, binary: Path) -> None:
        ports = [h.port for h in self.hosts.values()]
        with open(self.workdir / 'switch.log', 'ab') as log:
            self._switch = subprocess.Popen(
                [_IP, 'netns', 'exec', self.switch_netns, str(binary), '-s', str(self.seed), *ports],
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                stderr=log,
                bufsize=0,
                start_new_session=True,
                preexec_fn=_die_with_parent,
            )
        try:
            line = self._readline()
        except NetworkError as e:
            raise NetworkError(f'the switch did not start: {e}') from e
        if line != 'ready':
            raise NetworkError(f'the switch did not start ({line!r}): {self._log_tail()}')

    def _stop_processes(self) -> None:
        running = [p for p in self._procs if p.poll() is None]
        for p in running:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(p.pid, signal.SIGTERM)
        deadline = time.monotonic() + STOP_WAIT
        for p in running:
            with contextlib.suppress(subprocess.TimeoutExpired):
                p.wait(timeout=max(deadline - time.monotonic(), 0.01))
            if p.poll() is None:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(p.pid, signal.SIGKILL)
                p.wait(timeout=STOP_WAIT)
        self._procs.clear()
        for host in self.hosts.values():  # what left its process group but not our namespaces
            if host.netns in self._made:
                for pid in _ip('netns', 'pids', host.netns, check=False).split():
                    with contextlib.suppress(ProcessLookupError):
                        os.kill(int(pid), signal.SIGKILL)

    def _stop_switch(self) -> None:
        switch, self._switch = self._switch, None
        if switch is None:
            return
        if switch.stdin is not None:
            with contextlib.suppress(OSError):
                switch.stdin.close()  # end of its input: it exits
        try:
            switch.wait(timeout=STOP_WAIT)
        except subprocess.TimeoutExpired:
            switch.kill()
            switch.wait(timeout=STOP_WAIT)
        if switch.stdout is not None:
            switch.stdout.close()

    # ------------------------------------------------------------------ processes

    def popen_in(
        self, host: Host, argv: Sequence[str], env: Mapping[str, str] | None, kwargs: dict[str, Any]
    ) -> subprocess.Popen[Any]:
        if self._switch is None:
            raise NetworkError('the network is not running')
        kwargs.setdefault('start_new_session', True)
        kwargs.setdefault('preexec_fn', _die_with_parent)
        proc = subprocess.Popen([_IP, 'netns', 'exec', host.netns, *argv], env=env, **kwargs)
        self._procs.append(proc)
        return proc

    # ------------------------------------------------------------------ the switch

    def set(
        self,
        host: str,
        *,
        delay_ms: float | None = None,
        jitter_ms: float | None = None,
        loss: float | None = None,
        fifo: bool | None = None,
    ) -> None:
        """Change the impairments of ``host``'s link (those not given stay); frames from now on meet them.

        ``delay_ms`` (mean) and ``jitter_ms`` (uniform +-, may reorder frames unless ``fifo``)
        are drawn per frame per link; ``loss`` is the probability a frame is dropped at this link.
        """
        given = {'delay': delay_ms, 'jitter': jitter_ms, 'loss': loss, 'fifo': None if fifo is None else int(fifo)}
        options = ' '.join(f'{k}={v!r}' for k, v in given.items() if v is not None)
        self._command(f'set {self.hosts[host].port} {options}')

    def clear(self, host: str | None = None) -> None:
        """No impairment on ``host``'s link (every host's if None), and not cut."""
        for name in [host] if host else list(self.hosts):
            self.set(name, delay_ms=0.0, jitter_ms=0.0, loss=0.0, fifo=False)
            self.cut(name, False)

    def cut(self, host: str, cut: bool = True) -> None:
        """Take ``host``'s link down (every frame from or to it dropped) or, with ``cut=False``, up again."""
        self._command(f'cut {self.hosts[host].port} {int(cut)}')

    def counters(self) -> dict[str, PortCounters]:
        """The switch's counters of every host's port, by host name."""
        by_port = {h.port: h.name for h in self.hosts.values()}
        out = {}
        for line in self._command('stats'):
            port, *pairs = line.split()
            values = {k: int(v) for k, v in (p.split('=', 1) for p in pairs)}
            out[by_port[port]] = PortCounters(**values)
        return out

    def wait_idle(self, timeout: float = 10.0) -> dict[str, PortCounters]:
        """Wait until no frame is held for its delay; the counters then (NetworkError after ``timeout`` s)."""
        deadline = time.monotonic() + timeout
        while True:
            counters = self.counters()
            if not any(c.queued for c in counters.values()):
                return counters
            if time.monotonic() > deadline:
                raise NetworkError(f'frames still queued after {timeout:g} s: {counters}')
            time.sleep(0.005)

    def _command(self, line: str) -> list[str]:
        """Send one command to the switch; its data lines (NetworkError if it answers an error)."""
        with self._lock:
            if self._switch is None or self._switch.stdin is None:
                raise NetworkError('the network is not running')
            try:
                self._switch.stdin.write(line.encode() + b'\n')
            except OSError as e:
                raise NetworkError(f'the switch is gone ({e}): {self._log_tail()}') from e
            data = []
            while (reply := self._readline()) != 'ok':
                if reply.startswith('error:'):
                    raise NetworkError(f'switch: {line!r}: {reply}')
                data.append(reply)
            return data

    def _readline(self) -> str:
        """One line from the switch (NetworkError if it ends or says nothing for REPLY_WAIT s)."""
        assert self._switch is not None and self._switch.stdout is not None
        out: IO[bytes] = self._switch.stdout
        deadline = time.monotonic() + REPLY_WAIT
        while b'\n' not in self._replies:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([out], [], [], left)[0]:
                raise NetworkError(f'the switch did not answer in {REPLY_WAIT:g} s')
            chunk = os.read(out.fileno(), 65536)
            if not chunk:
                raise NetworkError(f'the switch ended: {self._log_tail()}')
            self._replies += chunk
        line, self._replies = self._replies.split(b'\n', 1)
        return line.decode()

    def _log_tail(self) -> str:
        try:
            return (self.workdir / 'switch.log').read_text(errors='replace')[-2000:].strip()
        except OSError:
            return '(no log)'
