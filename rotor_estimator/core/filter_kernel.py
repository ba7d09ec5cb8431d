# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The compiled EKF kernel (Miller & Howard Eqs. 9-17), shared by the streaming EKF and identification.

Building blocks, one copy each:

* **model** -- the rigid rotor of Eq. 2 (forces of Eqs. 1, 3 and 5, from
  :mod:`rotor_estimator.core.forcing`) in its generalized form: the 16 *physical* bearing
  coefficients (bearing 1 ``kxx kxy kyx kyy cxx cxy cyx cyy``, then bearing 2) are a linear
  map of the parameters ``theta`` with speed basis functions,
  ``phys(Omega) = sum_j dmap[:, j] * theta_j * s**powers_j``, ``s = (Omega - speed_ref) / speed_scale``,
  and the imbalance is carried as in-phase/quadrature moments ``b = [a_1, b_1, a_2, b_2, ...]``
  (kg*m; a moment ``u`` at phase ``phi`` is ``a = u cos phi``, ``b = u sin phi``). The seed model
  (identical bearings ``dmap = [I8; I8]``, ``powers = 0``, imbalance by moments and phases) has an
  unrolled special case, :func:`transition_seed`, used by the streaming EKF and the core CRLB; a
  test holds it equal to :func:`transition` with the identity map.
* **predict** (:func:`predict`, :func:`predict_seed`) -- the state prediction of Eq. 12 is one
  classical RK4 step (:func:`rk4_step`), carrying the sensitivities of the state forward by
  forward-mode differentiation of the four stages, i.e. the exact Jacobian of the RK4 map; the
  covariance prediction (Eq. 13, :func:`propagate_covariance`) uses that Jacobian with the process
  noise of Eq. 9 (:func:`add_process_noise`): the discrete EKF of the RK4-discretized model,
  consistent to the integration order with Eq. 13. The coefficients are constant between samples
  (Eq. 8, random walk in ``Q``), so ``Phi = [[Phi_m (8 x n)], [0, I]]`` and only ``Phi_m`` is integrated.
* **update** (:func:`update`) -- Eqs. 15-17: the measurement reads the 4 displacement states through
  the probe map (Eq. 6), so the gain needs ``P[:, 4:8]`` and a 4x4 innovation covariance;
  Cholesky solves, Mahalanobis gate, Joseph form, symmetric result.
* **operation order** -- :func:`propagate_covariance` and :func:`update` take ``blas_order``: numpy
  products and LAPACK solves (identification) or unrolled loops (streaming EKF). The formulas are the
  same; each caller keeps the order its published outputs were computed with (bit-identical results),
  and the tests hold both orders to the textbook formulas.
* :func:`run_block` -- the streaming driver (split into equal sub-steps when a gap makes a step
  longer than ``max_step_s``). Identification's drivers (batch sensitivities, EKF/RTS/UKF passes)
  are in :mod:`rotor_estimator.identification.passes`.

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


# ------------------------------------------------------------------------------------ model: generalized
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
def _stage_mapped(q, dq, ncol, theta, bvec, t, angle0, omega0, alpha, fgen, dmap, powers, speed_ref, speed_scale,
           minv, gyro, wimb, ct, cb, k_out, dk_out):
    """One RK4 stage of the generalized model (Eqs. 1, 3, 5 with the coefficient map):
    ``k = f(q, t)`` (8) and ``dk = df/dq @ dq + direct terms`` (8 x ncol)."""
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
def _rk4_buffers(ncol):
    """Scratch of one RK4 step: stage slopes ``k1..k4`` (8), their sensitivities ``d1..d4`` (8 x ncol) and
    the stage argument ``qs`` (8), ``dqs`` (8 x ncol)."""
    return (np.empty(8), np.empty(8), np.empty(8), np.empty(8), np.empty((8, ncol)), np.empty((8, ncol)),
            np.empty((8, ncol)), np.empty((8, ncol)), np.empty(8), np.empty((8, ncol)))


@njit
def _stage_point(q, dq, a, k, d, qs, dqs):
    """Argument of the next RK4 stage: ``qs = q + a k`` (8) and ``dqs = dq + a d`` (8 x ncol)."""
    for i in range(8):
        qs[i] = q[i] + a * k[i]
        for c in range(dq.shape[1]):
            dqs[i, c] = dq[i, c] + a * d[i, c]


@njit
def _rk4_combine(q, dq, h, k1, k2, k3, k4, d1, d2, d3, d4):
    """The RK4 step (Eq. 12) from its four stages, in place: ``q += h/6 (k1 + 2 k2 + 2 k3 + k4)``, same for ``dq``."""
    w = h / 6.0
    for i in range(8):
        q[i] += w * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
        for c in range(dq.shape[1]):
            dq[i, c] += w * (d1[i, c] + 2.0 * d2[i, c] + 2.0 * d3[i, c] + d4[i, c])


@njit
def rk4_step(q, dq, theta, bvec, h, angle0, omega0, alpha, fgen, dmap, powers, speed_ref, speed_scale, minv, gyro,
             wimb, ct, cb):
    """Eq. 12 for the generalized model: one RK4 step of length ``h`` (s) in place on ``q`` (8) and on the
    sensitivities ``dq`` (8 x ncol), with the direct derivatives w.r.t. ``theta`` added from column ``ct``
    and w.r.t. ``b`` from column ``cb`` (-1: none)."""
    ncol = dq.shape[1]
    k1, k2, k3, k4, d1, d2, d3, d4, qs, dqs = _rk4_buffers(ncol)
    _stage_mapped(q, dq, ncol, theta, bvec, 0.0, angle0, omega0, alpha, fgen, dmap, powers, speed_ref,
                  speed_scale, minv, gyro, wimb, ct, cb, k1, d1)
    _stage_point(q, dq, 0.5 * h, k1, d1, qs, dqs)
    _stage_mapped(qs, dqs, ncol, theta, bvec, 0.5 * h, angle0, omega0, alpha, fgen, dmap, powers, speed_ref,
                  speed_scale, minv, gyro, wimb, ct, cb, k2, d2)
    _stage_point(q, dq, 0.5 * h, k2, d2, qs, dqs)
    _stage_mapped(qs, dqs, ncol, theta, bvec, 0.5 * h, angle0, omega0, alpha, fgen, dmap, powers, speed_ref,
                  speed_scale, minv, gyro, wimb, ct, cb, k3, d3)
    _stage_point(q, dq, h, k3, d3, qs, dqs)
    _stage_mapped(qs, dqs, ncol, theta, bvec, h, angle0, omega0, alpha, fgen, dmap, powers, speed_ref,
                  speed_scale, minv, gyro, wimb, ct, cb, k4, d4)
    _rk4_combine(q, dq, h, k1, k2, k3, k4, d1, d2, d3, d4)


# ------------------------------------------------------------------------------------ model: seed special case
@njit
def _stage_seed(q, r, t, angle0, omega0, alpha, fimp, minv, gyro, moments, phases, wimb, wimp, dq, k_out, dk_out):
    """One RK4 stage of the seed model (Eqs. 1, 3, 5): ``k = f(q, r, t)`` and
    ``dk = df/dq @ dq + df/dr @ [0 I]`` (8x16)."""
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
def transition_seed(x, h, angle0, omega0, alpha, fimp, minv, gyro, moments, phases, wimb, wimp, phi_m):
    """Eq. 12 for the seed model: advance the 8 motion states of ``x`` (16: ``[v, z, r]``) by one RK4 step
    of ``h`` (s) in place and write their Jacobian w.r.t. ``x`` into ``phi_m`` (8x16).

    The special case of :func:`transition` with ``dmap = [I8; I8]``, ``powers = 0`` and the imbalance
    given by moments and phases (Eq. 5), unrolled for the 16-state problem; kept as its own code path
    because the streaming EKF and :mod:`rotor_estimator.core.crlb` depend on its exact operation order."""
    q = x[:8].copy()
    r = x[8:]
    k1, k2, k3, k4, d1, d2, d3, d4, qs, dqs = _rk4_buffers(16)
    eye = np.zeros((8, 16))
    for i in range(8):
        eye[i, i] = 1.0
    _stage_seed(q, r, 0.0, angle0, omega0, alpha, fimp, minv, gyro, moments, phases, wimb, wimp, eye, k1, d1)
    _stage_point(q, eye, 0.5 * h, k1, d1, qs, dqs)
    _stage_seed(qs, r, 0.5 * h, angle0, omega0, alpha, fimp, minv, gyro, moments, phases, wimb, wimp, dqs, k2, d2)
    _stage_point(q, eye, 0.5 * h, k2, d2, qs, dqs)
    _stage_seed(qs, r, 0.5 * h, angle0, omega0, alpha, fimp, minv, gyro, moments, phases, wimb, wimp, dqs, k3, d3)
    _stage_point(q, eye, h, k3, d3, qs, dqs)
    _stage_seed(qs, r, h, angle0, omega0, alpha, fimp, minv, gyro, moments, phases, wimb, wimp, dqs, k4, d4)
    phi_m[:, :] = eye
    _rk4_combine(q, phi_m, h, k1, k2, k3, k4, d1, d2, d3, d4)
    for i in range(8):
        x[i] = q[i]


# ------------------------------------------------------------------------------------ predict
@njit
def add_process_noise(P, h, accel_psd, rw_rate):
    """Add the discrete process noise of one step of ``h`` (s) to ``P`` (Eq. 9): white acceleration of PSD
    ``accel_psd`` ((m/s^2)^2/Hz) on each of the 4 coordinates (Q_v, Q_z) and random-walk variance rates
    ``rw_rate`` (per s) on the parameter states ``8, 9, ...``."""
    if accel_psd > 0.0:
        for i in range(4):
            P[i, i] += accel_psd * h
            P[i, 4 + i] += accel_psd * h * h / 2.0
            P[4 + i, i] += accel_psd * h * h / 2.0
            P[4 + i, 4 + i] += accel_psd * h * h * h / 3.0
    for i in range(rw_rate.shape[0]):
        P[8 + i, 8 + i] += rw_rate[i] * h


@njit
def propagate_covariance(P, phi_top, h, accel_psd, rw_rate, blas_order):
    """Eq. 13 in discrete form, in place: ``P = Phi P Phi^T + Qd`` with ``Phi = [[phi_top], [0, I]]``.

    Only the 8 motion states move (the parameters are constant between samples, Eq. 8), so
    ``phi_top`` (8 x n) is all of ``Phi`` that is not the identity and only the motion rows and
    columns of ``P`` change. ``blas_order`` picks the operation order, which is all that differs:
    numpy products (BLAS, identification's recorded results) or unrolled loops that compute the
    motion block once and mirror it (the streaming EKF; ``P`` stays exactly symmetric).
    """
    n = P.shape[0]
    if blas_order:
        w = phi_top @ P  # 8 x n
        mm = w @ phi_top.T
        for i in range(8):
            for c in range(8, n):
                P[i, c] = w[i, c]
                P[c, i] = w[i, c]
            for j in range(8):
                P[i, j] = mm[i, j]
    else:
        w = np.zeros((8, n))
        for i in range(8):
            for c in range(n):
                acc = 0.0
                for m in range(n):
                    acc += phi_top[i, m] * P[m, c]
                w[i, c] = acc
        for i in range(8):
            for j in range(i, 8):
                acc = 0.0
                for m in range(n):
                    acc += w[i, m] * phi_top[j, m]
                P[i, j] = acc
                P[j, i] = acc
            for c in range(8, n):
                P[i, c] = w[i, c]
                P[c, i] = w[i, c]
    add_process_noise(P, h, accel_psd, rw_rate)


@njit
def transition(x, xlin, nth, nbs, bfixed, h, angle0, omega0, alpha, fgen, dmap, powers, speed_ref, speed_scale, minv,
               gyro, wimb, x_out, phi_top):
    """Eq. 12 on the augmented state ``x = [q (8), theta (nth), b (nbs)]`` of the generalized model.

    Writes the predicted state into ``x_out`` and the top 8 rows of the transition Jacobian
    (8 x n) into ``phi_top``. Linearized at ``xlin`` when it has ``x``'s length
    (``x_out = f(xlin) + F(xlin) (x - xlin)``, the iterated smoother), else at ``x`` itself.
    With ``nbs == 0`` the imbalance is the fixed ``bfixed``.
    """
    n = x.shape[0]
    lin = xlin.shape[0] == n
    src = xlin if lin else x
    q = src[:8].copy()
    theta = src[8:8 + nth].copy()
    if nbs > 0:
        bvec = src[8 + nth:8 + nth + nbs].copy()
    else:
        bvec = bfixed
    dq = np.zeros((8, n))
    for i in range(8):
        dq[i, i] = 1.0
    rk4_step(q, dq, theta, bvec, h, angle0, omega0, alpha, fgen, dmap, powers, speed_ref, speed_scale, minv, gyro,
             wimb, 8, 8 + nth if nbs > 0 else -1)
    for i in range(n):
        x_out[i] = src[i]
    for i in range(8):
        x_out[i] = q[i]
        for c in range(n):
            phi_top[i, c] = dq[i, c]
    if lin:
        d = x - xlin
        x_out[:8] += phi_top @ d
        for i in range(8, n):
            x_out[i] = x[i]


@njit
def predict(x, P, xlin, nth, nbs, bfixed, h, angle0, omega0, alpha, fgen, dmap, powers, speed_ref, speed_scale, minv,
            gyro, wimb, accel_psd, rw_rate, phi_top, x_pred):
    """EKF prediction (Eqs. 12-13) of the generalized model, in place on ``x`` (n) and ``P`` (n, n).

    :func:`transition` (linearized at ``xlin`` when given, see there) then
    :func:`propagate_covariance` (BLAS order); ``phi_top`` (8 x n) receives the Jacobian, ``x_pred`` (n)
    is scratch.
    """
    transition(x, xlin, nth, nbs, bfixed, h, angle0, omega0, alpha, fgen, dmap, powers, speed_ref, speed_scale,
               minv, gyro, wimb, x_pred, phi_top)
    propagate_covariance(P, phi_top, h, accel_psd, rw_rate, True)
    for i in range(x.shape[0]):
        x[i] = x_pred[i]


@njit
def predict_seed(x, P, h, angle0, omega0, alpha, fimp, minv, gyro, moments, phases, wimb, wimp, accel_psd, rw_rate,
                 phi_m):
    """EKF prediction (Eqs. 12-13) of the seed model (16 states ``[v, z, r]``), in place on ``x`` and ``P``:
    :func:`transition_seed` then :func:`propagate_covariance` (loop order); ``phi_m`` (8x16) receives the
    Jacobian."""
    transition_seed(x, h, angle0, omega0, alpha, fimp, minv, gyro, moments, phases, wimb, wimp, phi_m)
    propagate_covariance(P, phi_m, h, accel_psd, rw_rate, False)


# ------------------------------------------------------------------------------------ update
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
def _innovation(x, P, y, hp, r_var, blas_order):
    """Eqs. 15 and 17: ``(P H^T (n x 4), S = H P H^T + R (symmetrized), e = y - H x)``."""
    if blas_order:
        pht = np.ascontiguousarray(P[:, 4:8]) @ np.ascontiguousarray(hp.T)  # n x 4
        S = hp @ np.ascontiguousarray(pht[4:8, :])
        for i in range(4):
            S[i, i] += r_var[i]
        S = 0.5 * (S + S.T)
        e = y - hp @ x[4:8]
        return pht, S, e
    n = x.shape[0]
    pht = np.zeros((n, 4))
    for i in range(n):
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
    return pht, S, e


@njit
def _nis(S, L, e, blas_order):
    """Normalized innovation squared ``e^T S^-1 e`` through the Cholesky factor ``L`` of ``S``."""
    if blas_order:
        u = np.linalg.solve(np.linalg.cholesky(S), e)
        return float(u @ u)
    u = np.zeros(4)
    for i in range(4):
        acc = e[i]
        for m in range(i):
            acc -= L[i, m] * u[m]
        u[i] = acc / L[i, i]
    nis = 0.0
    for i in range(4):
        nis += u[i] * u[i]
    return nis


@njit
def _correct(x, P, pht, S, L, e, blas_order):
    """Eq. 16: ``K = P H^T S^-1`` (solved, never inverted), ``x += K e`` and the Joseph form
    ``(I-KH)P(I-KH)^T + KRK^T = P - K PHt^T - PHt K^T + K S K^T``, symmetrized."""
    n = x.shape[0]
    if blas_order:
        K = np.ascontiguousarray(np.linalg.solve(S, np.ascontiguousarray(pht.T)).T)  # n x 4
        x += K @ e
        KS = K @ S
        Kt = np.ascontiguousarray(K.T)
        P += -K @ np.ascontiguousarray(pht.T) - pht @ Kt + KS @ Kt
        for i in range(n):
            for j in range(i + 1, n):
                a = 0.5 * (P[i, j] + P[j, i])
                P[i, j] = a
                P[j, i] = a
        return
    K = np.zeros((n, 4))
    for row in range(n):
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
    for i in range(n):
        acc = 0.0
        for j in range(4):
            acc += K[i, j] * e[j]
        x[i] += acc
    ks = np.zeros((n, 4))
    for i in range(n):
        for j in range(4):
            acc = 0.0
            for m in range(4):
                acc += K[i, m] * S[m, j]
            ks[i, j] = acc
    for i in range(n):
        for j in range(i, n):
            acc = 0.0
            for m in range(4):
                acc += -K[i, m] * pht[j, m] - pht[i, m] * K[j, m] + ks[i, m] * K[j, m]
            val = P[i, j] + acc
            if i != j:
                val = 0.5 * (val + P[j, i] + acc)
            P[i, j] = val
            P[j, i] = val


@njit
def update(x, P, y, hp, r_var, gate, innov_out, s_std_out, blas_order):
    """Gated Kalman measurement update, Eqs. 15-17 with the Joseph form, in place on ``x`` (n) and ``P`` (n, n).

    The measurement reads the displacement states ``x[4:8]`` through the probe map ``hp`` (4x4, Eq. 6)
    with noise variances ``r_var`` (m^2). Writes the innovation (m) and its std (m) into ``innov_out`` /
    ``s_std_out``; returns ``(status, nis)``: ``STATUS_GATED`` (no update) when the normalized innovation
    squared exceeds ``gate``, ``STATUS_NUMERICAL`` (no update) when ``S`` is not positive definite.
    ``blas_order`` picks the operation order, which is all that differs: numpy/LAPACK products and
    solves (identification's recorded results) or unrolled loops (the streaming EKF).
    """
    pht, S, e = _innovation(x, P, y, hp, r_var, blas_order)
    for i in range(4):
        innov_out[i] = e[i]
        s_std_out[i] = math.sqrt(S[i, i]) if S[i, i] > 0 else math.nan
    L = np.zeros((4, 4))
    if not _cholesky4(S, L):
        return STATUS_NUMERICAL, math.nan
    nis = _nis(S, L, e, blas_order)
    if nis > gate:
        return STATUS_GATED, nis
    _correct(x, P, pht, S, L, e, blas_order)
    return STATUS_UPDATED, nis


@njit
def healthy(x, P):
    """False when a state is NaN/inf or a variance is not a finite positive number (the filter diverged)."""
    for i in range(x.shape[0]):
        if not math.isfinite(x[i]) or not P[i, i] > 0.0 or not math.isfinite(P[i, i]):
            return False
    return True


# ------------------------------------------------------------------------------------ streaming driver
@njit
def run_block(x, P, dt_s, angle_rad, speed_rad_s, accel_rad_s2, impact_n, y, skip, minv, gyro, moments, phases,
              wimb, wimp, hp, r_var, accel_psd, coeff_rw_var_rate, gate, max_step_s,
              status_out, nis_out, innov_out, s_std_out):
    """Streaming driver: :func:`predict_seed` then :func:`update` (loop order) for ``n`` samples in order,
    in place on ``x`` (16,) and ``P`` (16, 16).

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
            predict_seed(x, P, h, a0, w0, accel_rad_s2[k], fimp, minv, gyro, moments, phases, wimb, wimp, accel_psd,
                         coeff_rw_var_rate, phi_m)
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
            st, nis = update(x, P, y[k], hp, r_var, gate, innov, sstd, False)
            status_out[k] = st
            nis_out[k] = nis
            for i in range(4):
                innov_out[k, i] = innov[i]
                s_std_out[k, i] = sstd[i]
        if not healthy(x, P):
            return k
    return n
