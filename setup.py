"""ament_python package: ``colcon build`` on a ROS 2 install, ``pip install`` elsewhere."""

from __future__ import annotations

from glob import glob

from setuptools import find_packages, setup

package_name = 'folder_line'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*', 'bench']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
        ('share/' + package_name + '/config/scenes', glob('config/scenes/*.yaml')),
        ('share/' + package_name + '/launch', glob('launch/*.launch.py')),
    ],
    # The ROS 2 stack (rclpy, message packages) comes from the ROS install or, for
    # `make`, from requirements.txt: it is deliberately not listed here.
    install_requires=[
        'setuptools',
        'numpy',
        'scipy',
        'PyYAML',
        'matplotlib',
        'imageio-ffmpeg',
        'rosbags',
        'mcap',
        'dask',
        'distributed',
    ],
    zip_safe=True,
    maintainer='folder_line team',
    maintainer_email='folder-line@example.com',
    description='Simulation of a folding/layup line as ROS 2 nodes',
    license='Apache-2.0',
    python_requires='>=3.10',
    entry_points={
        'console_scripts': [
            'folder-line = folder_line.cli.main:main',
            'line_clock = folder_line.ros.nodes.line_clock:main',
            'crank_drive = folder_line.ros.nodes.crank_drive:main',
            'belt_conveyor = folder_line.ros.nodes.belt_conveyor:main',
            'feed_transporter = folder_line.ros.nodes.feed_transporter:main',
            'sheet_counter = folder_line.ros.nodes.sheet_counter:main',
            'supervisor = folder_line.ros.nodes.supervisor:main',
        ],
    },
)
