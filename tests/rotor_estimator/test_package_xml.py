# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""package.xml lists every runtime dependency a colcon build needs: each ROS package the code
imports or names in a message type, and each pip requirement (rosdep key or the documented pip step)."""
from __future__ import annotations

import ast
import re
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SOURCES = [*ROOT.joinpath("rotor_estimator").rglob("*.py"), *ROOT.joinpath("msg_adapters").rglob("*.py"),
           *ROOT.joinpath("launch").glob("*.py")]
#: pip distribution -> module it is imported as
PIP_MODULES = {"numpy": "numpy", "scipy": "scipy", "numba": "numba", "filterpy": "filterpy", "pyyaml": "yaml",
               "rosbags": "rosbags", "mcap": "mcap", "mcap-ros2-support": "mcap_ros2", "tqdm": "tqdm",
               "matplotlib": "matplotlib", "threadpoolctl": "threadpoolctl", "h5py": "h5py", "dask": "dask",
               "distributed": "distributed", "pyarrow": "pyarrow"}
#: Imports that are optional by design (guarded; the feature says how to install them).
OPTIONAL = {"ross"}  # diagnosis/ross_cases.py: the ROSS cross-check of `bench diagnosis`


def _package_xml():
    text = ROOT.joinpath("package.xml").read_text()
    deps = {e.text for e in ET.fromstring(text).findall("exec_depend")}
    return text, deps


def _install_requires() -> list[str]:
    tree = ast.parse(ROOT.joinpath("setup.py").read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.keyword) and node.arg == "install_requires":
            return [re.split(r"[<>=!~ \[]", ast.literal_eval(e))[0].lower() for e in node.value.elts]
    raise AssertionError("setup.py has no install_requires")


def _imported_top_levels() -> set[str]:
    names = set()
    for path in SOURCES:
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                names |= {a.name.split(".")[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names.add(node.module.split(".")[0])
    return names


def test_every_imported_ros_package_is_an_exec_depend():
    """Every top-level import that is neither the standard library, this package, nor a pip
    requirement (rclpy, rcl_interfaces, std_srvs, launch, launch_ros, ament_index_python...) is an
    <exec_depend>: a colcon/rosdep install would otherwise miss it (launch files need launch_ros)."""
    _, deps = _package_xml()
    own = {"rotor_estimator", "msg_adapters"}
    ros = _imported_top_levels() - set(sys.stdlib_module_names) - own - set(PIP_MODULES.values()) - OPTIONAL
    assert {"rclpy", "launch", "launch_ros", "ament_index_python"} <= ros
    assert sorted(ros - deps) == []


def test_every_message_package_named_in_the_code_is_an_exec_depend():
    """Message and service types named as strings ('sensor_msgs/msg/PointCloud2') come from
    packages listed in package.xml."""
    _, deps = _package_xml()
    named = set()
    for path in SOURCES:
        named |= set(re.findall(r"\b([a-z_]+_(?:msgs|srvs|interfaces))/(?:msg|srv)/", path.read_text()))
    assert {"sensor_msgs", "diagnostic_msgs"} <= named
    assert sorted(named - deps) == []


def test_every_pip_requirement_has_a_rosdep_key_or_the_documented_pip_step():
    """Each install_requires entry is either an exec_depend python3-<name> rosdep key or named in
    package.xml's pip install line; numba in particular is a rosdep key."""
    text, deps = _package_xml()
    pip_line = next(line for line in text.splitlines() if "pip install" in line)
    for dist in _install_requires():
        module = PIP_MODULES[dist]  # a new requirement must be added to PIP_MODULES too
        key = f"python3-{module}"
        assert key in deps or f'"{dist}' in pip_line, dist
    assert "python3-numba" in deps
