# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The standard ``main()`` of every node: init, spin, report configuration errors, shut down cleanly."""
from __future__ import annotations

from typing import Callable

import rclpy
from rclpy.exceptions import InvalidParameterValueException
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node

from rotor_estimator.core.errors import RotorEstimatorError


def run_node(make_node: Callable[[], Node], executable: str, args: list[str] | None = None) -> int:
    """Spin the node built by ``make_node`` until shutdown; 1 on a configuration error, else 0."""
    rclpy.init(args=args)
    code = 0
    node = None
    try:
        node = make_node()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (RotorEstimatorError, InvalidParameterValueException) as exc:
        print(f"{executable}: error: {exc}")
        code = 1
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return code
