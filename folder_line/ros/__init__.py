"""The ROS 2 side of the line: rclpy adapters over :mod:`folder_line.core`.

========================  ==================================================================
module                    holds
========================  ==================================================================
``topics``                QoS profiles of the line's topics, ``joint_states_topic``
``time_msg``              integer nanoseconds <-> ``builtin_interfaces/msg/Time``
``parameters``            ``ParamSpec`` tables, ``declare_parameters`` and the validation
``runtime``               ``run_node`` (a node process: spin, stop, teardown, exit code),
                          ``events_executor``
``lockstep``              the lockstep protocol: acknowledgements, announcement, lost nodes
``nodes/``                the nodes, one per file, each with ``main(args=None)``
``recorder``              the recorder that takes every topic for the bag
``run``                   ``folder-line run``: the line in one process or one per node
``monitor``               the monitor's subscriptions, feeding a view it is given
========================  ==================================================================

Names and message types of the topics are in :mod:`folder_line.interfaces` (no rclpy).
Every module here loads rclpy on import; nothing below this layer imports them (the
command line imports :mod:`folder_line.ros.run` only for ``run``; see test/test_architecture.py).
"""
