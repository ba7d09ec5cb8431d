# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The diagnosis's least-squares kernels: the projection of the joint refits and the parameter covariance
(sandwich with a Welch residual spectrum)."""
from __future__ import annotations

import numpy as np
import pytest

from rotor_estimator.diagnosis.fitting import residual_after_fit, spectral_covariance, welch_cross_spectra


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


def _stub_context(rng, prior_std, t_n: int = 400):
    """The attributes the linear kernels read: a random coefficient sensitivity, no start transient, the
    coefficient prior at the record's noise level."""
    from types import SimpleNamespace

    from rotor_estimator.diagnosis.context import CoefficientPrior

    jac = rng.standard_normal((t_n, 4, 8)) * 1e-6
    coefficients = np.array([4e5, 1e5, -1e5, 5e5, 900.0, 10.0, -10.0, 800.0])
    prior = CoefficientPrior(mean=np.array([3e5, 0.0, 0.0, 3e5, 1000.0, 0.0, 0.0, 1000.0]),
                             std=np.asarray(prior_std, float), noise_std_m=1e-6)
    return SimpleNamespace(jacobian=jac, start_columns_m=np.zeros((t_n, 4, 0)),
                           design_start_columns_m=np.zeros((t_n, 4, 0)), y_nom_m=np.zeros((t_n, 4)),
                           y_m=rng.standard_normal((t_n, 4)) * 3e-6, mask=np.ones(t_n, bool),
                           coefficients=coefficients, prior=prior)


def test_the_linear_solve_is_the_map_estimate_under_the_coefficient_prior():
    """The coefficient correction of solve_linear equals the closed-form MAP estimate
    (A^T A + L^T L)^-1 (A^T b + L^T l) of the data rows and the prior's 8 pseudo-observations (an
    independent normal-equation solve), its prior_m2 is the prior's penalty there, and the Projector (the
    nonlinear searches' path) leaves the same penalized sum of squares."""
    from rotor_estimator.diagnosis.context import COEFFICIENT_SCALE, nuisance_columns
    from rotor_estimator.diagnosis.fitting import Projector, solve_linear

    rng = np.random.default_rng(11)
    ctx = _stub_context(rng, [3e5] * 4 + [1e3] * 4)
    cols = rng.standard_normal((400, 4, 3)) * 1e-6
    sol = solve_linear(ctx, None, cols)
    a = np.concatenate([ctx.jacobian, nuisance_columns(ctx.start_columns_m), cols], axis=2).reshape(-1, 15)
    b = ctx.y_m.ravel()
    lam = np.zeros((15, 15))
    w = ctx.prior.noise_std_m * COEFFICIENT_SCALE / ctx.prior.std  # d pseudo-observation / d dr
    lam[:8, :8] = np.diag(w ** 2)
    # the gains' magnitude prior: one gain's output carries LINEAR_PRIOR_SIGNAL_RATIO x the data's RMS at 1 sigma
    from rotor_estimator.diagnosis.fitting import LINEAR_PRIOR_SIGNAL_RATIO

    y_rms = np.sqrt(np.mean((ctx.y_m - ctx.y_m.mean(axis=0)) ** 2))
    w_gain = ctx.prior.noise_std_m * np.sqrt(np.mean(cols ** 2, axis=(0, 1))) / (LINEAR_PRIOR_SIGNAL_RATIO * y_rms)
    lam[12:, 12:] = np.diag(w_gain ** 2)
    target = np.zeros(15)
    target[:8] = w ** 2 * (ctx.prior.mean - ctx.coefficients) / COEFFICIENT_SCALE
    x = np.linalg.solve(a.T @ a + lam, a.T @ b + target)
    np.testing.assert_allclose(sol.dr, x[:8], rtol=1e-6, atol=1e-9 * np.max(np.abs(x[:8])))
    np.testing.assert_allclose(sol.theta, x[12:], rtol=1e-6)
    after = ctx.coefficients + x[:8] * COEFFICIENT_SCALE
    assert sol.prior_m2 == pytest.approx(ctx.prior.penalty_m2(after) + np.sum((w_gain * x[12:]) ** 2), rel=1e-6)
    projected = Projector(ctx, None, ctx.mask).residual(None, cols)
    assert float(projected @ projected) == pytest.approx(sol.rss_m2 + sol.prior_m2, rel=1e-6)


def test_a_tight_prior_holds_the_coefficients_and_a_broad_one_leaves_the_least_squares_fit():
    """Bounds of the MAP estimate: with a prior std of 1 (N/m, N s/m) the coefficients after the solve stay
    within that std of r0 (the data would move them by ~10^5); with a std 1e6 times the coefficients the
    correction is the plain least-squares one (within 1e-6 relative)."""
    from rotor_estimator.diagnosis.context import COEFFICIENT_SCALE, nuisance_columns
    from rotor_estimator.diagnosis.fitting import solve_linear

    rng = np.random.default_rng(12)
    tight = _stub_context(rng, np.full(8, 1.0))
    sol = solve_linear(tight, None, None)
    after = tight.coefficients + sol.dr * COEFFICIENT_SCALE
    assert np.all(np.abs(after - tight.prior.mean) < tight.prior.std), after - tight.prior.mean
    broad = _stub_context(np.random.default_rng(12), np.full(8, 1e12))
    sol = solve_linear(broad, None, None)
    a = np.concatenate([broad.jacobian, nuisance_columns(broad.start_columns_m)], axis=2).reshape(-1, 12)
    x, *_ = np.linalg.lstsq(a, broad.y_m.ravel(), rcond=None)
    np.testing.assert_allclose(sol.dr, x[:8], rtol=1e-6)


def test_a_prior_precision_shrinks_the_std_of_its_parameter_only():
    """The sandwich of a MAP fit: an infinite-like prior precision on one parameter drives its std to ~0
    (below 1 % of the one without it), a zero precision leaves the covariance unchanged."""
    rng = np.random.default_rng(4)
    a = _design()
    _, res = _fit(a, rng.standard_normal((3000, 2)) * 2e-6)
    free = spectral_covariance(a, res, 240)
    same = spectral_covariance(a, res, 240, np.zeros(5))
    np.testing.assert_allclose(same, free)
    held = spectral_covariance(a, res, 240, np.array([1e6, 0, 0, 0, 0]))
    assert np.sqrt(held[0, 0]) < 0.01 * np.sqrt(free[0, 0])
    np.testing.assert_allclose(np.diag(held)[2:4], np.diag(free)[2:4], rtol=1e-6)


def test_a_map_fit_covers_truths_drawn_from_its_prior_including_a_parameter_the_data_leave_free():
    """Calibration of a MAP fit (Laplace posterior): parameters drawn from the Gaussian prior, the data from
    them plus white noise, the MAP estimate under that prior; the +-1.96 std interval holds the truth in 90-98 %
    of 200 draws, for the 1X gains the data determine and for a column 1e-4 the size of the others (the data
    leave it at its prior), whose std is then the prior's own (within 2 %). Its pseudo-observations' noise
    enters the meat: without it that parameter's std is near zero and it is never covered."""
    rng = np.random.default_rng(17)
    a = _design()
    a[:, :, 4] *= 1e-4  # the DC column barely reaches the data
    noise_m = 2e-6
    prior_std = np.array([3e-6, 3e-6, 3e-6, 3e-6, 5e-6])
    precision = (noise_m / prior_std) ** 2  # pseudo-observations sqrt(precision) theta = 0 +- noise_m
    flat = a.reshape(-1, 5)
    hits, stds = [], []
    for _ in range(200):
        truth = rng.standard_normal(5) * prior_std
        y = np.einsum("tcp,p->tc", a, truth) + rng.standard_normal((3000, 2)) * noise_m
        theta = np.linalg.solve(flat.T @ flat + np.diag(precision), flat.T @ y.ravel())
        res = y - np.einsum("tcp,p->tc", a, theta)
        std = np.sqrt(np.diag(spectral_covariance(a, res, 240, precision, noise_m ** 2)))
        hits.append(np.abs(theta - truth) <= 1.96 * std)
        stds.append(std)
    coverage = np.mean(hits, axis=0)
    assert np.all((coverage >= 0.90) & (coverage <= 0.98)), coverage
    np.testing.assert_allclose(np.median(stds, axis=0)[4], prior_std[4], rtol=0.02)
    scatter_only = np.sqrt(np.diag(spectral_covariance(a, res, 240, precision)))
    assert scatter_only[4] < 0.05 * prior_std[4]  # the estimate's scatter alone (20x too small): the premise


def test_the_magnitude_prior_bounds_two_cancelling_gains_and_leaves_a_determined_gain_alone(monkeypatch):
    """Bounds of the gains' magnitude prior. Two columns that differ by a trace (1e-4 of their size) and a
    record that holds that trace: least squares cancels them at gains ~1e4 times the record's size; the MAP
    gains each move the output by under 3 sigma of the prior (LINEAR_PRIOR_SIGNAL_RATIO x the data's RMS). A
    well-determined gain (the record is 5 x one column plus noise) is the least-squares one within 1e-4."""
    from rotor_estimator.diagnosis.fitting import LINEAR_PRIOR_SIGNAL_RATIO, solve_linear

    rng = np.random.default_rng(21)
    ctx = _stub_context(rng, np.full(8, 1.0))  # the coefficients held: only the gains move
    t = np.arange(400)
    base = np.zeros((400, 4))
    base[:, 0] = np.cos(2 * np.pi * t / 37) * 1e-6
    trace = np.zeros((400, 4))
    trace[:, 1] = np.sin(2 * np.pi * t / 11) * 1e-10
    cols = np.stack([base, base + trace], axis=2)
    ctx.y_m = trace * 3e4 + rng.standard_normal((400, 4)) * 1e-7
    a = cols.reshape(-1, 2)
    ls, *_ = np.linalg.lstsq(a, ctx.y_m.ravel(), rcond=None)
    assert np.max(np.abs(ls)) > 1e4
    sol = solve_linear(ctx, None, cols)
    y_rms = np.sqrt(np.mean((ctx.y_m - ctx.y_m.mean(axis=0)) ** 2))
    own_rms = np.abs(sol.theta) * np.sqrt(np.mean(cols ** 2, axis=(0, 1)))
    assert np.all(own_rms < 3 * LINEAR_PRIOR_SIGNAL_RATIO * y_rms), own_rms / y_rms

    ctx.y_m = 5.0 * base + rng.standard_normal((400, 4)) * 1e-7
    sol = solve_linear(ctx, None, cols[:, :, :1])
    import rotor_estimator.diagnosis.fitting as fitting

    monkeypatch.setattr(fitting, "LINEAR_PRIOR_SIGNAL_RATIO", 1e12)  # the same solve without the gains' prior
    free = solve_linear(ctx, None, cols[:, :, :1])
    assert sol.theta[0] == pytest.approx(5.0, rel=0.05)
    assert sol.theta[0] == pytest.approx(free.theta[0], rel=1e-4)


@pytest.mark.parametrize(("n_samples", "segment"), [(5000, 200), (4999, 333), (300, 300), (257, 65)])
def test_welch_cross_spectra_agree_with_scipys_csd_pair_by_pair(n_samples, segment):
    """Agreement with an independent implementation: every channel pair's cross-spectral density (and the
    frequencies) equals scipy.signal.csd's with the settings spectral_covariance used, to rounding, for segment
    counts that do and do not divide the record; a segment longer than the record is refused by name."""
    from scipy.signal import csd

    x = np.random.default_rng(7).standard_normal((n_samples, 4)) * np.array([1.0, 2.0, 0.5, 3.0])
    freqs, cross = welch_cross_spectra(x, segment)
    for i in range(4):
        for j in range(4):
            f_ref, s_ref = csd(x[:, i], x[:, j], fs=1.0, nperseg=segment, return_onesided=False,
                               scaling="density", detrend=False)
            np.testing.assert_allclose(freqs, f_ref)
            np.testing.assert_allclose(cross[:, i, j], s_ref, rtol=1e-10, atol=1e-13 * np.abs(s_ref).max())
    with pytest.raises(ValueError, match="segment"):
        welch_cross_spectra(x, n_samples + 1)
