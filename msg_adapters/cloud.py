# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""``sensor_msgs/msg/PointCloud2`` as columns of numbers, vectorized with numpy.

Fields are located by name; their offset and datatype are read from the message,
so any layout (reordered fields, extra fields, padding) decodes. Encoding packs
the given columns little-endian in the given order, without padding.
"""
from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np

from rotor_estimator.core.errors import InputError

from msg_adapters._common import expect_type
from msg_adapters.factory import MessageFactory, make_header

POINTCLOUD2 = "sensor_msgs/msg/PointCloud2"

# sensor_msgs/msg/PointField datatype constants
INT8, UINT8, INT16, UINT16, INT32, UINT32, FLOAT32, FLOAT64 = range(1, 9)
DATATYPE_NAMES: dict[int, str] = {INT8: "INT8", UINT8: "UINT8", INT16: "INT16", UINT16: "UINT16",
                                  INT32: "INT32", UINT32: "UINT32", FLOAT32: "FLOAT32", FLOAT64: "FLOAT64"}
_NUMPY_CODES: dict[int, str] = {INT8: "i1", UINT8: "u1", INT16: "i2", UINT16: "u2",
                                INT32: "i4", UINT32: "u4", FLOAT32: "f4", FLOAT64: "f8"}


def cloud_columns(msg: Any, required: Mapping[str, int]) -> dict[str, np.ndarray]:
    """Read the named fields of a PointCloud2 as 1-D native-endian arrays (one entry per point).

    ``required`` maps field name to PointField datatype. Raises :class:`InputError`
    if a field is missing, has another datatype or count, or the data is too short.
    """
    expect_type(msg, {POINTCLOUD2}, "point cloud")
    by_name = {f.name: f for f in msg.fields}
    point_step, row_step = int(msg.point_step), int(msg.row_step)
    width, height = int(msg.width), int(msg.height)
    order = ">" if msg.is_bigendian else "<"
    names, formats, offsets = [], [], []
    for name, datatype in required.items():
        f = by_name.get(name)
        if f is None:
            raise InputError(f"PointCloud2 has no field {name!r} (fields: {sorted(by_name)}); "
                             f"publish fields {list(required)}")
        if int(f.datatype) != datatype:
            got = DATATYPE_NAMES.get(int(f.datatype), str(f.datatype))
            raise InputError(f"PointCloud2 field {name!r} has datatype {got}, expected {DATATYPE_NAMES[datatype]}")
        if int(f.count) not in (0, 1):
            raise InputError(f"PointCloud2 field {name!r} has count {f.count}, expected 1")
        size = np.dtype(_NUMPY_CODES[datatype]).itemsize
        if int(f.offset) < 0 or int(f.offset) + size > point_step:
            raise InputError(f"PointCloud2 field {name!r} at offset {f.offset} does not fit point_step {point_step}")
        names.append(name)
        formats.append(order + _NUMPY_CODES[datatype])
        offsets.append(int(f.offset))
    n = width * height
    raw = np.frombuffer(msg.data, dtype=np.uint8)
    if n == 0:
        return {name: np.empty(0, dtype=np.dtype(fmt).newbyteorder("=")) for name, fmt in zip(names, formats)}
    if row_step < width * point_step or raw.size < height * row_step:
        raise InputError(f"PointCloud2 data has {raw.size} bytes, expected height*row_step = "
                         f"{height}*{row_step} with row_step >= width*point_step = {width * point_step}")
    if row_step != width * point_step:  # padded rows: drop the padding
        raw = np.ascontiguousarray(raw[:height * row_step].reshape(height, row_step)[:, :width * point_step])
    dtype = np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": point_step})
    points = np.frombuffer(raw, dtype=dtype, count=n)
    return {name: points[name].astype(points.dtype[name].newbyteorder("=")) for name in names}


def cloud_from_columns(factory: MessageFactory, stamp_ns: int, frame_id: str,
                       columns: Sequence[tuple[str, int, np.ndarray]]) -> Any:
    """Build a PointCloud2 (height 1, little-endian) from ``(name, datatype, values)`` columns.

    ``is_dense`` is True unless a float column holds NaN or inf.
    """
    if not columns:
        raise InputError("a PointCloud2 needs at least one field")
    n = int(np.shape(columns[0][2])[0])
    dtype = np.dtype([(name, "<" + _NUMPY_CODES[datatype]) for name, datatype, _ in columns])
    points = np.empty(n, dtype=dtype)
    dense = True
    for name, datatype, values in columns:
        values = np.asarray(values)
        if values.shape != (n,):
            raise InputError(f"PointCloud2 column {name!r} has shape {values.shape}, expected ({n},)")
        points[name] = values
        if datatype in (FLOAT32, FLOAT64):
            dense = dense and bool(np.isfinite(values).all())
    fields = [factory.new("sensor_msgs/msg/PointField", name=name, offset=int(dtype.fields[name][1]),
                          datatype=int(datatype), count=1)
              for name, datatype, _ in columns]
    return factory.new(
        POINTCLOUD2, header=make_header(factory, stamp_ns, frame_id), height=1, width=n, fields=fields,
        is_bigendian=False, point_step=dtype.itemsize, row_step=dtype.itemsize * n,
        data=factory.uint8_seq(points.view(np.uint8)), is_dense=dense)
