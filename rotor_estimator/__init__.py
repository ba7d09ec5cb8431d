# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""rotor_estimator: identify rotor-bearing stiffness and damping while the machine runs.

The numerical core (``config``, ``model``, ``simulator``, ``ekf``, ``crlb``,
``tachometer``, ``alignment``, ...) imports no ROS; ``msg_adapters`` and the node
modules are the only places that touch ROS message classes.
"""
__version__ = "0.1.0"
