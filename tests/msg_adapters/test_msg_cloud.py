# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""PointCloud2 decoding locates fields by name, offset and datatype, not by assumed layout."""
from __future__ import annotations

import numpy as np
import pytest

import msg_adapters as ma
from msg_adapters.cloud import FLOAT32, FLOAT64, UINT32
from rotor_estimator.core.errors import InputError

T0_NS = 1_234_567_890_123_456_789


def _cloud(factory, fields, points: np.ndarray, *, height: int = 1, row_pad: int = 0, bigendian: bool = False):
    """A hand-made PointCloud2 with the given (name, offset, datatype) fields over a structured array."""
    n = points.size // height
    step = points.dtype.itemsize
    rows = points.view(np.uint8).reshape(height, n * step)
    data = np.hstack((rows, np.full((height, row_pad), 0xAB, np.uint8))).reshape(-1)
    pf = [factory.new("sensor_msgs/msg/PointField", name=name, offset=off, datatype=dt, count=1)
          for name, off, dt in fields]
    return factory.new("sensor_msgs/msg/PointCloud2", header=ma.make_header(factory, T0_NS, "probe1"),
                       height=height, width=n, fields=pf, is_bigendian=bigendian, point_step=step,
                       row_step=n * step + row_pad, data=factory.uint8_seq(data), is_dense=True)


def _reordered(n: int, order: str = "<") -> np.ndarray:
    dtype = np.dtype({"names": ["t_offset_ns", "intensity", "y_m", "x_m"],
                      "formats": [order + "u4", order + "f4", order + "f8", order + "f8"],
                      "offsets": [0, 4, 8, 24], "itemsize": 40})
    pts = np.zeros(n, dtype)
    pts["t_offset_ns"] = np.arange(n) * 50_000
    pts["x_m"] = np.linspace(-1e-5, 1e-5, n)
    pts["y_m"] = np.linspace(2e-5, 3e-5, n)
    pts["intensity"] = 7.0
    return pts


FIELDS = [("t_offset_ns", 0, UINT32), ("intensity", 4, FLOAT32), ("y_m", 8, FLOAT64), ("x_m", 24, FLOAT64)]


def test_reordered_fields_with_extra_field_and_padding_decode_by_name(factory):
    pts = _reordered(9)
    stamps, xy = ma.probe_block_from_msg(_cloud(factory, FIELDS, pts))
    assert np.array_equal(stamps, T0_NS + pts["t_offset_ns"].astype(np.int64))
    assert np.array_equal(xy[:, 0], pts["x_m"]) and np.array_equal(xy[:, 1], pts["y_m"])


def test_padded_rows_and_height_above_one_decode(factory):
    pts = _reordered(12)
    stamps, xy = ma.probe_block_from_msg(_cloud(factory, FIELDS, pts, height=3, row_pad=6))
    assert np.array_equal(xy[:, 0], pts["x_m"]) and stamps.size == 12


def test_big_endian_cloud_decodes_to_native_values(factory):
    pts = _reordered(5, ">")
    stamps, xy = ma.probe_block_from_msg(_cloud(factory, FIELDS, pts, bigendian=True))
    assert np.array_equal(xy[:, 0], pts["x_m"].astype(float)) and xy.dtype == np.float64
    assert np.array_equal(stamps - T0_NS, pts["t_offset_ns"].astype(np.int64))


def test_cloud_missing_a_field_raises_input_error_naming_it(factory):
    fields = [f for f in FIELDS if f[0] != "y_m"]
    with pytest.raises(InputError, match="no field 'y_m'"):
        ma.probe_block_from_msg(_cloud(factory, fields, _reordered(3)))


def test_cloud_field_with_wrong_datatype_raises_input_error(factory):
    fields = [(n, o, FLOAT32 if n == "x_m" else d) for n, o, d in FIELDS]
    with pytest.raises(InputError, match="'x_m' has datatype FLOAT32, expected FLOAT64"):
        ma.probe_block_from_msg(_cloud(factory, fields, _reordered(3)))


def test_cloud_with_short_data_raises_input_error(factory):
    msg = _cloud(factory, FIELDS, _reordered(4))
    msg.width = 5
    with pytest.raises(InputError, match="bytes"):
        ma.probe_block_from_msg(msg)


def test_field_beyond_point_step_raises_input_error(factory):
    fields = [(n, 36 if n == "x_m" else o, d) for n, o, d in FIELDS]
    with pytest.raises(InputError, match="does not fit point_step"):
        ma.probe_block_from_msg(_cloud(factory, fields, _reordered(3)))


def test_empty_cloud_decodes_to_empty_arrays(factory):
    stamps, xy = ma.probe_block_from_msg(_cloud(factory, FIELDS, _reordered(0)))
    assert stamps.shape == (0,) and xy.shape == (0, 2)
