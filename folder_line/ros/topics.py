"""The line's topics on DDS: the QoS profiles and the joint-states topic checked against ROS naming rules.

The topic names and their message types are in :mod:`folder_line.interfaces` (no rclpy);
this module holds what a publisher or subscription of the line is created with. The QoS
of the lockstep (``LINE_QOS``, ``CLOCK_SUB_QOS``) is in :mod:`folder_line.ros.lockstep`,
the supervisor's state QoS in :mod:`folder_line.ros.nodes.supervisor`.
"""

from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.validate_node_name import validate_node_name

from folder_line import interfaces

__all__ = [
    'CLOCK_QOS',
    'COMMANDS_QOS',
    'PUBLISH_DEPTH',
    'TUNE_QOS',
    'joint_states_topic',
]


def joint_states_topic(node_name: str) -> str:
    """``/line/<node_name>/joint_states``.

    Parameters
    ----------
    node_name : str
        A valid ROS node name (no namespace), e.g. ``'knife'``.

    Raises
    ------
    rclpy.exceptions.InvalidNodeNameException
        ``node_name`` is not a valid node name.
    """
    validate_node_name(node_name)
    return interfaces.joint_states_topic(node_name)


COMMANDS_QOS = QoSProfile(
    depth=1000,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
    history=HistoryPolicy.KEEP_ALL,
)
"""QoS of the supervisor's command topic: every command reaches every node, late joiners too."""

PUBLISH_DEPTH = 1000
"""History depth of every line publisher: a reliable subscriber (the recorder) that falls
behind by up to this many messages still gets them all."""

CLOCK_QOS = QoSProfile(depth=PUBLISH_DEPTH, reliability=ReliabilityPolicy.RELIABLE)
"""QoS of the ``/clock`` publisher: reliable, so that it also matches the best-effort
subscription every node's ``TimeSource`` makes, and recorders that want every tick."""

#: operators' tunings forwarded to the supervisor (``folder_line.interfaces.TUNE_TOPIC``): reliable but
#: volatile, so a supervisor that starts later is not handed old requests
TUNE_QOS = QoSProfile(depth=PUBLISH_DEPTH, reliability=ReliabilityPolicy.RELIABLE)
