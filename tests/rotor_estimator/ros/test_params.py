# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The documented parameters file agrees with the node's declared parameters (nodes.params); it
works for a renamed or namespaced node; integers for doubles are accepted and bad values are one line."""
from __future__ import annotations

from pathlib import Path

import pytest
import yaml

pytest.importorskip("rclpy")

from rotor_estimator.ros.estimator_node import PARAMETERS, parameters_file  # noqa: E402

CONFIG = Path(__file__).resolve().parents[3] / "config" / "estimator.yaml"


def test_committed_parameters_file_is_the_generated_one():
    """config/estimator.yaml is generated from PARAMETERS: a changed default, range or
    description cannot leave the documentation stale (it once said shaft_wait_s 0.2 for 0.5)."""
    assert CONFIG.read_text() == parameters_file(), (
        "config/estimator.yaml is stale; regenerate it with the command in its header")


def test_every_value_is_the_declared_default_within_its_range():
    """Loading the file gives each parameter its declared default, inside its declared range;
    parameters without a default appear only as a commented example of the right length."""
    values = yaml.safe_load(CONFIG.read_text())["/**"]["ros__parameters"]
    text = CONFIG.read_text()
    for spec in PARAMETERS:
        if spec.example:
            assert spec.name not in values and f"# {spec.name}: [" in text
            assert len(spec.example) == 8
            continue
        assert values[spec.name] == spec.default, spec.name
        if spec.low is not None:
            assert spec.low <= values[spec.name] <= spec.high, spec.name
        if spec.choices:
            assert values[spec.name] in spec.choices, spec.name
    assert set(values) == {s.name for s in PARAMETERS if not s.example}


# ------------------------------------------------------------------ deployment: real rclpy nodes
import os  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402

import rclpy  # noqa: E402
from rclpy.context import Context  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402

from rotor_estimator.core.errors import ConfigError  # noqa: E402
from rotor_estimator.ros.estimator_node import EstimatorNode  # noqa: E402

from live_helpers import random_domain_id  # noqa: E402


@pytest.fixture
def ctx():
    context = Context()
    rclpy.init(context=context, domain_id=random_domain_id())
    yield context
    rclpy.try_shutdown(context=context)


def _estimator(ctx, *ros_args):
    node = EstimatorNode(context=ctx, cli_args=["--ros-args", *ros_args])
    try:
        return node.get_fully_qualified_name(), dict(node.values), node.get_parameter("publish_rate_hz")
    finally:
        node.destroy_node()


def test_integer_for_a_double_parameter_is_taken_as_that_number(ctx):
    """`-p publish_rate_hz:=5` (rclpy reads 5 as INTEGER; the parameter is DOUBLE) used to raise
    InvalidParameterTypeException out of the constructor: it is now 5.0, typed DOUBLE, and so is
    an integer list for a double-list parameter."""
    _, values, param = _estimator(ctx, "-p", "publish_rate_hz:=5", "-p",
                                  "initial_coefficients:=[300000, 300000, -300000, 300000, 900, 0, 0, 900]")
    assert values["publish_rate_hz"] == 5.0 and param.type_ == Parameter.Type.DOUBLE
    assert values["initial_coefficients"] == [3e5, 3e5, -3e5, 3e5, 900.0, 0.0, 0.0, 900.0]


@pytest.mark.parametrize("arg, message", [
    ("publish_rate_hz:=0", r"parameter publish_rate_hz: must be from 0.01 to 10000, got 0.0 \(Estimate outputs"),
    ("publish_rate_hz:=fast", r"parameter publish_rate_hz: expected a number, got a string 'fast'"),
    ("input_queue_depth:=2.5", r"parameter input_queue_depth: expected an integer, got a number 2.5"),
    ("input_queue_depth:=5", r"parameter input_queue_depth: must be from 10 to 1e\+06, got 5"),
])
def test_bad_parameter_is_one_config_error_naming_it(ctx, arg, message):
    """Out-of-range and wrong-type overrides raise a ConfigError naming the parameter, the range or
    type expected and the value given (not an rclpy exception)."""
    with pytest.raises(ConfigError, match=message) as info:
        _estimator(ctx, "-p", arg)
    assert "\n" not in str(info.value)


def test_node_main_prints_one_line_and_exits_1_on_a_bad_parameter():
    """`estimator_node --ros-args -p publish_rate_hz:=0` (the real entry point) prints one error line
    and exits 1, no traceback."""
    env = {**os.environ, "ROS_DOMAIN_ID": str(random_domain_id()), "OMP_NUM_THREADS": "1"}
    proc = subprocess.run([sys.executable, "-m", "rotor_estimator.ros.estimator_node", "--ros-args", "-p",
                           "publish_rate_hz:=0"], capture_output=True, text=True, timeout=120, env=env)
    out = (proc.stdout + proc.stderr).strip()
    assert proc.returncode == 1, out
    assert out.splitlines() == ["estimator_node: error: parameter publish_rate_hz: must be from 0.01 to 10000, "
                                "got 0.0 (Estimate outputs per second of sample time, Hz)"]


def test_shipped_params_file_applies_to_a_renamed_namespaced_node(ctx, tmp_path):
    """config/estimator.yaml (keyed /**) sets the parameters of the node run as /rig2/other
    (`-r __node:=other -r __ns:=/rig2`); a file keyed by the node name would be ignored there.
    An integer written for a double in the file is accepted too."""
    text = CONFIG.read_text()
    assert "    publish_rate_hz: 20.0\n" in text and "    diagnostics_rate_hz: 1.0\n" in text
    edited = tmp_path / "estimator.yaml"
    edited.write_text(text.replace("    publish_rate_hz: 20.0\n", "    publish_rate_hz: 7.5\n")
                      .replace("    diagnostics_rate_hz: 1.0\n", "    diagnostics_rate_hz: 2\n"))
    name, values, _ = _estimator(ctx, "-r", "__node:=other", "-r", "__ns:=/rig2", "--params-file", str(edited))
    assert name == "/rig2/other"
    assert values["publish_rate_hz"] == 7.5 and values["diagnostics_rate_hz"] == 2.0


def test_simulator_node_accepts_integers_for_doubles_and_refuses_an_integer_for_a_bool(ctx):
    """simulator_node: `rate_factor:=2` is 2.0; `repeat:=1` is refused naming the boolean."""
    from rotor_estimator.ros.simulator_node import SimulatorNode

    node = SimulatorNode(context=ctx, cli_args=["--ros-args", "-p", "rate_factor:=2", "-p", "duration_s:=0.05"])
    try:
        assert node.rate_factor == 2.0 and node.get_parameter("rate_factor").type_ == Parameter.Type.DOUBLE
    finally:
        node.destroy_node()
    with pytest.raises(ConfigError, match=r"parameter repeat: expected a boolean \(true or false\), got an "
                                          r"integer 1"):
        SimulatorNode(context=ctx, cli_args=["--ros-args", "-p", "repeat:=1"])


def test_numba_missing_is_warned_at_estimator_start(ctx, monkeypatch):
    """With numba unavailable (HAVE_NUMBA False) the estimator node logs a warning naming numba and
    how to install it; with numba, nothing."""
    from rotor_estimator.core import jit as _jit
    from rotor_estimator.ros import params

    class Logger:
        def __init__(self):
            self.warnings = []

        def warning(self, text):
            self.warnings.append(text)

        def __getattr__(self, name):  # info, debug, error: ignored
            return lambda *a, **k: None

    log = Logger()
    monkeypatch.setattr(_jit, "HAVE_NUMBA", True)
    assert params.warn_if_numba_missing(log) is False and log.warnings == []
    monkeypatch.setattr(_jit, "HAVE_NUMBA", False)
    monkeypatch.setattr(EstimatorNode, "get_logger", lambda self: log)
    EstimatorNode(context=ctx).destroy_node()
    assert len(log.warnings) == 1
    assert "numba is not installed" in log.warnings[0] and "python3-numba" in log.warnings[0]
