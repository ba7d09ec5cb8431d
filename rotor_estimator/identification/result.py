# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""What every identification method returns."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rotor_estimator.identification.problem import CoefficientModel


@dataclass
class IdentificationResult:
    """Estimate of ``theta`` (see :class:`~.problem.CoefficientModel`) and its covariance.

    * ``covariance``: the method's own covariance of ``theta`` (SI^2): inverse Fisher
      information at the estimate for the batch fit, the (smoothed) filter covariance
      for the Kalman methods.
    * ``information``: Fisher information of ``[theta, b?]`` after eliminating the initial
      states, when the method computes it (batch fit); used by the identifiability report.
    * ``imbalance_kg_m``: estimated (or assumed) imbalance ``[a1, b1, a2, b2...]`` (kg*m).
    """

    method: str
    model: CoefficientModel
    theta: np.ndarray
    covariance: np.ndarray
    imbalance_kg_m: np.ndarray
    imbalance_estimated: bool
    runtime_s: float
    converged: bool = True
    iterations: int = 0
    information: np.ndarray | None = None
    extra: dict = field(default_factory=dict)

    @property
    def std(self) -> np.ndarray:
        return np.sqrt(np.clip(np.diag(self.covariance), 0, None))

    @property
    def coefficients(self) -> np.ndarray:
        """Constant part of the coefficients (theta's order-0 block), SI."""
        return self.theta[:self.model.n_coefficients].copy()
