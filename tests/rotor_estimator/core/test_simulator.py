# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The simulator against physics and an analytic solution."""
import numpy as np

from rotor_estimator.core.config import BearingCoefficients
from rotor_estimator.core.model import damping_matrix, imbalance_force, rotor_matrices, stiffness_matrix
from rotor_estimator.core.simulator import Impact, Scenario, paper_scenario, simulate


def test_undamped_free_rotor_conserves_energy_after_an_impact(seed_rig):
    """No damping, symmetric stiffness, no imbalance: kinetic + strain energy is constant (G does no work)."""
    coeffs = BearingCoefficients(5e5, 0.0, 0.0, 6e5, 0.0, 0.0, 0.0, 0.0)
    sim = simulate(seed_rig, Scenario(duration_s=0.1, discard_initial_s=0.01, coefficients=coeffs,
                                      imbalance_scale=0.0, noise_std_m=0.0,
                                      impacts=(Impact(0.001, 1e-4, 200.0, -300.0),)), seed=None)
    mats = rotor_matrices(seed_rig)
    s = stiffness_matrix(coeffs.as_array())
    v, z = sim.bearing_velocity_m_s, sim.bearing_displacement_m
    energy = 0.5 * np.einsum("ni,ij,nj->n", v, mats.mass_matrix, v) + 0.5 * np.einsum("ni,ij,nj->n", z, s, z)
    assert energy[0] > 0
    assert np.ptp(energy) / energy.mean() < 1e-8


def test_steady_imbalance_response_matches_frequency_domain_solution(seed_rig):
    """At constant speed the late response equals Re(Z e^{j Omega t}) with (-W^2 M + jW(C+WG) + S) Z = F."""
    sim = simulate(seed_rig, Scenario(duration_s=0.2, discard_initial_s=0.15, impacts=(), noise_std_m=0.0),
                   seed=None)
    mats = rotor_matrices(seed_rig)
    r = seed_rig.true_coefficients.as_array()
    w = seed_rig.speed_rad_s
    # complex force amplitude: F(t) = Re(F_hat e^{jwt}) from two quarter-period samples of imbalance_force
    f0 = imbalance_force(mats, 0.0, w)
    f90 = imbalance_force(mats, np.pi / 2, w)
    f_hat = f0 - 1j * f90
    dyn = -w ** 2 * mats.mass_matrix + 1j * w * (damping_matrix(r) + w * mats.gyro_matrix) + stiffness_matrix(r)
    z_hat = np.linalg.solve(dyn, f_hat)
    t = sim.angle_rad / w
    expected = np.real(np.outer(np.exp(1j * w * t), z_hat))
    err = np.abs(sim.bearing_displacement_m - expected).max()
    assert err < 1e-4 * np.abs(expected).max()


def test_same_seed_gives_identical_data_and_other_seed_differs(seed_rig):
    a = simulate(seed_rig, paper_scenario("imbalance"), seed=5).recording
    b = simulate(seed_rig, paper_scenario("imbalance"), seed=5).recording
    c = simulate(seed_rig, paper_scenario("imbalance"), seed=6).recording
    assert np.array_equal(a.probes_m, b.probes_m)
    assert not np.array_equal(a.probes_m, c.probes_m)


def test_paper_protocol_sampling_noise_and_impact(seed_rig, impact_sim):
    """0.125 s at 50 us with the first 30 ms dropped; 1 um noise; fy = -515 N for one sample at 40 ms."""
    rec = impact_sim.recording
    assert len(rec) == 1900
    assert np.allclose(np.diff(rec.stamps_ns), 50_000)
    noise = rec.probes_m - impact_sim.probes_clean_m
    assert abs(noise.std() - 1e-6) < 0.05e-6
    hit = np.flatnonzero(rec.impact_force_n[:, 1])
    assert len(hit) == 1 and rec.impact_force_n[hit[0], 1] == -515.0
    assert abs(rec.time_s()[hit[0]] + 0.03 - 0.04) < 1e-12


def test_keyphasor_pulses_mark_shaft_angle_zero_during_a_coastdown(seed_rig):
    sim = simulate(seed_rig, Scenario(duration_s=0.5, discard_initial_s=0.0, impacts=(),
                                      speed_start_rad_s=2094.0, speed_end_rad_s=314.0), seed=1)
    pulses_s = sim.recording.pulse_time_s()
    angle = 2094.0 * pulses_s + 0.5 * (314.0 - 2094.0) / 0.5 * pulses_s ** 2
    assert np.allclose(angle, 2 * np.pi * np.arange(len(pulses_s)), atol=1e-6)
