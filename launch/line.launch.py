"""Launch the folder_line line on a ROS 2 install.

    ros2 launch folder_line line.launch.py scene:=folder [rtf:=1.0] [duration:=20.0]
        [overrides:="feed_transporter.V_tr=5.833;seed=3"] [rate:=200.0] [horizon:=3600.0]

Starts the five machine nodes with the same scene, then ``line_clock`` (simulated
time on /clock; ``duration`` 0 runs until Ctrl-C). Equivalent to
``folder-line run --processes`` without the recorder.
"""

from __future__ import annotations

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue

MACHINE_NODES = ('crank_drive', 'belt_conveyor', 'feed_transporter', 'sheet_counter', 'supervisor')

ARGUMENTS = (
    ('scene', 'folder', 'scene name (config/scenes) or path of a scene YAML file'),
    ('overrides', '', 'scene overrides "MACHINE.KEY=VALUE" separated by ";"'),
    ('horizon', '3600.0', 'line time the node models are built for, s'),
    ('rate', '200.0', 'publishing rate of the machine nodes, Hz of sim time'),
    ('rtf', '1.0', 'real-time factor of line_clock'),
    ('duration', '0.0', 'sim time to run for, s (0: until Ctrl-C)'),
)


def generate_launch_description() -> LaunchDescription:
    """The line's nodes with shared scene parameters."""
    arg = {name: LaunchConfiguration(name) for name, _, _ in ARGUMENTS}
    common = {
        'scene': ParameterValue(arg['scene'], value_type=str),
        'overrides': ParameterValue(arg['overrides'], value_type=str),
        'horizon': ParameterValue(arg['horizon'], value_type=float),
        'rate': ParameterValue(arg['rate'], value_type=float),
        'use_sim_time': True,
    }
    actions = [DeclareLaunchArgument(name, default_value=default, description=text)
               for name, default, text in ARGUMENTS]
    actions += [Node(package='folder_line', executable=name, name=name, parameters=[common], output='screen')
                for name in MACHINE_NODES]
    actions.append(Node(package='folder_line', executable='line_clock', name='line_clock', output='screen',
                        parameters=[{'rtf': ParameterValue(arg['rtf'], value_type=float),
                                     'duration': ParameterValue(arg['duration'], value_type=float)}]))
    return LaunchDescription(actions)
