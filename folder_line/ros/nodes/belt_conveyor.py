"""Node ``belt_conveyor``: the belts that bring sheets in.

The layup chute belts (``chute_belts``) and the folder's first transporter
(``first_transporter``), with the leaves' chute events and the stream's faults.

Parameters and topics: see :mod:`folder_line.ros.nodes.machine`.
"""

from __future__ import annotations

import sys

from folder_line.ros.nodes.machine import machine_node

__all__ = ['BeltConveyor', 'main']

BeltConveyor, main = machine_node('belt_conveyor', __name__)

if __name__ == '__main__':
    sys.exit(main())
