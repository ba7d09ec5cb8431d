# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Non-identical bearings: 16 coefficients (bearing 1 and bearing 2 each ``kxx kxy kyx kyy cxx cxy cyx cyy``).

The seed model (Eq. 4) gives both bearings the same 2x2 stiffness and damping; a real
rotor's two bearings differ (load, clearance, temperature). The 16-coefficient model
replaces the stacked identity of :class:`~.problem.CoefficientModel` by ``I16``; the
kernels, the batch fit and the CRLB are unchanged. The data must then separate the two
bearings: impacts at two axial stations or a sweep (the imbalance planes sit at both
ends, and the conical and cylindrical modes load the bearings differently) do; a
single impact at the mass center does poorly. :func:`crlb16` tells, before the test,
and the identifiability report after it. The 8-coefficient model stays the default:
it has half the variance when the bearings are alike.
"""
from __future__ import annotations

import numpy as np

from rotor_estimator.core.config import RigConfig
from rotor_estimator.identification.batch_ml import BatchOptions, fit
from rotor_estimator.identification.planner import CandidateBound, evaluate
from rotor_estimator.identification.problem import CoefficientModel, Record, RigArrays
from rotor_estimator.identification.result import IdentificationResult
from rotor_estimator.identification.scenarios import TestDesign

MODEL16 = CoefficientModel(identical_bearings=False)


def fit16(arrays: RigArrays, records: Record | list[Record], coefficients0: np.ndarray, *,
          options: BatchOptions = BatchOptions()) -> IdentificationResult:
    """Batch ML of the 16 coefficients from 8 (copied to both bearings) or 16 starting values."""
    return fit(arrays, MODEL16, records, MODEL16.theta_from_coefficients(coefficients0), options=options)


def crlb16(rig: RigConfig, design: TestDesign, coefficients16: np.ndarray, *,
           unknown_imbalance: bool = True) -> CandidateBound:
    """Cramér-Rao bound of the 16 coefficients for a test design."""
    return evaluate(rig, design, np.asarray(coefficients16, dtype=float), unknown_imbalance=unknown_imbalance,
                    bearings16=True)
