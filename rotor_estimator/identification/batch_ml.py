# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Batch output-error maximum likelihood: the efficient reference.

Model: ``y_k = Hp z_k(p) + v_k`` with ``z_k`` the noise-free response of Eq. 2 (one RK4
step per sample along the measured shaft angle, Eq. 12), ``v_k ~ N(0, sigma^2 I)``.
Parameters ``p = [theta, b?, q0_1, ..., q0_R]``: the coefficients, the imbalance when
unknown, and every record's initial motion state. The negative log-likelihood is
``sum_k |y_k - Hp z_k|^2 / (2 sigma^2)``; it is minimized by Levenberg-Marquardt on the
normal equations ``(J^T J + mu diag) dp = J^T e`` with the analytic sensitivities
``J`` propagated through the exact Jacobian of each RK4 step
(:func:`.passes.sensitivity_pass`). The response is linear in ``q0`` and ``b``, so
Gauss-Newton solves those in one step; only ``theta`` needs iterating (the variable
projection idea, obtained here implicitly). At the optimum ``J^T J / sigma^2`` is the
Fisher information: its inverse is the reported covariance, i.e. the CRLB evaluated
at the estimate.

Starting far from the truth (the paper's r0 is 40% low), an output-error cost can
have local minima; :func:`fit` therefore fits a growing prefix of the data first
(``warm_start_fraction``), which keeps the early iterations in the convex basin.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from rotor_estimator.core.errors import InputError
from rotor_estimator.identification import passes
from rotor_estimator.identification.problem import CoefficientModel, Record, RigArrays
from rotor_estimator.identification.result import IdentificationResult


@dataclass(frozen=True)
class BatchOptions:
    """* ``noise_std_m``: sigma of the probe noise (m); scales the information only.
    * ``estimate_imbalance``: treat the rotor imbalance as unknown (2 per plane).
    * ``max_iterations``: LM iterations per stage.
    * ``warm_start_fraction``: fractions of the record fitted first (growing prefix).
    * ``tolerance``: stop when the Gauss-Newton decrement ``g^T dp`` is below this (in
      units of the noise variance; 1e-6 is far below the statistical precision)."""

    noise_std_m: float = 1e-6
    estimate_imbalance: bool = False
    max_iterations: int = 40
    warm_start_fraction: tuple[float, ...] = (0.25, 1.0)
    tolerance: float = 1e-6

    def __post_init__(self) -> None:
        from rotor_estimator.core.errors import ConfigError

        if not self.noise_std_m > 0:
            raise ConfigError("batch.noise_std_m: must be > 0 m")
        if not self.warm_start_fraction or any(not 0 < f <= 1 for f in self.warm_start_fraction):
            raise ConfigError("batch.warm_start_fraction: fractions in (0, 1]")


def _truncate(record: Record, fraction: float) -> Record:
    if fraction >= 1.0:
        return record
    n = max(int(len(record) * fraction), 50)
    return Record(record.t_s[:n], record.angle_rad[:n], record.speed_rad_s[:n], record.accel_rad_s2[:n],
                  record.force_gen_n[:n], record.probes_m[:n], record.use[:n])


class _Problem:
    def __init__(self, arrays: RigArrays, model: CoefficientModel, records: list[Record],
                 trial_imbalance: list[np.ndarray], estimate_b: bool, noise_std_m: float):
        self.arrays, self.model, self.records = arrays, model, records
        self.trial = trial_imbalance
        self.estimate_b = estimate_b
        self.nth = model.n_theta
        self.nb = arrays.n_imbalance if estimate_b else 0
        self.n_shared = self.nth + self.nb
        self.n_par = self.n_shared + 8 * len(records)
        self.rinv = np.full(4, 1.0 / noise_std_m)
        self.dmap, self.powers = model.dmap(), model.powers()

    def evaluate(self, p: np.ndarray, b_fixed: np.ndarray):
        """Total cost, gradient and information for parameters ``p``."""
        theta = p[:self.nth]
        b = p[self.nth:self.n_shared] if self.estimate_b else b_fixed
        cost = 0.0
        grad = np.zeros(self.n_par)
        fim = np.zeros((self.n_par, self.n_par))
        for r, (rec, trial) in enumerate(zip(self.records, self.trial)):
            q0 = p[self.n_shared + 8 * r:self.n_shared + 8 * r + 8]
            c, g, f, _ = passes.sensitivity_pass(
                np.ascontiguousarray(q0), np.ascontiguousarray(theta), np.ascontiguousarray(b + trial),
                self.estimate_b, rec.dt_s, rec.angle_rad, rec.speed_rad_s, rec.accel_rad_s2, rec.force_gen_n,
                rec.y(), rec.use, self.arrays.hp, self.rinv, self.dmap, self.powers, self.model.speed_ref_rad_s,
                self.model.speed_scale_rad_s, self.arrays.minv, self.arrays.gyro, self.arrays.wimb)
            if not np.isfinite(c):
                return np.inf, grad, fim
            # local layout [q0, theta, b] -> global [theta, b, q0_1, ...]
            idx = np.concatenate([np.arange(self.n_shared + 8 * r, self.n_shared + 8 * r + 8),
                                  np.arange(self.n_shared)])
            cost += c
            grad[idx] += g
            fim[np.ix_(idx, idx)] += f
        return cost, grad, fim


def _levenberg_marquardt(prob: _Problem, p: np.ndarray, b_fixed: np.ndarray, max_iterations: int, tol: float):
    cost, grad, fim = prob.evaluate(p, b_fixed)
    if not np.isfinite(cost):
        raise InputError("batch fit: the model response from the initial guess is not finite. The imbalance "
                         f"used ({np.round(b_fixed, 9).tolist()} kg*m per plane, cos/sin; plus any trial weights) "
                         "drives it: check the stated imbalance and trial weights (a linear rotor with stable "
                         "initial coefficients stays finite for any finite imbalance) or the initial coefficients")
    mu = 1e-3
    it = 0
    converged = False
    for it in range(1, max_iterations + 1):
        d = np.sqrt(np.clip(np.diag(fim), 1e-300, None))
        fn = fim / np.outer(d, d)
        gn = grad / d
        while True:
            step = np.linalg.solve(fn + mu * np.eye(len(p)), gn) / d
            trial = p + step
            c_new, g_new, f_new = prob.evaluate(trial, b_fixed)
            if np.isfinite(c_new) and c_new <= cost:
                break
            mu *= 8.0
            if mu > 1e12:
                return p, cost, grad, fim, it, False
        decrement = float(grad @ step)
        p, cost, grad, fim = trial, c_new, g_new, f_new
        mu = max(mu / 5.0, 1e-9)
        if decrement < tol:
            converged = True
            break
    return p, cost, grad, fim, it, converged


def fit(arrays: RigArrays, model: CoefficientModel, records: Record | list[Record], theta0: np.ndarray, *,
        options: BatchOptions = BatchOptions(), imbalance_kg_m: np.ndarray | None = None,
        trial_imbalance_kg_m: list[np.ndarray] | None = None) -> IdentificationResult:
    """Maximum-likelihood ``theta`` from one or several records.

    ``imbalance_kg_m``: the known imbalance, or the initial guess when estimated
    (default: the rig file's). ``trial_imbalance_kg_m``: known trial weights per record.
    """
    t_start = time.perf_counter()
    records = [records] if isinstance(records, Record) else list(records)
    if any(r.probes_m is None for r in records):
        raise InputError("batch fit: every record needs probe readings")
    trials = trial_imbalance_kg_m or [np.zeros(arrays.n_imbalance)] * len(records)
    b0 = arrays.imbalance_nominal_kg_m.copy() if imbalance_kg_m is None else np.asarray(imbalance_kg_m, float)
    if options.estimate_imbalance and imbalance_kg_m is None:
        b0 = np.zeros(arrays.n_imbalance)
    p = np.zeros(model.n_theta + (arrays.n_imbalance if options.estimate_imbalance else 0) + 8 * len(records))
    p[:model.n_theta] = theta0
    if options.estimate_imbalance:
        p[model.n_theta:model.n_theta + arrays.n_imbalance] = b0
    for r, rec in enumerate(records):  # initial displacement from the first reading (Eq. 6), velocity 0
        p[p.size - 8 * (len(records) - r) + 4:p.size - 8 * (len(records) - r) + 8] = (
            arrays.bearing_from_probe @ np.nan_to_num(rec.probes_m[0]))
    total_it = 0
    converged = False
    for frac in options.warm_start_fraction:
        prob = _Problem(arrays, model, [_truncate(r, frac) for r in records], trials, options.estimate_imbalance,
                        options.noise_std_m)
        if model.speed_order > 0 and not np.isfinite(prob.evaluate(p, b0)[0]):
            # a speed polynomial fitted on a prefix can extrapolate to unstable coefficients
            # over the rest of the sweep: restart the longer stage from its constant part
            p[model.n_coefficients:model.n_theta] = 0.0
        p, cost, grad, fim, it, converged = _levenberg_marquardt(prob, p, b0, options.max_iterations,
                                                                 options.tolerance)
        total_it += it
    n_shared = prob.n_shared
    # information of the shared parameters with the initial states eliminated
    from rotor_estimator.core.fisher import bound, eliminate_nuisance

    order = np.concatenate([np.arange(n_shared, prob.n_par), np.arange(n_shared)])
    info_shared = eliminate_nuisance(fim[np.ix_(order, order)], 8 * len(records))
    bnd = bound(info_shared, model.n_theta)
    n_used = sum(int(r.use.sum()) for r in records)
    b_est = p[model.n_theta:n_shared] if options.estimate_imbalance else b0
    return IdentificationResult(
        method="batch-ml", model=model, theta=p[:model.n_theta].copy(), covariance=bnd.covariance,
        imbalance_kg_m=np.asarray(b_est, dtype=float).copy(), imbalance_estimated=options.estimate_imbalance,
        runtime_s=time.perf_counter() - t_start, converged=converged, iterations=total_it, information=info_shared,
        extra={"cost": float(cost), "noise_std_estimate_m": float(options.noise_std_m * np.sqrt(cost / (4 * n_used))),
               "n_parameters": int(prob.n_par),
               "initial_states": p[n_shared:].reshape(-1, 8)})
