# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Compiled inner loop of the continuous-discrete EKF (Eqs. 9-17 of Miller & Howard).

One call processes a block of samples; the per-sample API calls it with a block of
one. The arithmetic is the same as :mod:`rotor_estimator.bench.reference_ekf` (plain numpy),
written as explicit loops that exploit the structure of the 16-state problem:

* the coefficients are constant between samples (Eq. 8 with Q_r as a random walk),
  so the transition matrix is ``[[Phi_m (8x16)], [0, I8]]`` and only its top 8 rows
  are integrated;
* the measurement reads the 4 displacement states only (Eq. 11 through the probe
  map of Eq. 6), so the gain needs ``P[:, 4:8]`` and a 4x4 innovation covariance.

The state prediction (Eq. 12) is one classical RK4 step per sample period (split
into equal sub-steps when a gap makes the step longer than ``max_step_s``), and the
covariance prediction (Eq. 13) uses the exact Jacobian of that RK4 map, obtained by
forward-mode differentiation of the four stages; this is the discrete EKF of the
RK4-discretized model, consistent to the integration order with Eq. 13.

Status codes written per sample: see ``STATUS_*``.
"""
from __future__ import annotations

import math

import numpy as np

from rotor_estimator.core.forcing import add_imbalance_force, rigid_state_derivative
from rotor_estimator.core.jit import njit

STATUS_UPDATED = 0
STATUS_GATED = 1          # innovation outside the gate: measurement rejected as an outlier
STATUS_NON_FINITE = 2     # NaN/inf in the measurement: rejected
STATUS_NUMERICAL = 3      # innovation covariance not positive definite: update skipped
STATUS_SKIPPED = 4        # caller asked to predict only (e.g. no shaft reference)
STATUS_INITIALIZED = 5    # first sample: used to initialize the displacement states
STATUS_NAMES = {STATUS_UPDATED: "updated", STATUS_GATED: "gated_outlier", STATUS_NON_FINITE: "non_finite",
                STATUS_NUMERICAL: "numerical_failure", STATUS_SKIPPED: "skipped", STATUS_INITIALIZED: "initialized"}

N_STATE = 16


@njit
def _stage(q, r, t, angle0, omega0, alpha, fimp, minv, gyro, moments, phases, wimb, wimp, dq, k_out, dk_out):
    """One RK4 stage: ``k = f(q, r, t)`` and ``dk = df/dq @ dq + df/dr @ [0 I]`` (8x16)."""
    theta = angle0 + omega0 * t + 0.5 * alpha * t * t
    omega = omega0 + alpha * t
    # generalized force, Eq. 5 (imbalance following the shaft angle) plus the impact
    force = np.empty(4)
    force[0] = wimp[0] * fimp[0]
    force[1] = wimp[0] * fimp[1]
    force[2] = wimp[1] * fimp[0]
    force[3] = wimp[1] * fimp[1]
    add_imbalance_force(theta, omega, alpha, moments, phases, wimb, force)
    f0, f1, f2, f3 = force[0], force[1], force[2], force[3]
    kxx, kxy, kyx, kyy = r[0], r[1], r[2], r[3]
    cxx, cxy, cyx, cyy = r[4], r[5], r[6], r[7]
    v0, v1, v2, v3 = q[0], q[1], q[2], q[3]
    z0, z1, z2, z3 = q[4], q[5], q[6], q[7]
    # bearing forces S z + C v (Eq. 1, identical bearings) and the gyroscopic term
    res = np.empty(4)
    res[0] = f0 - (kxx * z0 + kxy * z1 + cxx * v0 + cxy * v1)
    res[1] = f1 - (kyx * z0 + kyy * z1 + cyx * v0 + cyy * v1)
    res[2] = f2 - (kxx * z2 + kxy * z3 + cxx * v2 + cxy * v3)
    res[3] = f3 - (kyx * z2 + kyy * z3 + cyx * v2 + cyy * v3)
    rigid_state_derivative(res, q, omega, gyro, minv, k_out)
    # Jacobian of the bearing+gyro force w.r.t. q: B = -(C + Omega G) for v, -S for z
    bq = np.zeros((4, 8))
    bq[0, 0] = -cxx
    bq[0, 1] = -cxy
    bq[1, 0] = -cyx
    bq[1, 1] = -cyy
    bq[2, 2] = -cxx
    bq[2, 3] = -cxy
    bq[3, 2] = -cyx
    bq[3, 3] = -cyy
    bq[0, 4] = -kxx
    bq[0, 5] = -kxy
    bq[1, 4] = -kyx
    bq[1, 5] = -kyy
    bq[2, 6] = -kxx
    bq[2, 7] = -kxy
    bq[3, 6] = -kyx
    bq[3, 7] = -kyy
    for rr in range(4):
        for c in range(4):
            bq[rr, c] -= omega * gyro[rr, c]
    aq = np.zeros((4, 8))
    for rr in range(4):
        for c in range(8):
            acc = 0.0
            for m in range(4):
                acc += minv[rr, m] * bq[m, c]
            aq[rr, c] = acc
    # derivative w.r.t. r (Eq. 1): d(Sz + Cv)/dr, rows x1 y1 x2 y2, cols kxx kxy kyx kyy cxx cxy cyx cyy
    br = np.zeros((4, 8))
    br[0, 0] = -z0
    br[0, 1] = -z1
    br[1, 2] = -z0
    br[1, 3] = -z1
    br[2, 0] = -z2
    br[2, 1] = -z3
    br[3, 2] = -z2
    br[3, 3] = -z3
    br[0, 4] = -v0
    br[0, 5] = -v1
    br[1, 6] = -v0
    br[1, 7] = -v1
    br[2, 4] = -v2
    br[2, 5] = -v3
    br[3, 6] = -v2
    br[3, 7] = -v3
    # dk = [aq; I 0] @ dq + [minv @ br; 0] on the r columns
    for rr in range(4):
        for c in range(16):
            acc = 0.0
            for m in range(8):
                acc += aq[rr, m] * dq[m, c]
            dk_out[rr, c] = acc
        for c in range(8):
            acc = 0.0
            for m in range(4):
                acc += minv[rr, m] * br[m, c]
            dk_out[rr, 8 + c] += acc
    for rr in range(4):
        for c in range(16):
            dk_out[4 + rr, c] = dq[rr, c]


@njit
def _rk4_with_jacobian(x, h, angle0, omega0, alpha, fimp, minv, gyro, moments, phases, wimb, wimp, phi_m):
    """Advance the 8 motion states of ``x`` by ``h`` (in place); return their Jacobian in ``phi_m`` (8x16)."""
    q = x[:8].copy()
    r = x[8:]
    k1 = np.empty(8)
    k2 = np.empty(8)
    k3 = np.empty(8)
    k4 = np.empty(8)
    d1 = np.empty((8, 16))
    d2 = np.empty((8, 16))
    d3 = np.empty((8, 16))
    d4 = np.empty((8, 16))
    dq = np.zeros((8, 16))
    for i in range(8):
        dq[i, i] = 1.0
    _stage(q, r, 0.0, angle0, omega0, alpha, fimp, minv, gyro, moments, phases, wimb, wimp, dq, k1, d1)
    qs = np.empty(8)
    for i in range(8):
        qs[i] = q[i] + 0.5 * h * k1[i]
        for c in range(16):
            dq[i, c] = (1.0 if i == c else 0.0) + 0.5 * h * d1[i, c]
    _stage(qs, r, 0.5 * h, angle0, omega0, alpha, fimp, minv, gyro, moments, phases, wimb, wimp, dq, k2, d2)
    for i in range(8):
        qs[i] = q[i] + 0.5 * h * k2[i]
        for c in range(16):
            dq[i, c] = (1.0 if i == c else 0.0) + 0.5 * h * d2[i, c]
    _stage(qs, r, 0.5 * h, angle0, omega0, alpha, fimp, minv, gyro, moments, phases, wimb, wimp, dq, k3, d3)
    for i in range(8):
        qs[i] = q[i] + h * k3[i]
        for c in range(16):
            dq[i, c] = (1.0 if i == c else 0.0) + h * d3[i, c]
    _stage(qs, r, h, angle0, omega0, alpha, fimp, minv, gyro, moments, phases, wimb, wimp, dq, k4, d4)
    w = h / 6.0
    for i in range(8):
        x[i] = q[i] + w * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
        for c in range(16):
            phi_m[i, c] = (1.0 if i == c else 0.0) + w * (d1[i, c] + 2.0 * d2[i, c] + 2.0 * d3[i, c] + d4[i, c])


@njit
def _propagate_covariance(P, phi_m, h, accel_psd, coeff_rw_var_rate):
    """Eq. 13 in discrete form: ``P = Phi P Phi^T + Qd`` with ``Phi = [[phi_m], [0, I]]``."""
    w = np.zeros((8, 16))
    for i in range(8):
        for c in range(16):
            acc = 0.0
            for m in range(16):
                acc += phi_m[i, m] * P[m, c]
            w[i, c] = acc
    new_mm = np.zeros((8, 8))
    for i in range(8):
        for j in range(i, 8):
            acc = 0.0
            for m in range(16):
                acc += w[i, m] * phi_m[j, m]
            new_mm[i, j] = acc
            new_mm[j, i] = acc
    # white acceleration noise on the 4 coordinates (Q_v, Q_z of Eq. 9)
    if accel_psd > 0.0:
        for i in range(4):
            new_mm[i, i] += accel_psd * h
            new_mm[i, 4 + i] += accel_psd * h * h / 2.0
            new_mm[4 + i, i] += accel_psd * h * h / 2.0
            new_mm[4 + i, 4 + i] += accel_psd * h * h * h / 3.0
    for i in range(8):
        for j in range(8):
            P[i, j] = new_mm[i, j]
        for c in range(8, 16):
            P[i, c] = w[i, c]
            P[c, i] = w[i, c]
    for i in range(8):
        P[8 + i, 8 + i] += coeff_rw_var_rate[i] * h


@njit
def _cholesky4(S, L):
    """Cholesky of a 4x4 SPD matrix into ``L``; False when not positive definite."""
    for i in range(4):
        for j in range(i + 1):
            acc = S[i, j]
            for m in range(j):
                acc -= L[i, m] * L[j, m]
            if i == j:
                if not acc > 0.0 or not math.isfinite(acc):
                    return False
                L[i, i] = math.sqrt(acc)
            else:
                L[i, j] = acc / L[j, j]
        for j in range(i + 1, 4):
            L[i, j] = 0.0
    return True


@njit
def _update(x, P, y, hp, r_var, gate, innov_out, s_std_out):
    """Eqs. 15-17 with the Joseph form; returns (status, nis)."""
    # innovation (Eq. 15) and its covariance S = H P H^T + R (Eq. 17)
    pht = np.zeros((16, 4))
    for i in range(16):
        for j in range(4):
            acc = 0.0
            for m in range(4):
                acc += P[i, 4 + m] * hp[j, m]
            pht[i, j] = acc
    S = np.zeros((4, 4))
    e = np.zeros(4)
    for i in range(4):
        pred = 0.0
        for m in range(4):
            pred += hp[i, m] * x[4 + m]
        e[i] = y[i] - pred
        for j in range(4):
            acc = 0.0
            for m in range(4):
                acc += hp[i, m] * pht[4 + m, j]
            S[i, j] = acc
        S[i, i] += r_var[i]
    for i in range(4):
        for j in range(i + 1, 4):
            avg = 0.5 * (S[i, j] + S[j, i])
            S[i, j] = avg
            S[j, i] = avg
    for i in range(4):
        innov_out[i] = e[i]
        s_std_out[i] = math.sqrt(S[i, i]) if S[i, i] > 0 else math.nan
    L = np.zeros((4, 4))
    if not _cholesky4(S, L):
        return STATUS_NUMERICAL, math.nan
    # NIS = e^T S^-1 e via the Cholesky factor
    u = np.zeros(4)
    for i in range(4):
        acc = e[i]
        for m in range(i):
            acc -= L[i, m] * u[m]
        u[i] = acc / L[i, i]
    nis = 0.0
    for i in range(4):
        nis += u[i] * u[i]
    if nis > gate:
        return STATUS_GATED, nis
    # K = P H^T S^-1 (solve, never invert S)
    K = np.zeros((16, 4))
    for row in range(16):
        b = np.zeros(4)
        for i in range(4):
            acc = pht[row, i]
            for m in range(i):
                acc -= L[i, m] * b[m]
            b[i] = acc / L[i, i]
        for i in range(3, -1, -1):
            acc = b[i]
            for m in range(i + 1, 4):
                acc -= L[m, i] * K[row, m]
            K[row, i] = acc / L[i, i]
    for i in range(16):
        acc = 0.0
        for j in range(4):
            acc += K[i, j] * e[j]
        x[i] += acc
    # Joseph form, expanded: (I-KH)P(I-KH)^T + KRK^T = P - K PHt^T - PHt K^T + K S K^T
    ks = np.zeros((16, 4))
    for i in range(16):
        for j in range(4):
            acc = 0.0
            for m in range(4):
                acc += K[i, m] * S[m, j]
            ks[i, j] = acc
    for i in range(16):
        for j in range(i, 16):
            acc = 0.0
            for m in range(4):
                acc += -K[i, m] * pht[j, m] - pht[i, m] * K[j, m] + ks[i, m] * K[j, m]
            val = P[i, j] + acc
            if i != j:
                val = 0.5 * (val + P[j, i] + acc)
            P[i, j] = val
            P[j, i] = val
    return STATUS_UPDATED, nis


@njit
def run_block(x, P, dt_s, angle_rad, speed_rad_s, accel_rad_s2, impact_n, y, skip, minv, gyro, moments, phases,
              wimb, wimp, hp, r_var, accel_psd, coeff_rw_var_rate, gate, max_step_s,
              status_out, nis_out, innov_out, s_std_out):
    """Process ``n`` samples in order, in place on ``x`` (16,) and ``P`` (16, 16).

    For sample ``k``: predict over ``dt_s[k]`` from the previous sample with the
    shaft angle/speed/acceleration and impact force of the previous sample
    (``angle_rad[k]`` etc. hold those, already shifted by the caller), then update
    with ``y[k]`` (4 probe readings) unless ``skip[k]``.
    Returns the index of the first sample after which the state or covariance became
    non-finite (``n`` when healthy); processing stops there.
    """
    n = y.shape[0]
    phi_m = np.empty((8, 16))
    fimp = np.empty(2)
    innov = np.empty(4)
    sstd = np.empty(4)
    for k in range(n):
        h_total = dt_s[k]
        n_sub = 1
        if h_total > max_step_s:
            n_sub = int(math.ceil(h_total / max_step_s))
        h = h_total / n_sub
        fimp[0] = impact_n[k, 0]
        fimp[1] = impact_n[k, 1]
        for s in range(n_sub):
            t0 = s * h
            a0 = angle_rad[k] + speed_rad_s[k] * t0 + 0.5 * accel_rad_s2[k] * t0 * t0
            w0 = speed_rad_s[k] + accel_rad_s2[k] * t0
            _rk4_with_jacobian(x, h, a0, w0, accel_rad_s2[k], fimp, minv, gyro, moments, phases, wimb, wimp, phi_m)
            _propagate_covariance(P, phi_m, h, accel_psd, coeff_rw_var_rate)
        finite = True
        for i in range(4):
            if not math.isfinite(y[k, i]):
                finite = False
        if skip[k]:
            status_out[k] = STATUS_SKIPPED
            nis_out[k] = math.nan
            for i in range(4):
                innov_out[k, i] = math.nan
                s_std_out[k, i] = math.nan
        elif not finite:
            status_out[k] = STATUS_NON_FINITE
            nis_out[k] = math.nan
            for i in range(4):
                innov_out[k, i] = math.nan
                s_std_out[k, i] = math.nan
        else:
            st, nis = _update(x, P, y[k], hp, r_var, gate, innov, sstd)
            status_out[k] = st
            nis_out[k] = nis
            for i in range(4):
                innov_out[k, i] = innov[i]
                s_std_out[k, i] = sstd[i]
        healthy = True
        for i in range(16):
            if not math.isfinite(x[i]) or not P[i, i] > 0.0 or not math.isfinite(P[i, i]):
                healthy = False
        if not healthy:
            return k
    return n
