# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Assumed-mode reduction (Appendix A of Neisi et al.) and first-order state space (Eqs. 9-10).

``S_r`` holds the ``r`` lowest undamped, non-rotating mode shapes of ``(K_s, M)``
(``K_s`` the symmetric part of K, so cross-coupled bearings are allowed), mass
normalized. Then (Eq. A2) ``M_r = S_r^T M S_r = I``, ``K_r = S_r^T K S_r``,
``C_r = S_r^T C S_r``, ``G_r = S_r^T G S_r`` and ``F_r = S_r^T F``. With all modes kept
the reduced model is the full model in other coordinates.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from rotor_estimator.core.flexible.fe_rotor import FERotor, DOF_PER_NODE

__all__ = ["ReducedModel", "reduce", "state_matrices", "whirl_modes"]


@dataclass(frozen=True)
class ReducedModel:
    """Reduced matrices (r, r), basis ``S`` (n_dof, r) and undamped frequencies (rad/s)."""

    fe: FERotor
    S: np.ndarray
    M: np.ndarray
    C: np.ndarray
    K: np.ndarray
    G: np.ndarray
    undamped_rad_s: np.ndarray

    @property
    def n_modes(self) -> int:
        return self.S.shape[1]

    def physical(self, row: np.ndarray) -> np.ndarray:
        """Map a row acting on physical q to one acting on modal coordinates."""
        return np.asarray(row) @ self.S


def reduce(fe: FERotor, n_modes: int) -> ReducedModel:
    """Appendix A of Neisi et al.: keep the ``n_modes`` lowest modes (0 or >= n_dof: all)."""
    n = fe.n_dof
    r = n if n_modes <= 0 or n_modes >= n else n_modes
    ks = 0.5 * (fe.K + fe.K.T)
    lam, S = scipy.linalg.eigh(ks, fe.M, subset_by_index=[0, r - 1])
    return ReducedModel(fe, S, S.T @ fe.M @ S, S.T @ fe.C @ S, S.T @ fe.K @ S, S.T @ fe.G @ S,
                        np.sqrt(np.clip(lam, 0.0, None)))


def state_matrices(M: np.ndarray, C: np.ndarray, K: np.ndarray, G: np.ndarray, speed_rad_s: float,
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Eq. 10: ``A = [[0, I], [-M^-1 K, -M^-1 (C + Omega G)]]`` for ``x = [q, q']`` and
    ``B = [[0], [M^-1]]`` mapping generalized forces to ``x'``."""
    n = M.shape[0]
    minv = np.linalg.inv(M)
    A = np.zeros((2 * n, 2 * n))
    A[:n, n:] = np.eye(n)
    A[n:, :n] = -minv @ K
    A[n:, n:] = -minv @ (C + speed_rad_s * G)
    B = np.vstack([np.zeros((n, n)), minv])
    return A, B


def whirl_modes(M: np.ndarray, C: np.ndarray, K: np.ndarray, G: np.ndarray, speed_rad_s: float,
                shape_rows: np.ndarray | None = None) -> list[tuple[float, float, str]]:
    """(damped frequency rad/s, damping ratio, 'forward'|'backward') of each mode, ascending.

    Whirl direction from the orbit of the node with the largest motion, from the x/y
    rows ``shape_rows`` (2*k, n) mapping q to ``[x1, y1, x2, y2, ...]`` (default: the
    first n // 4 nodes of a shaft DOF ordering): forward when the orbit turns from +x
    toward +y, the sense of the spin.
    """
    A, _ = state_matrices(M, C, K, G, speed_rad_s)
    n = M.shape[0]
    if shape_rows is None:
        k = n // DOF_PER_NODE
        shape_rows = np.zeros((2 * k, n))
        for i in range(k):
            shape_rows[2 * i, DOF_PER_NODE * i] = 1.0
            shape_rows[2 * i + 1, DOF_PER_NODE * i + 1] = 1.0
    vals, vecs = np.linalg.eig(A)
    out = []
    for lam, vec in zip(vals, vecs.T):
        if lam.imag <= 1e-9 * max(1.0, abs(lam)):
            continue
        xy = (shape_rows @ vec[:n]).reshape(-1, 2)
        forward_part = np.abs(xy[:, 0] + 1j * xy[:, 1])
        backward_part = np.abs(xy[:, 0] - 1j * xy[:, 1])
        i = int(np.argmax(forward_part + backward_part))
        direction = "forward" if forward_part[i] > backward_part[i] else "backward"
        out.append((float(lam.imag), float(-lam.real / abs(lam)), direction))
    return sorted(out)
