"""The ROS environment of a test process (not a test module): a ROS domain of its own, discovery on this host,
and a line key of its own (the line's DDS partition).

``test/conftest.py`` applies :func:`use_ros_environment` to ``os.environ`` when pytest loads it,
before any test module imports rclpy. So every rclpy context of the test process, and every
process a test starts with a copy of ``os.environ`` (:func:`node_environment`), share one domain
and no other ROS graph on the machine does. Tests that need its number import :data:`DOMAIN_ID`.
Every process of the test process's tree is one line (``FOLDER_LINE_KEY``): a test's own nodes
are insiders, as an operator's would be; a stranger is a process started without the key
(:func:`stranger_environment`).
"""

from __future__ import annotations

import os
from collections.abc import MutableMapping
from pathlib import Path

from folder_line.ros.dds_profile import PROFILE_FILE, PROFILES_FILE_VARIABLE, use_line_profile
from folder_line.ros.line_key import KEY_VARIABLE, new_key

REPO = Path(__file__).resolve().parent.parent


def _domain_id() -> int:
    """1..100, never 0 (the default of any other ROS graph): for a worker of ``pytest -n`` (pytest-xdist) one
    of four from the run's controller (its parent) and the worker's number, so the run's workers never share
    one; for a lone test process one from its pid."""
    worker = os.environ.get('PYTEST_XDIST_WORKER', '')
    if worker.startswith('gw') and worker[2:].isdigit():
        return 1 + (os.getppid() % 25) * 4 + int(worker[2:]) % 4
    return 1 + os.getpid() % 100


#: one domain per test process (:func:`_domain_id`)
DOMAIN_ID = _domain_id()


def use_ros_environment(env: MutableMapping[str, str]) -> None:
    """Put ``env`` on this test process's ROS domain, with discovery kept to this host."""
    env['ROS_DOMAIN_ID'] = str(DOMAIN_ID)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env.pop('ROS_STATIC_PEERS', None)
    env.pop('ROS_LOCALHOST_ONLY', None)  # deprecated; would conflict with the range above
    env[KEY_VARIABLE] = new_key()
    env.pop(PROFILES_FILE_VARIABLE, None)
    env.pop('FASTRTPS_DEFAULT_PROFILES_FILE', None)
    use_line_profile(env)  # the key's partition, for the first participant of this process and its children


def node_environment() -> dict[str, str]:
    """Environment for a node process: this process's (its ROS domain too), and the repository importable."""
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join(p for p in (str(REPO), env.get('PYTHONPATH', '')) if p)
    env['PYTHONUNBUFFERED'] = '1'
    env['RCUTILS_COLORIZED_OUTPUT'] = '0'
    return env


def sniffer_environment() -> dict[str, str]:
    """:func:`node_environment` without the line's key but with its DDS profile (its partition): a process
    of someone who read the partition's name off the network."""
    env = node_environment()
    env.pop(KEY_VARIABLE)
    assert env[PROFILES_FILE_VARIABLE] != str(PROFILE_FILE)  # the line's keyed profile
    return env


def stranger_environment() -> dict[str, str]:
    """:func:`node_environment` without the line's key: a process on the same domain that is not of the line."""
    env = node_environment()
    env.pop(KEY_VARIABLE)
    env[PROFILES_FILE_VARIABLE] = str(PROFILE_FILE)
    return env
