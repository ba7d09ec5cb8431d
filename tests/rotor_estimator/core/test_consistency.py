# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Innovation consistency (NIS band and Ljung-Box whiteness): quiet on a matching model, loud on a
model error the coefficients absorb."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from rotor_estimator.io.bags import write_input_bag
from rotor_estimator.cli.main import main
from rotor_estimator.core.config import load_rig_file
from rotor_estimator.core.consistency import InnovationConsistency
from rotor_estimator.core.simulator import paper_scenario, simulate


def _feed(e: np.ndarray, block: int = 137) -> InnovationConsistency:
    c = InnovationConsistency()
    std = np.ones_like(e)
    for i in range(0, len(e), block):
        sl = slice(i, i + block)
        c.add(np.sum(e[sl] ** 2, axis=1), e[sl], std[sl], np.ones(e[sl].shape[0], bool))
    return c


def test_white_gaussian_innovations_are_consistent_in_nearly_every_trial():
    """White N(0,1) innovations of the predicted variance: at most 1 false alarm in 40 trials."""
    rng = np.random.default_rng(0)
    alarms = sum(_feed(rng.normal(size=(5000, 4))).verdict().model_mismatch for _ in range(40))
    assert alarms <= 1


def test_streaming_autocorrelation_equals_the_batch_one_whatever_the_block_size():
    """Lagged sums across block boundaries equal those of the whole series at once."""
    rng = np.random.default_rng(1)
    e = rng.normal(size=(3000, 4))
    a = _feed(e, block=7).verdict().autocorrelation_by_lag
    b = _feed(e, block=3000).verdict().autocorrelation_by_lag
    np.testing.assert_allclose(a, b, rtol=1e-10)


def test_correlated_or_wrongly_scaled_innovations_are_a_mismatch():
    """AR(1) innovations (rho 0.3) fail whiteness; white ones 30 % larger than predicted fail NIS."""
    rng = np.random.default_rng(2)
    w = rng.normal(size=(5000, 4))
    ar = np.zeros_like(w)
    for t in range(1, len(w)):
        ar[t] = 0.3 * ar[t - 1] + w[t]
    ar /= ar.std()
    v = _feed(ar).verdict()
    assert v.model_mismatch and "not white" in v.reason
    v = _feed(1.3 * w).verdict()
    assert v.model_mismatch and "mean NIS" in v.reason


@pytest.mark.parametrize("gain", [1.0, 1.25])
def test_replay_flags_a_probe_gain_error_as_model_mismatch_and_not_a_clean_record(tmp_path, capsys, gain):
    """A 25 % gain error on probe xp1 (the filter still says 'converged' or merely 'not converged')
    prints MODEL MISMATCH with the advice to run diagnose; the same record with the right gain does not."""
    rig = load_rig_file().rig
    rec = simulate(rig, paper_scenario("imbalance+impact"), seed=2).recording
    rec = dataclasses.replace(rec, probes_m=rec.probes_m * np.array([gain, 1.0, 1.0, 1.0]))
    bag = write_input_bag(tmp_path / "bag", rec)
    assert main(["replay", str(bag), "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert ("MODEL MISMATCH" in out and "rotor-estimator diagnose" in out) == (gain != 1.0)
