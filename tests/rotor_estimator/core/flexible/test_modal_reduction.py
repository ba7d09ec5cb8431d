# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Assumed-mode reduction (Appendix A of Neisi et al.) and the state-space output maps."""
from __future__ import annotations

import numpy as np

from rotor_estimator.core.flexible import (assemble, build_state_space, load_rotor_description, reduce,
                                      state_matrices, station_outputs)


def _lowest(A: np.ndarray, k: int) -> np.ndarray:
    lam = np.linalg.eigvals(A)
    lam = lam[lam.imag > 0.05 * np.abs(lam)]  # oscillatory modes (drop overdamped, real pairs)
    return lam[np.argsort(lam.imag)][:k]


def test_modal_reduction_converges_to_full_model():
    rotor = load_rotor_description("neisi_2022_like")
    fe = assemble(rotor)
    full = _lowest(state_matrices(fe.M, fe.C, fe.K, fe.G, rotor.speed_rad_s)[0], 6)
    errors = []
    for r in (8, 16, 32, 64, fe.n_dof):
        red = reduce(fe, r)
        approx = _lowest(state_matrices(red.M, red.C, red.K, red.G, rotor.speed_rad_s)[0], 6)
        errors.append(np.max(np.abs(approx - full) / np.abs(full)))
    # non-increasing down to the rounding floor
    assert all(b <= a * 1.0001 + 1e-9 for a, b in zip(errors, errors[1:])), errors
    assert errors[0] < 1e-3 and errors[2] < 1e-8, errors
    assert errors[-1] < 1e-9  # all modes kept: the full model in other coordinates


def test_reduced_mass_matrix_is_identity_and_gyroscopic_stays_skew():
    fe = assemble(load_rotor_description("three_probe_rig"))
    red = reduce(fe, 8)
    np.testing.assert_allclose(red.M, np.eye(8), atol=1e-10)
    np.testing.assert_allclose(red.G, -red.G.T, atol=1e-14)


def test_acceleration_output_is_second_derivative_of_displacement_output():
    """In the continuous synchronous steady state x = Re(X e^{i W t}), the station's
    acceleration map (which uses M_r^-1 (F - C q' - K q) and the input) must equal
    -W^2 times its displacement map, and velocity i W times it."""
    ss = build_state_space(load_rotor_description("three_probe_rig"))
    w = ss.rotor.speed_rad_s
    X = np.linalg.solve(1j * w * np.eye(ss.n_states) - ss.A, ss.Bu @ (w ** 2 * np.array([1.0, -1j])))
    C, D, names = station_outputs(ss, 0.4)
    U = w ** 2 * np.array([1.0, -1j])
    y = C @ X + D @ U
    np.testing.assert_allclose(y[2:4], 1j * w * y[0:2], rtol=1e-9)
    np.testing.assert_allclose(y[4:6], -(w ** 2) * y[0:2], rtol=1e-9)
    assert names[0] == "displacement_x" and names[5] == "acceleration_y"
