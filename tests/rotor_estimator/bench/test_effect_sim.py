# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The blind-set simulator: a record is steady running, with no start-up transient left in it."""
from __future__ import annotations

import math

import numpy as np
import pytest

from rotor_estimator.core.config import load_rig_file
from rotor_estimator.bench.effect_sim import (STARTUP_DECAY, EffectScenario, HiddenEffects, settling_time_s,
                                                  simulate_with_effects)


@pytest.fixture(scope="module")
def rig():
    return load_rig_file().rig


def test_record_of_a_lightly_damped_pedestal_is_periodic(rig):
    """No impact, constant speed: once the start-up transient has decayed, the probe signal repeats every
    revolution. A 0.3 s lead-in alone left the 3 % damped pedestal mode ringing at several % of the response."""
    speed = 2 * math.pi * 125.0  # 125 Hz: one revolution is a whole number of samples at the rig's rate
    spr = rig.sample_rate_hz / 125.0
    assert abs(spr - round(spr)) < 1e-9
    m, f, zeta = 3.8, 60.0, 0.03
    k = m * (2 * math.pi * f) ** 2
    effects = HiddenEffects(residual_unbalance_kg_m=(5e-6, 3e-5, 3e-5, 2e-6),
                            pedestal=(m, k, 2 * zeta * math.sqrt(k * m)))
    r = rig.true_coefficients.as_array()
    assert settling_time_s(rig, r, speed, effects) > 0.3  # the case the fixed lead-in got wrong
    sim = simulate_with_effects(rig, EffectScenario(speed_rad_s=speed, duration_s=0.2, lead_in_s=0.3, impacts=(),
                                                    noise_std_m=0.0, coefficients=r), effects, noise=False)
    y = sim.clean_m
    n = int(round(spr))
    drift = np.max(np.abs(y[n:] - y[:-n]))
    assert drift < 1e-3 * np.max(np.abs(y)), f"revolution-to-revolution change {drift:.3g} m"


def test_settling_time_is_set_by_the_slowest_mode(rig):
    """A lightly damped bending mode slower than the rigid modes sets it: ln(1/decay) / (zeta omega)."""
    r = rig.true_coefficients.as_array()
    bending = (300.0, 0.005, 1.0)
    t = settling_time_s(rig, r, rig.speed_rad_s, HiddenEffects(bending=bending))
    assert t == pytest.approx(math.log(1 / STARTUP_DECAY) / (bending[1] * 2 * math.pi * bending[0]))
    assert settling_time_s(rig, r, rig.speed_rad_s, HiddenEffects()) < t
