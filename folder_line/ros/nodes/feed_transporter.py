"""Node ``feed_transporter``: the folder's 2nd transporter and the delivery chain.

The transporter (``feed_belt``) and the chain (``chain``, ``carriage``; the sprocket
torque as the chain's effort with ``chain_friction``), with the signatures' hand-over,
front-stop and settle events.

Parameters and topics: see :mod:`folder_line.ros.nodes.machine`.
"""

from __future__ import annotations

import sys

from folder_line.ros.nodes.machine import machine_node

__all__ = ['FeedTransporter', 'main']

FeedTransporter, main = machine_node('feed_transporter', __name__)

if __name__ == '__main__':
    sys.exit(main())
