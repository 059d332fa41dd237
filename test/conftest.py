"""What every test shares: the test process's ROS environment (:mod:`_ros_env`), set before rclpy is imported.

pytest loads this file before any test module and before the conftest files below it, so the
ROS domain and discovery range set here hold for the whole test process: every test that
runs the line over real DDS (``ros/``, ``bag/``, ``analysis/``, ``accuracy/``) and every
process such a test starts.
"""

from __future__ import annotations

import os

import pytest
from _ros_env import node_environment, use_ros_environment
from hypothesis import settings

# no per-example deadline: how long an example takes depends on the machine's load (and on a first call's
# caches); speed is measured by bench/, not judged by a test
settings.register_profile('folder_line', deadline=None)
settings.load_profile('folder_line')

# read by rclpy when it is imported: before any test module (or test/ros/conftest.py) imports it
use_ros_environment(os.environ)


def pytest_configure(config: pytest.Config) -> None:
    # rosidl_generator_py (imported by the first node or message) imports lark 0.12, which
    # imports the deprecated sre_parse/sre_constants: not ours, not actionable.
    for module in ('sre_parse', 'sre_constants'):
        config.addinivalue_line('filterwarnings', f"ignore:module '{module}' is deprecated:DeprecationWarning")


@pytest.fixture
def node_env() -> dict[str, str]:
    """Environment for a node process: this process's ROS domain, and the repository importable."""
    return node_environment()
