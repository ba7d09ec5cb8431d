# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""``virtual_sensing_node``: live virtual sensing (thin rclpy shell).

Declares its parameters (all in :data:`PARAMETERS`, with unit and default), subscribes to
one topic per sensor of the rotor description (``<sensor_topic_prefix>/<sensor name>``,
``sensor_msgs/msg/PointCloud2`` blocks, see :mod:`msg_adapters.stations`) and to the
keyphasor (``sensor_msgs/msg/TimeReference``), and runs
:class:`~rotor_estimator.virtual_sensing.stream.VirtualSensingPipeline` (the same alignment and
per-sample filter step as ``rotor-estimator virtual-sensing``). Publishes:

* ``~/stations/<station>`` (``sensor_msgs/msg/JointState``): ``x_m y_m vx_m_s vy_m_s
  ax_m_s2 ay_m_s2 corr_xy``, position = estimate, velocity = standard deviation,
  ``header.stamp`` = the sample the estimate refers to;
* ``/diagnostics``: counts (late, missing, duplicate samples per sensor, gated updates,
  samples without shaft angle) and the coverage so far of the innovation's 95% region.

Messages that cannot be decoded are counted (``undecodable_<sensor>``), never raised.
"""
from __future__ import annotations

import re
import threading
from typing import Any, Mapping

from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import HistoryPolicy, QoSProfile, qos_profile_sensor_data

import msg_adapters as ma

from rotor_estimator.ros.params import ParamSpec, declare_parameters
from rotor_estimator.ros.spin import run_node
from rotor_estimator.core.errors import ConfigError, InputError
from rotor_estimator.core.flexible import build_state_space, load_rotor_description
from rotor_estimator.virtual_sensing.estimator import FILTERS, VirtualSensingConfig, resolve_stations
from rotor_estimator.virtual_sensing.stream import PipelineOptions, VirtualSensingPipeline

__all__ = ["PARAMETERS", "ParamSpec", "pipeline_from_parameters", "VirtualSensingNode", "main"]


#: Every parameter of the node, in one place.
PARAMETERS: tuple[ParamSpec, ...] = (
    ParamSpec("rotor_file", "three_probe_rig", "Rotor description YAML (path, or a bundled name such as "
              "three_probe_rig / neisi_2022_like)"),
    ParamSpec("n_modes", -1, "Modes kept by the reduction; -1: the rotor file's model.n_modes, 0: all", -1, 10_000),
    ParamSpec("filter", "kf", "Filter: kf (exact on the linear model), ekf or ukf", choices=FILTERS),
    ParamSpec("ukf_alpha", 1e-3, "UKF sigma-point spread alpha (0, 1]", 1e-9, 1.0),
    ParamSpec("ukf_beta", 2.0, "UKF beta (2 is optimal for Gaussians)", 0.0, 100.0),
    ParamSpec("ukf_kappa", 0.0, "UKF kappa", -1e6, 1e6),
    ParamSpec("stations", Parameter.Type.STRING_ARRAY, "Stations to estimate: a station or sensor name of the "
              "rotor file, or name=axial_position_m; unset or empty: the rotor file's stations"),
    ParamSpec("confidence", 0.95, "Confidence of intervals and of the innovation coverage check", 0.5, 0.9999),
    ParamSpec("gate_probability", 0.0, "Innovation gate: skip updates with NIS above chi2.ppf(p, channels); "
              "0: off", 0.0, 0.999999999),
    ParamSpec("publish_rate_hz", 0.0, "Station estimates per second of sample time, Hz; 0: every sample "
              "(every sample is filtered regardless)", 0.0, 1e6),
    ParamSpec("sensor_topic_prefix", "/rotor", "Sensor topics are <prefix>/<sensor name> (PointCloud2 blocks)"),
    ParamSpec("keyphasor_topic", "/rotor/keyphasor", "Keyphasor pulses (TimeReference); empty: no keyphasor, "
              "shaft angle = rotor speed x time since the first sample"),
    ParamSpec("reorder_window_s", 0.2, "How long a sample waits for missing sensors (sample time), s", 0.0, 60.0),
    ParamSpec("match_tolerance_fraction", 0.25, "Stamps of different sensors within this fraction of a sample "
              "period are one sample", 0.0, 0.49),
    ParamSpec("max_gap_s", 0.5, "A gap without samples longer than this restarts the filter from the prior, s",
              0.0, 3600.0),
    ParamSpec("idle_release_s", 0.25, "No sensor message for this long (wall time): release the samples still "
              "waiting for other sensors, s", 0.001, 60.0),
    ParamSpec("diagnostics_rate_hz", 1.0, "/diagnostics messages per second of wall time, Hz", 0.01, 100.0),
    ParamSpec("input_queue_depth", 1000, "Subscription queue depth per sensor (messages)", 1, 1_000_000),
    ParamSpec("hardware_id", "", "DiagnosticStatus hardware_id; empty: the rotor name"),
)

_TOKEN = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")


def pipeline_from_parameters(values: Mapping[str, Any]) -> VirtualSensingPipeline:
    """Build the pipeline from parameter values (missing names take the defaults).

    Raises :class:`~rotor_estimator.core.errors.ConfigError` naming the bad parameter."""
    v = {s.name: s.default for s in PARAMETERS}
    v.update({k: val for k, val in values.items() if val is not None})
    for spec in PARAMETERS:
        if spec.choices and v[spec.name] not in spec.choices:
            raise ConfigError(f"parameter {spec.name}: must be one of {spec.choices}, got {v[spec.name]!r}")
    rotor = load_rotor_description(v["rotor_file"])
    n_modes = int(v["n_modes"])
    ss = build_state_space(rotor, n_modes=None if n_modes < 0 else n_modes)
    gate = float(v["gate_probability"])
    config = VirtualSensingConfig(filter=v["filter"], ukf_alpha=float(v["ukf_alpha"]), ukf_beta=float(v["ukf_beta"]),
                                  ukf_kappa=float(v["ukf_kappa"]), confidence=float(v["confidence"]),
                                  gate_probability=gate if gate > 0 else None)
    names = v["stations"]
    names = [] if isinstance(names, Parameter.Type) or names is None else list(names)
    try:
        stations = resolve_stations(ss, names)
    except InputError as exc:
        raise ConfigError(f"parameter stations: {exc}") from None
    for name, _ in stations + [(s.name, 0.0) for s in rotor.sensors]:
        if not _TOKEN.match(name):
            raise ConfigError(f"station/sensor name {name!r} cannot be a topic name; use letters, digits and _")
    options = PipelineOptions(reorder_window_s=float(v["reorder_window_s"]),
                              match_tolerance_fraction=float(v["match_tolerance_fraction"]),
                              publish_rate_hz=float(v["publish_rate_hz"]), max_gap_s=float(v["max_gap_s"]),
                              use_keyphasor=bool(v["keyphasor_topic"]))
    return VirtualSensingPipeline(ss, config, stations, options)


class VirtualSensingNode(Node):
    """Virtual sensing as a ROS 2 node; all logic is in :attr:`pipeline`."""

    def __init__(self, node_name: str = "virtual_sensing", **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        values = declare_parameters(self, PARAMETERS)  # ints for doubles accepted; bad values: one line
        self.values = values
        self.pipeline = pipeline_from_parameters(values)
        rotor = self.pipeline.ss.rotor
        self.hardware_id = values["hardware_id"] or rotor.name
        self.lock = threading.Lock()
        self._factory = ma.RclpyFactory()
        qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=int(values["input_queue_depth"]),
                         reliability=qos_profile_sensor_data.reliability,
                         durability=qos_profile_sensor_data.durability)
        cloud = self._factory.message_class("sensor_msgs/msg/PointCloud2")
        prefix = values["sensor_topic_prefix"] or ma.SENSOR_TOPIC_PREFIX
        self.undecodable: dict[str, int] = {}
        for s in rotor.sensors:
            self.undecodable[s.name] = 0
            self.create_subscription(cloud, ma.sensor_topic(s.name, prefix),
                                     lambda msg, name=s.name, kind=s.kind: self._on_block(name, kind, msg), qos)
        if values["keyphasor_topic"]:
            self.undecodable["keyphasor"] = 0
            self.create_subscription(self._factory.message_class("sensor_msgs/msg/TimeReference"),
                                     values["keyphasor_topic"], self._on_pulse, QoSProfile(depth=100))
        joint = self._factory.message_class("sensor_msgs/msg/JointState")
        self._pubs = {name: self.create_publisher(joint, f"~/{ma.STATIONS_TOPIC}/{name}", 100)
                      for name, _ in self.pipeline.stations}
        self._diag_pub = self.create_publisher(self._factory.message_class("diagnostic_msgs/msg/DiagnosticArray"),
                                               ma.DIAGNOSTICS_TOPIC, 10)
        self._idle_ns = int(float(values["idle_release_s"]) * 1e9)
        self._last_input_ns = 0
        self.outputs_published = 0
        self.create_timer(min(0.05, float(values["idle_release_s"]) / 2), self._on_tick)
        self.create_timer(1.0 / float(values["diagnostics_rate_hz"]), self._publish_diagnostics)
        self.get_logger().info(
            f"virtual sensing on {rotor.name} ({self.pipeline.ss.n_states} states, filter "
            f"{self.pipeline.config.filter}) from {[ma.sensor_topic(s.name, prefix) for s in rotor.sensors]}; "
            f"stations {[n for n, _ in self.pipeline.stations]} under {self.get_fully_qualified_name()}/stations/")

    # ----------------------------------------------------------------- callbacks
    def _now_ns(self) -> int:
        return self.get_clock().now().nanoseconds

    def _on_block(self, sensor: str, kind: str, msg: Any) -> None:
        try:
            stamps, values = ma.sensor_block_from_msg(msg, kind)
        except (InputError, AttributeError, TypeError, ValueError):
            self.undecodable[sensor] += 1
            return
        self._last_input_ns = self._now_ns()
        with self.lock:
            self.pipeline.on_block(sensor, stamps, values)
            outputs = self.pipeline.process()
        self._publish(outputs)

    def _on_pulse(self, msg: Any) -> None:
        try:
            stamp = ma.pulse_stamp_from_msg(msg)
        except (InputError, AttributeError, TypeError, ValueError):
            self.undecodable["keyphasor"] += 1
            return
        self._last_input_ns = self._now_ns()          # pulses still arriving: the input is not idle
        with self.lock:
            self.pipeline.on_pulse(stamp)

    def _on_tick(self) -> None:
        """When the input has been idle, release the samples still waiting for a sensor."""
        if not self._last_input_ns or self._now_ns() - self._last_input_ns < self._idle_ns:
            return
        with self.lock:
            if not self.pipeline.aligner.pending:
                return
            outputs = self.pipeline.process(flush=True)
        self._publish(outputs)

    def _publish(self, outputs: list) -> None:
        names = [n for n, _ in self.pipeline.stations]
        for out in outputs:
            for i, name in enumerate(names):
                self._pubs[name].publish(ma.station_to_msg(self._factory, out.stamp_ns, name, out.mean[i],
                                                           out.std[i], out.disp_cov[i]))
            self.outputs_published += 1

    def diagnostic_record(self) -> ma.DiagnosticRecord:
        with self.lock:
            st = self.pipeline.status()
        values = dict(st.values)
        values.update({f"undecodable_{k}": str(v) for k, v in self.undecodable.items()})
        level, message = st.level, st.message
        bad = sum(self.undecodable.values())
        if bad:
            level, message = max(level, 1), f"{message}; {bad} undecodable messages"
        return ma.DiagnosticRecord(f"virtual_sensing: {self.pipeline.ss.rotor.name}", level, message,
                                   self.hardware_id, values)

    def _publish_diagnostics(self) -> None:
        record = self.diagnostic_record()
        last = self.pipeline.last_sample_stamp_ns
        stamp = last if last is not None else self._now_ns()
        self._diag_pub.publish(ma.diagnostics_to_msg(self._factory, stamp, [record]))


def main(args: list[str] | None = None) -> int:
    """``ros2 run rotor_estimator virtual_sensing_node [--ros-args -p rotor_file:=... -p filter:=ukf]``."""
    return run_node(VirtualSensingNode, "virtual_sensing_node", args)


if __name__ == "__main__":
    raise SystemExit(main())
