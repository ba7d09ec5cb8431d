# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Virtual sensing (Neisi et al. 2022): the orbit of a flexible rotor at stations without probes, offline and live."""
from __future__ import annotations

from typing import TYPE_CHECKING

from rotor_estimator.lazy_exports import lazy_exports

if TYPE_CHECKING:
    from rotor_estimator.virtual_sensing.estimator import VirtualSensingConfig, estimate_stations, leave_one_station_out
    from rotor_estimator.virtual_sensing.stream import VirtualSensingPipeline

_EXPORTS = {
    "VirtualSensingConfig": "rotor_estimator.virtual_sensing.estimator",
    "estimate_stations": "rotor_estimator.virtual_sensing.estimator",
    "leave_one_station_out": "rotor_estimator.virtual_sensing.estimator",
    "VirtualSensingPipeline": "rotor_estimator.virtual_sensing.stream",
}
__all__ = ["VirtualSensingConfig", "estimate_stations", "leave_one_station_out", "VirtualSensingPipeline"]
__getattr__ = lazy_exports(__name__, _EXPORTS)
