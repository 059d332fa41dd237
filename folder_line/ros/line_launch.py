"""What launch/line.launch.py starts, in Python the tests can import: its arguments and each node's parameters.

``ros2 launch folder_line line.launch.py`` declares :data:`ARGUMENTS` and, before it starts
any node, reads every node's parameters from them with :func:`line_parameters`: each value
is read and checked by the node's own :class:`~folder_line.ros.parameters.ParamSpec` (type,
range, choices) and the scene loaded with its overrides, so a bad argument (``rtf:=fast``,
``lost_timeout:=0.01``, ``scene:=nowhere``) fails the launch with one line naming it and no
node running. What only a node can judge (the clock's checks across its parameters) the
node refuses at start, with exit code 2, which fails the launch (see the launch file).

:class:`LineEnd` decides, from the nodes' exits, how the launch ends: when ``line_clock`` ends
the line every node ends by itself after the last tick, so the launch waits for them (no signal
to a node that is exiting: see :data:`END_GRACE`); a node that fails fails the launch.
"""

from __future__ import annotations

import enum
import signal
from collections.abc import Iterable, Mapping, Sequence

from folder_line.interfaces import LINE_CLOCK, MACHINE_NODES
from folder_line.ros.line_key import KEY_VARIABLE, new_key, read_key
from folder_line.ros.nodes import line_clock, machine
from folder_line.ros.nodes.line_clock import SPECS as CLOCK_SPECS
from folder_line.ros.nodes.machine import MACHINE_SPECS, node_scene
from folder_line.ros.nodes.sheet_counter import SheetCounter
from folder_line.ros.parameters import ParamSpec, ParamValue
from folder_line.ros.runtime import EXIT_BAD_PARAMETER, LINGER, TEARDOWN_TIMEOUT

__all__ = [
    'ARGUMENTS',
    'END_GRACE',
    'STATUS_LOST',
    'LineEnd',
    'Step',
    'failure_text',
    'line_key_environment',
    'line_parameters',
]

ARGUMENTS: tuple[tuple[str, str, str], ...] = (
    ('scene', 'folder', 'scene name (config/scenes) or path of a scene YAML file'),
    ('overrides', '', 'scene overrides "MACHINE.KEY=VALUE" separated by ";"'),
    ('rate', '200.0', 'tick rate of line_clock and joint-state rate of the machine nodes, Hz of sim time'),
    ('rtf', '1.0', 'real-time factor ceiling of line_clock (0.0: as fast as the line allows)'),
    ('duration', '0.0', 'sim time to run for, s (0: until Ctrl-C)'),
    ('start_time', '0.0', 'sim time of the first tick, s (the nodes fast-forward there)'),
    ('clock', 'lockstep', 'lockstep (sim time waits for every node) or wall (hardware in the loop)'),
    ('lost_timeout', '3.0', 'wall time a tick waits for a node before it is declared lost, s'),
    ('marker_rate', '5.0', 'sheet_counter: /line/markers per second of sim time, frame line (0: none)'),
)
"""The launch arguments: (name, default, description); each is a parameter of one node or more."""

END_GRACE = LINGER + TEARDOWN_TIMEOUT + 4.0
"""Wall time, s, the launch waits after ``line_clock`` ended the line for the other nodes to end by
themselves (each lingers :data:`~folder_line.ros.runtime.LINGER` s after its last tick, and its
teardown takes at most :data:`~folder_line.ros.runtime.TEARDOWN_TIMEOUT` s, or
:data:`~folder_line.ros.runtime.HUNG_TEARDOWN_EXIT` s more when the middleware hangs), before it
stops those still running. Signalling a node that is exiting anyway is what this avoids: launch's
SIGINT to a process that has just exited can lose its exit status (launch's ``Popen.send_signal``
reaps it first; launch's process watcher then reports 255)."""

STATUS_LOST = 255
"""The exit code launch reports for a process whose exit status its process watcher could not read
(``Unknown child process pid ..., will report returncode 255``); no node of the line exits with it."""


class Step(enum.Enum):
    """What the launch does after a node exited (:meth:`LineEnd.exited`)."""

    GO_ON = 'go on'
    """Nothing: the line runs on, or its clock ended it and other nodes are still ending."""
    FAIL = 'fail'
    """The node failed: the launch fails, and stops the others."""
    WAIT_FOR_THE_REST = 'wait for the rest'
    """The clock ended the line: the others end by themselves; those still running after
    :data:`END_GRACE` s are stopped."""
    ENDED = 'ended'
    """The clock ended the line and every node has ended: nothing is left to stop."""


class LineEnd:
    """The nodes of a launched line still running, and what each exit means for the launch.

    Parameters
    ----------
    nodes : iterable of str
        The nodes the launch starts, ``line_clock`` among them.
    """

    def __init__(self, nodes: Iterable[str]) -> None:
        self.running = set(nodes)
        self.clock_ended = False

    def exited(self, name: str, returncode: int) -> Step:
        """Node ``name`` exited with ``returncode`` (launch's: negative for a signal, :data:`STATUS_LOST`).

        A non-zero code fails the launch, but for :data:`STATUS_LOST`, a status launch lost (not
        known to be a failure; the launch file says so): that node counts as ended.
        """
        self.running.discard(name)
        if returncode not in (0, STATUS_LOST):
            return Step.FAIL
        if name == LINE_CLOCK:
            self.clock_ended = True
            return Step.ENDED if not self.running else Step.WAIT_FOR_THE_REST
        if self.clock_ended and not self.running:
            return Step.ENDED
        return Step.GO_ON


def line_parameters(given: Mapping[str, str]) -> dict[str, dict[str, ParamValue]]:
    """Each node's parameters from the launch arguments, read and checked as the nodes would.

    The machine nodes get ``scene``, ``overrides``, ``rate``, ``lost_timeout`` and
    ``use_sim_time`` on (``sheet_counter`` also ``marker_rate``); ``line_clock`` gets
    ``rtf``, ``duration``, ``start_time``, ``rate``, ``clock``, ``lost_timeout`` and the
    machine nodes as its ``participants``.

    Parameters
    ----------
    given : mapping of str to str
        Launch arguments by name, as typed (``{'rtf': '2'}``); missing ones take their default.

    Returns
    -------
    dict
        Node name -> parameter name -> value of the parameter's type (``rtf:=2`` is 2.0).

    Raises
    ------
    ParameterError
        An argument does not read as its parameter's type or is not an allowed value; the
        message names the argument and the value as typed.
    FolderLineError
        The scene does not load with its overrides (the message names them).
    """
    arguments = {name: default for name, default, _ in ARGUMENTS}
    arguments.update(given)
    machine = _read(MACHINE_SPECS, arguments)
    node_scene(str(machine['scene']), str(machine['overrides']))  # every machine node loads it at start
    out: dict[str, dict[str, ParamValue]] = {name: {**machine, 'use_sim_time': True} for name in MACHINE_NODES}
    out['sheet_counter'].update(_read(SheetCounter.EXTRA_SPECS, arguments))
    out[LINE_CLOCK] = {**_read(CLOCK_SPECS, arguments), 'participants': ','.join(MACHINE_NODES)}
    return out


def line_key_environment(environ: Mapping[str, str]) -> tuple[dict[str, str], str | None]:
    """The line's key for every node of the launch: the user's (:data:`~folder_line.ros.line_key.KEY_VARIABLE`
    in ``environ``) or a new one.

    Returns
    -------
    env : dict of str to str
        ``{KEY_VARIABLE: key}``, for each node's environment.
    told : str or None
        For a new key, the line to log: the operators and the nodes of other hosts need it.

    Raises
    ------
    ParameterError
        ``environ`` holds a key that is not one.
    """
    if read_key(environ) is not None:
        return {KEY_VARIABLE: environ[KEY_VARIABLE].strip()}, None
    key = new_key()
    told = (
        f"line key (the operators' folder-line hold/tune/monitor and other hosts' nodes need it): {KEY_VARIABLE}={key}"
    )
    return {KEY_VARIABLE: key}, told


def failure_text(name: str, returncode: int) -> str:
    """The launch's error line when node ``name`` exits with a non-zero ``returncode``.

    Parameters
    ----------
    name : str
        The node.
    returncode : int
        Its exit code, negative for the signal that killed it (as launch reports it).

    Returns
    -------
    str
        E.g. ``'line_clock exited with code 3 (a participant was lost): the line did not end as it should'``.
    """
    if returncode < 0:
        try:
            what = f'was killed by {signal.Signals(-returncode).name}'
        except ValueError:
            what = f'was killed by signal {-returncode}'
    else:
        what = f'exited with code {returncode}'
        if returncode == EXIT_BAD_PARAMETER:
            what += ' (it refused its parameters)'
        elif name == LINE_CLOCK and returncode == line_clock.EXIT_LOST:
            what += ' (a participant was lost)'
        elif name != LINE_CLOCK and returncode == machine.EXIT_LOST:
            what += ' (it lost a producer, or its clock before the end)'
    return f'{name} {what}: the line did not end as it should'


def _read(specs: Sequence[ParamSpec], arguments: Mapping[str, str]) -> dict[str, ParamValue]:
    return {spec.name: spec.from_text(arguments[spec.name]) for spec in specs if spec.name in arguments}
