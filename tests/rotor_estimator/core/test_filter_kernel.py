# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Properties of the one compiled EKF kernel (rotor_estimator.core.filter_kernel): the seed special case
against the generalized model, Jacobians against finite differences, the two operation orders of the
covariance prediction and of the update against textbook formulas, and a covariance that stays
symmetric positive semi-definite."""
import numpy as np
import pytest

from rotor_estimator.core import filter_kernel as fk
from rotor_estimator.core.ekf import FilterModel

H_S = 1.0 / 20480.0  # one sample period of the seed rig (s)
SHAFT = (0.7, 2094.4, -300.0)  # angle (rad), speed (rad/s), angular acceleration (rad/s^2)


@pytest.fixture(scope="module")
def fm(seed_rig_file):
    return FilterModel.build(seed_rig_file.rig, seed_rig_file.estimator)


def _seed_state(rig):
    """A plausible 16-state ``[v (m/s), z (m), r]`` near the seed rig's operating point."""
    rng = np.random.default_rng(7)
    return np.concatenate([rng.normal(0, 2e-3, 4), rng.normal(0, 2e-5, 4), rig.true_coefficients.as_array()])


def _generalized_args(fm, fimp):
    """The seed model written in the generalized parameterization: identity map ``[I8; I8]``, order-0 speed
    basis, imbalance moments/phases as in-phase/quadrature components, impact as generalized force."""
    dmap = np.vstack([np.eye(8), np.eye(8)])
    powers = np.zeros(8, dtype=np.int64)
    bvec = np.empty(2 * fm.moments.shape[0])
    bvec[0::2] = fm.moments * np.cos(fm.phases)
    bvec[1::2] = fm.moments * np.sin(fm.phases)
    fgen = np.array([fm.wimp[0] * fimp[0], fm.wimp[0] * fimp[1], fm.wimp[1] * fimp[0], fm.wimp[1] * fimp[1]])
    return dmap, powers, bvec, fgen


def _spd(n, rng, scales):
    a = rng.normal(size=(n, n))
    c = a @ a.T / n + 0.1 * np.eye(n)
    return c * np.outer(scales, scales)


def _scales(n):
    return np.concatenate([np.full(4, 2e-3), np.full(4, 2e-5), np.full(n - 8, 1e4)])


def test_seed_prediction_equals_generalized_prediction_with_identity_map(seed_rig, fm):
    """predict_seed (streaming EKF, loop order) and predict (identification, BLAS order) on the seed model
    written with the identity coefficient map give the same state, Jacobian and covariance to rounding."""
    fimp = np.array([30.0, -12.0])
    dmap, powers, bvec, fgen = _generalized_args(fm, fimp)
    x0 = _seed_state(seed_rig)
    P0 = _spd(16, np.random.default_rng(1), _scales(16))
    rw = np.full(8, 1e3)
    x_seed, P_seed, phi_m = x0.copy(), P0.copy(), np.empty((8, 16))
    fk.predict_seed(x_seed, P_seed, H_S, *SHAFT, fimp, fm.minv, fm.gyro, fm.moments, fm.phases, fm.wimb, fm.wimp,
                    1e-2, rw, phi_m)
    x_gen, P_gen, phi_top = x0.copy(), P0.copy(), np.empty((8, 16))
    fk.predict(x_gen, P_gen, np.zeros(0), 8, 0, bvec, H_S, *SHAFT, fgen, dmap, powers, 0.0, 1.0, fm.minv, fm.gyro,
               fm.wimb, 1e-2, rw, phi_top, np.empty(16))
    assert np.all(x_seed[:8] != x0[:8])  # the step moved the motion states
    for a, b in ((x_seed, x_gen), (phi_m, phi_top), (P_seed, P_gen)):
        assert np.allclose(a, b, rtol=1e-11, atol=1e-13 * np.abs(b).max())


def _central_difference(f, x, steps):
    cols = []
    for j, h in enumerate(steps):
        d = np.zeros_like(x)
        d[j] = h
        cols.append((f(x + d) - f(x - d)) / (2 * h))
    return np.array(cols).T


def test_generalized_transition_jacobian_matches_central_differences(seed_rig, fm):
    """transition's exact RK4 Jacobian (8 x n) equals central differences of its own state map, on a model
    with different bearings, speed-dependent coefficients (order 1) and estimated imbalance states."""
    fimp = np.array([30.0, -12.0])
    _, _, bvec, fgen = _generalized_args(fm, fimp)
    dmap = np.hstack([np.eye(16), np.eye(16)])  # per-bearing coefficients, constant + linear in speed
    powers = np.array([0] * 16 + [1] * 16, dtype=np.int64)
    base = seed_rig.true_coefficients.as_array()
    theta = np.concatenate([base, 1.1 * base, 0.05 * base, -0.03 * base])
    x0 = np.concatenate([_seed_state(seed_rig)[:8], theta, bvec])
    nth, nbs = 32, bvec.shape[0]

    def step(x, phi=None):
        out = np.empty_like(x)
        phi = np.empty((8, x.shape[0])) if phi is None else phi
        fk.transition(x, np.zeros(0), nth, nbs, bvec, H_S, *SHAFT, fgen, dmap, powers, 1500.0, 600.0, fm.minv,
                      fm.gyro, fm.wimb, out, phi)
        return out[:8]

    phi = np.empty((8, x0.shape[0]))
    step(x0, phi)
    steps = np.concatenate([np.full(4, 1e-4), np.full(4, 1e-6), 1e-4 * np.abs(theta) + 1e-3, np.full(nbs, 1e-7)])
    fd = _central_difference(step, x0, steps)
    col_scale = np.abs(fd).max(axis=0) + 1e-300
    assert np.all(np.abs(phi - fd) <= 1e-6 * col_scale + 1e-12)


def test_seed_transition_jacobian_matches_central_differences(seed_rig, fm):
    """transition_seed's exact RK4 Jacobian (8x16, motion states and coefficients) equals central
    differences of its own state map."""
    x0 = _seed_state(seed_rig)
    fimp = np.array([30.0, -12.0])

    def step(x, phi=None):
        y = x.copy()
        fk.transition_seed(y, H_S, *SHAFT, fimp, fm.minv, fm.gyro, fm.moments, fm.phases, fm.wimb, fm.wimp,
                           np.empty((8, 16)) if phi is None else phi)
        return y[:8]

    phi = np.empty((8, 16))
    step(x0, phi)
    steps = np.concatenate([np.full(4, 1e-4), np.full(4, 1e-6), 1e-4 * np.abs(x0[8:]) + 1e-3])
    fd = _central_difference(step, x0, steps)
    assert np.all(np.abs(phi - fd) <= 1e-6 * (np.abs(fd).max(axis=0) + 1e-300) + 1e-12)


@pytest.mark.parametrize("blas_order", [False, True], ids=["loops", "blas"])
@pytest.mark.parametrize("n", [16, 21])
def test_covariance_prediction_equals_dense_formula(blas_order, n):
    """propagate_covariance equals Phi P Phi^T + Qd written densely in numpy (Eq. 13, Qd of Eq. 9)."""
    rng = np.random.default_rng(n)
    P = _spd(n, rng, _scales(n))
    phi_top = np.hstack([np.eye(8) + 0.01 * rng.normal(size=(8, 8)), 1e-9 * rng.normal(size=(8, n - 8))])
    h, q, rw = 1e-4, 3e-2, rng.uniform(0, 10, n - 8)
    Phi = np.eye(n)
    Phi[:8] = phi_top
    Qd = np.zeros((n, n))
    Qd[:4, :4] = q * h * np.eye(4)
    Qd[:4, 4:8] = Qd[4:8, :4] = q * h ** 2 / 2 * np.eye(4)
    Qd[4:8, 4:8] = q * h ** 3 / 3 * np.eye(4)
    Qd[8:, 8:] = np.diag(rw * h)
    want = Phi @ P @ Phi.T + Qd
    got = P.copy()
    fk.propagate_covariance(got, phi_top, h, q, rw, blas_order)
    assert np.allclose(got, want, rtol=1e-12, atol=1e-14 * np.abs(want).max())


def _textbook_update(x, P, y, hp, r_var):
    n = x.shape[0]
    H = np.zeros((4, n))
    H[:, 4:8] = hp
    R = np.diag(r_var)
    S = H @ P @ H.T + R
    e = y - H @ x
    K = P @ H.T @ np.linalg.inv(S)
    IKH = np.eye(n) - K @ H
    return x + K @ e, IKH @ P @ IKH.T + K @ R @ K.T, float(e @ np.linalg.solve(S, e))


@pytest.mark.parametrize("blas_order", [False, True], ids=["loops", "blas"])
@pytest.mark.parametrize("n", [16, 21])
def test_update_equals_textbook_joseph_form(fm, blas_order, n):
    """update (Eqs. 15-17) equals the textbook Kalman update with an explicit inverse and the Joseph form,
    and returns the NIS ``e^T S^-1 e``; the posterior covariance is exactly symmetric."""
    rng = np.random.default_rng(100 + n)
    P = _spd(n, rng, _scales(n))
    x = rng.normal(size=n) * _scales(n)
    y = fm.hp @ x[4:8] + rng.normal(0, 1e-5, 4)
    r_var = np.full(4, 1e-12)
    x_ref, P_ref, nis_ref = _textbook_update(x, P, y, fm.hp, r_var)
    innov, sstd = np.empty(4), np.empty(4)
    st, nis = fk.update(x, P, y, fm.hp, r_var, 1e9, innov, sstd, blas_order)
    assert st == fk.STATUS_UPDATED
    assert np.isclose(nis, nis_ref, rtol=1e-9)
    assert np.allclose(x, x_ref, rtol=1e-9, atol=1e-9 * np.abs(_scales(n)))
    assert np.allclose(P, P_ref, rtol=1e-7, atol=1e-9 * np.abs(P_ref).max())
    assert np.array_equal(P, P.T)


@pytest.mark.parametrize("blas_order", [False, True], ids=["loops", "blas"])
def test_update_refuses_outliers_and_non_positive_definite_innovation_covariance(fm, blas_order):
    """An innovation beyond the gate is rejected (STATUS_GATED) and a non-positive-definite S is reported
    (STATUS_NUMERICAL, not an exception), both leaving the state and covariance untouched."""
    rng = np.random.default_rng(3)
    x, P = rng.normal(size=16) * _scales(16), _spd(16, rng, _scales(16))
    innov, sstd = np.empty(4), np.empty(4)
    x1, P1 = x.copy(), P.copy()
    st, nis = fk.update(x1, P1, fm.hp @ x[4:8] + 1.0, fm.hp, np.full(4, 1e-12), 100.0, innov, sstd, blas_order)
    assert st == fk.STATUS_GATED and nis > 100.0
    assert np.array_equal(x1, x) and np.array_equal(P1, P)
    P[4:8, :] = P[:, 4:8] = 0.0
    P[4:8, 4:8] = -np.eye(4) * 1e-10
    x2, P2 = x.copy(), P.copy()
    st, nis = fk.update(x2, P2, fm.hp @ x[4:8], fm.hp, np.zeros(4), 100.0, innov, sstd, blas_order)
    assert st == fk.STATUS_NUMERICAL and np.isnan(nis)
    assert np.array_equal(x2, x) and np.array_equal(P2, P)


@pytest.mark.parametrize("blas_order", [False, True], ids=["loops", "blas"])
def test_covariance_stays_symmetric_positive_definite_over_a_filter_run(seed_rig, fm, blas_order):
    """2000 predict/update cycles of the seed model (prediction in the caller's order, updates with noisy
    readings of the model's own response): P stays exactly symmetric after every update and positive
    definite (smallest eigenvalue of the correlation matrix > 0), and the NIS averages near 4."""
    rng = np.random.default_rng(11)
    fimp = np.zeros(2)
    dmap, powers, bvec, fgen = _generalized_args(fm, fimp)
    truth = _seed_state(seed_rig)
    x = truth.copy()
    x[8:] *= 0.8
    P = np.diag(np.concatenate([np.full(4, 0.02 ** 2), np.full(4, 1e-5 ** 2),
                                (0.3 * np.abs(truth[8:])) ** 2]))
    rw = np.zeros(8)
    phi, xs, innov, sstd = np.empty((8, 16)), np.empty(16), np.empty(4), np.empty(4)
    angle, speed, accel = SHAFT
    nis_all, min_eig = [], np.inf
    for k in range(2000):
        shaft = (angle + speed * k * H_S, speed, 0.0)
        fk.transition_seed(truth, H_S, *shaft, fimp, fm.minv, fm.gyro, fm.moments, fm.phases, fm.wimb, fm.wimp,
                           phi)
        if blas_order:
            fk.predict(x, P, np.zeros(0), 8, 0, bvec, H_S, *shaft, fgen, dmap, powers, 0.0, 1.0, fm.minv, fm.gyro,
                       fm.wimb, 1e-4, rw, phi, xs)
        else:
            fk.predict_seed(x, P, H_S, *shaft, fimp, fm.minv, fm.gyro, fm.moments, fm.phases, fm.wimb, fm.wimp,
                            1e-4, rw, phi)
        y = fm.hp @ truth[4:8] + rng.normal(0, np.sqrt(fm.r_var))
        st, nis = fk.update(x, P, y, fm.hp, fm.r_var, 1e6, innov, sstd, blas_order)
        assert st == fk.STATUS_UPDATED
        assert np.array_equal(P, P.T)
        nis_all.append(nis)
        if k % 50 == 0:
            d = np.sqrt(np.diag(P))
            min_eig = min(min_eig, np.linalg.eigvalsh(P / np.outer(d, d)).min())
    assert min_eig > 0.0
    assert 3.0 < np.mean(nis_all[200:]) < 5.0
