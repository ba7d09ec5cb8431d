# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""``estimator_node``: the live bearing-coefficient estimator (thin rclpy shell).

Declares its parameters (all in :data:`PARAMETERS`, documented in ``config/estimator.yaml``),
subscribes to the probe, keyphasor and impact topics with sensor-data QoS, decodes with
:mod:`msg_adapters`, runs :class:`~rotor_estimator.core.pipeline.EstimatorPipeline` and publishes
its outputs stamped with the sample each refers to:

* ``~/coefficients``, ``~/coefficients/covariance``, ``~/innovation``, ``~/nis``, ``~/shaft``
  (``sensor_msgs/msg/JointState``) and ``/diagnostics`` (``diagnostic_msgs/msg/DiagnosticArray``);
* service ``~/reset`` (``std_srvs/srv/Trigger``): restart the estimation from the prior.

A message that cannot be decoded is counted and reported on ``/diagnostics``; a publisher of
a wrong type on an input topic is reported too (DDS never delivers its messages).
"""
from __future__ import annotations

import threading
from dataclasses import replace
from typing import Any, Mapping

import numpy as np
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import HistoryPolicy, QoSProfile, qos_profile_sensor_data

try:  # Iron and later
    from rclpy.event_handler import SubscriptionEventCallbacks as _SubscriptionEventCallbacks
except ImportError:  # Humble
    from rclpy.qos_event import SubscriptionEventCallbacks as _SubscriptionEventCallbacks

import msg_adapters as ma

from rotor_estimator.ros.params import ParamSpec, declare_parameters, parameters_yaml, warn_if_numba_missing
from rotor_estimator.ros.spin import run_node
from rotor_estimator.core.alignment import AlignmentConfig
from rotor_estimator.core.config import BearingCoefficients, RigFile, load_rig_file
from rotor_estimator.core.pipeline import LEVEL_ERROR, LEVEL_WARN, EstimatorPipeline, PipelineOptions
from rotor_estimator.core.tachometer import TachometerConfig, max_speed_for_rig
from rotor_estimator.ros.pipeline_io import diagnostic_record, feed_message, output_messages

_PC2 = "sensor_msgs/msg/PointCloud2"


_ARRAY = Parameter.Type.DOUBLE_ARRAY  # declared without a default: unset means "the rig file's value"

#: Every parameter of the node, in one place (defaults and units also in config/estimator.yaml).
PARAMETERS: tuple[ParamSpec, ...] = (
    ParamSpec("rig_file", "", "Rig YAML file (rig + estimator sections); empty: the bundled Miller & Howard seed rig"),
    ParamSpec("probe1_topic", "/rotor/probe1", "Probe plane 1 [xp1, yp1] (PointCloud2 x_m,y_m,t_offset_ns or "
              "PointStamped), m"),
    ParamSpec("probe2_topic", "/rotor/probe2", "Probe plane 2 [xp2, yp2], same types as probe1_topic, m"),
    ParamSpec("keyphasor_topic", "/rotor/keyphasor", "Once-per-revolution keyphasor pulses (TimeReference)"),
    ParamSpec("impact_topic", "/rotor/impact", "Impact hammer force [fx, fy] (WrenchStamped or PointCloud2 "
              "fx_n,fy_n,t_offset_ns), N"),
    ParamSpec("probe_message_type", "auto", "Probe message type; auto follows the publishers on the topic",
              choices=("auto", "sensor_msgs/msg/PointCloud2", "geometry_msgs/msg/PointStamped")),
    ParamSpec("impact_message_type", "auto", "Impact message type; auto follows the publishers on the topic",
              choices=("auto", "sensor_msgs/msg/PointCloud2", "geometry_msgs/msg/WrenchStamped")),
    ParamSpec("input_queue_depth", 2000, "Subscription queue depth (messages); 2000 holds 20 s of 200-sample "
              "blocks at 20 kHz", 10, 1_000_000),
    ParamSpec("publish_rate_hz", 20.0, "Estimate outputs per second of sample time, Hz", 0.01, 10_000.0),
    ParamSpec("diagnostics_rate_hz", 1.0, "/diagnostics messages per second of wall time, Hz", 0.01, 100.0),
    ParamSpec("idle_process_rate_hz", 20.0, "Wall-clock processing ticks (release samples when input stops), Hz",
              1.0, 1000.0),
    ParamSpec("reorder_window_s", 0.01, "How long samples wait for late or out-of-order arrivals, s", 0.0, 10.0),
    ParamSpec("match_tolerance_fraction", 0.25, "Plane-1/plane-2 stamps within this fraction of a sample period "
              "are one sample", 0.0, 0.49),
    ParamSpec("measurement_noise_std_m", -1.0, "Override sqrt(R) per probe channel, m; negative: rig file", -1.0,
              0.01),
    ParamSpec("innovation_gate_nis", -1.0, "Override the outlier gate on the NIS (4 dof); negative: rig file",
              -1.0, 1e9),
    ParamSpec("motion_process_noise_accel_m_s2", -1.0, "Override the motion process noise density, "
              "m/s^2/sqrt(Hz); negative: rig file", -1.0, 1e6),
    ParamSpec("initial_coefficients", _ARRAY, "Override r0: 8 values kxx kxy kyx kyy (N/m) cxx cxy cyx cyy "
              "(N*s/m); unset: rig file", example=(3.0e5, 3.0e5, -3.0e5, 3.0e5, 900.0, 0.0, 0.0, 900.0)),
    ParamSpec("initial_coefficient_std", _ARRAY, "Override sqrt(diag P0) of the 8 coefficients (SI); unset: "
              "rig file", example=(3.16e5, 3.16e5, 3.16e5, 3.16e5, 1000.0, 1000.0, 1000.0, 1000.0)),
    ParamSpec("coefficient_random_walk", _ARRAY, "Override Q_r as 8 std rates, SI/sqrt(s) (> 0 lets the estimate "
              "track slow changes); unset: rig file",
              example=(1.0e3, 1.0e3, 1.0e3, 1.0e3, 1.0, 1.0, 1.0, 1.0)),
    ParamSpec("tach_window_pulses", 8, "Keyphasor pulses in the shaft-angle fit", 2, 1000),
    ParamSpec("tach_fit_order", 2, "Shaft-angle fit order: 1 constant speed, 2 constant acceleration", 1, 2),
    ParamSpec("tach_stop_timeout_s", 1.0, "No pulse for this long means the shaft stopped, s", 0.001, 3600.0),
    ParamSpec("tach_min_speed_rad_s", 10.0, "Lowest valid shaft speed, rad/s", 0.0, 1e6),
    ParamSpec("tach_fit_history", 1024, "Shaft-angle fits kept (pulses), so samples delivered after many newer "
              "pulses still find theirs", 16, 100_000),
    ParamSpec("shaft_wait_s", 0.5, "Samples wait at most this long (sample time) for the next keyphasor pulse; "
              "while pulses still arrive (keyphasor delivered behind the probes), samples wait for them, s",
              0.0, 60.0),
    ParamSpec("idle_release_s", 0.25, "No probe message for this long (wall time): release the samples still "
              "waiting in the reorder window; no input at all for this long: decide everything pending, s",
              0.001, 60.0),
    ParamSpec("convergence_relative_std", 0.05, "Converged when std/|estimate| of kxx kyy cxx cyy is below "
              "this (and the NIS is consistent)", 1e-6, 10.0),
    ParamSpec("falling_behind_s", 0.5, "Input handled later than this (beyond the best seen) is reported as "
              "falling behind, s", 0.001, 3600.0),
    ParamSpec("max_gap_s", 0.02, "A stretch without usable samples longer than this restarts the motion "
              "states, s", 1e-6, 3600.0),
    ParamSpec("clock_jump_s", 1.0, "A probe block this much older than the newest stamp is a clock jump back, s",
              1e-3, 3600.0),
    ParamSpec("hardware_id", "", "DiagnosticStatus hardware_id; empty: the rig name"),
)

PARAMETERS_FILE_HEADER = """Parameters of estimator_node (rotor_estimator), robot_localization style: every
parameter with its unit and default. Load with:
  ros2 run rotor_estimator estimator_node --ros-args --params-file config/estimator.yaml
or through launch/estimator.launch.py. All parameters are read once at start (read-only).
Generated from estimator_node.PARAMETERS (tests check it): edit those, then run
  python -c "from rotor_estimator.ros.estimator_node import parameters_file; print(parameters_file(), end='')" \\
    > config/estimator.yaml"""


def parameters_file() -> str:
    """The text of ``config/estimator.yaml``: every parameter with its description, range and default."""
    return parameters_yaml("rotor_estimator", PARAMETERS, PARAMETERS_FILE_HEADER)


def pipeline_from_parameters(values: Mapping[str, Any]) -> tuple[EstimatorPipeline, RigFile, ma.InputTopics]:
    """Build the pipeline from parameter values (missing names take :data:`PARAMETERS` defaults).

    Raises :class:`~rotor_estimator.core.errors.ConfigError` naming the bad parameter."""
    from rotor_estimator.core.errors import ConfigError

    v = {s.name: s.default for s in PARAMETERS}
    v.update({k: val for k, val in values.items() if val is not None})
    for spec in PARAMETERS:
        if spec.choices and v[spec.name] not in spec.choices:
            raise ConfigError(f"parameter {spec.name}: must be one of {spec.choices}, got {v[spec.name]!r}")
    rig_file = load_rig_file(v["rig_file"] or None)
    est = rig_file.estimator
    changes: dict[str, Any] = {}
    for name in ("measurement_noise_std_m", "innovation_gate_nis", "motion_process_noise_accel_m_s2"):
        if float(v[name]) >= 0:
            changes[name] = float(v[name])
    for name in ("initial_coefficients", "initial_coefficient_std", "coefficient_random_walk"):
        arr = v[name]
        if isinstance(arr, Parameter.Type) or arr is None:
            continue
        if len(arr) != 8:
            raise ConfigError(f"parameter {name}: needs 8 values (kxx kxy kyx kyy cxx cxy cyx cyy), got {len(arr)}")
        changes[name] = BearingCoefficients.from_array(np.asarray(arr, dtype=float))
    if changes:
        est = replace(est, **changes).validate()
        rig_file = RigFile(rig=rig_file.rig, estimator=est)
    tach = TachometerConfig(window_pulses=int(v["tach_window_pulses"]), fit_order=int(v["tach_fit_order"]),
                            stop_timeout_s=float(v["tach_stop_timeout_s"]),
                            min_speed_rad_s=float(v["tach_min_speed_rad_s"]),
                            max_speed_rad_s=max_speed_for_rig(rig_file.rig.speed_rad_s),
                            fit_history=int(v["tach_fit_history"]))
    align = AlignmentConfig(sample_rate_hz=rig_file.rig.sample_rate_hz,
                            match_tolerance_fraction=float(v["match_tolerance_fraction"]),
                            reorder_window_ns=int(round(float(v["reorder_window_s"]) * 1e9)),
                            duplicate_memory_ns=max(20_000_000, 2 * int(round(float(v["reorder_window_s"]) * 1e9))))
    options = PipelineOptions(convergence_relative_std=float(v["convergence_relative_std"]),
                              falling_behind_s=float(v["falling_behind_s"]), max_gap_s=float(v["max_gap_s"]),
                              clock_jump_s=float(v["clock_jump_s"]), shaft_wait_s=float(v["shaft_wait_s"]))
    pipe = EstimatorPipeline(rig_file.rig, est, tach, align, 1.0 / float(v["publish_rate_hz"]), options=options)
    topics = ma.InputTopics(probe1=v["probe1_topic"], probe2=v["probe2_topic"], keyphasor=v["keyphasor_topic"],
                            impact=v["impact_topic"])
    return pipe, rig_file, topics


class EstimatorNode(Node):
    """The estimator as a ROS 2 node; all logic is in :attr:`pipeline`."""

    def __init__(self, node_name: str = "rotor_estimator", **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        warn_if_numba_missing(self.get_logger())
        values = declare_parameters(self, PARAMETERS)  # ints for doubles accepted; bad values: one line
        self.pipeline, self.rig_file, self.topics = pipeline_from_parameters(values)
        self.pipeline.warm_up()
        self.values = values
        self.hardware_id = values["hardware_id"] or self.rig_file.rig.name
        self.lock = threading.Lock()
        self._factory = ma.RclpyFactory()
        self._namespace = self.get_fully_qualified_name()
        self._input_qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=int(values["input_queue_depth"]),
                                     reliability=qos_profile_sensor_data.reliability,
                                     durability=qos_profile_sensor_data.durability)
        self._subs: dict[str, tuple[str, Any]] = {}
        self._wrong_publishers: dict[str, set[str]] = {}
        self.messages_lost: dict[str, int] = {}   # per stream, reported by the middleware
        self.unexpected_errors = 0                # exceptions caught in callbacks (the node keeps running)
        for stream in ("probe1", "probe2", "keyphasor", "impact"):
            self._subscribe(stream, self._initial_type(stream))
        self._pubs = {}
        for name in (ma.COEFFICIENTS_TOPIC, ma.COVARIANCE_TOPIC, ma.INNOVATION_TOPIC, ma.NIS_TOPIC, ma.SHAFT_TOPIC,
                     ma.IDENTIFIABILITY_TOPIC):
            topic = ma.output_topic(name, self._namespace)
            self._pubs[topic] = self.create_publisher(self._factory.message_class("sensor_msgs/msg/JointState"),
                                                      topic, 50)
        self._diag_pub = self.create_publisher(self._factory.message_class("diagnostic_msgs/msg/DiagnosticArray"),
                                               ma.DIAGNOSTICS_TOPIC, 10)
        from std_srvs.srv import Trigger

        self.create_service(Trigger, "~/reset", self._on_reset)
        self._tick_period_ns = int(1e9 / float(values["idle_process_rate_hz"]))
        self._idle_ns = int(float(values["idle_release_s"]) * 1e9)
        self._last_probe_ns = 0
        self._last_input_ns = 0
        self._idle_flushed = False
        self._last_tick_ns = self._now_ns()
        self.create_timer(1.0 / float(values["idle_process_rate_hz"]), self._on_tick)
        self.create_timer(1.0 / float(values["diagnostics_rate_hz"]), self._publish_diagnostics)
        self.create_timer(1.0, self._check_graph)
        self.outputs_published = 0
        self._last_stamp_ns: int | None = None
        self.get_logger().info(
            f"estimating {self.rig_file.rig.name} bearings from {self.topics.probe1}, {self.topics.probe2}, "
            f"{self.topics.keyphasor}, {self.topics.impact}; outputs under {self._namespace}/")

    # ----------------------------------------------------------------- subscriptions
    def _initial_type(self, stream: str) -> str:
        if stream == "keyphasor":
            return "sensor_msgs/msg/TimeReference"
        chosen = self.values["impact_message_type" if stream == "impact" else "probe_message_type"]
        return _PC2 if chosen == "auto" else chosen

    def _subscribe(self, stream: str, typename: str) -> None:
        old = self._subs.pop(stream, None)
        if old is not None:
            self.destroy_subscription(old[1])
        topic = getattr(self.topics, stream)

        def callback(msg, s=stream):
            return self._on_input(s, msg)

        try:  # count messages the middleware drops (e.g. a keyphasor flood beyond the queue)
            events = _SubscriptionEventCallbacks(message_lost=lambda info, s=stream: self._on_lost(s, info))
            sub = self.create_subscription(self._factory.message_class(typename), topic, callback, self._input_qos,
                                           event_callbacks=events)
        except Exception as exc:  # an RMW without the message-lost event: loss cannot be counted there
            self.get_logger().info(f"{topic}: transport message loss is not reported by this RMW ({exc})")
            sub = self.create_subscription(self._factory.message_class(typename), topic, callback, self._input_qos)
        self._subs[stream] = (typename, sub)

    def _on_lost(self, stream: str, info: Any) -> None:
        """The middleware dropped ``info.total_count_change`` messages of ``stream`` before we saw them."""
        self.messages_lost[stream] = int(getattr(info, "total_count", 0)) or (
            self.messages_lost.get(stream, 0) + int(getattr(info, "total_count_change", 0)))

    def _check_graph(self) -> None:
        """Report publishers of a wrong type; in ``auto`` mode follow the publishers' type."""
        for stream, allowed in (("probe1", ma.PROBE_TYPES), ("probe2", ma.PROBE_TYPES),
                                ("keyphasor", ma.PULSE_TYPES), ("impact", ma.IMPACT_TYPES)):
            topic = getattr(self.topics, stream)
            types = {i.topic_type for i in self.get_publishers_info_by_topic(topic)}
            wrong = types - set(allowed)
            new = wrong - self._wrong_publishers.get(stream, set())
            if new:
                with self.lock:
                    for _ in new:
                        self.pipeline.reject_message(stream, "wrong_type_publisher")
                self.get_logger().warning(f"{topic} has publishers of type {sorted(new)}; expected "
                                          f"{' or '.join(allowed)}: their messages are ignored")
            self._wrong_publishers[stream] = wrong
            key = "impact_message_type" if stream == "impact" else "probe_message_type"
            good = sorted(types & set(allowed))
            if stream != "keyphasor" and self.values[key] == "auto" and good and self._subs[stream][0] not in good:
                self.get_logger().info(f"{topic}: publishers use {good[0]}, subscribing with it")
                self._subscribe(stream, good[0])

    # ----------------------------------------------------------------- callbacks
    def _now_ns(self) -> int:
        return self.get_clock().now().nanoseconds

    def _on_input(self, stream: str, msg: Any) -> None:
        probe = stream in ("probe1", "probe2")
        now = self._now_ns()
        try:
            with self.lock:
                feed_message(self.pipeline, stream, msg, now)
                outputs = self.pipeline.process() if probe else []
        except Exception as exc:  # one bad message must not take the rig's estimator down
            self._unexpected(f"handling a {stream} message", exc)
            return
        self._last_input_ns = now
        if probe:
            self._last_probe_ns = now
            self._idle_flushed = False
            self._publish(outputs)

    def _on_tick(self) -> None:
        """Release samples by wall clock only when the probe input is idle and this tick is on
        time: after a stall, messages still queued in the subscriptions must not be declared
        late. Decide everything (final estimate) only when no input at all arrives: keyphasor
        pulses still being delivered will give the last samples their shaft reference."""
        now = self._now_ns()
        on_time = now - self._last_tick_ns < 2 * self._tick_period_ns
        self._last_tick_ns = now
        idle = bool(self._last_probe_ns) and now - self._last_probe_ns > self._idle_ns and on_time
        all_idle = idle and now - self._last_input_ns > self._idle_ns
        with self.lock:
            if all_idle and not self._idle_flushed:
                outputs = self.pipeline.flush()      # input stopped: decide everything, final estimate
                self._idle_flushed = True
            else:
                try:
                    outputs = self.pipeline.process(now if idle else None)
                except Exception as exc:
                    self._unexpected("processing on the idle timer", exc)
                    return
        self._publish(outputs)

    def _unexpected(self, what: str, exc: Exception) -> None:
        """Log an unexpected exception with its traceback, count it, and keep the node running."""
        import traceback

        self.unexpected_errors += 1
        self.get_logger().error(f"unexpected error {what} ({self.unexpected_errors} so far; the node keeps "
                                f"running): {exc!r}\n{traceback.format_exc()}")

    def _publish(self, outputs: list) -> None:
        for out in outputs:
            for topic, msg in output_messages(self._factory, out, self._namespace, with_diagnostics=False):
                self._pubs[topic].publish(msg)
            self._last_stamp_ns = out.stamp_ns
            self.outputs_published += 1

    def _publish_diagnostics(self) -> None:
        with self.lock:
            status = self.pipeline.status()
            last = self.pipeline.last_sample_stamp_ns
        wrong = {s: sorted(t) for s, t in self._wrong_publishers.items() if t}
        if wrong:
            status = replace(status, level=max(status.level, LEVEL_WARN),
                             message=status.message + f"; wrong-type publishers {wrong}")
        lost = {s: n for s, n in self.messages_lost.items() if n}
        if lost:
            status = replace(status, level=max(status.level, LEVEL_WARN),
                             message=status.message + f"; messages dropped by the middleware before delivery {lost} "
                             "(input faster than the node takes it: raise input_queue_depth or lower the rate)",
                             extra={**status.extra, **{f"messages_lost_{s}": n for s, n in lost.items()}})
        if self.unexpected_errors:
            status = replace(status, level=LEVEL_ERROR,
                             message=status.message + f"; {self.unexpected_errors} unexpected error(s) in callbacks "
                             "(see the node's log)",
                             extra={**status.extra, "unexpected_errors": self.unexpected_errors})
        stamp = last if last is not None else self._now_ns()
        record = diagnostic_record(status, self.hardware_id)
        self._diag_pub.publish(ma.diagnostics_to_msg(self._factory, stamp, [record]))

    def _on_reset(self, request: Any, response: Any) -> Any:
        with self.lock:
            self.pipeline.reset()
        response.success = True
        response.message = "estimation restarted from the prior (r0, P0)"
        self.get_logger().info(response.message)
        return response

    def reset_estimation(self) -> None:
        """Same as the ``~/reset`` service, callable in-process."""
        with self.lock:
            self.pipeline.reset()


def main(args: list[str] | None = None) -> int:
    """``ros2 run rotor_estimator estimator_node [--ros-args --params-file config/estimator.yaml]``."""
    return run_node(EstimatorNode, "estimator_node", args)


if __name__ == "__main__":
    raise SystemExit(main())
