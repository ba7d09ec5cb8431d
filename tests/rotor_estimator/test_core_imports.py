"""Layering: the numerical core imports no ROS (neither rclpy nor rosbags)."""
import subprocess
import sys

CORE_MODULES = [
    "rotor_estimator.config", "rotor_estimator.model", "rotor_estimator.simulator", "rotor_estimator.ekf",
    "rotor_estimator.ekf_kernel", "rotor_estimator.ekf_reference", "rotor_estimator.crlb",
    "rotor_estimator.offline", "rotor_estimator.reproduce", "rotor_estimator.tachometer",
    "rotor_estimator.alignment", "rotor_estimator.recording", "rotor_estimator.pipeline",
    "rotor_estimator.linear_filters", "rotor_estimator.virtual_sensing", "rotor_estimator.virtual_sensing_stream",
    "rotor_estimator.flexible",
    "rotor_estimator.identification.methods", "rotor_estimator.identification.planner",
    "rotor_estimator.identification.identifiability", "rotor_estimator.diagnosis",
]


def test_core_modules_import_neither_rclpy_nor_rosbags():
    code = ("import sys, importlib\n"
            f"for m in {CORE_MODULES!r}:\n"
            "    importlib.import_module(m)\n"
            "bad = sorted(k for k in sys.modules if k.split('.')[0] in ('rclpy', 'rosbags', 'rosidl_parser'))\n"
            "print(','.join(bad))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "", f"core imported: {out.stdout.strip()}"
