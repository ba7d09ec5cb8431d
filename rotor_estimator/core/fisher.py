# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Cramer-Rao bounds from a Fisher information matrix: inversion with unidentified directions
made explicit, and elimination of nuisance parameters (Schur complement)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def eliminate_nuisance(fim: np.ndarray, n_nuisance: int = 8) -> np.ndarray:
    """Information of the trailing parameters with the first ``n_nuisance`` unknown (Schur complement)."""
    a = fim[:n_nuisance, :n_nuisance]
    b = fim[:n_nuisance, n_nuisance:]
    d = fim[n_nuisance:, n_nuisance:]
    scale = np.sqrt(np.clip(np.diag(a), 1e-300, None))
    an = a / np.outer(scale, scale)
    bn = b / scale[:, None]
    return d - bn.T @ np.linalg.lstsq(an, bn, rcond=1e-13)[0]


@dataclass(frozen=True)
class Bound:
    """Cramér-Rao bound of ``theta`` (the leading block of the parameters).

    ``covariance`` (ntheta, ntheta) and ``std`` (ntheta,), SI; ``std`` is ``inf`` for a
    parameter in the span of (numerically) zero information.
    """

    covariance: np.ndarray
    std: np.ndarray
    fisher: np.ndarray

    def relative(self, values: np.ndarray, floor: np.ndarray | None = None) -> np.ndarray:
        scale = np.abs(np.asarray(values, dtype=float))
        if floor is not None:
            scale = np.maximum(scale, floor)
        return self.std / scale


def bound(fisher: np.ndarray, n_theta: int, *, rel_tol: float = 1e-13) -> Bound:
    """Invert ``fisher`` (parameters ``[theta, nuisance...]``) and keep the ``theta`` block.

    Scaled symmetric eigen-decomposition; directions with eigenvalue below ``rel_tol``
    of the largest are treated as carrying no information (infinite bound).
    """
    scale = np.sqrt(np.clip(np.diag(fisher), 1e-300, None))
    fn = fisher / np.outer(scale, scale)
    w, v = np.linalg.eigh(fn)
    tol = max(w.max(), 1e-300) * rel_tol
    good = w > tol
    cov_n = (v[:, good] / w[good]) @ v[:, good].T
    cov = cov_n / np.outer(scale, scale)
    unidentified = (v[:, ~good] ** 2).sum(axis=1) > 1e-6
    c = cov[:n_theta, :n_theta]
    std = np.sqrt(np.clip(np.diag(c), 0, None))
    std[unidentified[:n_theta]] = np.inf
    return Bound(covariance=c, std=std, fisher=fisher)
