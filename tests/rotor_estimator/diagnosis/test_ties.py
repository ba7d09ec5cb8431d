# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Honest ties: effects the record cannot tell apart are returned as a set with the measurement that would."""
from __future__ import annotations

import warnings

import pytest

from rotor_estimator.bench.effect_sim import EffectScenario, HiddenEffects, simulate_with_effects
from rotor_estimator.core.config import load_rig_file
from rotor_estimator.core.simulator import Impact
from rotor_estimator.diagnosis.context import build_context
from rotor_estimator.diagnosis.effects import (LIBRARY, Misalignment, ProbeRunout, ResidualUnbalance)
from rotor_estimator.diagnosis.effects.base import MEASUREMENTS
from rotor_estimator.diagnosis.effects.base import separating_measurements
from rotor_estimator.diagnosis.ranking import rank_effects


def _ctx(effects: HiddenEffects, seed: int):
    rf = load_rig_file()
    rig = rf.rig
    scenario = EffectScenario(speed_rad_s=rig.speed_rad_s, duration_s=0.15, lead_in_s=0.3,
                              impacts=(Impact(0.05, 50e-6, 300.0, -400.0),), noise_std_m=1e-6,
                              coefficients=rig.true_coefficients.as_array())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return build_context(simulate_with_effects(rig, scenario, effects, seed=seed).recording, rig, rf.estimator)


@pytest.fixture(scope="module")
def unbalance_ctx():
    return _ctx(HiddenEffects(residual_unbalance_kg_m=(6e-6, -4e-6, -3e-6, 8e-6)), seed=4)


def test_unbalance_and_runout_at_one_speed_are_a_tie_with_slow_roll_to_separate(unbalance_ctx):
    """At one steady speed a residual unbalance's response is a fixed 1X pattern per probe, which runout
    reproduces exactly: the verdict is the set of both (not a pick by parameter count), and slow roll is
    named as the measurement that separates them (unbalance vanishes, runout persists)."""
    rk = rank_effects(unbalance_ctx, (ResidualUnbalance(), ProbeRunout()), second_stage=False)
    assert rk.best is not None
    assert {rk.best.name, *(f.name for f in rk.tied)} == {"residual_unbalance", "probe_runout"}
    first = separating_measurements(ResidualUnbalance(), ProbeRunout())[0]
    assert first["measurement"] == "slow_roll"


def test_a_decided_case_is_no_tie():
    """A 2X misalignment force gives a 2X response, which no (1X) unbalance can imitate: the verdict is the
    single effect, with no tie."""
    ctx = _ctx(HiddenEffects(misalignment_n=(20.0, 0.0, 0.0, 20.0)), seed=5)
    rk = rank_effects(ctx, (Misalignment(), ResidualUnbalance()), second_stage=False)
    assert rk.best is not None and rk.best.name == "misalignment"
    assert rk.tied == []


def test_every_effect_declares_responses_to_known_measurements_and_pairs_are_separable():
    """Each effect's declared responses use only known measurement keys, and every pair of library effects
    differs under at least one measurement (else no measurement could ever break their tie)."""
    for e in LIBRARY:
        assert set(e.responses) <= set(MEASUREMENTS), e.name
    for i, a in enumerate(LIBRARY):
        for b in LIBRARY[i + 1:]:
            assert separating_measurements(a, b), (a.name, b.name)
