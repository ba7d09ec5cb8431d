# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The launch files start real entry points with parameters the nodes declare, of the declared
types (launch/launch_ros are replaced by recording stand-ins: they are not pip-installable)."""
from __future__ import annotations

import importlib.util
import re
import sys
import types
from pathlib import Path

import pytest

pytest.importorskip("rclpy")

from rclpy.parameter import Parameter  # noqa: E402

from rotor_estimator.ros import estimator_node, simulator_node, virtual_sensing_node  # noqa: E402

ROOT = Path(__file__).resolve().parents[3]
SPECS = {"estimator_node": estimator_node.PARAMETERS, "simulator_node": simulator_node.PARAMETERS,
         "virtual_sensing_node": virtual_sensing_node.PARAMETERS}


class _Recorded:
    def __init__(self, *args, **kwargs):
        self.args, self.kwargs = args, kwargs


class LaunchConfiguration(_Recorded):
    pass


def _load(monkeypatch, name: str):
    mods = {
        "launch": {"LaunchDescription": lambda entities: list(entities)},
        "launch.actions": {"DeclareLaunchArgument": type("DeclareLaunchArgument", (_Recorded,), {})},
        "launch.substitutions": {"LaunchConfiguration": LaunchConfiguration,
                                 "PythonExpression": type("PythonExpression", (_Recorded,), {})},
        "launch.conditions": {"IfCondition": _Recorded, "UnlessCondition": _Recorded},
        "launch_ros": {},
        "launch_ros.actions": {"Node": type("Node", (_Recorded,), {})},
        "ament_index_python": {},
        "ament_index_python.packages": {"get_package_share_directory": lambda pkg: f"/share/{pkg}"},
    }
    for mod, attrs in mods.items():
        monkeypatch.setitem(sys.modules, mod, types.SimpleNamespace(**attrs))
    spec = importlib.util.spec_from_file_location(name, ROOT / "launch" / name)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.generate_launch_description()


def _entry_points() -> set[str]:
    text = (ROOT / "setup.py").read_text()
    return set(re.findall(r'"(\w+) = rotor_estimator\.ros\.\w+:main"', text))


@pytest.mark.parametrize("launch_file", sorted(p.name for p in (ROOT / "launch").glob("*.launch.py")))
def test_launch_nodes_use_entry_points_and_declared_parameters_of_the_right_type(monkeypatch, launch_file):
    """Every Node is an installed node entry point; every inline parameter is declared by that node
    with a value of the declared type (an int is allowed for a double: declare_parameters takes it);
    a params_file argument defaults to the shipped config/estimator.yaml, keyed /** so the node's
    name or namespace in the launch file does not matter."""
    entities = _load(monkeypatch, launch_file)
    nodes = [e for e in entities if type(e).__name__ == "Node"]
    args = {e.args[0]: e.kwargs for e in entities if type(e).__name__ == "DeclareLaunchArgument"}
    assert nodes
    for node in nodes:
        exe = node.kwargs["executable"]
        assert node.kwargs["package"] == "rotor_estimator" and exe in _entry_points()
        declared = {s.name: s for s in SPECS[exe]}
        for params in node.kwargs.get("parameters", []):
            if isinstance(params, LaunchConfiguration):
                assert params.args[0] == "params_file"
                assert args["params_file"]["default_value"] == "/share/rotor_estimator/config/estimator.yaml"
                assert (ROOT / "config" / "estimator.yaml").read_text().count("\n/**:\n") == 1
                continue
            for name, value in params.items():
                assert name in declared, f"{launch_file}: {exe} declares no parameter {name!r}"
                if isinstance(value, LaunchConfiguration):
                    continue
                want = Parameter.Type.from_parameter_value(declared[name].default)
                got = Parameter.Type.from_parameter_value(value)
                assert got == want or (want, got) == (Parameter.Type.DOUBLE, Parameter.Type.INTEGER), name
