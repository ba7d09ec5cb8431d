# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The one nominal output-error fit (diagnosis.context.fit_nominal), used by the diagnosis's context, its
nominal re-evaluation and the blind generators' gap proxy."""
from dataclasses import replace

import numpy as np

from rotor_estimator.bench.cases import nominal_unabsorbed_rms
from rotor_estimator.core.config import load_rig_file
from rotor_estimator.core.simulator import Scenario, simulate


def _clean_record():
    rig = load_rig_file().rig
    sim = simulate(rig, Scenario(duration_s=0.08, noise_std_m=0.0), seed=None)
    return rig, sim.recording


def test_the_fit_reaches_the_noise_free_record_from_a_10_percent_error_and_ignores_probe_dc_offsets():
    """On the model's own noise-free record the fit leaves < 1 % of the signal RMS from starts 10 % off the
    truth, the same with a DC gap offset on every probe (its mean is projected out), and ~0 from the truth."""
    rig, rec = _clean_record()
    truth = rig.true_coefficients.as_array()
    signal_rms = float(np.sqrt(np.mean(rec.probes_m ** 2)))
    start = truth * np.array([1.1, 0.9, 1.1, 0.9, 1.1, 0.9, 1.1, 0.9])
    fitted = nominal_unabsorbed_rms(rec, rig, [start], max_nfev=25)
    assert fitted < 0.01 * signal_rms
    shifted = replace(rec, probes_m=rec.probes_m + np.array([3e-5, -2e-5, 1e-5, 4e-5]))
    assert nominal_unabsorbed_rms(shifted, rig, [start], max_nfev=25) < 0.01 * signal_rms
    assert nominal_unabsorbed_rms(rec, rig, [truth], max_nfev=2) < 1e-3 * signal_rms


def test_a_start_that_cannot_be_fitted_is_skipped_not_raised():
    """A non-finite start is skipped; with no usable start the result is 'no fit' (inf), not an exception."""
    rig, rec = _clean_record()
    assert nominal_unabsorbed_rms(rec, rig, [np.full(8, np.nan)]) == float("inf")
    truth = rig.true_coefficients.as_array()
    assert np.isfinite(nominal_unabsorbed_rms(rec, rig, [np.full(8, np.nan), truth], max_nfev=3))
