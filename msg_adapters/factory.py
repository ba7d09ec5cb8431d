# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Message factories: build rclpy messages or rosbags dataclasses with the same encoder code.

Encoders always pass every field (rosbags dataclasses need all of them, nested
``Header``/``Time`` included); rclpy classes accept the same keyword arguments.
Sequence fields go through :meth:`uint8_seq` / :meth:`float64_seq` /
:meth:`byte`, because the two libraries store them differently (``array.array``
and ``bytes`` in rclpy, ``numpy.ndarray`` and ``int`` in rosbags).
"""
from __future__ import annotations

import array
import importlib
from functools import lru_cache
from typing import Any, Protocol

import numpy as np

from msg_adapters._common import ns_to_sec_nanosec


class MessageFactory(Protocol):
    """Builds messages of one library from a full ROS type name and keyword fields."""

    def new(self, typename: str, /, **fields: Any) -> Any:
        """A message of ``typename`` (e.g. ``std_msgs/msg/Header``) with ``fields``."""

    def uint8_seq(self, data: np.ndarray) -> Any:
        """Value for a ``uint8[]`` field from a contiguous uint8 array."""

    def float64_seq(self, values: np.ndarray) -> Any:
        """Value for a ``float64[]`` field."""

    def byte(self, value: int) -> Any:
        """Value for a ``byte`` field (e.g. ``DiagnosticStatus.level``)."""


class RclpyFactory:
    """Builds rclpy message objects (imports the ``<pkg>.msg`` module on first use).

    ``uint8[]`` data is handed to the constructor as ``bytes``: the generated
    ``__init__`` wraps it with ``array.array('B', bytes)``, a memcpy, and the
    setter then takes its ``array.array`` fast path even with
    ``ROS_PYTHON_CHECK_FIELDS=1`` (assigning ``bytes`` or a numpy array to
    ``msg.data`` afterwards instead loops over every byte).
    """

    def __init__(self) -> None:
        self._classes: dict[str, type] = {}

    def message_class(self, typename: str) -> type:
        """The rclpy message class for ``'pkg/msg/Name'`` (for publishers and subscriptions)."""
        cls = self._classes.get(typename)
        if cls is None:
            pkg, kind, name = typename.split("/")
            cls = getattr(importlib.import_module(f"{pkg}.{kind}"), name)
            self._classes[typename] = cls
        return cls

    def new(self, typename: str, /, **fields: Any) -> Any:
        return self.message_class(typename)(**fields)

    def uint8_seq(self, data: np.ndarray) -> Any:
        return np.ascontiguousarray(data, dtype=np.uint8).tobytes()

    def float64_seq(self, values: np.ndarray) -> Any:
        return array.array("d", np.ascontiguousarray(values, dtype=np.float64).tobytes())

    def byte(self, value: int) -> Any:
        return bytes([int(value)])


class TypestoreFactory:
    """Builds rosbags typestore dataclasses (default store: :func:`default_typestore`)."""

    def __init__(self, typestore: Any | None = None) -> None:
        self.typestore = typestore if typestore is not None else default_typestore()

    def new(self, typename: str, /, **fields: Any) -> Any:
        return self.typestore.types[typename](**fields)

    def uint8_seq(self, data: np.ndarray) -> Any:
        return np.ascontiguousarray(data, dtype=np.uint8).reshape(-1)

    def float64_seq(self, values: np.ndarray) -> Any:
        return np.array(values, dtype=np.float64).reshape(-1)

    def byte(self, value: int) -> Any:
        return int(value)


@lru_cache(maxsize=1)
def default_typestore() -> Any:
    """The rosbags typestore for ROS 2 Kilted (or the newest ROS 2 store this rosbags has)."""
    from rosbags.typesys import Stores, get_typestore

    for name in ("ROS2_KILTED", "ROS2_JAZZY", "LATEST"):
        store = getattr(Stores, name, None)
        if store is not None:
            return get_typestore(store)
    raise RuntimeError("rosbags has no ROS 2 typestore; install rosbags >= 0.10")


def make_header(factory: MessageFactory, stamp_ns: int, frame_id: str = "") -> Any:
    """A ``std_msgs/msg/Header`` with the stamp given in integer nanoseconds."""
    return factory.new("std_msgs/msg/Header", stamp=make_time(factory, stamp_ns), frame_id=str(frame_id))


def make_time(factory: MessageFactory, stamp_ns: int) -> Any:
    """A ``builtin_interfaces/msg/Time`` from integer nanoseconds (exact)."""
    sec, nanosec = ns_to_sec_nanosec(stamp_ns)
    return factory.new("builtin_interfaces/msg/Time", sec=sec, nanosec=nanosec)
