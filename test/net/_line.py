"""The live line distributed over the test network: ``folder-line run --external-nodes`` on host ``control``
(``line_clock`` and the recorder), each machine node on a host of its own, over UDP through the switch."""

from __future__ import annotations

import collections
import contextlib
import glob
import json
import signal
import subprocess
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from folder_line.config.run_config import RunConfig, node_parameters
from folder_line.interfaces import DIAGNOSTICS_TOPIC, MACHINE_NODES
from folder_line.ros.run import ros_arg

from .netns import Network
from .probes import PYTHON, REPO, domain_id, ros_environment

CONTROL = 'control'
HOSTS = (CONTROL, *MACHINE_NODES)
SIM_RUNS = 'every participant answered the first tick: sim time runs'
POLL = 0.01  # wall s between two looks at the logs


@dataclass
class LineRun:
    """What a distributed run left: exit codes, ``run.json``, the bag, the logs, when things were seen."""

    out: Path
    run_code: int | None = None
    node_codes: dict[str, int | None] = field(default_factory=dict)
    summary: dict[str, Any] = field(default_factory=dict)
    logs: dict[str, str] = field(default_factory=dict)
    sim_started: float | None = None  # wall (monotonic) s when every participant had answered the first tick
    seen: dict[str, float] = field(default_factory=dict)  # log text looked for -> wall s it first appeared

    @property
    def rtf(self) -> float:
        return float(self.summary.get('rtf_achieved') or 0.0)


def node_command(cfg: RunConfig, name: str) -> list[str]:
    """The machine node ``name`` as ``run --external-nodes`` says to start it."""
    cmd = [PYTHON, '-m', f'folder_line.ros.nodes.{name}', '--ros-args']
    for key, value in node_parameters(cfg, name).items():
        cmd += ['-p', ros_arg(key, value)]
    return cmd


def run_line(
    net: Network,
    cfg: RunConfig,
    *,
    during: Callable[[Network, dict[str, subprocess.Popen[bytes]], float], None] | None = None,
    watch: Sequence[str] = (),
    timeout: float = 240.0,
) -> LineRun:
    """Run the line with ``cfg`` (``cfg.out`` on the control host) on ``net``'s hosts.

    ``during(net, node_processes, sim_started)`` is called once sim time runs (in this thread: it
    may cut links, kill nodes and wait); ``watch`` are texts looked for in the run's log, with
    the wall time each first appears (:attr:`LineRun.seen`).
    """
    work = cfg.out.parent
    env = ros_environment(work, domain_id())
    logs = work / 'logs'
    logs.mkdir(parents=True, exist_ok=True)
    result = LineRun(cfg.out)
    run_log = logs / 'run.log'
    argv = [
        PYTHON,
        '-m',
        'folder_line.cli.main',
        'run',
        '--external-nodes',
        '--scene',
        cfg.scene,
        '--duration',
        repr(cfg.duration),
        '--rtf',
        'max' if cfg.rtf == 0.0 else repr(cfg.rtf),
        '--lost-timeout',
        repr(cfg.lost_timeout),
        '--out',
        str(cfg.out),
    ]
    with open(run_log, 'wb') as log:
        run = net[CONTROL].popen(argv, env=env, cwd=REPO, stdout=log, stderr=subprocess.STDOUT)
    nodes: dict[str, subprocess.Popen[bytes]] = {}
    for name in MACHINE_NODES:
        with open(logs / f'{name}.log', 'wb') as log:
            nodes[name] = net[name].popen(
                node_command(cfg, name), env=env, cwd=REPO, stdout=log, stderr=subprocess.STDOUT
            )
    deadline = time.monotonic() + timeout
    called = during is None
    while run.poll() is None and time.monotonic() < deadline:
        text = run_log.read_text(errors='replace')
        now = time.monotonic()
        for what in (SIM_RUNS, *watch):
            if what in text and what not in result.seen:
                result.seen[what] = now
        if not called and SIM_RUNS in result.seen:
            called = True
            assert during is not None
            during(net, nodes, result.seen[SIM_RUNS])
        time.sleep(POLL)
    result.sim_started = result.seen.get(SIM_RUNS)
    if run.poll() is None:
        run.send_signal(signal.SIGINT)
        with contextlib.suppress(subprocess.TimeoutExpired):
            run.wait(timeout=20)
    result.run_code = run.poll()
    for name, proc in nodes.items():  # they end by themselves after the last tick
        with contextlib.suppress(subprocess.TimeoutExpired):
            proc.wait(timeout=20)
        result.node_codes[name] = proc.poll()
    result.logs = {p.stem: p.read_text(errors='replace') for p in logs.glob('*.log')}
    with contextlib.suppress(OSError, ValueError):
        result.summary = json.loads((cfg.out / 'run.json').read_text())
    return result


def bag_messages(out: Path, *, skip: Callable[[str, Any], bool] | None = None) -> collections.Counter[tuple[Any, ...]]:
    """Every message of the run's bag as ``(topic, log ns, publish ns, decoded text)``, counted; read with
    the independent ``mcap`` reader and ``mcap-ros2-support``'s decoder (``skip(topic, message)``: left out)."""
    found: collections.Counter[tuple[Any, ...]] = collections.Counter()
    for path in sorted(glob.glob(str(out / 'bag' / '*.mcap'))):
        with open(path, 'rb') as f:
            for _, channel, message, decoded in make_reader(
                f, decoder_factories=[DecoderFactory()]
            ).iter_decoded_messages():
                if skip is None or not skip(channel.topic, decoded):
                    found[(channel.topic, message.log_time, message.publish_time, repr(decoded))] += 1
    return found


def clock_status(topic: str, message: Any) -> bool:
    """``line_clock``'s own statuses (waiting for a node, taken back, lost): they record the network, not the
    line, so an impaired run has them and a clean one has not."""
    return topic == DIAGNOSTICS_TOPIC and message.header.frame_id == 'line_clock'
