# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Speed-dependent coefficients: a sweep must not silently average them.

Two models, both on the generalized kernel:

* **Polynomial** (default): each coefficient ``c(Omega) = sum_{i<=p} c_i s^i`` with
  ``s = (Omega - Omega_mid) / Omega_half`` normalized over the record's speed range
  (so the ``c_i`` are well conditioned), fitted by batch output-error ML
  (:mod:`.batch_ml`). The covariance of ``c(Omega)`` is ``phi(s)^T Cov(c_.) phi(s)``
  (exact: the map is linear), from which the confidence bands follow. Choose ``p`` by
  :func:`select_order` (the likelihood-ratio / AIC test of p against p-1).
* **Random walk**: constant-in-model coefficients with a random-walk rate ``q`` (SI per
  sqrt(s)) tracked by the EKF and smoothed by the RTS pass (:func:`.kalman.run_ekf_rts`);
  the smoothed (two-sided) track against the measured speed is the curve. ``q`` trades
  lag/bias against noise and must be tuned; the polynomial has no such knob, which is
  why it is the default.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from rotor_estimator.core.config import COEFFICIENT_UNITS
from rotor_estimator.identification.batch_ml import BatchOptions, fit
from rotor_estimator.identification.problem import CoefficientModel, Record, RigArrays
from rotor_estimator.identification.result import IdentificationResult

if TYPE_CHECKING:
    from rotor_estimator.identification.kalman import KalmanOptions

RPM = 2.0 * np.pi / 60.0
Z95 = 1.959963984540054


def model_for_record(record: Record | list[Record], order: int, *, identical_bearings: bool = True) -> CoefficientModel:
    """Polynomial model of ``order`` normalized over the records' speed range."""
    recs = [record] if isinstance(record, Record) else record
    speeds = np.concatenate([r.speed_rad_s[r.use] for r in recs])
    lo, hi = float(speeds.min()), float(speeds.max())
    return CoefficientModel(identical_bearings=identical_bearings, speed_order=order,
                            speed_ref_rad_s=0.5 * (lo + hi), speed_scale_rad_s=max(0.5 * (hi - lo), 1.0))


def fit_polynomial(arrays: RigArrays, record: Record | list[Record], order: int, coefficients0: np.ndarray, *,
                   options: BatchOptions = BatchOptions(), identical_bearings: bool = True) -> IdentificationResult:
    """Batch ML of order-``order`` speed polynomials, started from constant ``coefficients0``."""
    model = model_for_record(record, order, identical_bearings=identical_bearings)
    return fit(arrays, model, record, model.theta_from_coefficients(coefficients0), options=options)


def select_order(arrays: RigArrays, record: Record | list[Record], coefficients0: np.ndarray, *, max_order: int = 2,
                 options: BatchOptions = BatchOptions()) -> tuple[int, list[IdentificationResult]]:
    """Fit orders 0..max_order; pick the lowest order whose successor does not improve the
    likelihood by more than AIC's 2 per added parameter (``cost`` is chi-square: -2 log L)."""
    results = []
    theta_prev = None
    for p in range(max_order + 1):
        model = model_for_record(record, p)
        theta0 = model.theta_from_coefficients(coefficients0)
        if theta_prev is not None:
            theta0[:theta_prev.size] = theta_prev
        res = fit(arrays, model, record, theta0, options=replace(options, warm_start_fraction=(1.0,))
                  if theta_prev is not None else options)
        results.append(res)
        theta_prev = res.theta
    chosen = 0
    for p in range(1, max_order + 1):
        gain = results[p - 1].extra["cost"] - results[p].extra["cost"]
        if gain > 2.0 * results[p].model.n_coefficients:
            chosen = p
    return chosen, results


@dataclass(frozen=True)
class SpeedTable:
    """Coefficients versus speed: ``values``/``std`` (len(speeds), n_coefficients), SI."""

    speeds_rad_s: np.ndarray
    names: tuple[str, ...]
    values: np.ndarray
    std: np.ndarray

    def lower95(self) -> np.ndarray:
        return self.values - Z95 * self.std

    def upper95(self) -> np.ndarray:
        return self.values + Z95 * self.std

    def format(self) -> str:
        head = f"{'rpm':>8}" + "".join(f"{n:>22}" for n in self.names)
        lines = [head, f"{'':>8}" + "".join(f"{'(' + u + ', +-95%)':>22}" for u in
                                          (COEFFICIENT_UNITS * 2)[:len(self.names)])]
        for i, w in enumerate(self.speeds_rad_s):
            lines.append(f"{w / RPM:>8.0f}" + "".join(f"{v:>13.5g} +-{Z95 * s:<7.2g}"
                                                     for v, s in zip(self.values[i], self.std[i])))
        return "\n".join(lines)

    def as_rows(self) -> list[dict]:
        return [{"speed_rpm": float(w / RPM), "coefficient": n, "value": float(self.values[i, j]),
                 "std": float(self.std[i, j]), "lower95": float(self.lower95()[i, j]),
                 "upper95": float(self.upper95()[i, j])}
                for i, w in enumerate(self.speeds_rad_s) for j, n in enumerate(self.names)]


def table(result: IdentificationResult, speeds_rad_s: np.ndarray) -> SpeedTable:
    """Coefficient-versus-speed table with standard deviations from the fit's covariance."""
    values, std = result.model.coefficients_at(result.theta, speeds_rad_s, result.covariance)
    return SpeedTable(np.asarray(speeds_rad_s, dtype=float), result.model.coefficient_names, values, std)


def random_walk_track(arrays: RigArrays, record: Record, options: KalmanOptions, *, rate: np.ndarray,
                      keep_every: int = 200,
                      estimate_imbalance: bool = False) -> SpeedTable:
    """Random-walk alternative: EKF + RTS with coefficient random-walk std rate ``rate`` (SI/sqrt(s));
    returns the smoothed coefficients at every ``keep_every``-th sample against the measured speed."""
    from rotor_estimator.identification.kalman import run_ekf_rts

    model = CoefficientModel()
    opts = replace(options, theta_random_walk=np.asarray(rate, dtype=float), passes=max(options.passes, 2))
    res = run_ekf_rts(arrays, model, record, opts, estimate_imbalance=estimate_imbalance, keep_every=keep_every)
    xs, pk = res.extra["smoothed_states"], res.extra["smoothed_cov_every"]
    idx = np.arange(0, len(record), keep_every)
    vals = xs[idx, 8:16]
    std = np.sqrt(np.clip(np.einsum("kii->ki", pk[:, 8:16, 8:16]), 0, None))
    return SpeedTable(record.speed_rad_s[idx], model.coefficient_names, vals, std)
