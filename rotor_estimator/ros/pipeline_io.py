# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Messages <-> :class:`~rotor_estimator.core.pipeline.EstimatorPipeline`, shared by the node and replay.

No rclpy import here: the same functions run on rclpy messages (live node) and on
rosbags messages (``rotor-estimator replay``), through :mod:`msg_adapters`.
"""
from __future__ import annotations

import math
from typing import Any

import msg_adapters as ma
from msg_adapters import InputTopics

from rotor_estimator.core.errors import InputError
from rotor_estimator.core.pipeline import EstimatorPipeline, Output, PipelineStatus

#: Input streams in the pipeline's vocabulary, keyed by :class:`InputTopics` field.
STREAMS: tuple[str, ...] = ("probe1", "probe2", "keyphasor", "impact")


def feed_message(pipeline: EstimatorPipeline, stream: str, msg: Any, arrival_ns: int | None = None) -> bool:
    """Decode ``msg`` of input ``stream`` and hand it to ``pipeline``; True if used.

    A message of the wrong type or layout is counted (``pipeline.reject_message``) and
    dropped; it never raises for bad input."""
    try:
        if stream in ("probe1", "probe2"):
            stamps, xy = ma.probe_block_from_msg(msg)
            pipeline.on_probe_block(1 if stream == "probe1" else 2, stamps, xy, arrival_ns)
        elif stream == "keyphasor":
            pipeline.on_pulse(ma.pulse_stamp_from_msg(msg), arrival_ns)
        elif stream == "impact":
            stamps, f = ma.impact_block_from_msg(msg)
            pipeline.on_impact_block(stamps, f)
        else:
            raise ValueError(f"unknown input stream {stream!r}; expected one of {STREAMS}")
    except InputError as exc:
        reason = "wrong_type" if "expected a message of type" in str(exc) else "undecodable"
        pipeline.reject_message(stream, reason)
        return False
    except (AttributeError, TypeError, ValueError) as exc:
        if isinstance(exc, ValueError) and str(exc).startswith("unknown input stream"):
            raise
        pipeline.reject_message(stream, "undecodable")
        return False
    return True


def stream_by_topic(topics: InputTopics) -> dict[str, str]:
    """``{topic name: stream}`` for the input topics."""
    return {getattr(topics, s): s for s in STREAMS}


def diagnostic_record(d: PipelineStatus, hardware_id: str = "", name: str = "rotor_estimator: bearing coefficients"
                      ) -> ma.DiagnosticRecord:
    """A pipeline health record as one ``DiagnosticStatus``."""
    return ma.DiagnosticRecord(name=name, level=d.level, message=d.message, hardware_id=hardware_id,
                               values=d.key_values())


def output_messages(factory: ma.MessageFactory, out: Output, namespace: str = ma.DEFAULT_NAMESPACE, *,
                    hardware_id: str = "", with_diagnostics: bool = True) -> list[tuple[str, Any]]:
    """``(absolute topic, message)`` pairs for one output, all stamped ``out.stamp_ns``."""
    t = out.stamp_ns
    msgs = [
        (ma.output_topic(ma.COEFFICIENTS_TOPIC, namespace), ma.coefficients_to_msg(factory, t, out.coefficients,
                                                                                  out.std)),
        (ma.output_topic(ma.COVARIANCE_TOPIC, namespace), ma.covariance_to_msg(factory, t, out.covariance)),
        (ma.output_topic(ma.INNOVATION_TOPIC, namespace), ma.innovation_to_msg(factory, t, out.innovation_m,
                                                                              out.innovation_std_m)),
        (ma.output_topic(ma.NIS_TOPIC, namespace), ma.nis_to_msg(factory, t, out.nis, out.nis_window_mean,
                                                                float(out.nis_dof))),
        (ma.output_topic(ma.SHAFT_TOPIC, namespace), ma.shaft_to_msg(factory, t, out.shaft_speed_rad_s,
                                                                    out.shaft_angle_rad)),
    ]
    if out.identifiability is not None:
        ident = out.identifiability.entries
        msgs.append((ma.output_topic(ma.IDENTIFIABILITY_TOPIC, namespace), ma.identifiability_to_msg(
            factory, t, [math.nan if e.value_for_display is None else e.estimate for e in ident],
            [e.predicted_std for e in ident], [e.status for e in ident])))
    if with_diagnostics:
        msgs.append((ma.DIAGNOSTICS_TOPIC,
                     ma.diagnostics_to_msg(factory, t, [diagnostic_record(out.diagnostics, hardware_id)])))
    return msgs
