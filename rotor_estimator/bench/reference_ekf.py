# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Plain-numpy reference of one EKF step, written with whole matrices for reading and checking.

This is the same discrete model as the compiled kernel (RK4 step of Eq. 12, its exact
Jacobian for Eq. 13, Joseph-form update of Eqs. 15-17), written independently with
matrix algebra. Tests require the kernel to match it to tight tolerance; the speed
benchmark feeds it to filterpy's ``ExtendedKalmanFilter`` as the baseline.
"""
from __future__ import annotations

import numpy as np

from rotor_estimator.core.ekf import FilterModel
from rotor_estimator.core.model import damping_matrix, stiffness_matrix


def generalized_force(model: FilterModel, t: float, angle0: float, omega0: float, alpha: float,
                      impact_n: np.ndarray) -> np.ndarray:
    """F0(t) of Eq. 5 along the shaft angle ``angle0 + omega0 t + alpha t^2/2`` plus the impact."""
    theta = angle0 + omega0 * t + 0.5 * alpha * t * t
    omega = omega0 + alpha * t
    a = theta + model.phases
    fx = model.moments * (omega ** 2 * np.cos(a) + alpha * np.sin(a))
    fy = model.moments * (omega ** 2 * np.sin(a) - alpha * np.cos(a))
    w1, w2 = model.wimb
    force = np.array([fx @ w1, fy @ w1, fx @ w2, fy @ w2])
    i1, i2 = model.wimp
    return force + np.array([i1 * impact_n[0], i1 * impact_n[1], i2 * impact_n[0], i2 * impact_n[1]])


def dynamics(model: FilterModel, x: np.ndarray, t: float, angle0: float, omega0: float, alpha: float,
             impact_n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``f`` of Eq. 9 for the 8 motion states and its Jacobian ``A`` (Eq. 14) w.r.t. all 16 states."""
    v, z, r = x[:4], x[4:8], x[8:]
    omega = omega0 + alpha * t
    c_total = damping_matrix(r) + omega * model.gyro
    s = stiffness_matrix(r)
    f = np.concatenate([model.minv @ (generalized_force(model, t, angle0, omega0, alpha, impact_n)
                                      - c_total @ v - s @ z), v])
    d = np.zeros((4, 8))  # d(S z + C v)/dr
    for b in (0, 2):
        d[b, 0:2], d[b + 1, 2:4] = z[b:b + 2], z[b:b + 2]
        d[b, 4:6], d[b + 1, 6:8] = v[b:b + 2], v[b:b + 2]
    jac = np.zeros((8, 16))
    jac[:4, :4] = -model.minv @ c_total
    jac[:4, 4:8] = -model.minv @ s
    jac[:4, 8:] = -model.minv @ d
    jac[4:, :4] = np.eye(4)
    return f, jac


def rk4_step(model: FilterModel, x: np.ndarray, h: float, angle0: float, omega0: float, alpha: float,
             impact_n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """State prediction (Eq. 12) by one RK4 step and the 16x16 Jacobian of that step."""
    lift = np.zeros((8, 16))
    lift[:, :8] = np.eye(8)
    r_cols = np.zeros((8, 16))
    q0 = x[:8]
    ks: list[np.ndarray] = []
    dks: list[np.ndarray] = []
    for c, tc in ((0.0, 0.0), (0.5, 0.5), (0.5, 0.5), (1.0, 1.0)):
        q = q0 + c * h * (ks[-1] if ks else 0.0)
        dq = lift + c * h * (dks[-1] if dks else r_cols)
        f, jac = dynamics(model, np.concatenate([q, x[8:]]), tc * h, angle0, omega0, alpha, impact_n)
        # chain rule: d f(q(theta), r)/d theta = J_q dq/dtheta + J_r dr/dtheta
        dk = jac[:, :8] @ dq
        dk[:, 8:] += jac[:, 8:]
        ks.append(f)
        dks.append(dk)
    x_new = x.copy()
    x_new[:8] = q0 + h / 6 * (ks[0] + 2 * ks[1] + 2 * ks[2] + ks[3])
    phi = np.eye(16)
    phi[:8, :] = lift + h / 6 * (dks[0] + 2 * dks[1] + 2 * dks[2] + dks[3])
    return x_new, phi


def measurement_matrix(model: FilterModel) -> np.ndarray:
    """H of Eq. 11 through the probe map: probes = Hp z."""
    h = np.zeros((4, 16))
    h[:, 4:8] = model.hp
    return h


def process_noise(model: FilterModel, h: float) -> np.ndarray:
    """Discrete Q over a step ``h``: white acceleration on the motion states, random walk on r."""
    q = np.zeros((16, 16))
    a = model.accel_psd
    for i in range(4):
        q[i, i] = a * h
        q[i, 4 + i] = q[4 + i, i] = a * h * h / 2
        q[4 + i, 4 + i] = a * h ** 3 / 3
    q[8:, 8:] = np.diag(model.coeff_rw_var_rate * h)
    return q


def ekf_step(model: FilterModel, x: np.ndarray, P: np.ndarray, h: float, shaft_prev: tuple[float, float, float],
             impact_prev: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """One full predict + update (no gating), returning ``x, P, innovation, NIS``."""
    x_bar, phi = rk4_step(model, x, h, *shaft_prev, impact_prev)
    p_bar = phi @ P @ phi.T + process_noise(model, h)
    hm = measurement_matrix(model)
    r = np.diag(model.r_var)
    e = y - hm @ x_bar
    s = hm @ p_bar @ hm.T + r
    k = np.linalg.solve(s, hm @ p_bar).T
    i_kh = np.eye(16) - k @ hm
    p_new = i_kh @ p_bar @ i_kh.T + k @ r @ k.T
    return x_bar + k @ e, 0.5 * (p_new + p_new.T), e, float(e @ np.linalg.solve(s, e))
