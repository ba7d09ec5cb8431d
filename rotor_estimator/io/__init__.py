# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Input and output: rosbag2/MCAP bags, DAQ exports, all-or-nothing file writes."""
from __future__ import annotations

from typing import TYPE_CHECKING

from rotor_estimator.lazy_exports import lazy_exports

if TYPE_CHECKING:
    from rotor_estimator.io.bags import (BagWriter, OutputBagWriter, bag_damage, iter_bag_messages, read_input_bag,
                                         write_input_bag)

_EXPORTS = {
    "read_input_bag": "rotor_estimator.io.bags",
    "write_input_bag": "rotor_estimator.io.bags",
    "BagWriter": "rotor_estimator.io.bags",
    "OutputBagWriter": "rotor_estimator.io.bags",
    "bag_damage": "rotor_estimator.io.bags",
    "iter_bag_messages": "rotor_estimator.io.bags",
}
__all__ = ["read_input_bag", "write_input_bag", "BagWriter", "OutputBagWriter", "bag_damage",
           "iter_bag_messages"]
__getattr__ = lazy_exports(__name__, _EXPORTS)
