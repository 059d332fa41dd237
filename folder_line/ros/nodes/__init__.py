"""ROS 2 nodes of the line: thin rclpy adapters over :mod:`folder_line.core`.

Every node declares its parameters from a :class:`~folder_line.ros.parameters.ParamSpec`
table, runs on simulated time published by :mod:`folder_line.ros.nodes.line_clock`, and
is started by a module-level ``main(args=None)`` built on
:func:`~folder_line.ros.runtime.run_node`. Topic names live in :mod:`folder_line.interfaces`
and nowhere else; the QoS profiles in :mod:`folder_line.ros.topics`.
"""
