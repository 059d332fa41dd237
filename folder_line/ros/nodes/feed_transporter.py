"""Node ``feed_transporter``: the folder's 2nd transporter and the delivery chain.

The transporter (``feed_belt``) and the chain (``chain``, ``carriage``; the sprocket
torque as the chain's effort with ``chain_friction``), with the signatures' hand-over,
front-stop and settle events.

Parameters and topics: see :mod:`folder_line.ros.nodes.machine`.
"""

from __future__ import annotations

import sys

from folder_line.ros.nodes.machine import MachineNode
from folder_line.ros.runtime import run_node

__all__ = ['FeedTransporter', 'main']


class FeedTransporter(MachineNode):
    """The ``feed_transporter`` node."""

    NODE_NAME = 'feed_transporter'


def main(args: list[str] | None = None) -> int:
    """Run ``feed_transporter`` until Ctrl-C; exit code 0 (2 on a bad parameter)."""
    return run_node(FeedTransporter, args)


if __name__ == '__main__':
    sys.exit(main())
