# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Compiled kernels of the generalized rigid-rotor model used by the identification methods.

The model is Eq. 2 of Miller & Howard with two generalizations, both reducing to the
seed model when unused:

* the 16 *physical* bearing coefficients (bearing 1 ``kxx kxy kyx kyy cxx cxy cyx cyy``,
  then bearing 2) are a linear map of the estimated parameters ``theta`` with speed
  basis functions: ``phys(Omega) = sum_j dmap[:, j] * theta_j * s**power_j`` with
  ``s = (Omega - speed_ref) / speed_scale`` (identical bearings: ``dmap = [I8; I8]``,
  powers 0 -- the seed model);
* the imbalance is carried as in-phase/quadrature moments ``b = [a_1, b_1, a_2, b_2, ...]``
  (kg*m) per plane, i.e. a mass moment ``u`` at phase ``phi`` is ``a = u cos phi``,
  ``b = u sin phi``; the force of Eq. 5 is linear in ``b``.

One RK4 step per sample (Eq. 12, as the EKF kernel) carries a sensitivity matrix
``dq`` (8 x ncol) along with the state: the columns are whatever the caller seeds them
with (identity for an EKF transition matrix, the running sensitivities for the batch
fit), plus the direct derivatives w.r.t. ``theta`` (columns ``ct .. ct+ntheta``) and
``b`` (columns ``cb .. cb+nb``) when ``ct``/``cb`` are >= 0.
"""
from __future__ import annotations

import math

import numpy as np

from rotor_estimator.core.forcing import rigid_state_derivative
from rotor_estimator.core.jit import njit


@njit
def _phys(theta, dmap, powers, s, phi, out):
    """Physical coefficients (16) at normalized speed ``s``; ``phi[j] = s**powers[j]``."""
    for j in range(theta.shape[0]):
        phi[j] = s ** powers[j] if powers[j] > 0 else 1.0
    for i in range(16):
        acc = 0.0
        for j in range(theta.shape[0]):
            acc += dmap[i, j] * theta[j] * phi[j]
        out[i] = acc


@njit
def _stage(q, dq, ncol, theta, bvec, t, angle0, omega0, alpha, fgen, dmap, powers, speed_ref, speed_scale,
           minv, gyro, wimb, ct, cb, k_out, dk_out):
    """``k = f(q, t)`` (8) and ``dk = df/dq @ dq + direct terms`` (8 x ncol)."""
    ang = angle0 + omega0 * t + 0.5 * alpha * t * t
    om = omega0 + alpha * t
    s = (om - speed_ref) / speed_scale
    nth = theta.shape[0]
    phi = np.empty(nth)
    ph = np.empty(16)
    _phys(theta, dmap, powers, s, phi, ph)
    c = math.cos(ang)
    sn = math.sin(ang)
    w2 = om * om
    gxa = w2 * c + alpha * sn
    gya = w2 * sn - alpha * c
    gxb = -w2 * sn + alpha * c
    gyb = w2 * c + alpha * sn
    res = np.empty(4)
    for r in range(4):
        res[r] = fgen[r]
    nplanes = wimb.shape[1]
    for i in range(nplanes):
        fx = bvec[2 * i] * gxa + bvec[2 * i + 1] * gxb
        fy = bvec[2 * i] * gya + bvec[2 * i + 1] * gyb
        res[0] += wimb[0, i] * fx
        res[1] += wimb[0, i] * fy
        res[2] += wimb[1, i] * fx
        res[3] += wimb[1, i] * fy
    # bearing forces: bearing b (0, 1) acts on coordinates 2b, 2b+1 (Eq. 1)
    for b in range(2):
        o = 8 * b
        x = q[4 + 2 * b]
        y = q[5 + 2 * b]
        vx = q[2 * b]
        vy = q[2 * b + 1]
        res[2 * b] -= ph[o] * x + ph[o + 1] * y + ph[o + 4] * vx + ph[o + 5] * vy
        res[2 * b + 1] -= ph[o + 2] * x + ph[o + 3] * y + ph[o + 6] * vx + ph[o + 7] * vy
    rigid_state_derivative(res, q, om, gyro, minv, k_out)
    if ncol == 0:
        return
    dres = np.empty(4)
    for col in range(ncol):
        for r in range(4):
            dres[r] = 0.0
        for b in range(2):
            o = 8 * b
            dx = dq[4 + 2 * b, col]
            dy = dq[5 + 2 * b, col]
            dvx = dq[2 * b, col]
            dvy = dq[2 * b + 1, col]
            dres[2 * b] -= ph[o] * dx + ph[o + 1] * dy + ph[o + 4] * dvx + ph[o + 5] * dvy
            dres[2 * b + 1] -= ph[o + 2] * dx + ph[o + 3] * dy + ph[o + 6] * dvx + ph[o + 7] * dvy
        for r in range(4):
            g = 0.0
            for m in range(4):
                g += gyro[r, m] * dq[m, col]
            dres[r] -= om * g
        if ct >= 0 and ct <= col < ct + nth:
            j = col - ct
            for b in range(2):
                o = 8 * b
                x = q[4 + 2 * b]
                y = q[5 + 2 * b]
                vx = q[2 * b]
                vy = q[2 * b + 1]
                f = phi[j]
                dres[2 * b] -= f * (dmap[o, j] * x + dmap[o + 1, j] * y + dmap[o + 4, j] * vx + dmap[o + 5, j] * vy)
                dres[2 * b + 1] -= f * (dmap[o + 2, j] * x + dmap[o + 3, j] * y + dmap[o + 6, j] * vx
                                        + dmap[o + 7, j] * vy)
        if cb >= 0 and cb <= col < cb + 2 * nplanes:
            m_ = col - cb
            i = m_ // 2
            if m_ % 2 == 0:
                fx, fy = gxa, gya
            else:
                fx, fy = gxb, gyb
            dres[0] += wimb[0, i] * fx
            dres[1] += wimb[0, i] * fy
            dres[2] += wimb[1, i] * fx
            dres[3] += wimb[1, i] * fy
        for r in range(4):
            acc = 0.0
            for m in range(4):
                acc += minv[r, m] * dres[m]
            dk_out[r, col] = acc
            dk_out[4 + r, col] = dq[r, col]


@njit
def rk4_step(q, dq, theta, bvec, h, angle0, omega0, alpha, fgen, dmap, powers, speed_ref, speed_scale, minv, gyro,
             wimb, ct, cb):
    """One RK4 step of length ``h`` in place on ``q`` (8) and ``dq`` (8 x ncol)."""
    ncol = dq.shape[1]
    k1 = np.empty(8)
    k2 = np.empty(8)
    k3 = np.empty(8)
    k4 = np.empty(8)
    d1 = np.empty((8, ncol))
    d2 = np.empty((8, ncol))
    d3 = np.empty((8, ncol))
    d4 = np.empty((8, ncol))
    qs = np.empty(8)
    dqs = np.empty((8, ncol))
    _stage(q, dq, ncol, theta, bvec, 0.0, angle0, omega0, alpha, fgen, dmap, powers, speed_ref, speed_scale,
           minv, gyro, wimb, ct, cb, k1, d1)
    for i in range(8):
        qs[i] = q[i] + 0.5 * h * k1[i]
        for c in range(ncol):
            dqs[i, c] = dq[i, c] + 0.5 * h * d1[i, c]
    _stage(qs, dqs, ncol, theta, bvec, 0.5 * h, angle0, omega0, alpha, fgen, dmap, powers, speed_ref, speed_scale,
           minv, gyro, wimb, ct, cb, k2, d2)
    for i in range(8):
        qs[i] = q[i] + 0.5 * h * k2[i]
        for c in range(ncol):
            dqs[i, c] = dq[i, c] + 0.5 * h * d2[i, c]
    _stage(qs, dqs, ncol, theta, bvec, 0.5 * h, angle0, omega0, alpha, fgen, dmap, powers, speed_ref, speed_scale,
           minv, gyro, wimb, ct, cb, k3, d3)
    for i in range(8):
        qs[i] = q[i] + h * k3[i]
        for c in range(ncol):
            dqs[i, c] = dq[i, c] + h * d3[i, c]
    _stage(qs, dqs, ncol, theta, bvec, h, angle0, omega0, alpha, fgen, dmap, powers, speed_ref, speed_scale,
           minv, gyro, wimb, ct, cb, k4, d4)
    w = h / 6.0
    for i in range(8):
        q[i] += w * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
        for c in range(ncol):
            dq[i, c] += w * (d1[i, c] + 2.0 * d2[i, c] + 2.0 * d3[i, c] + d4[i, c])


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
@njit
def _transition(x, nth, nbs, bfixed, h, angle0, omega0, alpha, fgen, dmap, powers, speed_ref, speed_scale, minv, gyro,
                wimb, x_out, phi_top):
    """Predicted augmented state ``x_out = f(x)`` and the top 8 rows of its Jacobian (8 x n)."""
    n = x.shape[0]
    q = x[:8].copy()
    theta = x[8:8 + nth].copy()
    if nbs > 0:
        bvec = x[8 + nth:8 + nth + nbs].copy()
    else:
        bvec = bfixed
    dq = np.zeros((8, n))
    for i in range(8):
        dq[i, i] = 1.0
    rk4_step(q, dq, theta, bvec, h, angle0, omega0, alpha, fgen, dmap, powers, speed_ref, speed_scale, minv, gyro,
             wimb, 8, 8 + nth if nbs > 0 else -1)
    for i in range(n):
        x_out[i] = x[i]
    for i in range(8):
        x_out[i] = q[i]
        for c in range(n):
            phi_top[i, c] = dq[i, c]


@njit
def _predict_cov(P, phi_top, h, accel_psd, rw_rate, out):
    """``out = Phi P Phi^T + Qd`` with ``Phi = [[phi_top], [0, I]]``."""
    n = P.shape[0]
    w = phi_top @ P  # 8 x n
    for i in range(n):
        for j in range(n):
            out[i, j] = P[i, j]
    for i in range(8):
        for c in range(n):
            out[i, c] = w[i, c]
            out[c, i] = w[i, c]
    mm = w @ phi_top.T
    for i in range(8):
        for j in range(8):
            out[i, j] = mm[i, j]
    if accel_psd > 0.0:
        for i in range(4):
            out[i, i] += accel_psd * h
            out[i, 4 + i] += accel_psd * h * h / 2.0
            out[4 + i, i] += accel_psd * h * h / 2.0
            out[4 + i, 4 + i] += accel_psd * h * h * h / 3.0
    for i in range(rw_rate.shape[0]):
        out[8 + i, 8 + i] += rw_rate[i] * h


@njit
def _kalman_update(x, P, y, hp, r_var, gate):
    """Linear update with ``y = Hp z`` (Eqs. 15-17), Joseph form; returns (status, nis). 0 updated, 1 gated."""
    n = x.shape[0]
    pht = np.ascontiguousarray(P[:, 4:8]) @ np.ascontiguousarray(hp.T)  # n x 4
    S = hp @ pht[4:8, :]
    for i in range(4):
        S[i, i] += r_var[i]
    S = 0.5 * (S + S.T)
    e = y - hp @ x[4:8]
    L = np.linalg.cholesky(S)
    u = np.linalg.solve(L, e)
    nis = float(u @ u)
    if nis > gate:
        return 1, nis
    K = np.ascontiguousarray(np.linalg.solve(S, np.ascontiguousarray(pht.T)).T)  # n x 4
    x += K @ e
    # Joseph form, expanded: P - K PHt^T - PHt K^T + K S K^T
    KS = K @ S
    Kt = np.ascontiguousarray(K.T)
    P += -K @ np.ascontiguousarray(pht.T) - pht @ Kt + KS @ Kt
    for i in range(n):
        for j in range(i + 1, n):
            a = 0.5 * (P[i, j] + P[j, i])
            P[i, j] = a
            P[j, i] = a
    return 0, nis


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
    have_nom = nominal.shape[0] == n
    phi = np.empty((8, m))
    xn = np.empty(m)
    Pn = np.empty((m, m))
    for k in range(n):
        if k > 0:
            kk = k - 1
            if have_nom:
                _transition(nominal[kk], nth, nbs, bfixed, dt[kk], angle[kk], speed[kk], accel[kk], fgen[kk], dmap,
                            powers, speed_ref, speed_scale, minv, gyro, wimb, xn, phi)
                d = x - nominal[kk]
                xn[:8] += phi @ d
                for i in range(8, m):
                    xn[i] = x[i]
            else:
                _transition(x, nth, nbs, bfixed, dt[kk], angle[kk], speed[kk], accel[kk], fgen[kk], dmap, powers,
                            speed_ref, speed_scale, minv, gyro, wimb, xn, phi)
            _predict_cov(P, phi, dt[kk], accel_psd, rw_rate, Pn)
            x[:] = xn
            P[:, :] = Pn
            if use[k]:
                st, nis = _kalman_update(x, P, y[k], hp, r_var, gate)
                nis_out[k] = nis
        if store:
            xf_out[k] = x
            pf_out[k] = P
        ok = True
        for i in range(m):
            if not math.isfinite(x[i]) or not P[i, i] > 0.0:
                ok = False
        if not ok:
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
    Ppred = np.empty((m, m))
    Phi = np.eye(m)
    for k in range(n - 2, -1, -1):
        _transition(nominal[k], nth, nbs, bfixed, dt[k], angle[k], speed[k], accel[k], fgen[k], dmap, powers,
                    speed_ref, speed_scale, minv, gyro, wimb, xn, phi)
        d = xf[k] - nominal[k]
        xn[:8] += phi @ d
        for i in range(8, m):
            xn[i] = xf[k, i]
        _predict_cov(pf[k], phi, dt[k], accel_psd, rw_rate, Ppred)
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
            if accel_psd > 0.0:
                for i in range(4):
                    Pm[i, i] += accel_psd * h
                    Pm[i, 4 + i] += accel_psd * h * h / 2.0
                    Pm[4 + i, i] += accel_psd * h * h / 2.0
                    Pm[4 + i, 4 + i] += accel_psd * h * h * h / 3.0
            for i in range(rw_rate.shape[0]):
                Pm[8 + i, 8 + i] += rw_rate[i] * h
            x[:] = xm
            P[:, :] = 0.5 * (Pm + Pm.T)
            if use[k]:
                st, nis = _kalman_update(x, P, y[k], hp, r_var, gate)
                nis_out[k] = nis
        ok = True
        for i in range(m):
            if not math.isfinite(x[i]) or not P[i, i] > 0.0:
                ok = False
        if not ok:
            return k
    return n
