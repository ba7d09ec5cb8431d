# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Speed-dependent coefficients and non-identical bearings on synthetic data with a known truth."""
import numpy as np

from rotor_estimator.identification import speed_dependent as sd
from rotor_estimator.identification.bearings16 import crlb16, fit16
from rotor_estimator.identification.problem import CoefficientModel
from rotor_estimator.identification.scenarios import multi_impact, simulate_design, sweep

W_LO, W_HI = 3000 * 2 * np.pi / 60, 20000 * 2 * np.pi / 60


def test_speed_dependent_coefficients_are_recovered(seed_rig, arrays, true8, r0, tmp_path):
    truth_model = CoefficientModel(speed_order=1, speed_ref_rad_s=0.5 * (W_LO + W_HI),
                                   speed_scale_rad_s=0.5 * (W_HI - W_LO))
    slope = np.array([0.15, -0.1, 0.1, 0.2, -0.2, 0.0, 0.0, -0.1]) * true8   # +-10-20% over the sweep
    theta_true = np.concatenate([true8, slope])
    rec = simulate_design(seed_rig, sweep("cd", 20000, 3000, 1.0), coefficient_model=truth_model, theta=theta_true,
                          seed=5, through_tachometer=True, arrays=arrays)[0].record
    order, results = sd.select_order(arrays, rec, r0, max_order=2)
    assert order >= 1
    speeds = np.linspace(W_LO, W_HI, 6)
    tab = sd.table(results[1], speeds)
    true_values, _ = truth_model.coefficients_at(theta_true, speeds)
    z = (tab.values - true_values) / tab.std
    assert np.all(np.abs(z) < 4.0), z
    # the constant model silently averages: far outside its own confidence
    const = results[0]
    assert np.max(np.abs(const.theta - true8) / const.std) > 10
    assert len(tab.as_rows()) == 6 * 8 and "rpm" in tab.format()
    from rotor_estimator.identification.plots import coefficients_vs_speed

    assert coefficients_vs_speed(tab, tmp_path / "c.png").exists()


def test_sixteen_coefficients_from_a_sweep(seed_rig, arrays, true8, r0):
    c16 = np.concatenate([true8, true8 * np.array([1.3, 0.8, 1.2, 1.25, 0.8, 1.5, 0.5, 0.9])])
    d = sweep("cd", 20000, 3000, 0.5)
    bnd = crlb16(seed_rig, d, c16, unknown_imbalance=False)
    assert np.all(np.isfinite(bnd.std)) and bnd.relative[[0, 3, 4, 7, 8, 11, 12, 15]].max() < 0.03
    rec = simulate_design(seed_rig, d, coefficients=c16, seed=8, arrays=arrays)[0].record
    res = fit16(arrays, rec, r0)
    assert res.converged and np.all(np.abs(res.theta - c16) < 4.5 * res.std)


def test_impacts_at_two_stations_separate_the_bearings_better_than_one(seed_rig, true8):
    c16 = np.concatenate([true8, true8])
    one = crlb16(seed_rig, multi_impact("1", 4, 0.53, 20000, discard_initial_s=0.03), c16, unknown_imbalance=False)
    two = crlb16(seed_rig,
                 multi_impact("2", 4, 0.53, 20000, positions_m=(-0.09, -0.09, 0.09, 0.09), discard_initial_s=0.03),
                 c16, unknown_imbalance=False)
    assert np.median(two.std / one.std) < 1.0
