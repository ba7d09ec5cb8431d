"""ROS parameters declared in one place per node: a spec per parameter and its descriptor."""
from __future__ import annotations

import json
import textwrap
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
    example: tuple[float, ...] = ()          # shown (commented out) for a parameter without a default


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


def parameters_yaml(node_name: str, specs: tuple[ParamSpec, ...], header: str) -> str:
    """A ``--params-file`` documenting every parameter: description, unit, range and default
    (robot_localization style). Generated from the specs, so it cannot disagree with them."""
    lines = [f"# {h}" if h else "#" for h in header.splitlines()]
    lines += [f"{node_name}:", "  ros__parameters:"]
    for spec in specs:
        text = spec.description
        if spec.choices:
            text += f". One of: {', '.join(spec.choices)}"
        if spec.low is not None and spec.high is not None:
            text += f". Range [{spec.low:g}, {spec.high:g}]"
        lines += ["", *textwrap.wrap(text + ".", width=104, initial_indent="    # ", subsequent_indent="    # ",
                                     break_on_hyphens=False)]
        if isinstance(spec.default, Parameter.Type):
            example = json.dumps(list(spec.example))
            lines += ["    # Default: unset (the rig file's values). Example:", f"    # {spec.name}: {example}"]
        else:
            value = json.dumps(spec.default)
            lines += [f"    # Default: {value}", f"    {spec.name}: {value}"]
    return "\n".join(lines) + "\n"
