# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Numerical core: configuration, model, simulator, filters, tachometer, alignment, pipeline (no ROS)."""
from __future__ import annotations

from typing import TYPE_CHECKING

from rotor_estimator.lazy_exports import lazy_exports

if TYPE_CHECKING:
    from rotor_estimator.core.alignment import StreamAligner
    from rotor_estimator.core.config import (BearingCoefficients, COEFFICIENT_NAMES, COEFFICIENT_UNITS,
                                             EstimatorConfig, RigConfig,
                                             RigFile, load_rig_file)
    from rotor_estimator.core.ekf import StreamingEKF
    from rotor_estimator.core.errors import BagError, ConfigError, InputError, NoDataError, RotorEstimatorError
    from rotor_estimator.core.identifiability import IdentifiabilityReport
    from rotor_estimator.core.offline import estimate
    from rotor_estimator.core.pipeline import EstimatorPipeline
    from rotor_estimator.core.recording import RigRecording
    from rotor_estimator.core.simulator import Impact, Scenario, simulate
    from rotor_estimator.core.tachometer import ShaftAngleTracker

_EXPORTS = {
    "load_rig_file": "rotor_estimator.core.config",
    "RigFile": "rotor_estimator.core.config",
    "RigConfig": "rotor_estimator.core.config",
    "EstimatorConfig": "rotor_estimator.core.config",
    "BearingCoefficients": "rotor_estimator.core.config",
    "COEFFICIENT_NAMES": "rotor_estimator.core.config",
    "COEFFICIENT_UNITS": "rotor_estimator.core.config",
    "RotorEstimatorError": "rotor_estimator.core.errors",
    "ConfigError": "rotor_estimator.core.errors",
    "InputError": "rotor_estimator.core.errors",
    "BagError": "rotor_estimator.core.errors",
    "NoDataError": "rotor_estimator.core.errors",
    "RigRecording": "rotor_estimator.core.recording",
    "Scenario": "rotor_estimator.core.simulator",
    "Impact": "rotor_estimator.core.simulator",
    "simulate": "rotor_estimator.core.simulator",
    "StreamingEKF": "rotor_estimator.core.ekf",
    "estimate": "rotor_estimator.core.offline",
    "EstimatorPipeline": "rotor_estimator.core.pipeline",
    "ShaftAngleTracker": "rotor_estimator.core.tachometer",
    "StreamAligner": "rotor_estimator.core.alignment",
    "IdentifiabilityReport": "rotor_estimator.core.identifiability",
}
__all__ = ["load_rig_file", "RigFile", "RigConfig", "EstimatorConfig", "BearingCoefficients",
           "COEFFICIENT_NAMES", "COEFFICIENT_UNITS", "RotorEstimatorError", "ConfigError", "InputError",
           "BagError", "NoDataError", "RigRecording", "Scenario", "Impact", "simulate", "StreamingEKF",
           "estimate", "EstimatorPipeline", "ShaftAngleTracker", "StreamAligner", "IdentifiabilityReport"]
__getattr__ = lazy_exports(__name__, _EXPORTS)
