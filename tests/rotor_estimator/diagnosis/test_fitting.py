# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The diagnosis's least-squares kernels: the projection of the joint refits and the parameter covariance
(sandwich with a Welch residual spectrum)."""
from __future__ import annotations

import numpy as np
import pytest

from rotor_estimator.diagnosis.fitting import residual_after_fit, spectral_covariance


def _design(t_n: int = 3000, period: float = 60.0) -> np.ndarray:
    """Two channels, each with a 1X cosine and sine column, and a common DC column."""
    t = np.arange(t_n)
    w = 2 * np.pi / period
    a = np.zeros((t_n, 2, 5))
    a[:, 0, 0], a[:, 0, 1] = np.cos(w * t), np.sin(w * t)
    a[:, 1, 2], a[:, 1, 3] = np.cos(w * t), np.sin(w * t)
    a[:, :, 4] = 1.0
    return a


def _fit(a: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    flat = a.reshape(-1, a.shape[2])
    theta, *_ = np.linalg.lstsq(flat, y.ravel(), rcond=None)
    return theta, y - np.einsum("tcp,p->tc", a, theta)


def test_white_residual_gives_the_ordinary_least_squares_covariance():
    """With white noise the sandwich reduces to sigma^2 (A^T A)^-1: every std within 25 % of it (the Welch
    estimate at one frequency, from 25 segments, scatters by about 20 %), the 1X ones within 5 %."""
    rng = np.random.default_rng(3)
    a = _design()
    _, res = _fit(a, rng.standard_normal((3000, 2)) * 2e-6)
    flat = a.reshape(-1, 5)
    ols = np.sqrt(np.diag(np.linalg.inv(flat.T @ flat)) * np.mean(res ** 2))
    sandwich = np.sqrt(np.diag(spectral_covariance(a, res, 240)))
    np.testing.assert_allclose(sandwich, ols, rtol=0.25)
    np.testing.assert_allclose(sandwich[:4], ols[:4], rtol=0.05)


@pytest.mark.parametrize("kind", ["white", "ar1"])
def test_coverage_of_the_95_percent_interval_is_calibrated(kind):
    """Calibration: over 150 noise draws, the true parameters lie within +-1.96 std in 90-98 % of the cases,
    for white noise and for strongly correlated AR(1) noise (rho 0.9, where the white-noise std is 4x too
    small)."""
    rng = np.random.default_rng(11)
    a = _design()
    truth = np.array([1.0, 2.0, 3.0, 4.0, 0.5])
    hits = []
    for _ in range(150):
        z = rng.standard_normal((3000, 2))
        if kind == "ar1":
            from scipy.signal import lfilter

            z = lfilter([1.0], [1.0, -0.9], z, axis=0)
        theta, res = _fit(a, np.einsum("tcp,p->tc", a, truth) + z)
        std = np.sqrt(np.diag(spectral_covariance(a, res, 240)))
        hits.append(np.abs(theta - truth) <= 1.96 * std)
    coverage = np.mean(hits)
    assert 0.90 <= coverage <= 0.98, coverage


@pytest.mark.parametrize("duplicate", [False, True])
def test_projection_residual_equals_the_svd_least_squares_residual_and_is_orthogonal_to_the_columns(duplicate):
    """The normal-equation projection of the joint refits leaves the same residual as an SVD ``lstsq`` (to 1e-9
    of the data), orthogonal to every column, on columns of scales 1e-9..1e3 and with an exactly repeated
    column (rank deficiency: the repeat is dropped, the residual unchanged)."""
    rng = np.random.default_rng(5)
    x = rng.standard_normal((4000, 12)) * np.logspace(-9, 3, 12)
    if duplicate:
        x = np.column_stack([x, 2.0 * x[:, 3]])
    b = rng.standard_normal(4000) + x[:, 6:].sum(axis=1)
    coef, *_ = np.linalg.lstsq(x, b, rcond=None)
    reference = b - x @ coef
    got = residual_after_fit(x, b)
    assert np.max(np.abs(got - reference)) < 1e-9 * np.max(np.abs(b))
    unit = x / np.linalg.norm(x, axis=0)
    assert np.max(np.abs(unit.T @ got)) < 1e-8 * np.linalg.norm(b)
