# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Identification's drivers of the compiled filter kernel (:mod:`rotor_estimator.core.filter_kernel`).

Everything model- and filter-related (the generalized rigid-rotor model of Eq. 2 with the coefficient
map ``dmap``/``powers`` and the in-phase/quadrature imbalance, the RK4 step of Eq. 12 with its
sensitivities, the prediction of Eqs. 12-13 and the gated update of Eqs. 15-17) is the shared kernel;
this module only runs it over whole records:

* :func:`simulate_states` -- the noise-free response;
* :func:`sensitivity_pass` -- output-error cost, gradient and Fisher information (batch fit, planner);
* :func:`ekf_pass` / :func:`rts_pass` -- the (iterated) EKF forward pass and the Rauch-Tung-Striebel
  backward pass on the augmented state ``[q (8), theta, b?]``;
* :func:`ukf_pass` -- the unscented filter (sigma points through :func:`~rotor_estimator.core.filter_kernel.rk4_step`).
"""
from __future__ import annotations

import math

import numpy as np

from rotor_estimator.core.filter_kernel import add_process_noise, healthy, predict, rk4_step, update
from rotor_estimator.core.jit import njit


# ------------------------------------------------------------------------------------ simulation
@njit(cache=True)
def simulate_states(q0, theta, bvec, dt, substeps, angle, speed, accel, fgen, dmap, powers, speed_ref, speed_scale,
                    minv, gyro, wimb):
    """States ``[v, z]`` at every sample (n, 8) from ``q0`` at sample 0; ``substeps`` RK4 steps per period.

    Sample ``k``'s shaft state (angle, speed, constant acceleration) and generalized
    impact force ``fgen[k]`` (zero-order hold) drive the step from ``k`` to ``k+1``.
    """
    n = angle.shape[0]
    out = np.empty((n, 8))
    q = q0.copy()
    dq = np.zeros((8, 0))
    for k in range(n):
        for i in range(8):
            out[k, i] = q[i]
        if k == n - 1:
            break
        h = dt[k] / substeps
        for s in range(substeps):
            t0 = s * h
            a0 = angle[k] + speed[k] * t0 + 0.5 * accel[k] * t0 * t0
            w0 = speed[k] + accel[k] * t0
            rk4_step(q, dq, theta, bvec, h, a0, w0, accel[k], fgen[k], dmap, powers, speed_ref, speed_scale,
                     minv, gyro, wimb, -1, -1)
    return out


# ------------------------------------------------------------------------------------ batch fit
@njit(cache=True)
def sensitivity_pass(q0, theta, bvec, estimate_b, dt, angle, speed, accel, fgen, y, use, hp, rinv, dmap, powers,
                     speed_ref, speed_scale, minv, gyro, wimb):
    """Output-error cost, gradient and Fisher information along the model response.

    Parameters (columns): ``[q0 (8), theta (ntheta), b (nb if estimate_b)]``.
    Residual ``e_k = y_k - Hp z_k`` on samples with ``use[k]``; returns
    ``(cost = sum e^T R^-1 e, grad = sum J^T R^-1 e, fim = sum J^T R^-1 J, n_used)``
    where ``J_k = Hp dz_k/dp``. With ``y`` of zero rows only the information is computed.
    """
    n = angle.shape[0]
    nth = theta.shape[0]
    nb = bvec.shape[0] if estimate_b else 0
    ncol = 8 + nth + nb
    q = q0.copy()
    dq = np.zeros((8, ncol))
    for i in range(8):
        dq[i, i] = 1.0
    fim = np.zeros((ncol, ncol))
    grad = np.zeros(ncol)
    cost = 0.0
    have_y = y.shape[0] == n
    dy = np.empty((4, ncol))
    e = np.empty(4)
    used = 0
    for k in range(n):
        if use[k]:
            used += 1
            for i in range(4):
                for c in range(ncol):
                    acc = 0.0
                    for m in range(4):
                        acc += hp[i, m] * dq[4 + m, c]
                    dy[i, c] = acc * rinv[i]
            for a in range(ncol):
                for b in range(a, ncol):
                    acc = 0.0
                    for i in range(4):
                        acc += dy[i, a] * dy[i, b]
                    fim[a, b] += acc
            if have_y:
                for i in range(4):
                    pred = 0.0
                    for m in range(4):
                        pred += hp[i, m] * q[4 + m]
                    e[i] = (y[k, i] - pred) * rinv[i]
                    cost += e[i] * e[i]
                for c in range(ncol):
                    acc = 0.0
                    for i in range(4):
                        acc += dy[i, c] * e[i]
                    grad[c] += acc
        if k == n - 1:
            break
        rk4_step(q, dq, theta, bvec, dt[k], angle[k], speed[k], accel[k], fgen[k], dmap, powers, speed_ref,
                 speed_scale, minv, gyro, wimb, 8, 8 + nth if estimate_b else -1)
        if not (math.isfinite(q[4]) and abs(q[4]) < 1.0):
            return math.inf, grad, fim, used
    for a in range(ncol):
        for b in range(a):
            fim[a, b] = fim[b, a]
    return cost, grad, fim, used


# ------------------------------------------------------------------------------------ EKF / smoother
@njit(cache=True)
def ekf_pass(x, P, nth, nbs, bfixed, nominal, store, dt, angle, speed, accel, fgen, y, use, hp, r_var, gate, accel_psd,
             rw_rate, dmap, powers, speed_ref, speed_scale, minv, gyro, wimb, xf_out, pf_out, nis_out):
    """Forward pass of the (iterated) EKF on the augmented state ``[q (8), theta, b?]``.

    Sample 0 is the prior (``x``, ``P``: already initialized by the caller). The
    prediction from ``k`` to ``k+1`` is linearized at ``nominal[k]`` when ``nominal`` has
    ``n`` rows (iterated smoother: ``x_pred = f(xbar) + F(xbar)(x_f - xbar)``), else at the
    current estimate (the plain EKF). With ``store`` the filtered means and covariances
    are written to ``xf_out`` (n, m) and ``pf_out`` (n, m, m) for the RTS pass.
    """
    n = angle.shape[0]
    m = x.shape[0]
    nom_none = np.zeros(0)
    phi = np.empty((8, m))
    xn = np.empty(m)
    innov = np.empty(4)
    sstd = np.empty(4)
    for k in range(n):
        if k > 0:
            kk = k - 1
            xlin = nominal[kk] if nominal.shape[0] == n else nom_none
            predict(x, P, xlin, nth, nbs, bfixed, dt[kk], angle[kk], speed[kk], accel[kk], fgen[kk], dmap, powers,
                    speed_ref, speed_scale, minv, gyro, wimb, accel_psd, rw_rate, phi, xn)
            if use[k]:
                st, nis = update(x, P, y[k], hp, r_var, gate, innov, sstd, True)
                nis_out[k] = nis
        if store:
            xf_out[k] = x
            pf_out[k] = P
        if not healthy(x, P):
            return k
    return n


@njit(cache=True)
def rts_pass(nominal, xf, pf, nth, nbs, bfixed, dt, angle, speed, accel, fgen, accel_psd, rw_rate, dmap, powers,
             speed_ref, speed_scale, minv, gyro, wimb, xs_out, ps0_out, ps_keep, keep_every):
    """Rauch-Tung-Striebel backward pass over the stored forward pass.

    ``nominal`` is the linearization trajectory the forward pass used (its filtered
    means for the plain EKF). Writes the smoothed means ``xs_out`` (n, m), the smoothed
    covariance at sample 0 ``ps0_out`` and every ``keep_every``-th smoothed covariance
    into ``ps_keep``.
    """
    n = xf.shape[0]
    m = xf.shape[1]
    xs = xf[n - 1].copy()
    ps = pf[n - 1].copy()
    xs_out[n - 1] = xs
    if keep_every > 0 and (n - 1) % keep_every == 0:
        ps_keep[(n - 1) // keep_every] = ps
    phi = np.empty((8, m))
    xn = np.empty(m)
    xpred = np.empty(m)
    Ppred = np.empty((m, m))
    Phi = np.eye(m)
    for k in range(n - 2, -1, -1):
        xn[:] = xf[k]
        Ppred[:, :] = pf[k]
        predict(xn, Ppred, nominal[k], nth, nbs, bfixed, dt[k], angle[k], speed[k], accel[k], fgen[k], dmap, powers,
                speed_ref, speed_scale, minv, gyro, wimb, accel_psd, rw_rate, phi, xpred)
        Phi[:8, :] = phi
        # G = Pf Phi^T Ppred^-1  (solve with the symmetric Ppred)
        cross = np.ascontiguousarray((pf[k] @ Phi.T).T)  # Phi Pf
        d = np.sqrt(np.diag(Ppred))
        A = Ppred / np.outer(d, d)
        B = cross / d.reshape(-1, 1)
        G = np.ascontiguousarray((np.linalg.solve(A, B) / d.reshape(-1, 1)).T)
        xs = xf[k] + G @ (xs - xn)
        ps = pf[k] + G @ (ps - Ppred) @ G.T
        ps = 0.5 * (ps + ps.T)
        xs_out[k] = xs
        if keep_every > 0 and k % keep_every == 0:
            ps_keep[k // keep_every] = ps
    ps0_out[:, :] = ps


# ------------------------------------------------------------------------------------ UKF
@njit(cache=True)
def ukf_pass(x, P, nth, nbs, bfixed, wm, wc, lam, dt, angle, speed, accel, fgen, y, use, hp, r_var, gate, accel_psd,
             rw_rate, dmap, powers, speed_ref, speed_scale, minv, gyro, wimb, nis_out):
    """Unscented Kalman filter (scaled sigma points, weights ``wm``/``wc`` from filterpy's
    ``MerweScaledSigmaPoints``) on the augmented state. The prediction propagates the
    2m+1 sigma points through the RK4 step; the measurement is linear in the state
    (``y = Hp z``), so the update is the exact linear one (equal to the unscented
    update for a linear measurement). Returns the number of samples processed."""
    n = angle.shape[0]
    m = x.shape[0]
    ns = 2 * m + 1
    sig = np.empty((ns, m))
    dq = np.zeros((8, 0))
    innov = np.empty(4)
    sstd = np.empty(4)
    for k in range(n):
        if k > 0:
            kk = k - 1
            h = dt[kk]
            Ps = 0.5 * (P + P.T) * (m + lam)
            L = np.linalg.cholesky(Ps)
            for i in range(m):
                sig[0, i] = x[i]
            for j in range(m):
                for i in range(m):
                    sig[1 + j, i] = x[i] + L[i, j]
                    sig[1 + m + j, i] = x[i] - L[i, j]
            for s in range(ns):
                q = sig[s, :8].copy()
                theta = sig[s, 8:8 + nth].copy()
                bvec = sig[s, 8 + nth:8 + nth + nbs].copy() if nbs > 0 else bfixed
                rk4_step(q, dq, theta, bvec, h, angle[kk], speed[kk], accel[kk], fgen[kk], dmap, powers, speed_ref,
                         speed_scale, minv, gyro, wimb, -1, -1)
                sig[s, :8] = q
            xm = np.zeros(m)
            for s in range(ns):
                xm += wm[s] * sig[s]
            Pm = np.zeros((m, m))
            for s in range(ns):
                d = sig[s] - xm
                Pm += wc[s] * np.outer(d, d)
            add_process_noise(Pm, h, accel_psd, rw_rate)
            x[:] = xm
            P[:, :] = 0.5 * (Pm + Pm.T)
            if use[k]:
                st, nis = update(x, P, y[k], hp, r_var, gate, innov, sstd, True)
                nis_out[k] = nis
        if not healthy(x, P):
            return k
    return n
