# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Bags <-> arrays for multi-sensor rigs (virtual sensing). I/O layer: imports rosbags.

Input bags carry one topic per sensor of the rotor description, ``/rotor/<sensor>``,
as PointCloud2 blocks (probes ``x_m``, ``y_m``; accelerometers ``ax_m_s2``, ``ay_m_s2``;
``t_offset_ns``; see :mod:`msg_adapters.stations`) and ``/rotor/keyphasor``
TimeReference pulses. As in :mod:`rotor_estimator.io.bags`, a block's log time is the
stamp of its last sample, stamps round-trip exactly as integer ns, bags are MCAP.

Output bags (``virtual-sensing --out-bag``) carry ``/virtual_sensing/stations/<name>``
JointState per sample, ``/virtual_sensing/leave_one_out/<sensor>`` (predicted hidden
channels and the hidden measurement) and one ``/diagnostics`` summary, for Foxglove or
PlotJuggler.
"""
from __future__ import annotations

import heapq
from pathlib import Path
from typing import Any, Iterator, Mapping, NamedTuple

import numpy as np

import msg_adapters as ma

from rotor_estimator.io.bags import BagWriter, OutputBagWriter, tag_stream, bag_topics, iter_bag_messages
from rotor_estimator.core.errors import BagError, InputError
from rotor_estimator.core.flexible.description import RotorDescription
from rotor_estimator.virtual_sensing.estimator import LeaveOneOutReport, StationEstimate
from rotor_estimator.virtual_sensing.stream import SensorAligner

__all__ = ["SensorData", "write_sensor_bag", "read_sensor_bag", "write_estimates_bag", "KEYPHASOR_TOPIC",
           "LEAVE_ONE_OUT_TOPIC"]

KEYPHASOR_TOPIC = ma.DEFAULT_INPUT_TOPICS.keyphasor
LEAVE_ONE_OUT_TOPIC = "leave_one_out"


class SensorData(NamedTuple):
    """A multi-sensor recording: ``stamps_ns`` (N,) int64 increasing, ``z`` (N, p) in the
    rotor file's channel order (``channel_names``; NaN where a sensor gave no sample),
    ``pulse_stamps_ns`` (K,) int64, and ``counters`` (alignment and gap counts)."""

    stamps_ns: np.ndarray
    z: np.ndarray
    pulse_stamps_ns: np.ndarray
    channel_names: tuple[str, ...]
    counters: dict


def _channel_matrix(rotor: RotorDescription, n: int, channels: Any) -> np.ndarray:
    names = rotor.channel_names
    if isinstance(channels, Mapping):
        unknown = sorted(set(channels) - set(names))
        if unknown:
            raise InputError(f"channels {unknown} are not in rotor {rotor.name} (channels: {list(names)})")
        z = np.full((n, len(names)), np.nan)
        for j, c in enumerate(names):
            if c in channels:
                z[:, j] = np.asarray(channels[c], dtype=float).reshape(-1)
        return z
    z = np.asarray(channels, dtype=float)
    if z.shape != (n, len(names)):
        raise InputError(f"channels: expected shape ({n}, {len(names)}) in the order {list(names)}, got {z.shape}")
    return z


def write_sensor_bag(path: str | Path, rotor: RotorDescription, stamps_ns: np.ndarray, channels: Any,
                     pulse_stamps_ns: np.ndarray, *, block_size: int = 256, prefix: str = ma.SENSOR_TOPIC_PREFIX,
                     keyphasor_topic: str = KEYPHASOR_TOPIC, meta: dict | None = None) -> Path:
    """Write a new MCAP rosbag2 bag at ``path``: one PointCloud2 topic per sensor of
    ``rotor`` (blocks of ``block_size`` samples) and a TimeReference per keyphasor pulse.

    ``stamps_ns`` (N,) integer ns, increasing; ``channels``: ``{channel name: (N,)}`` (e.g.
    ``probe1_x``, m or m/s^2) or an (N, p) array in ``rotor.channel_names`` order; a
    direction a sensor does not measure is written as NaN. Returns ``path``.
    """
    path = Path(path)
    stamps = np.asarray(stamps_ns)
    if stamps.ndim != 1 or not np.issubdtype(stamps.dtype, np.integer) or len(stamps) == 0:
        raise InputError(f"stamps_ns: a non-empty 1-D integer array (ns), got {stamps.dtype} {stamps.shape}")
    if np.any(np.diff(stamps) <= 0) or stamps[0] < 0:
        raise InputError("stamps_ns: must be >= 0 and strictly increasing")
    if block_size < 1:
        raise InputError(f"block_size must be >= 1, got {block_size}")
    n = len(stamps)
    z = _channel_matrix(rotor, n, channels)
    pulses = np.sort(np.asarray(pulse_stamps_ns, dtype=np.int64))
    if (pulses < 0).any():
        raise InputError("pulse_stamps_ns: bag log times are unsigned, must be >= 0 ns")
    fac = ma.TypestoreFactory()
    ts = fac.typestore
    col = {c: j for j, c in enumerate(rotor.channel_names)}

    def sensor_msgs(sensor: Any) -> Iterator[tuple[int, Any]]:
        vals = np.full((n, 2), np.nan)
        for k, d in enumerate(("x", "y")):
            if d in sensor.directions:
                vals[:, k] = z[:, col[f"{sensor.name}_{d}"]]
        for i in range(0, n, block_size):
            j = min(i + block_size, n)
            yield int(stamps[j - 1]), ma.sensor_block_to_msg(fac, sensor.kind, stamps[i:j], vals[i:j],
                                                             frame_id=sensor.name)

    def pulse_msgs() -> Iterator[tuple[int, Any]]:
        for p in pulses.tolist():
            yield p, ma.pulse_to_msg(fac, p)

    streams = {ma.sensor_topic(s.name, prefix): ("sensor_msgs/msg/PointCloud2", sensor_msgs(s))
               for s in rotor.sensors}
    streams[keyphasor_topic] = ("sensor_msgs/msg/TimeReference", pulse_msgs())
    with BagWriter(path, {"rotor": rotor.name, **(meta or {})}) as writer:
        conns = {t: writer.add_connection(t, typename, typestore=ts) for t, (typename, _) in streams.items()}
        tagged = [tag_stream(t, gen) for t, (_, gen) in streams.items()]
        for log_ns, _, topic, msg in heapq.merge(*tagged, key=lambda item: (item[0], item[1])):
            writer.write(conns[topic], log_ns, ts.serialize_cdr(msg, msg.__msgtype__))
    return path


def read_sensor_bag(path: str | Path, rotor: RotorDescription, *, prefix: str = ma.SENSOR_TOPIC_PREFIX,
                    keyphasor_topic: str = KEYPHASOR_TOPIC, match_tolerance_fraction: float = 0.25,
                    reorder_window_s: float = 1.0, fill_gaps: bool = True) -> SensorData:
    """Decode a multi-sensor bag into arrays, aligning sensors by stamp with the live
    node's :class:`~rotor_estimator.virtual_sensing.stream.SensorAligner` (same rules, same
    counters). With ``fill_gaps``, samples missing on every sensor become NaN rows on the
    sample grid (``counters['gap_samples']``), so rows are consecutive samples.
    Raises :class:`BagError` if a sensor topic is missing or has another type."""
    available = bag_topics(path)
    topic_of = {ma.sensor_topic(s.name, prefix): s for s in rotor.sensors}
    missing = [t for t in topic_of if t not in available]
    if missing:
        raise BagError(f"bag {path} lacks sensor topic(s) {missing} of rotor {rotor.name}; it has "
                       f"{sorted(available)}. Sensor topics are <prefix>/<sensor name> (prefix {prefix!r})")
    for t in topic_of:
        if available[t] != "sensor_msgs/msg/PointCloud2":
            raise BagError(f"topic {t} has type {available[t]}, expected sensor_msgs/msg/PointCloud2")
    if keyphasor_topic in available and available[keyphasor_topic] != "sensor_msgs/msg/TimeReference":
        raise BagError(f"topic {keyphasor_topic} has type {available[keyphasor_topic]}, "
                       f"expected sensor_msgs/msg/TimeReference")
    period_ns = 1e9 / rotor.sample_rate_hz
    aligner = SensorAligner([s.name for s in rotor.sensors], period_ns, match_tolerance_fraction,
                            int(round(reorder_window_s * 1e9)))
    parts, pulses = [], []
    for m in iter_bag_messages(path, [*topic_of, keyphasor_topic]):
        try:
            if m.topic == keyphasor_topic:
                pulses.append(ma.pulse_stamp_from_msg(m.msg))
                continue
            sensor = topic_of[m.topic]
            stamps, values = ma.sensor_block_from_msg(m.msg, sensor.kind)
        except InputError as exc:
            raise BagError(f"bag {path}, topic {m.topic} at log time {m.log_time_ns} ns: {exc}") from exc
        aligner.add_block(sensor.name, stamps, values)
        parts.append(aligner.pop_ready())
    parts.append(aligner.pop_ready(flush=True))
    stamps = np.concatenate([p.stamps_ns for p in parts])
    if stamps.size == 0:
        raise BagError(f"bag {path}: no sensor samples on {list(topic_of)}")
    values = np.concatenate([p.values for p in parts])
    present = np.concatenate([p.present for p in parts])
    values[~present] = np.nan
    sidx = {s.name: i for i, s in enumerate(rotor.sensors)}
    z = np.column_stack([values[:, sidx[s.name], 0 if d == "x" else 1]
                         for s in rotor.sensors for d in s.directions])
    counters = dict(aligner.counters)
    counters["gap_samples"] = 0
    if fill_gaps and len(stamps) > 1:
        steps = np.rint(np.diff(stamps) / period_ns).astype(np.int64)
        if np.any(steps > 1):
            pos = np.concatenate(([0], np.cumsum(np.maximum(steps, 1))))
            full = np.full((pos[-1] + 1, z.shape[1]), np.nan)
            full[pos] = z
            grid = np.empty(pos[-1] + 1, dtype=np.int64)
            grid[pos] = stamps
            for i in np.flatnonzero(steps > 1):  # integer ns after the last real stamp
                grid[pos[i] + 1:pos[i + 1]] = stamps[i] + np.rint(np.arange(1, steps[i]) * period_ns).astype(np.int64)
            counters["gap_samples"] = int(len(grid) - len(stamps))
            stamps, z = grid, full
    return SensorData(stamps, z, np.unique(np.asarray(pulses, dtype=np.int64)), rotor.channel_names, counters)


def write_estimates_bag(path: str | Path, estimates: list[StationEstimate], stamps_ns: np.ndarray, *,
                        report: LeaveOneOutReport | None = None, namespace: str = ma.VIRTUAL_SENSING_NAMESPACE,
                        hardware_id: str = "") -> Path:
    """Write station estimates (and leave-one-out traces, if ``report`` has them) to a
    new MCAP bag: ``<namespace>/stations/<station>`` JointState per sample (see
    :mod:`msg_adapters.stations`); ``<namespace>/leave_one_out/<sensor>`` JointState with
    ``<channel>_<unit>`` = prediction (velocity: std of the hidden measurement's
    prediction, incl. its noise) and ``<channel>_<unit>_measured`` = the hidden
    measurement (velocity 0); one ``/diagnostics`` with the leave-one-out table."""
    stamps = np.asarray(stamps_ns, dtype=np.int64)
    unit_tag = {"m": "m", "m/s^2": "m_s2"}
    with OutputBagWriter(path) as w:
        for k, t in enumerate(stamps.tolist()):
            for e in estimates:
                w.write(ma.station_topic(e.name, namespace),
                        ma.station_to_msg(w.factory, t, e.name, e.mean[k], e.std[k], e.disp_cov[k]), t)
            if report is not None:
                for tr in report.traces:
                    names = [f"{c}_{unit_tag.get(u, 'si')}" for c, u in zip(tr.channels, tr.units)]
                    std = tr.half_width[k] / _z(report.confidence)
                    pos = np.concatenate((tr.predicted[k], tr.measured[k]))
                    vel = np.concatenate((std, np.zeros(len(names))))
                    msg = w.factory.new("sensor_msgs/msg/JointState",
                                        header=ma.make_header(w.factory, t, tr.sensor),
                                        name=names + [f"{n}_measured" for n in names],
                                        position=w.factory.float64_seq(pos), velocity=w.factory.float64_seq(vel),
                                        effort=w.factory.float64_seq(np.empty(0)))
                    w.write(f"{namespace.rstrip('/')}/{LEAVE_ONE_OUT_TOPIC}/{tr.sensor}", msg, t)
        if report is not None and len(stamps):
            values = {r.channel: f"coverage {r.coverage_measured:.3f}, width {r.mean_interval_width:.3e} {r.unit}, "
                                 f"rms error {r.rms_error:.3e}" for r in report.rows}
            flagged = [f"{r.channel}" for r in report.rows if not r.calibrated]
            rec = ma.DiagnosticRecord("virtual_sensing: leave-one-station-out", 1 if flagged else 0,
                                      f"not calibrated: {flagged}" if flagged else "all hidden channels calibrated",
                                      hardware_id, values)
            w.write(ma.DIAGNOSTICS_TOPIC, ma.diagnostics_to_msg(w.factory, int(stamps[-1]), [rec]), int(stamps[-1]))
    return Path(path)


def _z(confidence: float) -> float:
    from scipy.stats import norm

    return float(norm.ppf(0.5 + 0.5 * confidence))
