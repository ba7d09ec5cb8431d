# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""ROS 2 nodes (thin rclpy shells over :mod:`rotor_estimator.core.pipeline` and the simulator).

* :mod:`.estimator_node`: ``estimator_node`` executable, the live estimator.
* :mod:`.simulator_node`: ``simulator_node`` executable, synthetic or recorded input topics.
* :mod:`.pipeline_io`: message <-> pipeline glue shared with offline replay (no rclpy import).

Only the two node modules import rclpy; everything else here runs without ROS.
"""
