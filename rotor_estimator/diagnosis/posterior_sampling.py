# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Sampling a posterior that is not Gaussian: the affine-invariant ensemble sampler (Goodman & Weare 2010, the
"stretch move" of emcee, Foreman-Mackey et al. 2013), and the covariance of its draws about a point estimate.

Used for the verdict's bearing coefficients (the nominal model's, or an effect's with its nonlinear parameters)
on a record of one steady speed without an impact: its 1X pins the 8 coefficients along a long curved valley
(the nominal estimate and the truth seen 8 local stds apart with the truth inside the joint 95 % region), which
neither the local curvature nor profiles along two directions describe, so the posterior is sampled instead
(:func:`.ranking.sampled_coefficient_cov`). The misfit costs about 1 ms for the nominal model there and 2-9 ms
with an effect.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

#: Walkers of the ensemble, steps of each, and the first steps dropped (burn-in).
WALKERS = 32
STEPS = 400
BURN_IN = 150
#: The stretch move's scale ``a`` (the proposal ``z`` has density ``1 / sqrt(z)`` on ``[1 / a, a]``).
STRETCH_A = 2.0


def stretch_move_chain(log_density: Callable[[np.ndarray], float], starts: np.ndarray, steps: int,
                       rng: np.random.Generator, a: float = STRETCH_A) -> np.ndarray:
    """(steps, walkers, d) positions of the ensemble, each step updating the two halves in turn: walker ``i``
    proposes ``y = x_j + z (x_i - x_j)`` with ``x_j`` from the other half and accepts it with probability
    ``min(1, z^(d-1) p(y) / p(x_i))`` (Goodman & Weare 2010, Eq. 7). ``starts`` (walkers, d) must have a
    finite log density; ``log_density`` returns ``-inf`` outside the support."""
    x = np.array(starts, dtype=float)
    walkers, d = x.shape
    if walkers < 4 or walkers % 2:
        raise ValueError(f"the ensemble needs an even number of walkers >= 4, got {walkers}")
    lp = np.array([log_density(v) for v in x])
    if not np.all(np.isfinite(lp)):
        raise ValueError("every start of the ensemble needs a finite log density")
    chain = np.empty((steps, walkers, d))
    halves = (np.arange(0, walkers, 2), np.arange(1, walkers, 2))
    for s in range(steps):
        for h in (0, 1):
            mine, other = halves[h], halves[1 - h]
            for i in mine:
                j = other[rng.integers(other.size)]
                z = ((a - 1.0) * rng.random() + 1.0) ** 2 / a
                y = x[j] + z * (x[i] - x[j])
                lp_y = log_density(y)
                if np.isfinite(lp_y) and np.log(rng.random()) < (d - 1) * np.log(z) + lp_y - lp[i]:
                    x[i], lp[i] = y, lp_y
        chain[s] = x
    return chain


def draws_cov_about(log_density: Callable[[np.ndarray], float], estimate: np.ndarray, cov: np.ndarray, *,
                    seed: int = 0, walkers: int = WALKERS, steps: int = STEPS,
                    burn_in: int = BURN_IN) -> np.ndarray:
    """``E[(x - estimate)(x - estimate)^T]`` over draws of ``log_density`` (the covariance about the reported
    point, its offset from the posterior mean included), the ensemble started from ``N(estimate, cov)``
    (draws without a finite density are redrawn, at most 50 rounds). Deterministic for a given ``seed``."""
    estimate = np.asarray(estimate, float)
    d = estimate.size
    rng = np.random.default_rng(seed)
    chol = np.linalg.cholesky(np.asarray(cov, float) + 1e-12 * np.eye(d) * max(float(np.trace(cov)) / d, 1e-300))
    starts: list[np.ndarray] = []
    for _ in range(50):
        for v in estimate + (chol @ rng.standard_normal((d, walkers))).T:
            if len(starts) < walkers and np.isfinite(log_density(v)):
                starts.append(v)
        if len(starts) == walkers:
            break
    else:
        raise ValueError(f"only {len(starts)} of {walkers} ensemble starts have a finite density")
    chain = stretch_move_chain(log_density, np.array(starts), steps, rng)
    dev = chain[burn_in:].reshape(-1, d) - estimate
    return dev.T @ dev / dev.shape[0]
