"""The ROS 2 side of the line: rclpy adapters over :mod:`folder_line.core`.

==========================  ================================================================
module                      holds
==========================  ================================================================
``topics``                  QoS profiles of the line's topics, ``joint_states_topic``
``time_msg``                integer nanoseconds <-> ``builtin_interfaces/msg/Time`` *
``message_fields``          the fields of ROS messages the package reads, as protocols *
``parameters``              ``ParamSpec`` tables, ``declare_parameters`` and the validation
``ros_args``                a node's ``--ros-args`` values, read before rcl starts
``runtime``                 ``run_node`` (a node process: spin, stop, teardown, exit code),
                            ``events_executor``
``entry``, ``exit_timer``   the node executables' entry points and their exit deadline *
``dds_profile``             the Fast DDS profile of the line's processes *
``line_key``, ``signing``   the line's key, its partition and its signatures *
``strangers``               publishers on the line's topics that are not the line's nodes
``lockstep``                the lockstep protocol: acknowledgements, announcement, lost nodes
``lockstep_messages``       the lockstep's messages on the wire *
``nodes/``                  the nodes, one per file, each with ``main(args=None)``
``recorder``                the recorder that takes every topic for the bag
``run``                     ``folder-line run``: the line in one process or one per node
``run_summary``             ``run.json``: the run's summary and its verdict *
``line_launch``             what launch/line.launch.py starts
``player``                  ``folder-line bag play``: a bag republished with ``/clock``
``operator``                the operator's commands: one call of a supervisor service
``markers``                 the scenery's markers as a ``MarkerArray`` *
``monitor``                 the monitor's subscriptions, feeding a view it is given
==========================  ================================================================

Names and message types of the topics are in :mod:`folder_line.interfaces` (no rclpy).
The modules marked * do not load rclpy on import; the others do. Nothing below this layer
imports this package (the command line imports :mod:`folder_line.ros.run` only for ``run``;
see test/test_architecture.py).
"""
