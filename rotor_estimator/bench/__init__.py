# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Benchmarks behind ``rotor-estimator bench ...``: scripts that print figures, never timed tests."""
