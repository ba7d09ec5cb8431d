"""Blind-set generator: realistic caps, redrawn conditions when a capped effect would hide under the noise."""
from __future__ import annotations

import math

import numpy as np

from rotor_estimator.diagnosis import blind
from rotor_estimator.diagnosis.effect_sim import HiddenEffects


def test_cubic_cap_is_the_stated_tangent_stiffness_increase():
    """At the cap, 3 k3 x_rms^2 / k equals CUBIC_TANGENT_RATIO_CAP in the limiting direction and is below it in the other."""
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
        return HiddenEffects(skew_s=(1e-6, 0.0, 0.0)), {"timing_skew": 1.0}, reached

    monkeypatch.setattr(blind, "calibrate", fake_calibrate)
    case = blind.make_case("c", ("timing_skew",), 7, near_limit=True)
    assert len(calls) == 3 and case.label["redraws"] == 2
    assert len(set(calls)) == 3, "each redraw draws new conditions"


def test_controls_are_never_redrawn():
    case = blind.make_case("c", (), 8, near_limit=False)
    assert case.label["redraws"] == 0 and case.label["effects"] == []
