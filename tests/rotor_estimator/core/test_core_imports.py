# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Layering: the numerical core imports no ROS (neither rclpy nor rosbags)."""
import subprocess
import sys

CORE_MODULES = [
    "rotor_estimator.core.config", "rotor_estimator.core.model", "rotor_estimator.core.simulator",
    "rotor_estimator.core.ekf",
    "rotor_estimator.core.filter_kernel", "rotor_estimator.bench.reference_ekf", "rotor_estimator.core.crlb",
    "rotor_estimator.core.offline", "rotor_estimator.bench.reproduce", "rotor_estimator.core.tachometer",
    "rotor_estimator.core.alignment", "rotor_estimator.core.recording", "rotor_estimator.core.pipeline",
    "rotor_estimator.core.linear_filters", "rotor_estimator.virtual_sensing.estimator",
    "rotor_estimator.virtual_sensing.stream",
    "rotor_estimator.core.flexible",
    "rotor_estimator.identification.methods", "rotor_estimator.identification.planner",
    "rotor_estimator.core.identifiability", "rotor_estimator.diagnosis",
]


def test_core_modules_import_neither_rclpy_nor_rosbags():
    code = ("import sys, importlib\n"
            f"for m in {CORE_MODULES!r}:\n"
            "    importlib.import_module(m)\n"
            "bad = sorted(k for k in sys.modules if k.split('.')[0] in ('rclpy', 'rosbags', 'rosidl_parser'))\n"
            "print(','.join(bad))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "", f"core imported: {out.stdout.strip()}"
