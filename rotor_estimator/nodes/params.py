"""ROS parameters declared in one place per node: a spec per parameter and its descriptor."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.parameter import Parameter


@dataclass(frozen=True)
class ParamSpec:
    """One ROS parameter: name, default (or a ``Parameter.Type`` for no default), description with
    unit, numeric range and allowed choices."""

    name: str
    default: Any
    description: str
    low: float | None = None
    high: float | None = None
    choices: tuple[str, ...] = ()


def descriptor(spec: ParamSpec) -> ParameterDescriptor:
    """Read-only descriptor with the description (and choices) and the numeric range, if any."""
    text = spec.description
    if spec.choices:
        text += f" (one of: {', '.join(spec.choices)})"
    d = ParameterDescriptor(description=text, read_only=True)
    if isinstance(spec.default, bool) or isinstance(spec.default, (str, Parameter.Type)):
        return d
    if isinstance(spec.default, float):
        d.floating_point_range = [FloatingPointRange(from_value=float(spec.low), to_value=float(spec.high), step=0.0)]
    elif isinstance(spec.default, int):
        d.integer_range = [IntegerRange(from_value=int(spec.low), to_value=int(spec.high), step=1)]
    return d
