# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The ensemble sampler against densities whose moments are known in closed form, and its clear errors."""
from __future__ import annotations

import numpy as np
import pytest

from rotor_estimator.diagnosis.posterior_sampling import draws_cov_about, stretch_move_chain


def test_the_stretch_move_draws_a_correlated_gaussian_with_its_mean_and_covariance():
    """A 3-D Gaussian with correlations up to 0.95 (a narrow tilted valley, where a random walk with a
    diagonal step mixes badly): the ensemble's draws after burn-in match its mean within 0.15 std and its
    covariance within 15 % (affine invariance: the tilt costs nothing)."""
    mean = np.array([1.0, -2.0, 0.5])
    std = np.array([1.0, 3.0, 0.2])
    corr = np.array([[1.0, 0.95, -0.5], [0.95, 1.0, -0.4], [-0.5, -0.4, 1.0]])
    cov = corr * np.outer(std, std)
    prec = np.linalg.inv(cov)

    def log_density(x):
        d = x - mean
        return -0.5 * float(d @ prec @ d)

    rng = np.random.default_rng(1)
    chain = stretch_move_chain(log_density, mean + 0.1 * rng.standard_normal((32, 3)), 1500, rng)
    draws = chain[300:].reshape(-1, 3)
    assert np.all(np.abs(draws.mean(axis=0) - mean) < 0.15 * std)
    assert np.allclose(np.cov(draws.T), cov, rtol=0.15, atol=0.05 * np.outer(std, std).max())


def test_the_covariance_about_an_estimate_adds_its_offset_from_the_posterior_mean():
    """About a point ``e`` off the mean ``m``, ``E[(x - e)^2] = var + (m - e)^2``: a truncated 1-D Gaussian
    (density zero below 0, the support's wall as an unstable rotor's) with mean 2, std 1 gives 1 + 1.5^2 about
    0.5 and 1 about its mean, within 10-15 %."""
    def log_density(x):
        return -np.inf if x[0] < 0.0 else -0.5 * float((x[0] - 2.0) ** 2)

    # about 0.5: 1 + 1.5^2 (the truncation at 0, 2 std below the mean, moves the moments by about 1 %)
    about_off = draws_cov_about(log_density, np.array([0.5]), np.array([[1.0]]), steps=1200, burn_in=200)
    assert about_off[0, 0] == pytest.approx(1.0 + 1.5 ** 2, rel=0.1)
    about_mean = draws_cov_about(log_density, np.array([2.0]), np.array([[1.0]]), seed=3)
    assert about_mean[0, 0] == pytest.approx(1.0, rel=0.15)


def test_bad_ensembles_are_clear_errors():
    """An odd or too small ensemble, a start outside the support, or a density finite nowhere near the estimate
    is a ValueError that says which, never a chain of NaN."""
    def log_density(x):
        return -0.5 * float(x @ x)

    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="even number of walkers"):
        stretch_move_chain(log_density, np.zeros((5, 2)), 10, rng)
    with pytest.raises(ValueError, match="finite log density"):
        stretch_move_chain(lambda x: -np.inf, np.zeros((4, 2)), 10, rng)
    with pytest.raises(ValueError, match="ensemble starts have a finite density"):
        draws_cov_about(lambda x: -np.inf, np.zeros(2), np.eye(2))
