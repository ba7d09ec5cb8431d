# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Numerical core: configuration, model, simulator, filters, tachometer, alignment, pipeline (no ROS)."""
