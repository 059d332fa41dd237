"""Node ``belt_conveyor``: the belts that bring sheets in.

The layup chute belts (``chute_belts``) and the folder's first transporter
(``first_transporter``), with the leaves' chute events and the stream's faults.

Parameters and topics: see :mod:`folder_line.ros.nodes.machine`.
"""

from __future__ import annotations

import sys

from folder_line.ros.nodes.machine import MachineNode
from folder_line.ros.runtime import run_node

__all__ = ['BeltConveyor', 'main']


class BeltConveyor(MachineNode):
    """The ``belt_conveyor`` node."""

    NODE_NAME = 'belt_conveyor'


def main(args: list[str] | None = None) -> int:
    """Run ``belt_conveyor`` until Ctrl-C; exit code 0 (2 on a bad parameter)."""
    return run_node(BeltConveyor, args)


if __name__ == '__main__':
    sys.exit(main())
