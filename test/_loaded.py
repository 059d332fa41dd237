"""Which ROS modules a piece of Python loads, run in a fresh interpreter (the layering tests share it)."""

from __future__ import annotations

import ast
import subprocess
import sys

from _ros_env import REPO, node_environment

#: top-level modules that mean "ROS is loaded": rclpy and the generated message packages
ROS_MODULES = (
    'rclpy',
    'rosidl_runtime_py',
    'sensor_msgs',
    'std_msgs',
    'diagnostic_msgs',
    'builtin_interfaces',
    'rosgraph_msgs',
)


def ros_modules_loaded(statements: str, timeout: float = 120.0) -> tuple[str, list[str]]:
    """Run ``statements`` in a new interpreter (this repository importable); (its last stdout line, the
    :data:`ROS_MODULES` it loaded). Fails the test with the child's stderr if the child fails."""
    code = (
        f'{statements}\n'
        'import sys as _sys\n'
        f'print(sorted({{m.split(".")[0] for m in _sys.modules}} & {set(ROS_MODULES)!r}))\n'
    )
    proc = subprocess.run(
        [sys.executable, '-c', code],
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
        cwd=REPO,
        env=node_environment(),
    )
    assert proc.returncode == 0, proc.stderr
    *out, loaded = proc.stdout.strip().splitlines()
    return (out[-1] if out else ''), ast.literal_eval(loaded)
