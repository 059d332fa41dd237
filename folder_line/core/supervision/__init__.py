"""The supervisor's decisions, the PackML state machine and the lockstep ledger (no ROS)."""
