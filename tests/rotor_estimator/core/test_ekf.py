# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The compiled EKF against independent implementations and its own statistical promises."""
import numpy as np
import pytest

from rotor_estimator.bench import reference_ekf as ref
from rotor_estimator.bench.filterpy_baseline import run_filterpy
from rotor_estimator.core.config import BearingCoefficients
from rotor_estimator.core.ekf import FilterModel, StreamingEKF
from rotor_estimator.core.filter_kernel import STATUS_GATED, STATUS_NON_FINITE, STATUS_UPDATED
from rotor_estimator.core.offline import estimate, shaft_inputs_from_recording
from rotor_estimator.core.simulator import Scenario, simulate


def _inputs(sim):
    rec = sim.recording
    shaft = shaft_inputs_from_recording(rec)
    return (rec.time_s(), rec.probes_m, shaft.angle_rad, shaft.speed_rad_s, shaft.accel_rad_s2, rec.impact_force_n)


def test_rk4_jacobian_matches_finite_differences(seed_rig_file):
    model = FilterModel.build(seed_rig_file.rig, seed_rig_file.estimator)
    x = np.concatenate([[1e-3, -2e-3, 5e-4, 1e-3], [3e-6, -1e-6, 2e-6, 4e-6],
                        seed_rig_file.rig.true_coefficients.as_array()])
    args = (5e-5, 0.3, 2094.0, -800.0, np.array([10.0, -500.0]))
    _, phi = ref.rk4_step(model, x, *args)
    scale = np.abs(x) + 1e-9
    for j in range(16):
        dx = np.zeros(16)
        dx[j] = 1e-6 * scale[j]
        fd = (ref.rk4_step(model, x + dx, *args)[0] - ref.rk4_step(model, x - dx, *args)[0]) / (2 * dx[j])
        assert np.allclose(phi[:, j], fd, rtol=1e-6, atol=1e-9 * np.abs(fd).max() + 1e-300)


def test_compiled_kernel_equals_numpy_reference_step_by_step(seed_rig_file, impact_sim):
    rig, cfg = seed_rig_file.rig, seed_rig_file.estimator
    t, y, ang, spd, acc, imp = _inputs(impact_sim)
    ekf = StreamingEKF(rig, cfg)
    ekf.process_block(t[:1], y[:1], ang[:1], spd[:1], acc[:1], imp[:1])
    x, p = ekf.x.copy(), ekf.P.copy()
    for k in range(1, 250):  # crosses the impact at sample 200
        x, p, e, nis = ref.ekf_step(ekf.model, x, p, t[k] - t[k - 1], (ang[k - 1], spd[k - 1], acc[k - 1]),
                                    imp[k - 1], y[k])
        res = ekf.step(t[k], y[k], ang[k], spd[k], acc[k], imp[k])
        assert res.status[0] == STATUS_UPDATED
        assert np.allclose(res.innovation_m[0], e, rtol=1e-8, atol=1e-16)
    assert np.allclose(ekf.x, x, rtol=1e-7, atol=0)
    assert np.allclose(ekf.P, p, rtol=1e-6, atol=1e-12 * np.abs(p).max())


def test_agrees_with_filterpy_extended_kalman_filter(seed_rig_file, impact_sim):
    """An EKF built on filterpy (code nobody here wrote does P = FPF'+Q and the Joseph update)."""
    rig, cfg = seed_rig_file.rig, seed_rig_file.estimator
    args = _inputs(impact_sim)
    n = 400
    ekf = StreamingEKF(rig, cfg)
    ekf.process_block(*(a[:1] for a in args))
    fp = run_filterpy(ekf.model, ekf.x, ekf.P, *(a[:n] for a in args))
    ekf.process_block(*(a[1:n] for a in args))
    assert np.allclose(ekf.x[8:], fp.x.ravel()[8:], rtol=1e-8)
    assert np.allclose(ekf.P[8:, 8:], fp.P[8:, 8:], rtol=1e-6, atol=1e-9 * np.abs(fp.P[8:, 8:]).max())


def test_per_sample_steps_and_one_block_give_identical_estimates(seed_rig_file, impact_sim):
    rig, cfg = seed_rig_file.rig, seed_rig_file.estimator
    args = _inputs(impact_sim)
    block = StreamingEKF(rig, cfg)
    block.process_block(*(a[:300] for a in args))
    single = StreamingEKF(rig, cfg)
    for k in range(300):
        single.step(*(a[k] for a in args))
    assert np.array_equal(block.x, single.x)
    assert np.array_equal(block.P, single.P)


def test_filter_converges_to_truth_on_noise_free_data(seed_rig_file):
    rig, cfg = seed_rig_file.rig, seed_rig_file.estimator
    sim = simulate(rig, Scenario(noise_std_m=0.0), seed=None)
    est = estimate(sim.recording, rig, cfg, passes=3)
    true = rig.true_coefficients.as_array()
    rel = np.abs(est.coefficients - true) / np.maximum(np.abs(true), 1000.0)
    assert rel.max() < 2e-3, rel


def test_normalized_innovation_squared_is_consistent_with_four_channels(seed_rig_file, impact_sim):
    """On data from the same model, mean NIS ~ chi-square mean = 4 (std of the mean ~0.07 here)."""
    est = estimate(impact_sim.recording, seed_rig_file.rig, seed_rig_file.estimator, passes=2)
    nis = est.last_pass.nis[est.last_pass.status == STATUS_UPDATED]
    assert 3.6 < nis.mean() < 4.4
    assert np.mean(nis > 13.28) < 0.03  # chi2(4) 99% point


def test_reported_std_covers_the_actual_error(seed_rig_file, impact_sim):
    est = estimate(impact_sim.recording, seed_rig_file.rig, seed_rig_file.estimator, passes=2)
    z = (est.coefficients - seed_rig_file.rig.true_coefficients.as_array()) / est.std
    assert np.all(np.abs(z) < 4.0), z


def test_spike_is_gated_and_nan_is_rejected_and_both_are_counted(seed_rig_file, impact_sim):
    rig, cfg = seed_rig_file.rig, seed_rig_file.estimator
    t, y, ang, spd, acc, imp = _inputs(impact_sim)
    y = y.copy()
    y[600, 0] += 500e-6   # 500 um spike on xp1
    y[700, 2] = np.nan
    ekf = StreamingEKF(rig, cfg)
    res = ekf.process_block(t, y, ang, spd, acc, imp)
    assert res.status[600] == STATUS_GATED and res.status[700] == STATUS_NON_FINITE
    assert ekf.health.counts["gated_outlier"] == 1 and ekf.health.counts["non_finite"] == 1
    clean = StreamingEKF(rig, cfg)
    clean.process_block(t, impact_sim.recording.probes_m, ang, spd, acc, imp)
    # two lost samples out of 1900 barely move the estimate
    assert np.all(np.abs(ekf.coefficients - clean.coefficients) < 0.5 * clean.coefficient_std)


def test_non_increasing_times_are_refused(seed_rig_file, impact_sim):
    args = [a[:10].copy() for a in _inputs(impact_sim)]
    args[0][5] = args[0][4]
    with pytest.raises(ValueError, match="increase strictly"):
        StreamingEKF(seed_rig_file.rig, seed_rig_file.estimator).process_block(*args)


def test_corrupted_covariance_recovers_to_last_healthy_state(seed_rig_file, impact_sim):
    rig, cfg = seed_rig_file.rig, seed_rig_file.estimator
    args = _inputs(impact_sim)
    ekf = StreamingEKF(rig, cfg)
    ekf.process_block(*(a[:500] for a in args))
    healthy, healthy_std = ekf.coefficients, ekf.coefficient_std
    ekf.P[9, 9] = -1.0e30  # not positive definite: the next step must detect and recover
    ekf.P[0, 0] = np.nan
    ekf.process_block(*(a[500:510] for a in args))
    assert ekf.health.divergence_recoveries >= 1
    assert np.all(np.isfinite(ekf.x)) and np.all(np.diag(ekf.P) > 0)
    # back at the last healthy estimate, moved only by the 9 samples after the failure
    assert np.all(np.abs(ekf.coefficients - healthy) < 2 * healthy_std)


def test_initial_coefficients_can_seed_a_second_pass(seed_rig_file):
    guess = BearingCoefficients(4e5, 3e5, -3e5, 5e5, 1000, 0, 0, 1000)
    ekf = StreamingEKF(seed_rig_file.rig, seed_rig_file.estimator, initial_coefficients=guess)
    assert np.array_equal(ekf.coefficients, guess.as_array())
