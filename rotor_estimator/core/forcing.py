# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Compiled pieces of the rigid model (Eqs. 3 and 5) shared by the simulator, the EKF kernels and the
diagnosis's effect simulator: one copy of the imbalance force, of the impact force held over an
integration substep and of the rigid state derivative."""
from __future__ import annotations

import math

from rotor_estimator.core.jit import njit


@njit
def add_imbalance_force(theta, omega, alpha, moments, phases, wimb, out):
    """Add the generalized imbalance force at shaft angle ``theta`` (rad), speed ``omega`` (rad/s)
    and angular acceleration ``alpha`` (rad/s^2) to ``out[0:4]`` = ``[x1, y1, x2, y2]`` (N).

    Each mass ``m r`` at phase ``phi`` pushes with ``m r (w^2 cos a + dw/dt sin a, w^2 sin a - dw/dt cos a)``,
    ``a = theta + phi``, shared between the bearings by the lever weights ``wimb`` (Eq. 5).
    """
    for i in range(moments.shape[0]):
        a = theta + phases[i]
        ca = math.cos(a)
        sa = math.sin(a)
        fx = moments[i] * (omega * omega * ca + alpha * sa)
        fy = moments[i] * (omega * omega * sa - alpha * ca)
        out[0] += wimb[0, i] * fx
        out[1] += wimb[0, i] * fy
        out[2] += wimb[1, i] * fx
        out[3] += wimb[1, i] * fy


@njit
def rigid_state_derivative(res, q, omega, gyro, minv, out):
    """``out[0:4] = M^-1 (res - omega G v)`` and ``out[4:8] = v`` for the rigid rotor (Eq. 3).

    ``res`` (4,) is the applied minus bearing force (N) and is overwritten with the net force;
    ``q[0:4]`` are the velocities ``v`` = [x1, y1, x2, y2]' (m/s).
    """
    for r in range(4):
        g = 0.0
        for c in range(4):
            g += gyro[r, c] * q[c]
        res[r] -= omega * g
    for r in range(4):
        acc = 0.0
        for c in range(4):
            acc += minv[r, c] * res[c]
        out[r] = acc
        out[4 + r] = q[r]


@njit
def average_impact_force(t, h, imp_start, imp_end, imp_fx, imp_fy, fimp):
    """Set ``fimp`` (2,) to the exact mean over ``[t, t + h]`` (s) of the rectangular impacts
    ``[imp_start, imp_end)`` with forces ``(imp_fx, imp_fy)`` (N)."""
    fimp[0] = 0.0
    fimp[1] = 0.0
    for j in range(imp_start.shape[0]):
        overlap = min(t + h, imp_end[j]) - max(t, imp_start[j])
        if overlap > 0:
            fimp[0] += imp_fx[j] * overlap / h
            fimp[1] += imp_fy[j] * overlap / h
