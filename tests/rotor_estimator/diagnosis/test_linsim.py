# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The start transient's columns (diagnosis.linsim.free_response) against an independent matrix exponential."""
import numpy as np
from scipy.linalg import expm

from rotor_estimator.core.config import load_rig_file
from rotor_estimator.core.model import rotor_matrices
from rotor_estimator.diagnosis import models
from rotor_estimator.diagnosis.linsim import SpeedSchedule, free_response


def _rigid(speed_rad_s: float, n: int):
    rig = load_rig_file().rig
    mats = rotor_matrices(rig)
    r = rig.true_coefficients.as_array()
    schedule = SpeedSchedule.from_speed(np.full(n, speed_rad_s))
    return mats, r, schedule


def test_free_response_is_c_expm_a_t_on_each_unit_initial_state():
    """At one speed, column i at sample k equals ``C expm(A k h) e_i`` (scipy's expm, no recursion), to 1e-9
    of the column's largest value: the exact discretization's powers, nothing lost in the recursion."""
    h = 1.0 / 20000.0
    mats, r, schedule = _rigid(2000.0, 600)
    a = models.rigid_state_matrix(mats, r, 2000.0)
    c = models.rigid_output(mats)[:4]
    cols = free_response(lambda w: models.rigid_state_matrix(mats, r, w), models.rigid_input(mats), c, h, schedule)
    assert cols.shape == (600, 4, 8)
    for k in (0, 1, 37, 599):
        ref = c @ expm(a * k * h)
        np.testing.assert_allclose(cols[k], ref, rtol=0, atol=1e-9 * np.abs(cols).max(axis=(0, 1)).max())


def test_free_response_decays_and_is_cut_to_zero_only_after_the_floor():
    """The rigid model is stable, so every column decays; the recursion stops once the transition matrix is
    below 1e-9 of its start, and the zeros after it are below that bound of each column's peak."""
    h = 1.0 / 20000.0
    mats, r, schedule = _rigid(1500.0, 20000)
    c = models.rigid_output(mats)[:4]
    cols = free_response(lambda w: models.rigid_state_matrix(mats, r, w), models.rigid_input(mats), c, h, schedule)
    peak = np.abs(cols).max(axis=(0, 1))
    tail = np.abs(cols[-2000:]).max(axis=(0, 1))
    assert np.all(tail <= 1e-6 * peak)
    assert np.all(peak > 0)
