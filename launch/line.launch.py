"""Launch the folder_line line on a ROS 2 install.

    ros2 launch folder_line line.launch.py scene:=folder [rtf:=1.0] [duration:=20.0]
        [overrides:="feed_transporter.V_tr=5.833;seed=3"] [rate:=200.0] [start_time:=0.0]
        [clock:=lockstep|wall] [lost_timeout:=3.0] [marker_rate:=5.0]

Starts the five machine nodes with the same scene and ``line_clock`` with those five
as its lockstep participants: sim time does not advance until every one of them has
answered the first tick, and then only as fast as the slowest allows (``rtf`` is a
ceiling; ``0.0`` = as fast as possible). Without ``duration`` the line runs until
Ctrl-C, in memory that does not grow with line time; ``start_time`` starts the clock
that far into the line (the nodes fast-forward there). With ``duration`` > 0 every node
ends after the last tick and the launch shuts down when ``line_clock`` exits; a node that
dies shuts the launch down too (its exit is reported). This is ``folder-line run --processes``
without the recorder: record with ``ros2 bag record`` (which cannot answer ticks, so
it is not a participant).
"""

from __future__ import annotations

from launch.actions import DeclareLaunchArgument, EmitEvent, RegisterEventHandler
from launch.event_handlers import OnProcessExit
from launch.events import Shutdown
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue

from folder_line.interfaces import MACHINE_NODES  # the installed package names its nodes once
from launch import LaunchDescription

ARGUMENTS = (
    ('scene', 'folder', 'scene name (config/scenes) or path of a scene YAML file'),
    ('overrides', '', 'scene overrides "MACHINE.KEY=VALUE" separated by ";"'),
    ('rate', '200.0', 'tick rate of line_clock and joint-state rate of the machine nodes, Hz of sim time'),
    ('rtf', '1.0', 'real-time factor ceiling of line_clock (0.0: as fast as the line allows)'),
    ('duration', '0.0', 'sim time to run for, s (0: until Ctrl-C)'),
    ('start_time', '0.0', 'sim time of the first tick, s (the nodes fast-forward there)'),
    ('clock', 'lockstep', 'lockstep (sim time waits for every node) or wall (hardware in the loop)'),
    ('lost_timeout', '3.0', 'wall time a tick waits for a node before it is declared lost, s'),
    ('marker_rate', '5.0', 'sheet_counter: /line/markers per second of sim time, frame line (0: none)'),
)


def generate_launch_description() -> LaunchDescription:
    """The line's nodes with shared scene parameters; the launch ends with ``line_clock``."""
    arg = {name: LaunchConfiguration(name) for name, _, _ in ARGUMENTS}
    lost = ParameterValue(arg['lost_timeout'], value_type=float)
    common = {
        'scene': ParameterValue(arg['scene'], value_type=str),
        'overrides': ParameterValue(arg['overrides'], value_type=str),
        'rate': ParameterValue(arg['rate'], value_type=float),
        'lost_timeout': lost,
        'use_sim_time': True,
    }
    actions: list = [
        DeclareLaunchArgument(name, default_value=default, description=text) for name, default, text in ARGUMENTS
    ]
    drawing = {'marker_rate': ParameterValue(arg['marker_rate'], value_type=float)}  # the node that draws
    nodes = [
        Node(
            package='folder_line',
            executable=name,
            name=name,
            parameters=[common, drawing] if name == 'sheet_counter' else [common],
            output='screen',
        )
        for name in MACHINE_NODES
    ]
    clock = Node(
        package='folder_line',
        executable='line_clock',
        name='line_clock',
        output='screen',
        parameters=[
            {
                'rtf': ParameterValue(arg['rtf'], value_type=float),
                'duration': ParameterValue(arg['duration'], value_type=float),
                'start_time': ParameterValue(arg['start_time'], value_type=float),
                'rate': ParameterValue(arg['rate'], value_type=float),
                'clock': ParameterValue(arg['clock'], value_type=str),
                'participants': ','.join(MACHINE_NODES),
                'lost_timeout': lost,
            }
        ],
    )
    actions += nodes + [clock]
    for node in [*nodes, clock]:  # the line ends with its clock; a node that dies ends it too
        actions.append(
            RegisterEventHandler(
                OnProcessExit(target_action=node, on_exit=[EmitEvent(event=Shutdown(reason='a line node exited'))])
            )
        )
    return LaunchDescription(actions)
