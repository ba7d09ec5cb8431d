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


def test_a_record_from_rest_is_fitted_to_the_noise_free_record_through_the_estimated_start_transient():
    """A record that starts from rest (no discarded lead-in: the free decay from q = 0 runs through it) is not
    the periodic start the re-simulation assumes; the fit's start-transient columns (the free response from
    each of the 8 initial states) take it up, so the truth leaves < 1e-3 of the signal RMS and a 10 % start
    < 1 %."""
    rig = load_rig_file().rig
    rec = simulate(rig, Scenario(duration_s=0.08, noise_std_m=0.0, discard_initial_s=0.0), seed=None).recording
    truth = rig.true_coefficients.as_array()
    signal_rms = float(np.sqrt(np.mean(rec.probes_m ** 2)))
    assert nominal_unabsorbed_rms(rec, rig, [truth], max_nfev=2, start_transient=True) < 1e-3 * signal_rms
    start = truth * np.array([1.1, 0.9, 1.1, 0.9, 1.1, 0.9, 1.1, 0.9])
    assert nominal_unabsorbed_rms(rec, rig, [start], max_nfev=25, start_transient=True) < 0.01 * signal_rms
    assert nominal_unabsorbed_rms(rec, rig, [truth], max_nfev=2) > 0.01 * signal_rms  # taken as steady: it stays


def test_the_start_transient_is_estimated_only_when_the_record_before_its_first_impact_shows_it():
    """A record from rest shows its start transient (the decay from q = 0 before the impact); the paper's
    record (30 ms discarded, the impact 10 ms after its start, at the first fitted sample) does not, so it is
    taken to start steady and its impact's scale stays identifiable."""
    from rotor_estimator.diagnosis.context import build_context

    rf = load_rig_file()
    from_rest = simulate(rf.rig, Scenario(duration_s=0.125, discard_initial_s=0.0), seed=1).recording
    assert build_context(from_rest, rf.rig, rf.estimator).start_transient
    paper = simulate(rf.rig, Scenario(), seed=1).recording
    assert not build_context(paper, rf.rig, rf.estimator).start_transient


def test_nuisance_fit_is_the_least_squares_dc_and_start_transient_with_or_without_start_columns():
    """Agreement with an independent least-squares solve (numpy lstsq on the stacked design): the DC-only
    case (each channel's mean on the rows) and the DC + start-transient case give the same fitted signal, and
    start_transient_fit (DC centred out, 8 x 8 normal equations) is that solve's start-transient part."""
    from rotor_estimator.diagnosis.context import nuisance_columns, nuisance_fit, start_transient_fit

    rng = np.random.default_rng(3)
    n = 300
    rows = rng.random(n) > 0.2
    err = rng.standard_normal((n, 4)) + np.array([1.0, -2.0, 0.5, 3.0])
    for start in (np.zeros((n, 4, 0)), rng.standard_normal((n, 4, 8)) * np.exp(-np.arange(n) / 50.0)[:, None, None]):
        cols = nuisance_columns(start)
        coef, *_ = np.linalg.lstsq(cols[rows].reshape(-1, cols.shape[2]), err[rows].ravel(), rcond=None)
        assert np.allclose(nuisance_fit(start, err, rows), np.einsum("nck,k->nc", cols, coef), atol=1e-10)
        assert np.allclose(start_transient_fit(start, err, rows), np.einsum("nck,k->nc", start, coef[4:]),
                           atol=1e-10)


def test_bearings_without_cross_coupling_are_stable_at_every_speed_and_an_unstable_start_is_moved_to_stability():
    """Kelvin-Tait-Chetaev: symmetric positive stiffness and damping with gyroscopic coupling is asymptotically
    stable at any speed, so :func:`without_cross_coupling` of any coefficient set is a stable reference; and
    :func:`stable_start` returns a stable point on the line to it from a start that is not."""
    from rotor_estimator.core.model import rotor_matrices
    from rotor_estimator.diagnosis.context import rigid_model_is_stable, stable_start, without_cross_coupling

    rig = load_rig_file().rig
    mats = rotor_matrices(rig)
    rng = np.random.default_rng(3)
    for _ in range(50):
        r = rng.normal(0.0, 1.0, 8) * np.array([5e5] * 4 + [1e3] * 4)
        speed = rng.uniform(0.0, 3.0) * rig.speed_rad_s
        reference = without_cross_coupling(r)
        assert rigid_model_is_stable(mats, reference, speed)
        moved = stable_start(mats, r, reference, speed)
        assert rigid_model_is_stable(mats, moved, speed)
        if rigid_model_is_stable(mats, r, speed):
            assert np.array_equal(moved, r)
    # a strongly cross-coupled set (kxy = -kyx = 3 kxx) whirls unstably at the rig's speed
    unstable = np.array([3e5, 9e5, -9e5, 3e5, 300.0, 0.0, 0.0, 300.0])
    assert not rigid_model_is_stable(mats, unstable, rig.speed_rad_s)



def test_the_nominal_fit_of_a_record_an_unstable_rotor_fits_better_is_still_stable():
    """An independent record (bench.independent: its own solve_ivp physics) of a stable rotor from rest without
    an impact, both probes of plane 1 five samples late: the periodic response of an unstable coefficient set
    matched it better (cxx = -670 N s/m, a mode growing at 73 1/s, before the wall), but the rig ran with a
    bounded response, so the nominal model is asymptotically stable at the record's speed, and its prediction
    over the whole record stays of the size of the measured response. The wall holds it at the stability limit,
    and the diagnosis says so (the diagnose command's test sees no such warning on a record that needs no
    wall)."""
    from rotor_estimator.bench import independent
    from rotor_estimator.diagnosis.api import nominal_stability
    from rotor_estimator.diagnosis.context import build_context, rigid_model_is_stable

    case = independent.make_case("t", {"kind": "single", "form": "timing_skew:whole_sample_delay:one_plane"},
                                 7412010)
    assert case.label["start"] == "from_rest" and not case.label["impacts"]
    ctx = build_context(case.recording, case.rig_file.rig, case.rig_file.estimator)
    assert rigid_model_is_stable(ctx.mats, ctx.coefficients, ctx.mean_speed_rad_s), ctx.coefficients
    assert np.max(np.abs(ctx.y_nom_m)) < 3 * np.max(np.abs(ctx.y_m))
    decay, warnings = nominal_stability(ctx)
    assert 0.0 < decay < 1.0 / 0.49
    assert len(warnings) == 1 and "stability limit" in warnings[0], warnings



def test_a_fit_from_rest_has_the_coefficient_covariance_of_its_exact_misfit_once_the_start_transient_moves_with_them():
    """Agreement with an independent computation: a record from rest without an impact, fitted with a probe
    runout (its 1X-4X columns take up every probe's steady response, so the coefficients are seen through the
    start transient alone). The coefficient stds from the fit's linearized design ``[J + dS/dr s, D, S, X]``
    (parameter_covariance) are those of the Gauss-Newton curvature of the exact re-simulated misfit
    (joint_misfit, forward differences in the 8 coefficients, every other parameter re-projected) within 50 %
    (0.70-0.81 of them here); with ``J`` alone (the transient's shape held) some are more than 3x off (the two
    terms are large and nearly cancel): 6x too wide here, where the held design leaves the coefficients to the
    prior and its std stands (10x too narrow before the prior's noise entered the sandwich's meat, 100x on an
    independent record)."""
    from rotor_estimator.diagnosis.context import (COEFFICIENT_SCALE, build_context, recentered,
                                                   start_transient_sensitivity)
    from rotor_estimator.diagnosis.effects import LIBRARY
    from rotor_estimator.diagnosis.fitting import solve_linear
    from rotor_estimator.diagnosis.ranking import RESIDUAL_SCALE, fit_effect, joint_misfit, parameter_covariance

    rf = load_rig_file()
    rec = simulate(rf.rig, Scenario(duration_s=0.15, discard_initial_s=0.0, impacts=()), seed=3).recording
    ctx = build_context(rec, rf.rig, rf.estimator)
    assert ctx.start_transient
    runout = next(e for e in LIBRARY if e.name == "probe_runout")
    fun, lo, hi = joint_misfit(ctx, runout)
    from rotor_estimator.diagnosis.secant_jacobian import least_squares_secant

    x0 = least_squares_secant(fun, ctx.coefficients / COEFFICIENT_SCALE, lo, hi, max_nfev=60).x  # its optimum
    ctx = recentered(ctx, x0 * COEFFICIENT_SCALE)
    fit = fit_effect(ctx, runout, hold_coefficients=True)
    sol = solve_linear(ctx, fit.offset, fit.cols, hold_coefficients=True)
    none = np.zeros((ctx.t_s.size, 4, 0))

    def stds(jacobian):
        cov = parameter_covariance(replace(ctx, jacobian=jacobian), fit.cols, none, sol.prediction_m)
        return np.sqrt(np.diag(cov[:8, :8]))

    moving = stds(ctx.jacobian + start_transient_sensitivity(ctx, sol.start_state))
    held = stds(ctx.jacobian)
    f0 = fun(x0)
    jac = np.zeros((f0.size, 8))
    for i in range(8):
        step = 1e-4 * max(abs(x0[i]), 1.0)
        x = x0.copy()
        x[i] += step
        jac[:, i] = (fun(x) - f0) / step
    sigma2 = np.mean(ctx.noise_std_m ** 2) * RESIDUAL_SCALE ** 2
    exact = np.sqrt(np.diag(np.linalg.inv(jac.T @ jac)) * sigma2)
    assert np.all(np.abs(np.log(moving / exact)) < np.log(1.5)), (moving, exact)
    assert np.max(np.abs(np.log(exact / held))) > np.log(3.0), (held, exact)


def test_the_nominal_fit_never_returns_negative_direct_damping_even_where_the_record_is_fitted_best_by_it():
    """A bound: the noise-free record of a rotor that is stable with cyy = -300 N s/m (strong cross-coupled
    damping; such a set fits a record with unmodelled 2X forces best: an independent record was fitted by LM with
    cyy = -2 993 N s/m), fitted from that very set, where unbounded LM stays (its misfit is 0 there). A passive
    bearing has cxx, cyy >= 0, as the joint refits are bounded, so the fit ends at cyy >= 0, and no worse than
    the truth with its cyy set to 0 (the passive refit starts there)."""
    from rotor_estimator.core.config import BearingCoefficients
    from rotor_estimator.core.model import imbalance_force, impact_force, rotor_matrices
    from rotor_estimator.diagnosis.context import (COEFFICIENT_SCALE, WARMUP_S, fit_nominal, nuisance_fit,
                                                   rigid_model_is_stable, shaft_track, simulate_nominal,
                                                   start_columns)
    from rotor_estimator.diagnosis.linsim import SpeedSchedule

    negative = np.array([1.5e6, 1.0e6, -3.5e5, 1.9e6, 3500.0, 2100.0, -3900.0, -300.0])
    rig = load_rig_file().rig
    mats = rotor_matrices(rig)
    assert rigid_model_is_stable(mats, negative, rig.speed_rad_s)
    rig = replace(rig, true_coefficients=BearingCoefficients.from_array(negative))
    rec = simulate(rig, Scenario(duration_s=0.08, noise_std_m=0.0), seed=None).recording
    shaft = shaft_track(rec)
    t = rec.time_s()
    h = float(np.median(np.diff(t)))
    rows = shaft.valid & (t >= t[0] + WARMUP_S)
    inputs = (rig, mats, t, rec.probes_m, rows, shaft, SpeedSchedule.from_speed(shaft.speed_rad_s),
              imbalance_force(mats, shaft.angle_rad, shaft.speed_rad_s, shaft.accel_rad_s2),
              impact_force(mats, rec.impact_force_n), h)
    fit = fit_nominal(*inputs, [negative], max_nfev=15, x_scale=1.0)
    fitted = fit.x * COEFFICIENT_SCALE
    assert fitted[4] >= 0.0 and fitted[7] >= 0.0, fitted
    clipped = negative * np.array([1.0] * 7 + [0.0])
    assert rigid_model_is_stable(mats, clipped, rig.speed_rad_s)
    error = rec.probes_m - simulate_nominal(rig, mats, clipped, t, *inputs[5:])[0]
    error_um = (error - nuisance_fit(start_columns(mats, clipped, inputs[6], h), error, rows))[rows] * 1e6
    clipped_cost = 0.5 * float(np.sum(error_um ** 2))
    assert clipped_cost > 0.0  # the clipped set does not fit exactly: the bound costs something
    assert fit.cost <= clipped_cost
