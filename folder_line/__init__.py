"""folder_line: simulation of an industrial folding/layup line (ROS 2, rclpy)."""

from __future__ import annotations

__version__ = '0.1.0'
