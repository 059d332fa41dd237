"""Publishers on the line's topics that are not the line's nodes: found in the ROS graph, named by node.

A closed line (a key: :mod:`folder_line.ros.line_key`) hears none of them: DDS matches its
readers only with writers of its partition. An open line hears them all. Either way
``line_clock`` names them on ``/diagnostics`` (:func:`foreign_publishers`), so an operator
sees who tried.
"""

from __future__ import annotations

from collections.abc import Collection
from typing import Final

from rclpy.node import Node

from folder_line.interfaces import (
    GRANT_TOPIC,
    KNOWN_PARTICIPANTS,
    LINE_CLOCK,
    LINE_TOPIC_TYPES,
    TUNE_TOPIC,
    progress_topic,
    tick_done_topic,
)

__all__ = ['UNKNOWN_NODE', 'WATCHED_TOPICS', 'foreign_publishers']

UNKNOWN_NODE: Final = '_NODE_NAME_UNKNOWN_'
"""rmw_dds_common's node name of an endpoint whose node is not known yet."""

WATCHED_TOPICS: Final[tuple[str, ...]] = (
    *LINE_TOPIC_TYPES,
    TUNE_TOPIC,
    GRANT_TOPIC,
    *(progress_topic(p) for p in KNOWN_PARTICIPANTS),
    *(tick_done_topic(p) for p in KNOWN_PARTICIPANTS),
)
"""Every topic a node of the line publishes on, or reads."""

_OWN: Final = frozenset({*KNOWN_PARTICIPANTS, LINE_CLOCK})


def foreign_publishers(node: Node, topics: Collection[str] = WATCHED_TOPICS) -> dict[str, set[str]]:
    """``'/namespace/node'`` -> the ``topics`` it publishes on, for every publisher of a node not of the line.

    A node of the line is one named as a line node (:data:`folder_line.interfaces.KNOWN_PARTICIPANTS`,
    ``line_clock``), in any namespace; an endpoint whose node the graph does not know yet is left for
    a later look.
    """
    found: dict[str, set[str]] = {}
    for topic in topics:
        for info in node.get_publishers_info_by_topic(topic):
            if info.node_name in _OWN or info.node_name == UNKNOWN_NODE:
                continue
            found.setdefault(f'{info.node_namespace.rstrip("/")}/{info.node_name}', set()).add(topic)
    return found
