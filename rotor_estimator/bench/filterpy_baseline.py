# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The same EKF written the straightforward way with filterpy's ``ExtendedKalmanFilter``.

Prediction uses the numpy reference RK4 step and its Jacobian
(:mod:`rotor_estimator.bench.reference_ekf`); filterpy does ``P = F P F^T + Q`` and the
Joseph-form update. This is the speed baseline and an independent check of the
compiled kernel's update arithmetic.
"""
from __future__ import annotations

from typing import Any

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter

from rotor_estimator.bench import reference_ekf as ref
from rotor_estimator.core.ekf import FilterModel


class FilterpyRotorEKF(ExtendedKalmanFilter):
    """filterpy EKF whose state prediction is the nonlinear RK4 step (Eq. 12)."""

    def __init__(self, model: FilterModel, x0: np.ndarray, p0: np.ndarray) -> None:
        super().__init__(dim_x=16, dim_z=4)
        self.model = model
        self.x = np.asarray(x0, dtype=float).reshape(16, 1).copy()
        self.P = np.asarray(p0, dtype=float).copy()
        self.R = np.diag(model.r_var)
        self._h = ref.measurement_matrix(model)
        self._step_args: Any = None  # (h, shaft_prev, impact_prev), set by step() before predict()

    def predict_x(self, u=0):  # noqa: D401 - filterpy hook
        h, shaft, impact = self._step_args
        x_new, phi = ref.rk4_step(self.model, self.x.ravel(), h, *shaft, impact)
        self.F = phi
        self.x = x_new.reshape(16, 1)

    def step(self, h: float, shaft_prev, impact_prev, y: np.ndarray) -> None:
        self._step_args = (h, shaft_prev, impact_prev)
        self.Q = ref.process_noise(self.model, h)
        self.predict()
        hm = self._h
        self.update(np.asarray(y, dtype=float).reshape(4, 1), HJacobian=lambda x: hm, Hx=lambda x: hm @ x)


def run_filterpy(model: FilterModel, x0: np.ndarray, p0: np.ndarray, t_s: np.ndarray, probes_m: np.ndarray,
                 angle_rad: np.ndarray, speed_rad_s: np.ndarray, accel_rad_s2: np.ndarray,
                 impact_n: np.ndarray) -> FilterpyRotorEKF:
    """Filter samples ``1..n-1`` starting from ``x0, p0`` at ``t_s[0]`` (sample 0 initializes)."""
    f = FilterpyRotorEKF(model, x0, p0)
    for k in range(1, len(t_s)):
        f.step(t_s[k] - t_s[k - 1], (angle_rad[k - 1], speed_rad_s[k - 1], accel_rad_s2[k - 1]),
               impact_n[k - 1], probes_m[k])
    return f
