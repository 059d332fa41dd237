"""The ROS 2 side: nodes, lockstep protocol, parameter specs, ``run``, the recorder, the monitor."""
