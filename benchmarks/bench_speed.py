#!/usr/bin/env python3
# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""EKF speed: our compiled EKF vs a filterpy EKF of the same model (same process, same samples).

Same as ``rotor-estimator bench speed [--json]``. Targets: <= 10 us/sample, >= 20x filterpy.
"""
import sys

from rotor_estimator.cli.main import main

if __name__ == "__main__":
    sys.exit(main(["bench", "speed", *sys.argv[1:]]))
