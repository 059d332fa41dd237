"""What ``folder-line run`` runs, and the parameters it gives each node: pure, no ROS.

:mod:`folder_line.ros.run` starts the line from a :class:`RunConfig`; the analysis of a
run directory (:mod:`folder_line.analysis`) and the accuracy studies read the same rules
from here, without importing the ROS layer.

A run directory ``<out>/`` holds :data:`SCENE_FILE` (the merged scene, written once by
the run and loaded by every node), :data:`BAG_DIR` (the bag), ``run.json`` and, with
``--processes``, ``logs/``.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Any

from folder_line.core.limits import Limit
from folder_line.core.line.scene import Scene
from folder_line.core.supervision.supervisor import Supervisor

__all__ = [
    'BAG_DIR',
    'MARKER_RATE',
    'MARKER_RATES',
    'RATE',
    'SCENE_FILE',
    'SUPERVISOR_DEFAULTS',
    'RunConfig',
    'bag_of',
    'clock_parameters',
    'node_parameters',
    'supervisor_logic',
]

#: the run's bag, under ``cfg.out``
BAG_DIR = 'bag'
#: the merged scene the run's nodes load, under ``cfg.out``
SCENE_FILE = 'scene.yaml'

#: tick rate of ``line_clock`` and joint-state rate of the machine nodes, Hz of sim time: the nodes'
#: default and ``run``'s
RATE = 200.0
#: rate of ``/line/markers`` (``sheet_counter``'s ``marker_rate``), Hz of sim time: 5 frames per second of
#: line time (10 per crank turn of the layup) adds about 80 MB per hour of ``line`` to its bag (docs/nodes.md)
MARKER_RATE = 5.0
#: the range of ``marker_rate`` (``run --marker-rate``, ``simulate --marker-rate``, the node's parameter)
MARKER_RATES = Limit('marker rate', 0.0, 1000.0, 'Hz', 'marker arrays per second of line time; 0: none')

#: the ``supervisor`` node's parameters as ``folder-line run`` starts it: the node declares these defaults
#: (with ``rate`` = :data:`RATE`), and the analysis replays a bag that does not record them with them
SUPERVISOR_DEFAULTS: Mapping[str, Any] = MappingProxyType(
    {'rate': RATE, 'command_lead': 0.1, 'enforce': True, 'double_sheet': 'hold'}
)


def bag_of(path: str | os.PathLike[str]) -> Path:
    """The bag of ``path``: its :data:`BAG_DIR` when ``path`` is a run folder that holds one, else ``path``."""
    p = Path(path)
    return p / BAG_DIR if (p / BAG_DIR).is_dir() else p


def supervisor_logic(scene: Scene, settings: Mapping[str, Any]) -> Supervisor:
    """The supervisor's logic as the supervisor node builds it at start-up: ``settings`` has the node's
    parameters of :data:`SUPERVISOR_DEFAULTS` (``rate``, ``command_lead``, ``enforce``, ``double_sheet``).
    ``simulate --bag`` builds it the same way, so its bag is the live one."""
    return Supervisor(
        scene,
        periods={},
        lead=settings['command_lead'],
        check_period=1.0 / settings['rate'],
        enforce=settings['enforce'],
        double=settings['double_sheet'],
        state='STARTING',
        t_start=None,
    )


@dataclass(frozen=True)
class RunConfig:
    """What to run.

    Attributes
    ----------
    scene : str
        Scene name or file.
    duration : float
        Line time, s.
    overrides : tuple of str
        ``MACHINE.KEY=VALUE`` items.
    rtf : float
        Real-time factor ceiling of ``line_clock``; 0 = as fast as the line allows (lockstep).
    rate : float
        Publishing rate of the machine nodes, Hz of sim time.
    out : Path
        Output directory.
    processes : bool
        One process per node instead of one executor.
    external : bool
        The machine nodes run elsewhere (their own hosts, started by hand or by their own launch):
        only ``line_clock`` and the recorder run here, and wait for them.
    clock : {'lockstep', 'wall'}
        Lockstep sim time (default) or wall-clock pacing (hardware in the loop).
    lost_timeout : float
        Wall seconds a tick may wait for a participant before it is declared lost.
    marker_rate : float
        Rate of ``/line/markers``, Hz of sim time (0 = off).
    max_bag_duration : float
        Line time per ``.mcap`` file of the bag, s (0 = one file).
    max_bag_size : int
        Bytes at which a ``.mcap`` file is finished, at its next flush (0 = no split by size).
    """

    scene: str = 'folder'
    duration: float = 20.0
    overrides: tuple[str, ...] = ()
    rtf: float = 1.0
    rate: float = RATE
    out: Path = Path('out')
    processes: bool = False
    external: bool = False
    clock: str = 'lockstep'
    lost_timeout: float = 3.0
    marker_rate: float = MARKER_RATE
    max_bag_duration: float = 0.0
    max_bag_size: int = 0


def node_parameters(
    cfg: RunConfig, name: str, scene_file: str | os.PathLike[str] | None = None
) -> dict[str, str | float]:
    """The parameters ``run`` gives machine node ``name`` (every machine node gets the same).

    Parameters
    ----------
    cfg : RunConfig
        The run.
    name : str
        The node (one of :data:`folder_line.interfaces.MACHINE_NODES`).
    scene_file : path-like, optional
        The merged scene the run wrote (:data:`SCENE_FILE`): the node loads it as it is. Without
        it the node gets ``cfg.scene`` and the overrides joined by ``;``, as from a launch file.

    Returns
    -------
    dict
        ``scene`` (and ``overrides``), ``rate``, ``lost_timeout``; ``sheet_counter`` also
        ``marker_rate``.
    """
    params: dict[str, str | float] = {'scene': str(cfg.scene if scene_file is None else scene_file)}
    if scene_file is None and cfg.overrides:  # rcl cannot parse an empty '-p overrides:=' rule
        params['overrides'] = ';'.join(cfg.overrides)
    params.update({'rate': cfg.rate, 'lost_timeout': cfg.lost_timeout})
    if name == 'sheet_counter':  # the node that draws the line
        params['marker_rate'] = float(cfg.marker_rate)
    return params


def clock_parameters(cfg: RunConfig, participants: tuple[str, ...]) -> dict[str, str | float]:
    """The parameters ``run`` gives ``line_clock`` (its tick rate is the nodes' ``cfg.rate``)."""
    return {
        'rate': cfg.rate,
        'rtf': float(cfg.rtf),
        'clock': cfg.clock,
        'duration': float(cfg.duration),
        'participants': ','.join(participants),
        'lost_timeout': cfg.lost_timeout,
    }
