# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Properties of the rigid rotor model (Miller & Howard Eqs. 2-6)."""
import numpy as np

from rotor_estimator.core.model import (bearing_from_probe, gyro_matrix, imbalance_force, mass_matrix,
                                   probe_from_bearing, rotor_matrices, whirl_modes)


def test_mass_matrix_is_symmetric_positive_definite(seed_rig):
    m = mass_matrix(seed_rig)
    assert np.allclose(m, m.T)
    assert np.all(np.linalg.eigvalsh(m) > 0)


def test_mass_matrix_reproduces_rigid_body_kinetic_energy(seed_rig):
    """1/2 zdot' M zdot equals 1/2 m vc^2 + 1/2 It theta_dot^2 computed from center velocity and tilt rate."""
    rng = np.random.default_rng(0)
    zd = rng.standard_normal(4)
    l1, l2 = -seed_rig.bearing1_position_m, seed_rig.bearing2_position_m
    span = l1 + l2
    vc = np.array([(l2 * zd[0] + l1 * zd[2]) / span, (l2 * zd[1] + l1 * zd[3]) / span])
    tilt = np.array([(zd[2] - zd[0]) / span, (zd[3] - zd[1]) / span])
    expected = 0.5 * seed_rig.shaft_mass_kg * vc @ vc + 0.5 * seed_rig.transverse_inertia_kg_m2 * tilt @ tilt
    assert np.isclose(0.5 * zd @ mass_matrix(seed_rig) @ zd, expected)


def test_gyroscopic_matrix_is_skew_symmetric_so_does_no_work(seed_rig):
    g = gyro_matrix(seed_rig)
    assert np.allclose(g, -g.T)
    v = np.random.default_rng(1).standard_normal(4)
    assert abs(v @ g @ v) < 1e-15


def test_forward_whirl_frequency_rises_and_backward_falls_with_speed(seed_rig):
    """Campbell diagram check of the G sign (errata 6): the tilt mode splits, forward stiffening."""
    mats = rotor_matrices(seed_rig)
    r = seed_rig.true_coefficients.as_array()

    def top(speed, kind):
        return max(f for f, _, d in whirl_modes(mats, r, speed) if d == kind)

    fwd = [max(f for f, _, d in whirl_modes(mats, r, w) if d == "forward") for w in (0, 1000, 2000, 4000)]
    bwd = [min(f for f, _, d in whirl_modes(mats, r, w) if d == "backward") for w in (0, 1000, 2000, 4000)]
    assert np.all(np.diff(fwd) > 0)
    assert np.all(np.diff(bwd) < 0)


def test_probe_transform_inverts_exactly(seed_rig):
    """Eq. 6 (with the 1/(p1+p2) factor) is the exact inverse of the rigid-shaft probe map."""
    assert np.allclose(bearing_from_probe(seed_rig) @ probe_from_bearing(seed_rig), np.eye(4), atol=1e-14)


def test_probe_transform_matches_errata_formula(seed_rig):
    l1, l2 = -seed_rig.bearing1_position_m, seed_rig.bearing2_position_m
    p1, p2 = -seed_rig.probe1_position_m, seed_rig.probe2_position_m
    xp = np.array([1.3e-6, -0.4e-6, 2.1e-6, 0.7e-6])
    z = bearing_from_probe(seed_rig) @ xp
    assert np.isclose(z[0], ((p2 + l1) * xp[0] + (p1 - l1) * xp[2]) / (p1 + p2))
    assert np.isclose(z[2], ((p2 - l2) * xp[0] + (p1 + l2) * xp[2]) / (p1 + p2))


def test_imbalance_force_matches_eq5_at_constant_speed(seed_rig):
    mats = rotor_matrices(seed_rig)
    w, t = seed_rig.speed_rad_s, 0.0123
    f = imbalance_force(mats, w * t, w)
    l1, l2 = -seed_rig.bearing1_position_m, seed_rig.bearing2_position_m
    span = l1 + l2
    u1, u2 = seed_rig.imbalances
    d1, d2 = -u1.axial_position_m, u2.axial_position_m
    a1, a2 = u1.moment_kg_m * w ** 2, u2.moment_kg_m * w ** 2
    expected_x1 = a1 * (l2 + d1) / span * np.cos(w * t + u1.phase_rad) + a2 * (l2 - d2) / span * np.cos(
        w * t + u2.phase_rad)
    expected_y2 = a1 * (l1 - d1) / span * np.sin(w * t + u1.phase_rad) + a2 * (l1 + d2) / span * np.sin(
        w * t + u2.phase_rad)
    assert np.isclose(f[0], expected_x1)
    assert np.isclose(f[3], expected_y2)
