# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Input and output: rosbag2/MCAP bags, DAQ exports, all-or-nothing file writes."""
