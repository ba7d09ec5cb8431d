# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Message adapters: ROS messages <-> plain arrays, for rclpy and rosbags message classes alike.

Decoders read fields by name and dispatch on the message type name, so the
same function accepts an rclpy message, a rosbags typestore dataclass or an
mcap_ros2 decoded message. Encoders take a :class:`MessageFactory`
(:class:`RclpyFactory` or :class:`TypestoreFactory`). Stamps are integer ns.
A message of the wrong type raises ``rotor_estimator.core.errors.InputError``.
"""
from msg_adapters._common import msg_typename, ns_to_sec_nanosec, stamp_to_ns
from msg_adapters.cloud import cloud_columns, cloud_from_columns
from msg_adapters.factory import (MessageFactory, RclpyFactory, TypestoreFactory, default_typestore, make_header,
                                  make_time)
from msg_adapters.inputs import (IMPACT_FIELDS, IMPACT_TYPES, PROBE_FIELDS, PROBE_TYPES, PULSE_TYPES,
                     impact_block_from_msg, impact_block_to_msg, impact_sample_to_msg, probe_block_from_msg,
                     probe_block_to_msg, probe_sample_to_msg, pulse_stamp_from_msg, pulse_to_msg)
from msg_adapters.outputs import (COVARIANCE_NAMES, IDENTIFIABILITY_STATUS, INNOVATION_NAMES, NIS_NAMES, SHAFT_NAMES,
                      Coefficients, Covariance, DiagnosticRecord, Diagnostics, Identifiability, Innovation, Nis,
                      Shaft, coefficients_from_msg, identifiability_from_msg, identifiability_to_msg,
                      coefficients_to_msg, covariance_from_msg, covariance_to_msg, diagnostics_from_msg,
                      diagnostics_to_msg, innovation_from_msg, innovation_to_msg, nis_from_msg, nis_to_msg,
                      shaft_from_msg, shaft_to_msg)
from msg_adapters.stations import (ACCEL_FIELDS, SENSOR_FIELDS, SENSOR_TOPIC_PREFIX, STATION_NAMES, STATIONS_TOPIC,
                       VIRTUAL_SENSING_NAMESPACE, StationState, sensor_block_from_msg, sensor_block_to_msg,
                       sensor_topic, station_from_msg, station_to_msg, station_topic)
from msg_adapters.topics import (COEFFICIENTS_TOPIC, COVARIANCE_TOPIC, DEFAULT_INPUT_TOPICS, DEFAULT_NAMESPACE,
                     DIAGNOSTICS_TOPIC, IDENTIFIABILITY_TOPIC, INNOVATION_TOPIC, NIS_TOPIC, SHAFT_TOPIC, InputTopics,
                     output_topic)

__all__ = [
    "COEFFICIENTS_TOPIC", "COVARIANCE_NAMES", "COVARIANCE_TOPIC", "DEFAULT_INPUT_TOPICS", "DEFAULT_NAMESPACE",
    "DIAGNOSTICS_TOPIC", "IMPACT_FIELDS", "IMPACT_TYPES", "INNOVATION_NAMES", "INNOVATION_TOPIC", "NIS_NAMES",
    "NIS_TOPIC", "PROBE_FIELDS", "PROBE_TYPES", "PULSE_TYPES", "SHAFT_NAMES", "SHAFT_TOPIC",
    "Coefficients", "Covariance", "DiagnosticRecord", "Diagnostics", "InputTopics", "Innovation",
    "MessageFactory", "Nis", "RclpyFactory", "Shaft", "TypestoreFactory",
    "cloud_columns", "cloud_from_columns", "coefficients_from_msg", "coefficients_to_msg",
    "covariance_from_msg", "covariance_to_msg", "default_typestore", "diagnostics_from_msg",
    "diagnostics_to_msg", "impact_block_from_msg", "impact_block_to_msg", "impact_sample_to_msg",
    "innovation_from_msg", "innovation_to_msg", "make_header", "make_time", "msg_typename",
    "nis_from_msg", "nis_to_msg", "ns_to_sec_nanosec", "output_topic", "probe_block_from_msg",
    "probe_block_to_msg", "probe_sample_to_msg", "pulse_stamp_from_msg", "pulse_to_msg",
    "shaft_from_msg", "shaft_to_msg", "stamp_to_ns",
    "IDENTIFIABILITY_STATUS", "IDENTIFIABILITY_TOPIC", "Identifiability", "identifiability_from_msg",
    "identifiability_to_msg",
    # virtual sensing (msg_adapters.stations)
    "ACCEL_FIELDS", "SENSOR_FIELDS", "SENSOR_TOPIC_PREFIX", "STATION_NAMES", "STATIONS_TOPIC",
    "VIRTUAL_SENSING_NAMESPACE", "StationState",
    "sensor_block_from_msg", "sensor_block_to_msg", "sensor_topic", "station_from_msg", "station_to_msg",
    "station_topic",
]
