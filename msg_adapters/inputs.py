# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Adapters for the estimator's input topics: probes, keyphasor, impact force.

* probes (``/rotor/probe1``, ``/rotor/probe2``): ``geometry_msgs/msg/PointStamped``
  (one sample, ``point.x``/``point.y`` in m) or ``sensor_msgs/msg/PointCloud2``
  blocks with fields ``x_m`` FLOAT64, ``y_m`` FLOAT64, ``t_offset_ns`` UINT32
  (ns after ``header.stamp``, the first sample's stamp).
* keyphasor (``/rotor/keyphasor``): ``sensor_msgs/msg/TimeReference``, one per revolution.
* impact (``/rotor/impact``): ``geometry_msgs/msg/WrenchStamped`` (``force.x``/``force.y``
  in N) or PointCloud2 blocks with ``fx_n``, ``fy_n`` FLOAT64 and ``t_offset_ns`` UINT32.
"""
from __future__ import annotations

from typing import Any, Callable

import numpy as np

from rotor_estimator.core.errors import InputError

from msg_adapters._common import expect_type, header_stamp_ns, stamp_to_ns
from msg_adapters.cloud import FLOAT64, POINTCLOUD2, UINT32, cloud_columns, cloud_from_columns
from msg_adapters.factory import MessageFactory, make_header, make_time

POINT_STAMPED = "geometry_msgs/msg/PointStamped"
WRENCH_STAMPED = "geometry_msgs/msg/WrenchStamped"
TIME_REFERENCE = "sensor_msgs/msg/TimeReference"
PROBE_TYPES: tuple[str, ...] = (POINTCLOUD2, POINT_STAMPED)
IMPACT_TYPES: tuple[str, ...] = (POINTCLOUD2, WRENCH_STAMPED)
PULSE_TYPES: tuple[str, ...] = (TIME_REFERENCE,)
PROBE_FIELDS: dict[str, int] = {"x_m": FLOAT64, "y_m": FLOAT64, "t_offset_ns": UINT32}
IMPACT_FIELDS: dict[str, int] = {"fx_n": FLOAT64, "fy_n": FLOAT64, "t_offset_ns": UINT32}
MAX_BLOCK_SPAN_NS = 2**32 - 1

Block = tuple[np.ndarray, np.ndarray]


def _block_from_cloud(msg: Any, fields: dict[str, int]) -> Block:
    cols = cloud_columns(msg, fields)
    a, b = (name for name in fields if name != "t_offset_ns")
    stamps_ns = header_stamp_ns(msg) + cols["t_offset_ns"].astype(np.int64)
    return stamps_ns, np.column_stack((cols[a], cols[b])).astype(np.float64, copy=False)


def _probe_from_point(msg: Any) -> Block:
    p = msg.point
    return np.array([header_stamp_ns(msg)], dtype=np.int64), np.array([[float(p.x), float(p.y)]])


def _impact_from_wrench(msg: Any) -> Block:
    f = msg.wrench.force
    return np.array([header_stamp_ns(msg)], dtype=np.int64), np.array([[float(f.x), float(f.y)]])


_PROBE_DECODERS: dict[str, Callable[[Any], Block]] = {
    POINTCLOUD2: lambda m: _block_from_cloud(m, PROBE_FIELDS),
    POINT_STAMPED: _probe_from_point,
}
_IMPACT_DECODERS: dict[str, Callable[[Any], Block]] = {
    POINTCLOUD2: lambda m: _block_from_cloud(m, IMPACT_FIELDS),
    WRENCH_STAMPED: _impact_from_wrench,
}


def probe_block_from_msg(msg: Any) -> Block:
    """Probe samples of one plane: ``(stamps_ns int64 (N,), xy_m float64 (N, 2))``."""
    return _PROBE_DECODERS[expect_type(msg, PROBE_TYPES, "probe message")](msg)


def impact_block_from_msg(msg: Any) -> Block:
    """Impact force samples: ``(stamps_ns int64 (N,), f_n float64 (N, 2) [fx, fy])``."""
    return _IMPACT_DECODERS[expect_type(msg, IMPACT_TYPES, "impact message")](msg)


def pulse_stamp_from_msg(msg: Any) -> int:
    """Keyphasor pulse time in integer ns: ``time_ref`` (``header.stamp`` if ``time_ref`` is zero)."""
    expect_type(msg, PULSE_TYPES, "keyphasor message")
    stamp_ns = stamp_to_ns(msg.time_ref)
    return stamp_ns if stamp_ns != 0 else header_stamp_ns(msg)


def check_block(stamps_ns: np.ndarray, values: np.ndarray, what: str) -> tuple[np.ndarray, np.ndarray]:
    """Validate a block of (N,) integer ns stamps and (N, 2) values; return (uint32 offsets from the first
    stamp, float64 values)."""
    stamps_ns = np.asarray(stamps_ns)
    values = np.asarray(values, dtype=np.float64)
    if stamps_ns.ndim != 1 or stamps_ns.size == 0 or not np.issubdtype(stamps_ns.dtype, np.integer):
        raise InputError(f"{what}: stamps_ns must be a non-empty 1-D integer array, got "
                         f"{stamps_ns.dtype} {stamps_ns.shape}")
    if values.shape != (stamps_ns.size, 2):
        raise InputError(f"{what}: values must have shape ({stamps_ns.size}, 2), got {values.shape}")
    offsets = stamps_ns.astype(np.int64) - np.int64(stamps_ns[0])
    if offsets.min() < 0 or offsets.max() > MAX_BLOCK_SPAN_NS:
        raise InputError(f"{what}: stamps must not precede the first one and must span at most "
                         f"{MAX_BLOCK_SPAN_NS} ns (t_offset_ns is UINT32); use smaller blocks")
    return offsets.astype(np.uint32), values


def probe_block_to_msg(factory: MessageFactory, stamps_ns: np.ndarray, xy_m: np.ndarray,
                       *, frame_id: str) -> Any:
    """PointCloud2 block of probe samples (fields ``x_m``, ``y_m``, ``t_offset_ns``)."""
    offsets, xy = check_block(stamps_ns, xy_m, "probe block")
    return cloud_from_columns(factory, int(stamps_ns[0]), frame_id, [
        ("x_m", FLOAT64, xy[:, 0]), ("y_m", FLOAT64, xy[:, 1]), ("t_offset_ns", UINT32, offsets)])


def impact_block_to_msg(factory: MessageFactory, stamps_ns: np.ndarray, f_n: np.ndarray,
                        *, frame_id: str = "impact") -> Any:
    """PointCloud2 block of impact force samples (fields ``fx_n``, ``fy_n``, ``t_offset_ns``)."""
    offsets, f = check_block(stamps_ns, f_n, "impact block")
    return cloud_from_columns(factory, int(stamps_ns[0]), frame_id, [
        ("fx_n", FLOAT64, f[:, 0]), ("fy_n", FLOAT64, f[:, 1]), ("t_offset_ns", UINT32, offsets)])


def probe_sample_to_msg(factory: MessageFactory, stamp_ns: int, x_m: float, y_m: float,
                        *, frame_id: str) -> Any:
    """PointStamped with one probe sample (``z`` = 0)."""
    point = factory.new("geometry_msgs/msg/Point", x=float(x_m), y=float(y_m), z=0.0)
    return factory.new(POINT_STAMPED, header=make_header(factory, stamp_ns, frame_id), point=point)


def impact_sample_to_msg(factory: MessageFactory, stamp_ns: int, fx_n: float, fy_n: float,
                         *, frame_id: str = "impact") -> Any:
    """WrenchStamped with one force sample (other components 0)."""
    force = factory.new("geometry_msgs/msg/Vector3", x=float(fx_n), y=float(fy_n), z=0.0)
    torque = factory.new("geometry_msgs/msg/Vector3", x=0.0, y=0.0, z=0.0)
    wrench = factory.new("geometry_msgs/msg/Wrench", force=force, torque=torque)
    return factory.new(WRENCH_STAMPED, header=make_header(factory, stamp_ns, frame_id), wrench=wrench)


def pulse_to_msg(factory: MessageFactory, stamp_ns: int, *, source: str = "keyphasor") -> Any:
    """TimeReference for one keyphasor pulse: ``header.stamp`` = ``time_ref`` = pulse time."""
    return factory.new(TIME_REFERENCE, header=make_header(factory, stamp_ns, source),
                       time_ref=make_time(factory, stamp_ns), source=source)
