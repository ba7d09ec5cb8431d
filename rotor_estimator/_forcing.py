"""Compiled Eq. 5 shared by the simulator and the EKF kernel (one copy of the imbalance force)."""
from __future__ import annotations

import math

from ._jit import njit


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
