# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Properties of the linear filters and cross-checks against the exact KF and filterpy."""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from rotor_estimator.core.linear_filters import (ExtendedKalmanFilter, KalmanFilter, LinearGaussianModel,
                                            UnscentedKalmanFilter, discretize, merwe_weights)


def _random_model(n: int = 6, p: int = 3, m: int = 2, seed: int = 0) -> LinearGaussianModel:
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    F = 0.9 * A / np.max(np.abs(np.linalg.eigvals(A)))
    Gq = rng.standard_normal((n, n)) * 0.1
    Gr = rng.standard_normal((p, p)) * 0.2
    return LinearGaussianModel(F=F, Q=Gq @ Gq.T + 1e-3 * np.eye(n), H=rng.standard_normal((p, n)),
                               R=Gr @ Gr.T + 0.05 * np.eye(p), B=rng.standard_normal((n, m)),
                               D=rng.standard_normal((p, m)))


def _data(model: LinearGaussianModel, N: int = 60, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    n, p, m = model.F.shape[0], model.H.shape[0], model.B.shape[1]
    us = rng.standard_normal((N, m))
    x = np.zeros(n)
    zs = np.empty((N, p))
    for k in range(N):
        zs[k] = model.hx(x, us[k]) + rng.multivariate_normal(np.zeros(p), model.R)
        x = model.fx(x, us[k]) + rng.multivariate_normal(np.zeros(n), model.Q)
    return zs, us


@pytest.mark.parametrize("alpha", [1e-3, 0.01, 0.5, 1.0])
def test_ukf_equals_kalman_filter_on_linear_model_means_and_covariances(alpha):
    model = _random_model()
    zs, us = _data(model)
    x0, P0 = np.ones(6), np.eye(6)
    kf = KalmanFilter(model, x0, P0)
    ukf = UnscentedKalmanFilter.from_linear(model, x0, P0, alpha=alpha, beta=2.0, kappa=0.0)
    for z, u in zip(zs, us):
        kf.update(z, u=u)
        ukf.update(z, u=u)
        np.testing.assert_allclose(ukf.x, kf.x, rtol=1e-7, atol=1e-9)
        np.testing.assert_allclose(ukf.P, kf.P, rtol=1e-7, atol=1e-9)
        kf.predict(u)
        ukf.predict(u)
        np.testing.assert_allclose(ukf.P, kf.P, rtol=1e-7, atol=1e-9)


def test_ekf_equals_kalman_filter_on_linear_model():
    model = _random_model(seed=3)
    zs, us = _data(model, seed=4)
    kf = KalmanFilter(model, np.zeros(6), 2 * np.eye(6)).run(zs, us)
    ekf = ExtendedKalmanFilter.from_linear(model, np.zeros(6), 2 * np.eye(6)).run(zs, us)
    np.testing.assert_allclose(ekf.x, kf.x, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(ekf.P_diag, kf.P_diag, rtol=1e-10)


def test_ekf_uses_the_jacobian_of_a_nonlinear_model():
    """On a nonlinear measurement the EKF's update equals the KF linearized at the prior."""
    Q, R = 0.01 * np.eye(2), np.array([[0.04]])
    hx = lambda x, u: np.array([x[0] ** 2 + x[1]])  # noqa: E731
    Hj = lambda x, u: np.array([[2 * x[0], 1.0]])  # noqa: E731
    ekf = ExtendedKalmanFilter(lambda x, u: x, lambda x, u: np.eye(2), hx, Hj, Q, R, np.array([1.0, 0.5]),
                               np.eye(2))
    ekf.update(np.array([2.0]))
    H = np.array([[2.0, 1.0]])
    S = H @ H.T + R
    K = H.T / S
    np.testing.assert_allclose(ekf.x, np.array([1.0, 0.5]) + (K * (2.0 - 1.5)).ravel())


def test_vectorized_ukf_matches_filterpy_unscented_kalman_filter():
    fp = pytest.importorskip("filterpy.kalman")
    model = _random_model(n=4, p=2, m=1, seed=5)
    zs, us = _data(model, N=8, seed=6)
    alpha, beta, kappa = 0.3, 2.0, 1.0
    points = fp.MerweScaledSigmaPoints(4, alpha=alpha, beta=beta, kappa=kappa)
    ref = fp.UnscentedKalmanFilter(dim_x=4, dim_z=2, dt=1.0, points=points,
                                   fx=lambda x, dt, u: model.F @ x + model.B @ u,
                                   hx=lambda x, u: model.H @ x + model.D @ u)
    ref.x, ref.P, ref.Q, ref.R = np.zeros(4), np.eye(4), model.Q, model.R
    ours = UnscentedKalmanFilter.from_linear(model, np.zeros(4), np.eye(4), alpha, beta, kappa)
    for z, u in zip(zs, us):
        ref.predict(u=u)
        ours.predict(u)
        ref.update(z, u=u)
        ours.update(z, u=u)
        np.testing.assert_allclose(ours.x, ref.x, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(ours.P, ref.P, rtol=1e-9, atol=1e-12)


def test_merwe_weights_match_filterpy():
    fp = pytest.importorskip("filterpy.kalman")
    points = fp.MerweScaledSigmaPoints(7, alpha=0.01, beta=2.0, kappa=0.5)
    Wm, Wc, _ = merwe_weights(7, 0.01, 2.0, 0.5)
    np.testing.assert_allclose(Wm, points.Wm)
    np.testing.assert_allclose(Wc, points.Wc)


def test_masked_update_equals_filter_without_the_hidden_channels():
    model = _random_model(seed=7)
    zs, us = _data(model, seed=8)
    keep = np.array([True, False, True])
    sub = LinearGaussianModel(model.F, model.Q, model.H[keep], model.R[np.ix_(keep, keep)], model.B, model.D[keep])
    for cls in (KalmanFilter, UnscentedKalmanFilter.from_linear):
        a = cls(model, np.zeros(6), np.eye(6)).run(zs, us, masks=keep)
        b = cls(sub, np.zeros(6), np.eye(6)).run(zs[:, keep], us)
        np.testing.assert_allclose(a.x, b.x, rtol=1e-9, atol=1e-12)


def test_non_finite_measurements_are_rejected_and_counted():
    model = _random_model(seed=9)
    zs, us = _data(model, N=20, seed=10)
    zs[3, 1] = np.nan
    zs[7, :] = np.inf
    run = KalmanFilter(model, np.zeros(6), np.eye(6)).run(zs, us)
    assert run.n_rejected == 4
    assert run.n_used[3] == 2 and run.n_used[7] == 0
    assert np.all(np.isfinite(run.x))


def test_discretize_matches_closed_form_for_a_scalar_system():
    a, b, q, dt = -3.0, 2.0, 0.7, 0.05
    F, Bd, Qd = discretize(np.array([[a]]), np.array([[b]]), dt, np.array([[1.0]]), np.array([[q]]))
    assert F[0, 0] == pytest.approx(np.exp(a * dt))
    assert Bd[0, 0] == pytest.approx((np.exp(a * dt) - 1) / a * b)
    assert Qd[0, 0] == pytest.approx(q * (np.exp(2 * a * dt) - 1) / (2 * a))


def test_numerical_core_imports_no_ros():
    code = ("import sys, rotor_estimator.core.linear_filters, rotor_estimator.virtual_sensing.estimator, "
            "rotor_estimator.cli.virtual_sensing, rotor_estimator.core.flexible; "
            "bad = [m for m in sys.modules if m.split('.')[0] in ('rclpy', 'rosbags', 'ross')]; "
            "print(bad); sys.exit(1 if bad else 0)")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert res.returncode == 0, res.stdout + res.stderr


@pytest.mark.parametrize("cls", [KalmanFilter, ExtendedKalmanFilter.from_linear, UnscentedKalmanFilter.from_linear])
def test_gated_outlier_update_equals_skipping_that_sample_and_is_counted(cls):
    model = _random_model(seed=11)
    zs, us = _data(model, N=30, seed=12)
    zs[10, 1] += 1e3  # a spike far outside any innovation covariance
    skip = np.ones((30, 3), bool)
    skip[10] = False
    gated = cls(model, np.zeros(6), np.eye(6), gate_probability=0.9999).run(zs, us)
    ref = cls(model, np.zeros(6), np.eye(6)).run(zs, us, masks=skip)
    assert gated.n_gated == 1 and gated.n_used[10] == 0 and gated.nis[10] > 1e4
    np.testing.assert_allclose(gated.x, ref.x, rtol=1e-9, atol=1e-12)
    ungated = cls(model, np.zeros(6), np.eye(6)).run(zs, us)  # default: no gate
    assert ungated.n_gated == 0 and ungated.n_used[10] == 3


def test_generous_gate_rejects_about_its_tail_probability_on_consistent_data():
    model = _random_model(seed=13)
    zs, us = _data(model, N=1500, seed=14)
    run = KalmanFilter(model, np.zeros(6), np.eye(6), gate_probability=0.99).run(zs, us)
    assert 0 < run.n_gated < 40  # 1% of 1500 = 15 expected


def test_gate_probability_outside_0_1_is_a_config_error():
    from rotor_estimator.core.errors import ConfigError
    with pytest.raises(ConfigError, match="gate_probability"):
        KalmanFilter(_random_model(), np.zeros(6), np.eye(6), gate_probability=1.0)
