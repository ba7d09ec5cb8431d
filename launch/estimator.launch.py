# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Launch the estimator node with config/estimator.yaml (override with params_file:=...).

``namespace:=/rig2`` runs it as /rig2/rotor_estimator: the shipped file is keyed ``/**`` so it
applies under any name and namespace (outputs then go under /rig2/rotor_estimator/...). Needs a
full ROS 2 install (launch, launch_ros; package.xml lists them); the tests load it with stand-ins.
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def generate_launch_description() -> LaunchDescription:
    default_params = os.path.join(get_package_share_directory("rotor_estimator"), "config", "estimator.yaml")
    return LaunchDescription([
        DeclareLaunchArgument("params_file", default_value=default_params,
                              description="estimator parameters (YAML, see config/estimator.yaml)"),
        DeclareLaunchArgument("namespace", default_value="", description="namespace of the estimator node"),
        Node(package="rotor_estimator", executable="estimator_node", name="rotor_estimator",
             namespace=LaunchConfiguration("namespace"), parameters=[LaunchConfiguration("params_file")],
             output="screen"),
    ])
