# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Shared helpers: message type names, stamps, type checks.

Works on message objects from rclpy (generated classes), rosbags (typestore
dataclasses with ``__msgtype__``) and mcap_ros2 (dynamic classes with ``_type``),
reading fields by name only.
"""
from __future__ import annotations

from typing import Any, Collection

from rotor_estimator.core.errors import InputError

NS_PER_S = 1_000_000_000


def msg_typename(msg: Any) -> str:
    """Full ROS type name of a message object, e.g. ``sensor_msgs/msg/PointCloud2``."""
    cls = type(msg)
    name = getattr(cls, "__msgtype__", None)  # rosbags dataclasses
    if isinstance(name, str):
        return name
    parts = cls.__module__.split(".")  # rclpy: sensor_msgs.msg._point_cloud2.PointCloud2
    if len(parts) >= 2 and parts[1] in ("msg", "srv", "action"):
        return f"{parts[0]}/{parts[1]}/{cls.__name__}"
    dyn = getattr(msg, "_type", None)  # mcap_ros2 dynamic classes: 'pkg/msg/Name' or 'pkg/Name'
    if isinstance(dyn, str):
        pieces = dyn.split("/")
        return f"{pieces[0]}/msg/{pieces[-1]}" if len(pieces) == 2 else dyn
    return f"{cls.__module__}.{cls.__qualname__}"


def expect_type(msg: Any, allowed: Collection[str], what: str) -> str:
    """Return ``msg``'s type name, or raise :class:`InputError` if it is not in ``allowed``."""
    name = msg_typename(msg)
    if name not in allowed:
        raise InputError(f"{what}: expected a message of type {' or '.join(sorted(allowed))}, "
                         f"got {name}; publish/record the topic with the documented type")
    return name


def stamp_to_ns(stamp: Any) -> int:
    """``builtin_interfaces/msg/Time`` (sec, nanosec) to integer nanoseconds, exact."""
    return int(stamp.sec) * NS_PER_S + int(stamp.nanosec)


def ns_to_sec_nanosec(stamp_ns: int) -> tuple[int, int]:
    """Integer nanoseconds to ``(sec, nanosec)`` with ``0 <= nanosec < 1e9``, exact."""
    sec, nanosec = divmod(int(stamp_ns), NS_PER_S)
    if not -(2**31) <= sec < 2**31:
        raise InputError(f"stamp {stamp_ns} ns does not fit builtin_interfaces/msg/Time (int32 seconds)")
    return sec, nanosec


def header_stamp_ns(msg: Any) -> int:
    """``msg.header.stamp`` in integer nanoseconds."""
    return stamp_to_ns(msg.header.stamp)
