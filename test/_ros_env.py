"""The ROS environment of a test process (not a test module): a ROS domain of its own, discovery on this host.

``test/conftest.py`` applies :func:`use_ros_environment` to ``os.environ`` when pytest loads it,
before any test module imports rclpy. So every rclpy context of the test process, and every
process a test starts with a copy of ``os.environ`` (:func:`node_environment`), share one domain
and no other ROS graph on the machine does. Tests that need its number import :data:`DOMAIN_ID`.
"""

from __future__ import annotations

import os
from collections.abc import MutableMapping
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent

#: 1..100 from the pid: one domain per test process, never 0 (the default of any other ROS graph)
DOMAIN_ID = 1 + os.getpid() % 100


def use_ros_environment(env: MutableMapping[str, str]) -> None:
    """Put ``env`` on this test process's ROS domain, with discovery kept to this host."""
    env['ROS_DOMAIN_ID'] = str(DOMAIN_ID)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env.pop('ROS_STATIC_PEERS', None)
    env.pop('ROS_LOCALHOST_ONLY', None)  # deprecated; would conflict with the range above


def node_environment() -> dict[str, str]:
    """Environment for a node process: this process's (its ROS domain too), and the repository importable."""
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join(p for p in (str(REPO), env.get('PYTHONPATH', '')) if p)
    env['PYTHONUNBUFFERED'] = '1'
    env['RCUTILS_COLORIZED_OUTPUT'] = '0'
    return env
