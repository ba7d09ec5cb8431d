# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Default topic names of the estimator's interface (all configurable)."""
from __future__ import annotations

from dataclasses import dataclass

#: Output topics, relative to the estimator node's namespace (default ``/rotor_estimator``).
COEFFICIENTS_TOPIC = "coefficients"
COVARIANCE_TOPIC = "coefficients/covariance"
INNOVATION_TOPIC = "innovation"
NIS_TOPIC = "nis"
SHAFT_TOPIC = "shaft"
IDENTIFIABILITY_TOPIC = "identifiability"
DIAGNOSTICS_TOPIC = "/diagnostics"
DEFAULT_NAMESPACE = "/rotor_estimator"


@dataclass(frozen=True)
class InputTopics:
    """Input topic names: two probe planes, keyphasor pulses, impact force."""

    probe1: str = "/rotor/probe1"
    probe2: str = "/rotor/probe2"
    keyphasor: str = "/rotor/keyphasor"
    impact: str = "/rotor/impact"


DEFAULT_INPUT_TOPICS = InputTopics()


def output_topic(name: str, namespace: str = DEFAULT_NAMESPACE) -> str:
    """Absolute topic name of an output (``coefficients`` -> ``/rotor_estimator/coefficients``)."""
    if name.startswith("/"):
        return name
    return f"{namespace.rstrip('/')}/{name}"
