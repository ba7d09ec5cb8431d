# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Adapters for virtual sensing: multi-sensor input blocks and per-station estimates.

Inputs, one topic per sensor of the rotor description (``/rotor/<sensor_name>``), as
``sensor_msgs/msg/PointCloud2`` blocks (``header.stamp`` = first sample's stamp,
``t_offset_ns`` UINT32 = ns after it):

* probes: fields ``x_m``, ``y_m`` FLOAT64 (shaft relative to the housing, m), the same
  layout as the rigid estimator's ``/rotor/probe1``;
* accelerometers: fields ``ax_m_s2``, ``ay_m_s2`` FLOAT64 (absolute acceleration, m/s^2).

A sensor measuring one direction only publishes NaN in the other field. The shaft
angle comes from ``/rotor/keyphasor`` (``sensor_msgs/msg/TimeReference``, see
:mod:`msg_adapters.inputs`).

Outputs, one topic per station, ``~/stations/<station_name>`` as
``sensor_msgs/msg/JointState`` (decoded by name, order free), ``header.stamp`` = the
sample the estimate refers to, ``header.frame_id`` = the station name:

============  ==========================================  =====================
name          position                                    velocity
============  ==========================================  =====================
``x_m``       displacement x estimate (m)                 its standard deviation
``y_m``       displacement y estimate (m)                 its standard deviation
``vx_m_s``    velocity x (m/s)                            its standard deviation
``vy_m_s``    velocity y (m/s)                            its standard deviation
``ax_m_s2``   acceleration x (m/s^2)                      its standard deviation
``ay_m_s2``   acceleration y (m/s^2)                      its standard deviation
``corr_xy``   correlation of the x and y displacement     0 (unused)
              errors (-1..1), for the orbit's ellipse
============  ==========================================  =====================

So ``velocity`` holds the **standard deviation** (1 sigma), the same convention as
``~/coefficients``; the 95% interval is ``position +- 1.96 * velocity`` and the 95%
orbit ellipse has covariance ``[[sx^2, r sx sy], [r sx sy, sy^2]]`` scaled by
``-2 ln(0.05) = 5.99``. ``effort`` is empty. Stamps are integer ns.
"""
from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from rotor_estimator.core.errors import InputError

from msg_adapters._common import expect_type, header_stamp_ns
from msg_adapters.cloud import FLOAT64, POINTCLOUD2, UINT32, cloud_columns, cloud_from_columns
from msg_adapters.factory import MessageFactory
from msg_adapters.inputs import PROBE_FIELDS, check_block
from msg_adapters.outputs import joint_state, joint_values

ACCEL_FIELDS: dict[str, int] = {"ax_m_s2": FLOAT64, "ay_m_s2": FLOAT64, "t_offset_ns": UINT32}
SENSOR_FIELDS: dict[str, dict[str, int]] = {"probe": PROBE_FIELDS, "accelerometer": ACCEL_FIELDS}
STATION_NAMES: tuple[str, ...] = ("x_m", "y_m", "vx_m_s", "vy_m_s", "ax_m_s2", "ay_m_s2")
STATION_CORR_NAME = "corr_xy"
SENSOR_TOPIC_PREFIX = "/rotor"
STATIONS_TOPIC = "stations"
VIRTUAL_SENSING_NAMESPACE = "/virtual_sensing"


class StationState(NamedTuple):
    """One station estimate: ``mean``/``std`` (6,) in :data:`STATION_NAMES` order (SI),
    ``disp_cov`` (2, 2) displacement covariance (m^2)."""

    stamp_ns: int
    station: str
    mean: np.ndarray
    std: np.ndarray
    disp_cov: np.ndarray


def sensor_topic(sensor: str, prefix: str = SENSOR_TOPIC_PREFIX) -> str:
    """Input topic of a sensor: ``/rotor/<sensor>``."""
    return f"{prefix.rstrip('/')}/{sensor}"


def station_topic(station: str, namespace: str = VIRTUAL_SENSING_NAMESPACE) -> str:
    """Absolute output topic of a station: ``<namespace>/stations/<station>``."""
    return f"{namespace.rstrip('/')}/{STATIONS_TOPIC}/{station}"


def _fields(kind: str) -> dict[str, int]:
    fields = SENSOR_FIELDS.get(kind)
    if fields is None:
        raise InputError(f"sensor kind {kind!r}: expected one of {sorted(SENSOR_FIELDS)}")
    return fields


def sensor_block_to_msg(factory: MessageFactory, kind: str, stamps_ns: np.ndarray, values: np.ndarray,
                        *, frame_id: str) -> Any:
    """PointCloud2 block of one sensor: ``values`` (N, 2) [x, y] in m (probe) or m/s^2
    (accelerometer), ``stamps_ns`` (N,) integer ns, non-decreasing from the first."""
    fields = _fields(kind)
    offsets, vals = check_block(stamps_ns, values, f"{kind} block")
    a, b = (n for n in fields if n != "t_offset_ns")
    return cloud_from_columns(factory, int(np.asarray(stamps_ns)[0]), frame_id, [
        (a, FLOAT64, vals[:, 0]), (b, FLOAT64, vals[:, 1]), ("t_offset_ns", UINT32, offsets)])


def sensor_block_from_msg(msg: Any, kind: str) -> tuple[np.ndarray, np.ndarray]:
    """``(stamps_ns int64 (N,), values float64 (N, 2))`` of a sensor block; fields by name."""
    fields = _fields(kind)
    expect_type(msg, {POINTCLOUD2}, f"{kind} message")
    cols = cloud_columns(msg, fields)
    a, b = (n for n in fields if n != "t_offset_ns")
    stamps = header_stamp_ns(msg) + cols["t_offset_ns"].astype(np.int64)
    return stamps, np.column_stack((cols[a], cols[b])).astype(np.float64, copy=False)


def station_to_msg(factory: MessageFactory, stamp_ns: int, station: str, mean: Any, std: Any,
                   disp_cov: Any | None = None) -> Any:
    """``~/stations/<station>``: estimates in position, standard deviations in velocity,
    plus ``corr_xy`` from ``disp_cov`` (2, 2) (0 when not given)."""
    m = np.asarray(mean, dtype=np.float64).reshape(-1)
    s = np.asarray(std, dtype=np.float64).reshape(-1)
    if m.size != 6 or s.size != 6:
        raise InputError(f"station {station}: mean and std need 6 values {STATION_NAMES}, got {m.size}, {s.size}")
    corr = 0.0
    if disp_cov is not None:
        c = np.asarray(disp_cov, dtype=np.float64)
        den = float(np.sqrt(c[0, 0] * c[1, 1]))
        corr = float(np.clip(c[0, 1] / den, -1.0, 1.0)) if den > 0 else 0.0
    return joint_state(factory, stamp_ns, STATION_NAMES + (STATION_CORR_NAME,), np.append(m, corr),
                        np.append(s, 0.0), station)


def station_from_msg(msg: Any) -> StationState:
    """Decode ``~/stations/<station>`` (station name from ``header.frame_id``)."""
    stamp_ns, mean, std = joint_values(msg, STATION_NAMES, "station message")
    index = {str(n): i for i, n in enumerate(msg.name)}
    corr = float(msg.position[index[STATION_CORR_NAME]]) if STATION_CORR_NAME in index else 0.0
    cxy = corr * std[0] * std[1]
    return StationState(stamp_ns, str(msg.header.frame_id), mean, std,
                        np.array([[std[0] ** 2, cxy], [cxy, std[1] ** 2]]))
