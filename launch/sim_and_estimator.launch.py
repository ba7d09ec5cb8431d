# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Launch the simulator node (seed rig, imbalance+impact, repeating) and the estimator node.

Arguments: ``rate_factor`` (playback speed), ``bag_path`` (replay this MCAP bag instead of
simulating), ``params_file`` (estimator parameters). Needs a full ROS 2 install.
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.conditions import IfCondition, UnlessCondition
from launch.substitutions import LaunchConfiguration, PythonExpression
from launch_ros.actions import Node


def generate_launch_description() -> LaunchDescription:
    share = get_package_share_directory("rotor_estimator")
    bag = LaunchConfiguration("bag_path")
    replaying = PythonExpression(["'", bag, "' != ''"])
    common = {"rate_factor": LaunchConfiguration("rate_factor")}
    return LaunchDescription([
        DeclareLaunchArgument("rate_factor", default_value="1.0", description="playback speed (1 = real time)"),
        DeclareLaunchArgument("bag_path", default_value="", description="MCAP bag to replay instead of simulating"),
        DeclareLaunchArgument("params_file", default_value=os.path.join(share, "config", "estimator.yaml")),
        Node(package="rotor_estimator", executable="simulator_node", name="rotor_simulator", output="screen",
             condition=UnlessCondition(replaying),
             parameters=[{**common, "mode": "simulate", "duration_s": 2.03, "impact_period_s": 0.1,
                          "repeat": True}]),
        Node(package="rotor_estimator", executable="simulator_node", name="rotor_simulator", output="screen",
             condition=IfCondition(replaying),
             parameters=[{**common, "mode": "replay", "bag_path": bag, "loop": True}]),
        Node(package="rotor_estimator", executable="estimator_node", name="rotor_estimator", output="screen",
             parameters=[LaunchConfiguration("params_file")]),
    ])
