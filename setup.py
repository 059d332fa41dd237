"""ament_python package: ``colcon build`` on a ROS 2 install, ``pip install`` elsewhere."""

from __future__ import annotations

from glob import glob

from setuptools import find_packages, setup

package_name = 'folder_line'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*', 'bench']),
    # the Fast DDS profile the node processes load (folder_line.ros.dds_profile)
    package_data={'folder_line.ros': ['fastdds_line.xml']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
        ('share/' + package_name + '/config/scenes', glob('config/scenes/*.yaml')),
        ('share/' + package_name + '/config/foxglove', glob('config/foxglove/*.json')),
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
    # a node's executable enters through folder_line.ros.entry, which makes a stop during its imports a
    # clean exit (0, no traceback) before it imports the node's module
    entry_points={
        'console_scripts': [
            'folder-line = folder_line.cli.main:main',
            'line_clock = folder_line.ros.entry:line_clock',
            'crank_drive = folder_line.ros.entry:crank_drive',
            'belt_conveyor = folder_line.ros.entry:belt_conveyor',
            'feed_transporter = folder_line.ros.entry:feed_transporter',
            'sheet_counter = folder_line.ros.entry:sheet_counter',
            'supervisor = folder_line.ros.entry:supervisor',
        ],
    },
)
