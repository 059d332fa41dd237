"""The package builds with colcon as an ament_python package and installs what ROS tools look for.

colcon (``colcon-core`` + ``colcon-ros``, from requirements.txt) runs from this
Python, on a copy of the package in ``tmp_path``: nothing is written to the
repository. No ROS installation is needed: colcon-ros identifies the package from
``package.xml`` (build type ``ament_python``) and builds it with setuptools.
"""

from __future__ import annotations

import ast
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
PACKAGE = 'folder_line'
PACKAGE_FILES = ('setup.py', 'setup.cfg', 'package.xml', 'resource', 'config', 'launch', PACKAGE)


def console_scripts() -> dict[str, str]:
    """``name -> module:function`` of setup.py's console_scripts, read from its syntax tree."""
    tree = ast.parse((REPO / 'setup.py').read_text(encoding='utf-8'))
    for node in ast.walk(tree):
        if isinstance(node, ast.keyword) and node.arg == 'entry_points':
            scripts = ast.literal_eval(node.value)['console_scripts']
            return dict((part.strip() for part in line.split('=', 1)) for line in scripts)
    raise AssertionError('setup.py has no entry_points')


def _env(tmp: Path) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith('COLCON_')}  # ROS domain: test/conftest.py
    env['COLCON_HOME'] = str(tmp / 'colcon_home')  # no user defaults or mixins
    env['PYTHONDONTWRITEBYTECODE'] = '1'
    return env


@pytest.fixture(scope='module')
def install(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``colcon build`` of a copy of the package; returns the install space."""
    tmp = tmp_path_factory.mktemp('colcon')
    src = tmp / 'src' / PACKAGE
    src.mkdir(parents=True)
    ignore = shutil.ignore_patterns('__pycache__', '*.pyc', '*.egg-info')
    for name in PACKAGE_FILES:
        path = REPO / name
        if path.is_dir():
            shutil.copytree(path, src / name, ignore=ignore)
        else:
            shutil.copy2(path, src / name)
    before = {p.name for p in REPO.iterdir()}
    command = [
        sys.executable,
        '-m',
        'colcon',
        '--log-base',
        str(tmp / 'log'),
        'build',
        '--base-paths',
        str(tmp / 'src'),
        '--build-base',
        str(tmp / 'build'),
        '--install-base',
        str(tmp / 'install'),
        '--event-handlers',
        'console_direct+',
    ]
    done = subprocess.run(command, cwd=tmp, env=_env(tmp), capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    assert 'ament_python' in (tmp / 'log' / 'latest_build' / 'logger_all.log').read_text()
    new = {p.name for p in REPO.iterdir()} - before  # nothing left in the repository
    assert not {n for n in new if n in ('build', 'install', 'log') or n.endswith('.egg-info')}
    return tmp / 'install'


def test_console_scripts_are_listed() -> None:
    scripts = console_scripts()
    assert scripts['folder-line'] == 'folder_line.cli.main:main'
    assert scripts['line_clock'] == 'folder_line.ros.entry:line_clock'  # light: a stop while it imports exits 0


def test_every_console_script_is_an_executable_in_lib_package(install: Path) -> None:
    lib = install / PACKAGE / 'lib' / PACKAGE
    for name in console_scripts():
        script = lib / name
        assert script.is_file(), sorted(p.name for p in lib.iterdir())
        assert os.access(script, os.X_OK)
        assert script.read_text().startswith('#!')


def test_ament_index_package_xml_and_config_are_installed(install: Path) -> None:
    share = install / PACKAGE / 'share'
    assert (share / 'ament_index' / 'resource_index' / 'packages' / PACKAGE).is_file()
    assert (share / PACKAGE / 'package.xml').read_bytes() == (REPO / 'package.xml').read_bytes()
    for pattern in ('config/*.yaml', 'config/scenes/*.yaml', 'launch/*.launch.py'):
        expected = sorted(REPO.glob(pattern))
        if pattern == 'config/*.yaml':
            assert expected  # the package has configuration
        for path in expected:
            installed = share / PACKAGE / path.relative_to(REPO)
            assert installed.read_bytes() == path.read_bytes(), installed


def test_the_fast_dds_profile_is_installed_beside_its_module(install: Path) -> None:
    [site] = (install / PACKAGE / 'lib').glob('python3*/site-packages')
    shipped = REPO / 'folder_line' / 'ros' / 'fastdds_line.xml'
    assert (site / 'folder_line' / 'ros' / 'fastdds_line.xml').read_bytes() == shipped.read_bytes()


def _installed_env(install: Path, tmp: Path) -> dict[str, str]:
    env = _env(tmp)
    [site] = (install / PACKAGE / 'lib').glob('python3*/site-packages')
    env['PYTHONPATH'] = os.pathsep.join(p for p in (str(site), env.get('PYTHONPATH', '')) if p)
    env['AMENT_PREFIX_PATH'] = os.pathsep.join(
        p for p in (str(install / PACKAGE), env.get('AMENT_PREFIX_PATH', '')) if p
    )
    return env


def test_installed_scripts_run_from_the_install_space(install: Path, tmp_path: Path) -> None:
    env = _installed_env(install, tmp_path)
    where = subprocess.run(
        [sys.executable, '-c', 'import folder_line; print(folder_line.__file__)'],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert Path(where.stdout.strip()).is_relative_to(install), where.stdout + where.stderr
    lib = install / PACKAGE / 'lib' / PACKAGE
    cli = subprocess.run(
        [str(lib / 'folder-line'), '--help'], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=60
    )
    assert cli.returncode == 0 and 'usage' in cli.stdout.lower(), cli.stdout + cli.stderr
    # a lockstep line of one participant, as `ros2 run` of a subset would start it: both end with the duration
    node = subprocess.Popen(
        [str(lib / 'crank_drive'), '--ros-args', '-p', 'horizon:=1.0'],
        cwd=tmp_path,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        clock = subprocess.run(
            [
                str(lib / 'line_clock'),
                '--ros-args',
                '-p',
                'duration:=0.2',
                '-p',
                'rtf:=0.0',
                '-p',
                'participants:=crank_drive',
            ],
            cwd=tmp_path,
            env=env,
            capture_output=True,
            text=True,
            timeout=60,
        )
        node_out, _ = node.communicate(timeout=60)
    finally:  # never leave a node behind on this domain
        if node.poll() is None:
            node.kill()
            node.wait()
    assert clock.returncode == 0, clock.stdout + clock.stderr
    assert 'duration reached (41 ticks' in clock.stdout + clock.stderr, clock.stdout + clock.stderr
    assert node.returncode == 0, node_out


def test_ament_index_finds_the_installed_share_directory(install: Path, tmp_path: Path) -> None:
    code = f'from ament_index_python.packages import get_package_share_directory as g; print(g({PACKAGE!r}))'
    found = subprocess.run(
        [sys.executable, '-c', code],
        cwd=tmp_path,
        env=_installed_env(install, tmp_path),
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert found.returncode == 0, found.stderr
    assert Path(found.stdout.strip()) == install / PACKAGE / 'share' / PACKAGE
