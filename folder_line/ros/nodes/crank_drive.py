"""Node ``crank_drive``: the line's crank shafts and the knife's contact and exit events.

The crank shafts: the layup six-bar (joints ``layup_crank``, ``transporter3``,
``transporter4``) and the folding knife (``knife_crank``, ``knife``).

Parameters and topics: see :mod:`folder_line.ros.nodes.machine`.
"""

from __future__ import annotations

import sys

from folder_line.ros.nodes.machine import MachineNode
from folder_line.ros.runtime import run_node

__all__ = ['CrankDrive', 'main']


class CrankDrive(MachineNode):
    """The ``crank_drive`` node."""

    NODE_NAME = 'crank_drive'


def main(args: list[str] | None = None) -> int:
    """Run ``crank_drive`` until Ctrl-C; exit code 0 (2 on a bad parameter)."""
    return run_node(CrankDrive, args)


if __name__ == '__main__':
    sys.exit(main())
