# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""ROS parameters declared in one place per node: a spec per parameter, its descriptor, the
declaration (with integer-for-double coercion and one-line errors) and the documented file."""
from __future__ import annotations

import json
import textwrap
from dataclasses import dataclass
from typing import Any

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.parameter import Parameter

from rotor_estimator.core.errors import ConfigError


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


def _type_of(spec: ParamSpec) -> Parameter.Type:
    if isinstance(spec.default, Parameter.Type):
        return spec.default
    return Parameter.Type.from_parameter_value(spec.default)


_TYPE_WORDS = {
    Parameter.Type.BOOL: "a boolean (true or false)", Parameter.Type.INTEGER: "an integer",
    Parameter.Type.DOUBLE: "a number", Parameter.Type.STRING: "a string",
    Parameter.Type.DOUBLE_ARRAY: "a list of numbers", Parameter.Type.INTEGER_ARRAY: "a list of integers",
    Parameter.Type.STRING_ARRAY: "a list of strings", Parameter.Type.BOOL_ARRAY: "a list of booleans",
    Parameter.Type.BYTE_ARRAY: "a list of bytes", Parameter.Type.NOT_SET: "nothing",
}


def _coerce_integer_override(node: Any, spec: ParamSpec) -> None:
    """``-p publish_rate_hz:=5`` (or ``publish_rate_hz: 5`` in a params file) reaches rclpy as an
    INTEGER, which a statically typed DOUBLE parameter refuses with a traceback: an integer (list)
    given for a double (list) is taken as that number. rclpy offers no public hook before
    declaration, so this edits the node's override table (``Node._parameter_overrides``, present
    from Foxy to Kilted); without it the type error is still reported in one line."""
    overrides = getattr(node, "_parameter_overrides", None)
    if not isinstance(overrides, dict) or spec.name not in overrides:
        return
    given = overrides[spec.name]
    want = _type_of(spec)
    if want == Parameter.Type.DOUBLE and given.type_ == Parameter.Type.INTEGER:
        overrides[spec.name] = Parameter(spec.name, Parameter.Type.DOUBLE, float(given.value))
    elif want == Parameter.Type.DOUBLE_ARRAY and given.type_ == Parameter.Type.INTEGER_ARRAY:
        overrides[spec.name] = Parameter(spec.name, Parameter.Type.DOUBLE_ARRAY, [float(v) for v in given.value])


def declare_parameters(node: Any, specs: tuple[ParamSpec, ...]) -> dict[str, Any]:
    """Declare every spec on ``node`` (read-only, with its range) and return ``{name: value}``
    (``None`` for a parameter without default left unset).

    An integer given for a double parameter is accepted as that number; a value of the wrong type
    or outside the range raises :class:`~rotor_estimator.core.errors.ConfigError` naming the parameter,
    what it expects and what it got (the node's ``main`` prints it as one line and exits 1)."""
    values: dict[str, Any] = {}
    for spec in specs:
        _coerce_integer_override(node, spec)
        try:
            node.declare_parameter(spec.name, spec.default, descriptor(spec))
        except InvalidParameterTypeException:
            given = node._parameter_overrides.get(spec.name) if hasattr(node, "_parameter_overrides") else None
            got = f", got {_TYPE_WORDS.get(given.type_, given.type_.name.lower())} {given.value!r}" if given else ""
            raise ConfigError(f"parameter {spec.name}: expected {_TYPE_WORDS.get(_type_of(spec), 'another type')}"
                              f"{got} ({spec.description})") from None
        except InvalidParameterValueException:
            given = node._parameter_overrides.get(spec.name) if hasattr(node, "_parameter_overrides") else None
            got = f", got {given.value!r}" if given is not None else ""
            span = f"from {spec.low:g} to {spec.high:g}" if spec.low is not None else "a valid value"
            raise ConfigError(f"parameter {spec.name}: must be {span}{got} ({spec.description})") from None
        p = node.get_parameter_or(spec.name, None)
        values[spec.name] = None if p is None or p.type_ == Parameter.Type.NOT_SET else p.value
    return values


def warn_if_numba_missing(logger: Any) -> bool:
    """Log a warning when numba cannot be imported (the filter then runs as plain Python, far slower
    than real time at 20 kHz); True if it warned. Call once at node start."""
    from rotor_estimator.core import jit as _jit

    if _jit.HAVE_NUMBA:
        return False
    logger.warning("numba is not installed: the EKF kernels run as plain Python, far slower than real time "
                   "at 20 kHz. Install it (rosdep key python3-numba, or pip install numba) and restart")
    return True


def parameters_yaml(node_name: str, specs: tuple[ParamSpec, ...], header: str) -> str:
    """A ``--params-file`` documenting every parameter: description, unit, range and default
    (robot_localization style). Generated from the specs, so it cannot disagree with them.

    Keyed ``/**:`` (any node name, any namespace), so the same file works for a renamed or
    namespaced node (``-r __node:=...``, ``-r __ns:=...``, a launch file's ``name=``/``namespace=``);
    ``node_name`` appears in a comment."""
    lines = [f"# {h}" if h else "#" for h in header.splitlines()]
    lines += [f"# Keyed /** (every node name and namespace): works for {node_name} renamed or namespaced.",
              "/**:", "  ros__parameters:"]
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
