# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Estimators: the batch fit is efficient (planner CRLB = empirical spread), the UKF matches filterpy's,
the smoother does not increase the error."""
import numpy as np

from rotor_estimator.core import filter_kernel
from rotor_estimator.identification.batch_ml import BatchOptions, fit
from rotor_estimator.identification.kalman import KalmanOptions, run_ekf, run_ekf_rts, run_ukf, ukf_weights
from rotor_estimator.identification.planner import evaluate
from rotor_estimator.identification.problem import record_from_recording
from rotor_estimator.identification.scenarios import design_from_scenario, simulate_design, sweep
from rotor_estimator.core.simulator import paper_scenario, simulate


def test_planner_crlb_matches_empirical_spread_of_batch_ml(seed_rig, arrays, model8, true8, r0):
    """A 0.25 s coast-down, imbalance known: spread of 30 seeded batch fits vs the planner's bound."""
    design = sweep("small", 20000, 3000, 0.25)
    crlb = evaluate(seed_rig, design, true8, unknown_imbalance=False, arrays=arrays).std
    est = np.array([fit(arrays, model8, simulate_design(seed_rig, design, seed=100 + s, arrays=arrays)[0].record,
                        r0).theta for s in range(30)])
    ratio = est.std(axis=0, ddof=1) / crlb
    bias = (est.mean(axis=0) - true8) / crlb
    # 30 runs: the std ratio's own spread is ~0.13, the bias's ~0.18 (in CRLB units)
    assert np.all((ratio > 0.6) & (ratio < 1.45)), ratio
    assert np.all(np.abs(bias) < 0.8), bias


def test_batch_ml_estimates_unknown_imbalance(seed_rig, arrays, model8, true8, r0):
    rec = simulate_design(seed_rig, sweep("cd", 20000, 3000, 0.5), seed=3, arrays=arrays)[0].record
    res = fit(arrays, model8, rec, r0, options=BatchOptions(estimate_imbalance=True))
    assert res.converged
    assert np.all(np.abs(res.theta - true8) < 4 * res.std)
    assert np.allclose(res.imbalance_kg_m, arrays.imbalance_nominal_kg_m, atol=0.02 * 9.21e-6)


def test_ukf_matches_filterpy_unscented_kalman_filter(seed_rig_file, impact_sim, arrays, model8):
    """Our compiled UKF and filterpy's UnscentedKalmanFilter, same sigma points, same model, 60 samples."""
    from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter

    rig, cfg = seed_rig_file.rig, seed_rig_file.estimator
    rec = record_from_recording(rig, impact_sim.recording)
    n = 60
    sub = type(rec)(rec.t_s[:n], rec.angle_rad[:n], rec.speed_rad_s[:n], rec.accel_rad_s2[:n],
                    rec.force_gen_n[:n], rec.probes_m[:n])
    opts = KalmanOptions.from_config(cfg, model8, passes=1)
    ours = run_ukf(arrays, model8, sub, opts)
    m = 16
    pts = MerweScaledSigmaPoints(m, alpha=opts.ukf_alpha, beta=opts.ukf_beta, kappa=opts.ukf_kappa)
    state = {"k": 0}
    dmap, powers = model8.dmap(), model8.powers()

    def fx(x, dt):
        k = state["k"]
        q = x[:8].copy()
        filter_kernel.rk4_step(q, np.zeros((8, 0)), x[8:].copy(), arrays.imbalance_nominal_kg_m, dt, sub.angle_rad[k],
                         sub.speed_rad_s[k], sub.accel_rad_s2[k], sub.force_gen_n[k], dmap, powers, 0.0, 1.0,
                         arrays.minv, arrays.gyro, arrays.wimb, -1, -1)
        return np.concatenate([q, x[8:]])

    ukf = UnscentedKalmanFilter(dim_x=m, dim_z=4, dt=sub.dt_s[0], fx=fx, hx=lambda x: arrays.hp @ x[4:8], points=pts)
    ukf.x = np.zeros(m)
    ukf.x[4:8] = arrays.bearing_from_probe @ sub.probes_m[0]
    ukf.x[8:] = opts.theta0
    ukf.P = np.diag(np.concatenate([np.full(4, opts.initial_velocity_std_m_s ** 2),
                                    np.full(4, opts.initial_displacement_std_m ** 2), opts.theta_std ** 2]))
    ukf.Q = np.zeros((m, m))
    ukf.R = np.eye(4) * opts.noise_std_m ** 2
    for k in range(1, n):
        state["k"] = k - 1
        ukf.predict(dt=sub.dt_s[k - 1])
        ukf.update(sub.probes_m[k])
    assert np.allclose(ours.theta, ukf.x[8:], rtol=1e-6, atol=1e-6 * np.abs(opts.theta0).max())
    wm, wc, lam = ukf_weights(m, opts.ukf_alpha, opts.ukf_beta, opts.ukf_kappa)
    assert np.allclose(wm, pts.Wm) and np.allclose(wc, pts.Wc)


def test_smoother_does_not_increase_error(seed_rig_file, arrays, model8, true8):
    """Seed imbalance+impact case, 4 seeds: the error of EKF + RTS (iterated) is not larger than that of the
    EKF pass it starts from, nor (within 10%) than that of the 2-pass EKF, in CRLB units."""
    rig, cfg = seed_rig_file.rig, seed_rig_file.estimator
    crlb = evaluate(rig, design_from_scenario(rig, paper_scenario("imbalance+impact")), true8,
                    unknown_imbalance=False, arrays=arrays).std
    opts = KalmanOptions.from_config(cfg, model8)
    e_ekf, e_pass, e_rts = 0.0, 0.0, 0.0
    for s in range(4):
        rec = record_from_recording(rig, simulate(rig, paper_scenario("imbalance+impact"), seed=40 + s).recording)
        a = run_ekf(arrays, model8, rec, opts)
        b = run_ekf_rts(arrays, model8, rec, opts)
        # its first forward pass is the EKF (up to the tiny regularizing process noise)
        one_pass = run_ekf(arrays, model8, rec, KalmanOptions.from_config(cfg, model8, passes=1)).theta
        assert np.all(np.abs(b.extra["ekf_theta"] - one_pass) < 0.1 * crlb)
        e_ekf += np.sum(((a.theta - true8) / crlb) ** 2)
        e_pass += np.sum(((one_pass - true8) / crlb) ** 2)
        e_rts += np.sum(((b.theta - true8) / crlb) ** 2)
    assert e_rts <= e_pass
    assert e_rts <= 1.1 * e_ekf
