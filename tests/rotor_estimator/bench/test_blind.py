# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Blind-set generator: realistic caps, redrawn conditions when a capped effect would hide under the noise."""
from __future__ import annotations

import math

import numpy as np
import pytest

from rotor_estimator.bench import blind
from rotor_estimator.bench.effect_sim import HiddenEffects


def test_cubic_cap_is_the_stated_tangent_stiffness_increase():
    """At the cap, 3 k3 x_rms^2 / k equals CUBIC_TANGENT_RATIO_CAP in the limiting direction and is below
    it in the other."""
    rng = np.random.default_rng(1)
    ctx = {"k3": np.array([0.6, 0.9])}
    coefficients = np.array([4e5, 0, 0, 7e5, 1e3, 0, 0, 1e3])
    probes = rng.normal(size=(5000, 4)) * np.array([12e-6, 8e-6, 5e-6, 4e-6])
    s = blind._cubic_cap(ctx, coefficients, probes)
    rms = np.sqrt(np.mean((probes - probes.mean(axis=0)) ** 2, axis=0))
    ratio = [3 * s * 1e13 * ctx["k3"][0] * max(rms[0], rms[2]) ** 2 / coefficients[0],
             3 * s * 1e13 * ctx["k3"][1] * max(rms[1], rms[3]) ** 2 / coefficients[3]]
    assert math.isclose(max(ratio), blind.CUBIC_TANGENT_RATIO_CAP, rel_tol=1e-12)
    assert min(ratio) < blind.CUBIC_TANGENT_RATIO_CAP
    assert blind._cap("bearing_cubic", 1e9, {**ctx, "cubic_cap": s}) == s


def test_case_whose_capped_effect_falls_short_is_redrawn_and_counted(monkeypatch):
    """A calibration that reaches only 1.05x the noise twice triggers two redraws; the third draw is kept."""
    calls = []

    def fake_calibrate(rig, scenario, names, rng, targets, **kw):
        calls.append(scenario.noise_std_m)
        reached = 0.3 * scenario.noise_std_m if len(calls) <= 2 else 2.0 * scenario.noise_std_m  # gap 1.04, then 2.2
        return HiddenEffects(skew_s=(1e-6, 0.0, 0.0)), {"timing_skew": 1.0}, reached, {"timing_skew": reached}

    monkeypatch.setattr(blind, "calibrate", fake_calibrate)
    case = blind.make_case("c", ("timing_skew",), 7, near_limit=True)
    assert len(calls) == 3 and case.label["redraws"] == 2
    assert len(set(calls)) == 3, "each redraw draws new conditions"


def test_controls_are_never_redrawn():
    case = blind.make_case("c", (), 8, near_limit=False)
    assert case.label["redraws"] == 0 and case.label["effects"] == []


def test_pair_member_its_partner_absorbs_is_redrawn(monkeypatch):
    """A pair whose total gap is fine but whose second effect hides in its partner's model (own gap 1.05x)
    is redrawn; the draw where both effects show on their own is kept, with each effect's gap in the label."""
    calls = []

    def fake_calibrate(rig, scenario, names, rng, targets, **kw):
        calls.append(scenario.noise_std_m)
        noise = scenario.noise_std_m
        hidden = 0.2 * noise if len(calls) <= 2 else 1.0 * noise
        return HiddenEffects(), dict.fromkeys(names, 1.0), 3.0 * noise, {names[0]: 2.0 * noise, names[1]: hidden}

    monkeypatch.setattr(blind, "calibrate", fake_calibrate)
    case = blind.make_case("c", ("probe_runout", "bearing_cubic"), 7, near_limit=True)
    assert len(calls) == 3 and case.label["redraws"] == 2
    assert min(case.label["effect_gap"].values()) >= blind.MIN_GAP


@pytest.mark.parametrize("name,effects,rel_tol", [
    ("probe_runout", HiddenEffects(runout_m=np.random.default_rng(2).normal(size=(4, 3, 2)) * 1e-6), 1e-9),
    ("residual_unbalance", HiddenEffects(residual_unbalance_kg_m=(3e-6, -2e-6, 1e-6, 4e-6)), 1e-6),
    ("misalignment", HiddenEffects(misalignment_n=(8.0, -5.0, 3.0, 6.0)), 1e-6),
    # linearized map: a 1 % gain and 0.6 deg leave their second-order part only
    ("probe_gain_orientation",
     HiddenEffects(gain=(0.01, -0.01, 0.005, 0.01), orientation_rad=(0.01, -0.01, 0.005, 0.0)),
     2e-2),
])
def test_linear_partner_columns_absorb_the_partners_own_signal(name, effects, rel_tol):
    """A linear effect's partner columns span its own signal: projected off them, (almost) nothing is left."""
    from dataclasses import replace as dc_replace

    from rotor_estimator.core.config import load_rig_file
    from rotor_estimator.bench.effect_sim import EffectScenario, simulate_with_effects
    from rotor_estimator.core.simulator import Impact

    rig = load_rig_file().rig
    rig = dc_replace(rig, speed_rad_s=1200.0)
    scenario = EffectScenario(speed_rad_s=1200.0, duration_s=0.06, lead_in_s=0.05,
                              impacts=(Impact(0.02, 50e-6, 300.0, -200.0),), noise_std_m=1e-6,
                              coefficients=rig.true_coefficients.as_array())
    first = int(round(blind.WARMUP_S / rig.sample_period_s))
    base = simulate_with_effects(rig, scenario, HiddenEffects(), noise=False).clean_m
    y = simulate_with_effects(rig, scenario, effects, noise=False).clean_m
    d = (y - base)[first:].ravel()
    q = blind._with_columns(np.zeros((d.size, 0)), blind._partner_columns(name, rig, scenario, base, first))
    left = d - q @ (q.T @ d)
    assert np.linalg.norm(left) <= rel_tol * np.linalg.norm(d)
