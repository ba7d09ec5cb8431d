"""The documented parameters file agrees with the node's declared parameters (nodes.params)."""
from __future__ import annotations

from pathlib import Path

import pytest
import yaml

pytest.importorskip("rclpy")

from rotor_estimator.nodes.estimator_node import PARAMETERS, parameters_file  # noqa: E402

CONFIG = Path(__file__).resolve().parents[3] / "config" / "estimator.yaml"


def test_committed_parameters_file_is_the_generated_one():
    """config/estimator.yaml is generated from PARAMETERS: a changed default, range or
    description cannot leave the documentation stale (it once said shaft_wait_s 0.2 for 0.5)."""
    assert CONFIG.read_text() == parameters_file(), (
        "config/estimator.yaml is stale; regenerate it with the command in its header")


def test_every_value_is_the_declared_default_within_its_range():
    """Loading the file gives each parameter its declared default, inside its declared range;
    parameters without a default appear only as a commented example of the right length."""
    values = yaml.safe_load(CONFIG.read_text())["rotor_estimator"]["ros__parameters"]
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
