"""Node ``crank_drive``: the line's crank shafts and the knife's contact and exit events.

The crank shafts: the layup six-bar (joints ``layup_crank``, ``transporter3``,
``transporter4``) and the folding knife (``knife_crank``, ``knife``).

Parameters and topics: see :mod:`folder_line.ros.nodes.machine`.
"""

from __future__ import annotations

import sys

from folder_line.ros.nodes.machine import machine_node

__all__ = ['CrankDrive', 'main']

CrankDrive, main = machine_node('crank_drive', __name__)

if __name__ == '__main__':
    sys.exit(main())
