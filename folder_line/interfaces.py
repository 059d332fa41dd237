"""Names of the line's interfaces that every layer may import (no rclpy here).

The ROS adapters (:mod:`folder_line.ros.nodes`), ``folder-line run``, the analysis and the
launch file take the node names from here.
"""

from __future__ import annotations

__all__ = ['KNOWN_PARTICIPANTS', 'MACHINE_NODES', 'RECORDER']

#: the machine nodes of the line, in start order
MACHINE_NODES: tuple[str, ...] = ('crank_drive', 'belt_conveyor', 'feed_transporter', 'sheet_counter', 'supervisor')
#: the recorder's node name (a lockstep participant when ``folder-line run`` records)
RECORDER = 'line_recorder'
#: every node that can take part in the lockstep
KNOWN_PARTICIPANTS: tuple[str, ...] = (*MACHINE_NODES, RECORDER)
