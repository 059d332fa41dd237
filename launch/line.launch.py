"""Launch the folder_line line on a ROS 2 install.

    ros2 launch folder_line line.launch.py scene:=folder [rtf:=1.0] [duration:=20.0]
        [overrides:="feed_transporter.V_tr=5.833;seed=3"] [rate:=200.0] [start_time:=0.0]
        [clock:=lockstep|wall] [lost_timeout:=3.0] [marker_rate:=5.0]

Starts the five machine nodes with the same scene and ``line_clock`` with those five
as its lockstep participants: sim time does not advance until every one of them has
answered the first tick, and then only as fast as the slowest allows (``rtf`` is a
ceiling; ``0.0`` = as fast as possible). Without ``duration`` the line runs until
Ctrl-C, in memory that does not grow with line time; ``start_time`` starts the clock
that far into the line (the nodes fast-forward there). This is ``folder-line run --processes``
without the recorder: record with ``ros2 bag record`` (which cannot answer ticks, so
it is not a participant).

How it ends, and its exit code:

* Every argument is read and checked, as its nodes would, before any node starts
  (:func:`folder_line.ros.line_launch.line_parameters`): a bad one (``rtf:=fast``) fails the
  launch with one line naming it, exit code 1, and no node running.
* With ``duration`` > 0 every node ends by itself after the last tick: once ``line_clock``
  has exited, the launch waits for the others (it signals none of them: a signal to a process
  that is exiting can lose its exit status in launch), stops any still running ``END_GRACE`` s
  later, and exits 0.
* A node that exits non-zero (a participant lost: ``line_clock`` exits 3; parameters refused:
  2; a machine node that lost a producer or its clock: 3) shuts the launch down, which then
  exits 1 (launch's code for an error, the only non-zero one it has) with one ERROR line naming
  the node and its code. An exit status launch lost itself (reported as 255) is not counted as a
  failure; a line says so.
* Every node gets the line's key (``FOLDER_LINE_KEY``: the caller's, or a new one, logged at the
  start), so the line hears only its own nodes (:mod:`folder_line.ros.line_key`).
* Each node asks the kernel to stop it (SIGTERM) if this launch process dies
  (:mod:`folder_line.ros.entry`): a launch that is killed leaves no node behind.
"""

from __future__ import annotations

import functools
import os

from launch.actions import DeclareLaunchArgument, EmitEvent, LogInfo, OpaqueFunction, RegisterEventHandler, TimerAction
from launch.event_handlers import OnProcessExit
from launch.events import Shutdown
from launch.events.process import ProcessExited
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from folder_line.interfaces import LINE_CLOCK, MACHINE_NODES  # the installed package names its nodes once
from folder_line.ros.entry import PARENT_PID_ENV
from folder_line.ros.line_launch import (
    ARGUMENTS,
    END_GRACE,
    STATUS_LOST,
    LineEnd,
    Step,
    failure_text,
    line_key_environment,
    line_parameters,
)
from launch import Action, LaunchContext, LaunchDescription


class LineNodeFailed(RuntimeError):
    """A node of the line exited non-zero: raised in launch's event handling, it makes the launch exit 1."""


def generate_launch_description() -> LaunchDescription:
    """The arguments, then the line's nodes, built once every argument has been checked."""
    actions: list[Action] = [
        DeclareLaunchArgument(name, default_value=default, description=text) for name, default, text in ARGUMENTS
    ]
    actions.append(OpaqueFunction(function=start_line))
    return LaunchDescription(actions)


def start_line(context: LaunchContext) -> list[Action]:
    """The nodes with their parameters, and what ends the launch; raises (nothing started) on a bad argument."""
    given = {name: LaunchConfiguration(name).perform(context) for name, _, _ in ARGUMENTS}
    parameters = line_parameters(given)  # a ParameterError: launch logs it, starts nothing and exits 1
    key_env, told = line_key_environment(os.environ)  # a bad FOLDER_LINE_KEY fails the launch, as a bad argument
    parent = {PARENT_PID_ENV: str(os.getpid()), **key_env}  # each node stops if this process dies; one line key
    names = (*MACHINE_NODES, LINE_CLOCK)
    end = LineEnd(names)
    stragglers = TimerAction(period=END_GRACE, actions=[EmitEvent(event=Shutdown(reason='the line ended'))])
    actions: list[Action] = [] if told is None else [LogInfo(msg=told)]
    for name in names:
        node = Node(
            package='folder_line',
            executable=name,
            name=name,
            parameters=[parameters[name]],
            output='screen',
            additional_env=parent,
        )
        on_exit = functools.partial(node_exited, end, stragglers, name)
        actions += [node, RegisterEventHandler(OnProcessExit(target_action=node, on_exit=on_exit))]
    return actions


def node_exited(
    end: LineEnd, stragglers: TimerAction, name: str, event: ProcessExited, context: LaunchContext
) -> list[Action]:
    """A node exited: the line ends with its clock, the others by themselves; a node that failed fails the launch."""
    step = end.exited(name, event.returncode)
    if step is Step.FAIL:
        # launch shuts down on an exception in an event handler and then exits 1: its only way to a non-zero code
        raise LineNodeFailed(failure_text(name, event.returncode))
    actions: list[Action] = []
    if event.returncode == STATUS_LOST:
        actions.append(LogInfo(msg=f'{name}: launch lost its exit status (reported as {STATUS_LOST}); not a failure'))
    if step is Step.WAIT_FOR_THE_REST:
        actions.append(stragglers)  # stops the nodes still running END_GRACE s from now
    elif step is Step.ENDED:
        stragglers.cancel()  # every node has ended: launch is idle and exits
    return actions
