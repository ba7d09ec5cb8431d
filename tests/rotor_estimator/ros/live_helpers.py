# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Helpers shared by the live rclpy tests: polling with a timeout and an isolated DDS domain."""
from __future__ import annotations

import os
import random
import time


def wait_for(predicate, timeout_s: float, step_s: float = 0.02) -> bool:
    """Poll ``predicate`` until it is true or ``timeout_s`` passes; return its last value."""
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(step_s)
    return predicate()


def random_domain_id() -> int:
    """A ROS_DOMAIN_ID unlikely to collide with another test run on the same machine."""
    return random.Random(os.getpid() ^ time.time_ns()).randint(1, 215)
