# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The four identification methods behind one call, and the default for each situation.

=============  =====================================================================
``batch-ml``   batch output-error maximum likelihood (:mod:`.batch_ml`): the efficient
               reference; whole record(s) in memory; several records (trial weights),
               speed polynomials and 16 coefficients. **Default offline.**
``ekf+rts``    EKF pass + RTS smoother, iterated about the smoothed trajectory
               (:func:`.kalman.run_ekf_rts`): converges to the batch estimate with the
               prior; use it with random-walk coefficients (two-sided tracks).
``ekf``        the EKF (:func:`.kalman.run_ekf`; the node runs the compiled core
               :class:`rotor_estimator.core.ekf.StreamingEKF`): **default live**, the only one
               that is causal and O(1) per sample.
``ukf``        the UKF with filterpy's scaled sigma points (:func:`.kalman.run_ukf`):
               same accuracy as the EKF here (the model is bilinear, its linearization
               error over one 50 us step is tiny) at ~8x the cost; offered for comparison.
=============  =====================================================================

Why (``rotor-estimator bench identification``): on every scenario the batch fit
reaches the CRLB (spread/CRLB ~1, bias < 0.3 CRLB) and is the fastest offline method
for sweeps; the EKF and UKF carry the linearization bias of a filter started 40% off
(passes reduce it), and the iterated smoother removes it at ~3x the EKF's cost.
"""
from __future__ import annotations

import numpy as np

from rotor_estimator.core.config import EstimatorConfig
from rotor_estimator.core.errors import ConfigError
from rotor_estimator.identification.batch_ml import BatchOptions, fit
from rotor_estimator.identification.kalman import KalmanOptions, run_ekf, run_ekf_rts, run_ukf
from rotor_estimator.identification.problem import CoefficientModel, Record, RigArrays
from rotor_estimator.identification.result import IdentificationResult

METHODS: tuple[str, ...] = ("ekf", "ukf", "ekf+rts", "batch-ml")
DEFAULT_OFFLINE = "batch-ml"
DEFAULT_LIVE = "ekf"


def identify(arrays: RigArrays, config: EstimatorConfig, records: Record | list[Record], *, method: str = "auto",
             model: CoefficientModel = CoefficientModel(), estimate_imbalance: bool = False,
             imbalance_kg_m: np.ndarray | None = None, theta0: np.ndarray | None = None,
             trial_imbalance_kg_m: list[np.ndarray] | None = None) -> IdentificationResult:
    """Run ``method`` (``auto``: the offline default) on the records with the rig file's prior/tuning."""
    if method == "auto":
        method = DEFAULT_OFFLINE
    if method not in METHODS:
        raise ConfigError(f"identify.method: unknown {method!r}; choose one of {', '.join(METHODS)} or auto")
    recs = [records] if isinstance(records, Record) else list(records)
    if theta0 is None:
        theta0 = model.theta_from_coefficients(config.initial_coefficients.as_array())
    if method == "batch-ml":
        return fit(arrays, model, recs, theta0, options=BatchOptions(
            noise_std_m=config.measurement_noise_std_m, estimate_imbalance=estimate_imbalance),
            imbalance_kg_m=imbalance_kg_m, trial_imbalance_kg_m=trial_imbalance_kg_m)
    if len(recs) != 1:
        raise ConfigError(f"identify.method: {method} takes one record; use batch-ml for several")
    if trial_imbalance_kg_m is not None and np.any(np.asarray(trial_imbalance_kg_m)):
        raise ConfigError(f"identify.method: {method} does not take trial weights; use batch-ml")
    opts = KalmanOptions.from_config(config, model)
    from dataclasses import replace

    opts = replace(opts, theta0=np.asarray(theta0, dtype=float))
    run = {"ekf": run_ekf, "ukf": run_ukf, "ekf+rts": run_ekf_rts}[method]
    return run(arrays, model, recs[0], opts, estimate_imbalance=estimate_imbalance, imbalance_kg_m=imbalance_kg_m)
