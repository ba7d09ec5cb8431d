# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Anti-aliased decimation of a record before the diagnosis (rotor_estimator.diagnosis.decimation)."""
from __future__ import annotations

import numpy as np
import pytest

from rotor_estimator.core.errors import InputError
from rotor_estimator.core.recording import RigRecording
from rotor_estimator.diagnosis.decimation import (HALF_TAPS_PER_FACTOR, decimated, half_band_taps,
                                                  largest_factor)

FS_HZ = 20000.0


def _record(probes: np.ndarray, force: np.ndarray | None = None, speed_hz: float = 200.0) -> RigRecording:
    n = probes.shape[0]
    stamps = 1_000_000_000 + np.round(np.arange(n) / FS_HZ * 1e9).astype(np.int64)
    pulses = 1_000_000_000 + np.round(np.arange(0.0, n / FS_HZ, 1.0 / speed_hz) * 1e9).astype(np.int64)
    return RigRecording(stamps, probes, pulses, np.zeros((n, 2)) if force is None else force)


@pytest.mark.parametrize("q", [2, 4])
def test_the_band_below_045_of_the_new_rate_passes_unchanged_at_the_kept_stamps(q):
    """Sines up to 0.45 of the new sampling rate come out as the same sines sampled at the kept stamps (the
    filter is flat there to 1e-5 and zero-phase: no gain error, no delay)."""
    n = 8000
    t = np.arange(n) / FS_HZ
    freqs = np.array([37.0, 333.0, 1333.0, 0.45 * FS_HZ / q])
    probes = np.stack([np.sin(2 * np.pi * f * t + k) for k, f in enumerate(freqs)], axis=1)
    out = decimated(_record(probes), q)
    t_new = (out.stamps_ns - 1_000_000_000) * 1e-9
    truth = np.stack([np.sin(2 * np.pi * f * t_new + k) for k, f in enumerate(freqs)], axis=1)
    assert np.max(np.abs(out.probes_m - truth)) < 3e-5


@pytest.mark.parametrize("q", [2, 4])
def test_white_noise_stays_white_with_its_variance_over_the_factor_and_the_noise_floor_reads_it(q):
    """White noise of std sigma comes out of std sigma / sqrt(q) (the kept band's share), and the diagnosis's noise
    floor estimate (the periodogram's median above 0.3 of the rate) reads that same std: no part of its band is in
    the filter's roll-off."""
    from rotor_estimator.diagnosis.context import noise_std_from_spectrum

    rng = np.random.default_rng(11)
    sigma = 2e-6
    out = decimated(_record(sigma * rng.standard_normal((40000, 4))), q)
    std = float(np.std(out.probes_m))
    assert abs(std / (sigma / np.sqrt(q)) - 1.0) < 0.02
    fs_new = FS_HZ / q
    floor = float(np.sqrt(np.mean(noise_std_from_spectrum(out.probes_m, fs_new, 0.3 * fs_new) ** 2)))
    assert abs(floor / std - 1.0) < 0.03


def test_the_impact_impulse_the_stamps_and_the_keyphasor_are_kept():
    """The held impact force's impulse (sum of force x period) is the same after decimation; the kept stamps are
    every q-th of the record's after the filter's dropped edges, the keyphasor stamps are untouched, and the record
    says how it was decimated."""
    q, n = 2, 6000
    force = np.zeros((n, 2))
    force[3001:3004] = [[120.0, -80.0], [300.0, -200.0], [90.0, -60.0]]  # a 3-sample pulse, odd start
    rec = _record(np.zeros((n, 4)), force)
    out = decimated(rec, q)
    half = HALF_TAPS_PER_FACTOR * q
    assert np.allclose(out.impact_force_n.sum(axis=0) * q / FS_HZ, force.sum(axis=0) / FS_HZ, rtol=1e-12)
    assert np.array_equal(out.stamps_ns, rec.stamps_ns[half:n - half][::q][:len(out)])
    assert len(out) == (n - 2 * half) // q
    assert np.array_equal(out.pulse_stamps_ns, rec.pulse_stamps_ns)
    assert out.meta["decimation"] == {"factor": 2, "filter_taps": half_band_taps(2).size,
                                      "dropped_edge_samples": half}
    assert decimated(rec, 1) is rec


def test_the_largest_factor_keeps_ten_times_the_speed_in_the_flat_band():
    """At 20 kHz a 400 Hz rotor allows 2 (4 kHz below 0.45 x 10 kHz), a 200 Hz one 4, a 1 kHz one none."""
    assert largest_factor(FS_HZ, 400.0) == 2
    assert largest_factor(FS_HZ, 200.0) == 4
    assert largest_factor(FS_HZ, 1000.0) == 1
    assert largest_factor(FS_HZ, 10.0, limit=3) == 3


@pytest.mark.parametrize("factor,match", [(0, "positive integer"), (1.5, "positive integer"),
                                          (True, "positive integer"), (5, "allows at most 4")])
def test_a_bad_or_unsafe_factor_is_refused_naming_decimate(factor, match):
    """A factor that is not a positive integer, or one that would put 10x the running speed (from the keyphasor)
    above the flat band of the new rate, is an InputError naming ``decimate``, not a silently aliased record."""
    rec = _record(np.zeros((8000, 4)), speed_hz=200.0)
    with pytest.raises(InputError, match=f"decimate: .*{match}"):
        decimated(rec, factor)


def test_a_record_too_short_for_the_filter_edges_is_refused():
    """A record shorter than the filter's two dropped edges and a minimal kept span is refused with the counts."""
    with pytest.raises(InputError, match="decimate: a factor of 2 needs at least 912 samples.*has 600"):
        decimated(_record(np.zeros((600, 4))), 2)


def test_a_decimated_record_carries_the_same_information_on_the_parameters():
    """An unbalance fitted with the coefficients held at the truth (a linear fit: its std is the record's
    information on it) on a record decimated by 2 (default rig at 20 kHz, one impact) agrees with the full rate's
    within their standard deviations, and those are about the same: fewer samples, each less noisy (plain
    subsampling would widen them by sqrt(2)). Over 8 noise seeds the two rates' estimates scattered alike (per
    component 0.016-0.025 at the full rate, 0.018-0.025 decimated)."""
    from rotor_estimator.bench.effect_sim import EffectScenario, HiddenEffects, simulate_with_effects
    from rotor_estimator.core.config import load_rig_file
    from rotor_estimator.core.simulator import Impact
    from rotor_estimator.diagnosis.context import build_context, recentered
    from rotor_estimator.diagnosis.effects import ResidualUnbalance
    from rotor_estimator.diagnosis.ranking import fit_effect

    rf = load_rig_file()
    rig = rf.rig
    scenario = EffectScenario(speed_rad_s=rig.speed_rad_s, duration_s=0.2, lead_in_s=0.1,
                              impacts=(Impact(0.08, 50e-6, 350.0, -300.0),), noise_std_m=1e-6,
                              coefficients=rig.true_coefficients.as_array())
    sim = simulate_with_effects(rig, scenario, HiddenEffects(residual_unbalance_kg_m=(2e-5, -1e-5, 1e-5, 1.5e-5)),
                                seed=5)
    fits, truth = [], rig.true_coefficients.as_array()
    for q in (1, 2):
        ctx = recentered(build_context(decimated(sim.recording, q), rig, rf.estimator), truth)
        fits.append(fit_effect(ctx, ResidualUnbalance(), hold_coefficients=True))
    full, half = fits
    assert np.all(np.abs(full.lin - half.lin) < 3.0 * np.hypot(full.lin_std, half.lin_std))
    ratio = half.lin_std / full.lin_std
    assert np.all((ratio > 0.8) & (ratio < 1.25)), ratio
