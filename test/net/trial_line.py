"""Trial (not a test): the live line distributed, one host per node, over UDP through the impairing switch.

    .venv/bin/python test/net/trial_line.py [--delay MS] [--jitter MS] [--loss P]
        [--cut HOST:START:SECONDS ...] [--duration 5] [--rtf 0] [--workdir DIR] [--json FILE]
        [--clock-param KEY:=VALUE ...] [--node-param KEY:=VALUE ...]

``line_clock`` and each machine node (``folder_line.interfaces.MACHINE_NODES``) run in a
network namespace of their own (host name = node name), started as ``python -m
folder_line.ros.nodes.<name> --ros-args -p ...`` with ``scene:=folder``, as the launch
file and ``folder-line run --processes`` give them, in a ROS domain of their own,
discovery on the subnet, Fast DDS over UDPv4 only. ``--delay``/``--jitter``/``--loss`` are
set on every host's link (``--on`` chooses), so a message from one node to another
crosses two impaired links: twice the delay on average. ``--cut HOST:START:SECONDS``
partitions HOST's link from START s of wall time after sim time starts (every
participant answered the first tick) for SECONDS s.

Reports the wall time (to sim start, of the line, in all), the rtf (sim seconds per wall
second from the first tick answered, as ``line_clock`` logs it at its end), each
process's exit code and the last lines of its log, and the switch's counters. Needs root
(network namespaces); exits 0 if every node exited 0.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

if not __package__:  # run as a script: the package ``net`` is test/net
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from folder_line.interfaces import MACHINE_NODES
from folder_line.ros.run import ros_arg
from net.netns import Network, available, build_switch
from net.probes import PYTHON, domain_id, ros_environment

CLOCK = 'line_clock'
NODES = (CLOCK, *MACHINE_NODES)
SIM_RUNS = 'every participant answered the first tick: sim time runs'
STOPPED = re.compile(r'stopped at sim time ([0-9.]+) s: .*\((\d+) ticks, rtf ([0-9.]+)\)')
POLL = 0.01  # s between looks at the logs and processes
TAIL = 4  # log lines reported per process


@dataclass(frozen=True)
class Cut:
    """HOST's link down from ``start`` s after sim time starts, for ``seconds`` s."""

    host: str
    start: float
    seconds: float

    @classmethod
    def parse(cls, text: str) -> Cut:
        """``'feed_transporter:1.5:2'`` -> ``Cut('feed_transporter', 1.5, 2.0)``."""
        host, start, seconds = text.rsplit(':', 2)
        if host not in NODES:
            raise argparse.ArgumentTypeError(f'no host {host!r} (hosts: {", ".join(NODES)})')
        return cls(host, float(start), float(seconds))


@dataclass
class Trial:
    """What one trial measured."""

    impairment: str
    parameters: str = ''
    wall_to_sim_start_s: float | None = None
    wall_line_s: float | None = None
    wall_total_s: float = 0.0
    sim_time_s: float | None = None
    ticks: int | None = None
    rtf: float | None = None
    exit_codes: dict[str, int | None] = field(default_factory=dict)
    log_tails: dict[str, list[str]] = field(default_factory=dict)
    switch: dict[str, dict[str, int]] = field(default_factory=dict)
    cuts: list[str] = field(default_factory=list)
    load_average: tuple[float, float] = (0.0, 0.0)  # 1-minute load of the machine at start and end


def node_command(
    name: str, duration: float, rtf: float, rate: float, lost_timeout: float, extra: Sequence[str] = ()
) -> list[str]:
    """The command line of node ``name``; ``extra`` are more ``KEY:=VALUE`` parameters, as given."""
    if name == CLOCK:
        params: dict[str, Any] = {
            'rtf': rtf,
            'duration': duration,
            'rate': rate,
            'participants': ','.join(MACHINE_NODES),
            'lost_timeout': lost_timeout,
        }
    else:
        params = {'scene': 'folder', 'rate': rate, 'lost_timeout': lost_timeout, 'use_sim_time': True}
    cmd = [PYTHON, '-m', f'folder_line.ros.nodes.{name}', '--ros-args']
    for key, value in params.items():
        cmd += ['-p', ros_arg(key, value)]
    for rule in extra:
        cmd += ['-p', rule]
    return cmd


def _read(path: Path) -> str:
    try:
        return path.read_text(errors='replace')
    except OSError:
        return ''


def run_trial(args: argparse.Namespace, workdir: Path) -> Trial:
    """Run the line once under ``args``' impairments; what it measured."""
    links = args.on.split(',') if args.on else list(NODES)
    trial = Trial(
        impairment=f'links of {", ".join(links)}: delay {args.delay:g} +- {args.jitter:g} ms, loss {args.loss:g}'
        + ''.join(f'; cut {c.host} at +{c.start:g} s for {c.seconds:g} s' for c in args.cut),
        parameters=' '.join(
            [f'line_clock: rtf {args.rtf:g}, duration {args.duration:g}, rate {args.rate:g}', *args.clock_param]
            + (['; machine nodes:', *args.node_param] if args.node_param else [])
        ),
    )
    env = ros_environment(workdir, domain_id())
    logs = workdir / 'logs'
    logs.mkdir(parents=True, exist_ok=True)
    load_start = os.getloadavg()[0]
    with Network(list(NODES), workdir / 'net', switch=build_switch(workdir)) as net:
        for host in links:
            net.set(host, delay_ms=args.delay, jitter_ms=args.jitter, loss=args.loss)
        t0 = time.monotonic()
        procs = {}
        for name in (*MACHINE_NODES, CLOCK):  # the clock last, as the launch file lists them
            with open(logs / f'{name}.log', 'wb') as log:
                extra = args.clock_param if name == CLOCK else args.node_param
                cmd = node_command(name, args.duration, args.rtf, args.rate, args.lost_timeout, extra)
                procs[name] = net[name].popen(cmd, env=env, stdout=log, stderr=subprocess.STDOUT)
        t_sim = _follow(net, procs, logs / f'{CLOCK}.log', args, trial, t0)
        t_end = time.monotonic()
        deadline = t_end + args.grace
        for proc in procs.values():  # the machine nodes end after the last tick
            with contextlib.suppress(subprocess.TimeoutExpired):
                proc.wait(timeout=max(deadline - time.monotonic(), 0.01))
        trial.exit_codes = {name: proc.poll() for name, proc in procs.items()}
        trial.switch = {host: asdict(c) for host, c in net.counters().items()}
    trial.wall_total_s = t_end - t0
    trial.load_average = (load_start, os.getloadavg()[0])
    if t_sim is not None:
        trial.wall_to_sim_start_s = t_sim - t0
        trial.wall_line_s = t_end - t_sim
    clock_log = _read(logs / f'{CLOCK}.log')
    if stopped := STOPPED.search(clock_log):
        trial.sim_time_s, trial.ticks, trial.rtf = float(stopped[1]), int(stopped[2]), float(stopped[3])
    trial.log_tails = {n: _read(logs / f'{n}.log').strip().splitlines()[-TAIL:] for n in NODES}
    return trial


def _follow(
    net: Network,
    procs: dict[str, subprocess.Popen[Any]],
    clock_log: Path,
    args: argparse.Namespace,
    trial: Trial,
    t0: float,
) -> float | None:
    """Until ``line_clock`` ends (or the timeout): note when sim time starts, cut and heal links on time."""
    t_sim: float | None = None
    pending = sorted(((c.start, True, c) for c in args.cut), key=lambda e: e[0])
    while procs[CLOCK].poll() is None and time.monotonic() - t0 < args.timeout:
        now = time.monotonic()
        if t_sim is None and SIM_RUNS in _read(clock_log):
            t_sim = now
        while t_sim is not None and pending and now >= t_sim + pending[0][0]:
            at, down, cut = pending.pop(0)
            net.cut(cut.host, down)
            trial.cuts.append(f'{cut.host} {"cut" if down else "healed"} at +{now - t_sim:.3f} s (planned {at:g})')
            if down:
                pending.append((at + cut.seconds, False, cut))
                pending.sort(key=lambda e: e[0])
        time.sleep(POLL)
    return t_sim


def report(trial: Trial) -> str:
    """The trial as text."""

    def s(x: float | None, fmt: str = '.2f') -> str:
        return 'n/a' if x is None else format(x, fmt)

    lines = [
        f'impairment: {trial.impairment}',
        f'parameters: {trial.parameters}',
        f'wall: {s(trial.wall_total_s)} s in all, {s(trial.wall_to_sim_start_s)} s to sim start, '
        f'{s(trial.wall_line_s)} s of line',
        f'line_clock: sim time {s(trial.sim_time_s, ".3f")} s in {trial.ticks} ticks, rtf {s(trial.rtf)}',
        f'machine load (1 min, {os.cpu_count()} cores): {trial.load_average[0]:.2f} at start, '
        f'{trial.load_average[1]:.2f} at end',
        'exit codes: ' + ', '.join(f'{n} {c}' for n, c in trial.exit_codes.items()),
        *trial.cuts,
        'switch (per host link): '
        + '; '.join(
            f'{h} rx {c["rx"]} tx {c["tx"]} lost {c["lost"]} cut {c["cut"]} err {c["err"]}'
            for h, c in trial.switch.items()
        ),
    ]
    for name, tail in trial.log_tails.items():
        lines.append(f'--- {name}')
        lines += [f'    {line}' for line in tail]
    return '\n'.join(lines)


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """The command line (see the module's doc)."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument('--delay', type=float, default=0.0, help='mean delay of each link, ms')
    p.add_argument('--jitter', type=float, default=0.0, help='uniform +- jitter of each link, ms')
    p.add_argument('--loss', type=float, default=0.0, help='loss probability of each link')
    p.add_argument('--on', default='', help='comma-separated hosts whose links are impaired (default: all)')
    p.add_argument('--cut', type=Cut.parse, action='append', default=[], metavar='HOST:START:SECONDS')
    p.add_argument('--duration', type=float, default=5.0, help='sim time, s')
    p.add_argument('--rtf', type=float, default=0.0, help='line_clock rtf ceiling (0: as fast as it goes)')
    p.add_argument('--rate', type=float, default=200.0, help='tick rate, Hz of sim time')
    p.add_argument('--lost-timeout', type=float, default=3.0, help='wall s before a silent node is lost')
    p.add_argument('--clock-param', action='append', default=[], metavar='KEY:=VALUE', help='more for line_clock')
    p.add_argument('--node-param', action='append', default=[], metavar='KEY:=VALUE', help='more for machine nodes')
    p.add_argument('--timeout', type=float, default=180.0, help='wall s the line is given')
    p.add_argument('--grace', type=float, default=15.0, help='wall s the nodes are given to end after line_clock')
    p.add_argument('--workdir', type=Path, help='logs and the switch (default: a new temporary directory)')
    p.add_argument('--json', type=Path, help='also write the results here')
    return p.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    """Run one trial; 0 if every node exited 0, 1 if not, 2 if namespaces cannot be made here."""
    args = parse_args(argv)
    reason = available()
    if reason is not None:
        print(f'trial_line: {reason}', file=sys.stderr)
        return 2
    workdir = args.workdir or Path(tempfile.mkdtemp(prefix='trial_line-'))
    trial = run_trial(args, workdir)
    print(report(trial))
    print(f'(logs in {workdir / "logs"})')
    if args.json:
        args.json.write_text(json.dumps(asdict(trial), indent=2))
    return 0 if trial.exit_codes and all(c == 0 for c in trial.exit_codes.values()) else 1


if __name__ == '__main__':
    sys.exit(main())
