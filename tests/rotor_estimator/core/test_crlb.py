# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The Cramer-Rao bound code against independent finite differences and known regimes."""
import numpy as np

from rotor_estimator.core.config import BearingCoefficients
from rotor_estimator.core.crlb import bound_from_fisher, fisher_information
from rotor_estimator.core.ekf import FilterModel
from rotor_estimator.core.simulator import Scenario, paper_scenario, simulate


def _fim(rig_file, scenario, **kw):
    rig = rig_file.rig
    sim = simulate(rig, scenario, seed=None)
    t = sim.recording.time_s()
    x0 = np.concatenate([sim.bearing_velocity_m_s[0], sim.bearing_displacement_m[0], sim.coefficients])
    model = FilterModel.build(rig, rig_file.estimator)
    return sim, fisher_information(model, x0, t, sim.angle_rad, sim.speed_rad_s, np.zeros_like(t),
                                   sim.recording.impact_force_n, **kw)


def test_fisher_information_matches_finite_differences_of_the_simulator(seed_rig_file):
    """Sensitivities w.r.t. the coefficients, from the independent (sub-stepped) simulator, give the same FIM."""
    rig = seed_rig_file.rig
    scen = Scenario(duration_s=0.06, discard_initial_s=0.0, noise_std_m=0.0)
    sim, fim = _fim(seed_rig_file, scen)
    base = rig.true_coefficients.as_array()
    jac = []
    for j in range(8):
        d = np.zeros(8)
        d[j] = 1e-4 * max(abs(base[j]), 100.0)
        up = simulate(rig, Scenario(duration_s=0.06, discard_initial_s=0.0, noise_std_m=0.0,
                                    coefficients=BearingCoefficients.from_array(base + d)), seed=None)
        dn = simulate(rig, Scenario(duration_s=0.06, discard_initial_s=0.0, noise_std_m=0.0,
                                    coefficients=BearingCoefficients.from_array(base - d)), seed=None)
        jac.append(((up.probes_clean_m - dn.probes_clean_m) / (2 * d[j])).ravel())
    jac = np.array(jac).T
    fd_fim = jac.T @ jac / rig.noise_std_m ** 2
    # from rest the initial state is known (zero): compare the r-block
    assert np.allclose(fim[8:, 8:], fd_fim, rtol=2e-3, atol=1e-6 * np.abs(fd_fim).max())


def test_imbalance_only_at_constant_speed_is_information_starved(seed_rig_file):
    """The seed's imbalance-only case: CRLB of stiffness > 100% and cross damping > 500% of the value."""
    _, fim = _fim(seed_rig_file, paper_scenario("imbalance"))
    rel = bound_from_fisher(fim, 1900).coefficient_std / np.abs(seed_rig_file.rig.true_coefficients.as_array())
    assert np.all(rel[:4] > 1.0) and np.all(rel[5:7] > 5.0)


def test_impact_makes_direct_coefficients_identifiable(seed_rig_file):
    _, fim = _fim(seed_rig_file, paper_scenario("imbalance+impact"))
    rel = bound_from_fisher(fim, 1900).coefficient_std / np.abs(seed_rig_file.rig.true_coefficients.as_array())
    assert np.all(rel[[0, 1, 2, 3, 4, 7]] < 0.08)


def test_unknown_imbalance_can_only_widen_the_bound(seed_rig_file):
    _, known = _fim(seed_rig_file, paper_scenario("imbalance+impact"))
    _, unknown = _fim(seed_rig_file, paper_scenario("imbalance+impact"), unknown_imbalance=True)
    a = bound_from_fisher(known, 1900).coefficient_std
    b = bound_from_fisher(unknown, 1900).coefficient_std
    assert np.all(b >= a * (1 - 1e-9))
