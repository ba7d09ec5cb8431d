# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Fixtures: the same adapter code is exercised with rclpy classes and rosbags dataclasses."""
from __future__ import annotations

from typing import Any, Callable

import pytest

import msg_adapters as ma


def _rclpy_wire(msg: Any) -> Any:
    """Serialize with rclpy (CDR) and deserialize again, as a subscriber would receive it."""
    from rclpy.serialization import deserialize_message, serialize_message

    return deserialize_message(serialize_message(msg), type(msg))


def _rosbags_wire(msg: Any) -> Any:
    ts = ma.default_typestore()
    return ts.deserialize_cdr(ts.serialize_cdr(msg, msg.__msgtype__), msg.__msgtype__)


@pytest.fixture(params=["rclpy", "rosbags"])
def factory(request: pytest.FixtureRequest) -> ma.MessageFactory:
    if request.param == "rclpy":
        pytest.importorskip("rclpy")
        return ma.RclpyFactory()
    return ma.TypestoreFactory()


@pytest.fixture
def wire(factory: ma.MessageFactory) -> Callable[[Any], Any]:
    """Round trip through the library's own CDR serializer."""
    return _rclpy_wire if isinstance(factory, ma.RclpyFactory) else _rosbags_wire
