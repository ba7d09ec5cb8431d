# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The generalized model against the core simulator and the core CRLB.

The filter kernel's own properties, including the seed special case against the generalized model,
are in tests/rotor_estimator/core/test_filter_kernel.py.
"""

import numpy as np
import pytest

from rotor_estimator.core.crlb import bound_from_fisher, fisher_information
from rotor_estimator.core.ekf import FilterModel
from rotor_estimator.core.errors import ConfigError
from rotor_estimator.core.fisher import bound
from rotor_estimator.identification.information import design_information
from rotor_estimator.identification.scenarios import (SpeedSegment, TestDesign, design_from_scenario,
                                                      simulate_design)
from rotor_estimator.core.simulator import Scenario, paper_scenario, simulate

SWEEP = Scenario(duration_s=0.3, discard_initial_s=0.01, impacts=(), speed_start_rad_s=2094.4,
                 speed_end_rad_s=314.16, name="sweep")


@pytest.mark.parametrize("scenario", [paper_scenario("imbalance+impact"), SWEEP], ids=["seed", "sweep"])
def test_generalized_simulator_equals_core_simulator(seed_rig, scenario):
    ours = simulate_design(seed_rig, design_from_scenario(seed_rig, scenario), seed=None)[0]
    core = simulate(seed_rig, scenario, seed=None)
    assert np.abs(ours.probes_clean_m - core.probes_clean_m).max() < 1e-9 * np.abs(core.probes_clean_m).max()


@pytest.mark.parametrize("unknown", [False, True])
def test_information_equals_core_crlb(seed_rig_file, arrays, model8, true8, unknown):
    rig = seed_rig_file.rig
    sim = simulate(rig, SWEEP, seed=None)
    t = sim.recording.time_s()
    x0 = np.concatenate([sim.bearing_velocity_m_s[0], sim.bearing_displacement_m[0], sim.coefficients])
    accel = np.full_like(t, (SWEEP.speed_end_rad_s - SWEEP.speed_start_rad_s) / SWEEP.duration_s)
    core = fisher_information(FilterModel.build(rig, seed_rig_file.estimator), x0, t, sim.angle_rad,
                              sim.speed_rad_s, accel, sim.recording.impact_force_n, unknown_imbalance=unknown)
    core_std = bound_from_fisher(core, len(t)).coefficient_std
    recs = simulate_design(rig, design_from_scenario(rig, SWEEP), seed=None, arrays=arrays)
    ours = bound(design_information(arrays, model8, recs, true8, estimate_imbalance=unknown,
                                    noise_std_m=rig.noise_std_m), 8).std
    assert np.allclose(ours, core_std, rtol=1e-5)


def test_design_validation_names_the_field():
    with pytest.raises(ConfigError, match=r"segments\[0\]\.duration_s"):
        TestDesign(name="bad", segments=(SpeedSegment(-1.0, 100.0, 100.0),))

