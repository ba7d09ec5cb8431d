# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Cramér-Rao lower bound of the bearing coefficients from the samples actually used.

For Gaussian measurement noise ``y_k = H z_k(theta) + v_k``, ``v_k ~ N(0, R)``, the
Fisher information is ``F = sum_k J_k^T H^T R^-1 H J_k`` with ``J_k = dz_k/dtheta``.
The parameters ``theta`` are the 8 coefficients plus, as nuisance parameters, the 8
motion states at the first sample (the estimator does not know them either), and
optionally the imbalance (2 components per plane) when it is unknown. The
sensitivities are propagated with the exact Jacobian of the RK4 step of Eq. 12 along
the noise-free trajectory (:func:`rotor_estimator.core.filter_kernel.transition_seed`),
and cross-checked in the tests against finite differences of the independent
simulator.

The CRLB standard deviation of coefficient ``i`` is ``sqrt((F^-1)_ii)``; an efficient
unbiased estimator's spread reaches it. A coefficient whose bound exceeds its own
magnitude cannot be pinned down by the data.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rotor_estimator.core.jit import njit
from rotor_estimator.core.ekf import FilterModel
from rotor_estimator.core.filter_kernel import transition_seed


@dataclass
class CramerRaoBound:
    """Fisher information and the resulting bounds.

    * ``fisher``: information of all parameters ``[q0 (8), r (8), imbalance (2 per plane)?]``.
    * ``coefficient_covariance``: the 8x8 block of ``F^-1`` for ``r`` (SI units squared).
    * ``coefficient_std``: its square-rooted diagonal; ``inf`` where not identifiable.
    """

    fisher: np.ndarray
    coefficient_covariance: np.ndarray
    coefficient_std: np.ndarray
    n_samples: int

    def relative_std(self, coefficients: np.ndarray, floor: np.ndarray | None = None) -> np.ndarray:
        """Bound relative to ``|coefficients|`` (or to ``floor`` where larger, for near-zero terms)."""
        scale = np.abs(np.asarray(coefficients, dtype=float))
        if floor is not None:
            scale = np.maximum(scale, floor)
        return self.coefficient_std / scale


@njit
def _sensitivities_fim(x0, dt, angle, speed, accel, impact, minv, gyro, moments, phases, wimb, wimp, hp, r_var,
                       imb_cols):
    """Accumulate the Fisher information along the trajectory from ``x0`` (16 states incl. r)."""
    n = dt.shape[0] + 1
    n_par = 16 + imb_cols
    x = x0.copy()
    sens = np.zeros((8, n_par))
    for i in range(8):
        sens[i, i] = 1.0
    fim = np.zeros((n_par, n_par))
    phi_m = np.empty((8, 16))
    fimp = np.empty(2)
    zero_moments = np.zeros(moments.shape[0])
    for k in range(n):
        # information of sample k
        dy = np.zeros((4, n_par))
        for i in range(4):
            for c in range(n_par):
                acc = 0.0
                for m in range(4):
                    acc += hp[i, m] * sens[4 + m, c]
                dy[i, c] = acc
        for a in range(n_par):
            for b in range(a, n_par):
                acc = 0.0
                for i in range(4):
                    acc += dy[i, a] * dy[i, b] / r_var[i]
                fim[a, b] += acc
        if k == n - 1:
            break
        fimp[0] = impact[k, 0]
        fimp[1] = impact[k, 1]
        transition_seed(x, dt[k], angle[k], speed[k], accel[k], fimp, minv, gyro, moments, phases, wimb, wimp,
                        phi_m)
        new = np.zeros((8, n_par))
        for i in range(8):
            for c in range(n_par):
                acc = 0.0
                for m in range(8):
                    acc += phi_m[i, m] * sens[m, c]
                if 8 <= c < 16:
                    acc += phi_m[i, c]
                new[i, c] = acc
        if imb_cols > 0:
            # d q_{k+1} / d (imbalance component): the forcing enters linearly, so the
            # derivative of one RK4 step w.r.t. a unit force component is the step of a
            # unit force; computed by finite difference of the (linear) forcing term.
            for j in range(moments.shape[0]):
                for comp in range(2):
                    xb = np.zeros(16)  # zero motion state: the step's forced part only
                    xb[8:] = x0[8:16]
                    # unit moment rotated by 0 (cos part) or 90 deg (sin part)
                    m_unit = zero_moments.copy()
                    m_unit[j] = 1.0
                    ph = phases.copy()
                    ph[j] = phases[j] + (0.0 if comp == 0 else 0.5 * np.pi)
                    phi_dummy = np.empty((8, 16))
                    zero_f = np.zeros(2)
                    transition_seed(xb, dt[k], angle[k], speed[k], accel[k], zero_f, minv, gyro, m_unit, ph,
                                    wimb, wimp, phi_dummy)
                    col = 16 + 2 * j + comp
                    for i in range(8):
                        new[i, col] += xb[i]
        sens = new
    for a in range(n_par):
        for b in range(a):
            fim[a, b] = fim[b, a]
    return fim


def fisher_information(model: FilterModel, x_start: np.ndarray, t_s: np.ndarray, angle_rad: np.ndarray,
                       speed_rad_s: np.ndarray, accel_rad_s2: np.ndarray, impact_n: np.ndarray,
                       *, unknown_imbalance: bool = False) -> np.ndarray:
    """Fisher information of ``[q0, r, (imbalance)]`` from samples at ``t_s``.

    ``x_start``: true ``[v, z, r]`` (16) at ``t_s[0]``; shaft and impact inputs per sample
    (the prediction from sample k to k+1 uses those of sample k, as the EKF does).
    With ``unknown_imbalance`` the 2 components (in phase, in quadrature) of each
    imbalance plane's moment are extra nuisance parameters (a unit-moment basis).
    """
    dt = np.diff(np.asarray(t_s, dtype=float))
    imb_cols = 2 * model.moments.shape[0] if unknown_imbalance else 0
    return _sensitivities_fim(np.asarray(x_start, dtype=float), dt, np.ascontiguousarray(angle_rad, dtype=float),
                              np.ascontiguousarray(speed_rad_s, dtype=float),
                              np.ascontiguousarray(accel_rad_s2, dtype=float),
                              np.ascontiguousarray(impact_n, dtype=float), model.minv, model.gyro, model.moments,
                              model.phases, model.wimb, model.wimp, model.hp, model.r_var, imb_cols)


def bound_from_fisher(fisher: np.ndarray, n_samples: int, *, nuisance_first: int = 8) -> CramerRaoBound:
    """Invert the information (scaled, symmetric eigen-decomposition) and take the r block.

    Parameters whose information is numerically zero give an infinite bound instead of
    a misleading finite number.
    """
    scale = np.sqrt(np.clip(np.diag(fisher), 1e-300, None))
    normalized = fisher / np.outer(scale, scale)
    w, v = np.linalg.eigh(normalized)
    tol = w.max() * 1e-13
    inv_w = np.where(w > tol, 1.0 / np.where(w > tol, w, 1.0), np.inf)
    with np.errstate(invalid="ignore", over="ignore"):
        cov_normalized = (v * np.where(np.isinf(inv_w), 0.0, inv_w)) @ v.T
        unidentified = (v[:, np.isinf(inv_w)] ** 2).sum(axis=1) > 1e-6
        cov = cov_normalized / np.outer(scale, scale)
    r = slice(nuisance_first, nuisance_first + 8)
    cov_r = cov[r, r]
    std = np.sqrt(np.clip(np.diag(cov_r), 0, None))
    std[unidentified[r]] = np.inf
    return CramerRaoBound(fisher=fisher, coefficient_covariance=cov_r, coefficient_std=std, n_samples=n_samples)
