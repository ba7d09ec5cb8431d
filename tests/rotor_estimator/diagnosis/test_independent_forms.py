# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Effect forms on records of the independent generator (bench.independent: its own solve_ivp physics, which
shares no model code with the diagnosis): a radial bearing hardening under gravity, and records from rest."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

from rotor_estimator.bench import independent
from rotor_estimator.diagnosis.context import build_context
from rotor_estimator.diagnosis.effects import Misalignment, ProbeRunout, ResidualUnbalance
from rotor_estimator.diagnosis.effects.bearing_cubic import BearingCubic, ClearanceContact, RadialBearingCubic
from rotor_estimator.diagnosis.ranking import fit_effect, nominal_solution, rank_effects, refine, single_refit_starts

warnings.filterwarnings("ignore", category=RuntimeWarning)


def _case(spec: dict, first_seed: int, start: str, min_gap: float = 1.0):
    """The first independent case from ``first_seed`` on whose label's start (steady / from_rest) is ``start``
    and whose true gap is at least ``min_gap``: chosen on the generator's own draw, without any fit."""
    for seed in range(first_seed, first_seed + 40):
        case = independent.make_case("t", spec, seed)
        if case.label["start"] == start and case.label["true_gap"] >= min_gap:
            return case
    raise AssertionError(f"no {start} case with a gap >= {min_gap} in 40 seeds")


def _refined(ctx, effect, bic0):
    """The first pass, then the joint refit with the search's starts for a single effect."""
    fit = fit_effect(ctx, effect, reference_bic=bic0)
    return refine(ctx, effect, fit, reference_bic=bic0,
                  **single_refit_starts(ctx, effect, tuple(effect.refine_starts(ctx))))


@pytest.mark.slow
@pytest.mark.parametrize("first_seed", [5150, pytest.param(6160, marks=pytest.mark.extended)])
def test_a_radial_hardening_under_gravity_is_the_radial_form_not_a_2x_force(first_seed):
    """A radial cubic ``k3 |d|^2 d`` about the gravity sag (2X and DC from its quadratic part; a true gap of
    at least 1.3x the noise) is explained better by the radial form about a fitted static point than by the
    per-axis cubic or by free 2X forces (misalignment, 8 gains), and its k3 is recovered within 50 %.
    Its reported std is not asserted: k3 trades off against the static point and the coefficients, which
    on these records of another physics sit 10x their std off (kxx 6.6 +- 0.13 against 5.1 on seed
    5150), so the std is not calibrated here: one case reported 200 % for an estimate 13 % off, another
    8 % for 28-33 % off (2.6 std before the coefficient prior, 3.0 after). Coverage is the benchmark's
    figure, not this test's."""
    case = _case({"kind": "single", "form": "bearing_cubic:radial_cubic"}, first_seed, "steady", min_gap=1.3)
    k3_true = case.label["effect_params"]["bearing_cubic"]["cubic_n_per_m3"]
    ctx = build_context(case.recording, case.rig_file.rig, case.rig_file.estimator)
    _, bic0, _ = nominal_solution(ctx)
    radial = _refined(ctx, RadialBearingCubic(), bic0)
    per_axis = _refined(ctx, BearingCubic(), bic0)
    misalignment = fit_effect(ctx, Misalignment(), reference_bic=bic0)
    assert radial.delta_bic > 30
    assert radial.delta_bic > max(per_axis.delta_bic, misalignment.delta_bic) + 10, \
        (radial.delta_bic, per_axis.delta_bic, misalignment.delta_bic)
    k3, std = radial.physical["k3_N_per_m3"], radial.physical_std["k3_N_per_m3"]
    assert abs(k3 / k3_true - 1) < 0.5, (k3, std, k3_true)


@pytest.mark.slow
def test_a_stiff_clearance_contact_is_the_contact_form_not_a_radial_cubic():
    """A contact spring beyond a radial clearance at both bearings (the independent generator's rub, here 30x
    the bearing stiffness: a stop the orbit about the gravity sag reaches for part of each revolution; the
    first steady case from seed 9100 with a true gap of at least 1.2x, the generator's least) is explained
    better by the contact form than by the radial cubic (delta BIC 1942 against 585), the tangent coefficients
    within 20 % of the largest direct one (the radial form's 245 % off), and its stiffness within 3 reported
    std. Its clearance is not asserted: 1.4 um off at a std of 0.3 um (a stop's clearance trades off against
    the static point). Of 7 contact records seen, the contact form beat the radial one on 5; on one it lost
    (1020 against 1218) and on one of 6.9x both failed."""
    case = _case({"kind": "single", "form": "bearing_cubic:clearance_contact"}, 9100, "steady", min_gap=1.2)
    truth = case.label["effect_params"]["bearing_cubic"]
    ctx = build_context(case.recording, case.rig_file.rig, case.rig_file.estimator)
    _, bic0, _ = nominal_solution(ctx)
    contact = _refined(ctx, ClearanceContact(), bic0)
    radial = _refined(ctx, RadialBearingCubic(), bic0)
    assert contact.delta_bic > max(30.0, radial.delta_bic + 10), (contact.delta_bic, radial.delta_bic)
    value, std = contact.physical["contact_stiffness_N_per_m"], contact.physical_std["contact_stiffness_N_per_m"]
    assert abs(value - truth["contact_stiffness_n_per_m"]) < 3 * std, (value, std, truth)
    tangent = np.asarray(case.label["true_tangent_coefficients"])
    assert np.max(np.abs(contact.coefficients[:4] - tangent[:4])) < 0.2 * np.abs(tangent[[0, 3]]).max()


@pytest.mark.slow
def test_a_control_from_rest_without_impact_stays_clean():
    """A record that starts from rest (the free decay from q = 0 under gravity runs into the fit span) and has
    no effect: the start transient is the nominal's own (8 estimated initial states), so no effect is
    significant (before them one such control was called probe gain + runout)."""
    case = _case({"kind": "control", "impact": False}, 3030, "from_rest")
    ctx = build_context(case.recording, case.rig_file.rig, case.rig_file.estimator)
    rk = rank_effects(ctx, second_stage=False)
    assert rk.best is None, [(f.name, round(f.delta_bic, 1)) for f in rk.singles[:3]]


@pytest.mark.slow
def test_a_common_foundation_from_rest_is_recovered_through_its_housing_start_transient():
    """A common foundation mass under both housings (probes on the housings), the record from rest: the
    foundation's own free decay rings through it, which the rigid start transient cannot hold. The pedestal
    form of that shape, with the initial state of the rotor on its foundation as its linear parameters (8
    rotor and 4 housing states), recovers the foundation's frequency within 10 % and its mass within 30 %."""
    from rotor_estimator.diagnosis.effects import PedestalFlexibility

    case = _case({"kind": "single", "form": "pedestal:common_foundation:relative_probes"}, 8080, "from_rest",
                 min_gap=1.5)
    truth = case.label["effect_params"]["pedestal"]
    ctx = build_context(case.recording, case.rig_file.rig, case.rig_file.estimator)
    assert ctx.start_transient
    _, bic0, _ = nominal_solution(ctx)
    fit = _refined(ctx, PedestalFlexibility("common", "relative"), bic0)
    assert fit.delta_bic > 30 and fit.lin.size == 12
    assert abs(fit.physical["pedestal_frequency_hz"] / truth["frequency_hz"] - 1) < 0.1, (fit.physical, truth)
    assert abs(fit.physical["pedestal_mass_kg"] / truth["mass_kg"] - 1) < 0.3, (fit.physical, truth)


@pytest.mark.slow
def test_a_common_foundation_from_rest_with_absolute_probes_leaves_the_coefficients_within_their_std():
    """Coverage of the bearing coefficients beside a foundation in a record from rest (the first case from seed
    8080 with a true gap of at least 1.5x: 7.1x, one impact). The rotor's free decay from rest is that of the rotor
    on its foundation: the pedestal's start columns are its own model's free response from all 12 initial
    states. With the rigid nominal's 8 in their place (and the 4 housing states beside them), the foundation was
    found to 0.2 % but kxy, kyx and cyy sat 3.7-4.2 reported std off; now every coefficient is within 3 std (of
    the covariance that holds the fit's own coupling, as a diagnosis reports it)."""
    from rotor_estimator.diagnosis.effects import PedestalFlexibility
    from rotor_estimator.diagnosis.ranking import with_coupled_covariance

    case = _case({"kind": "single", "form": "pedestal:common_foundation:absolute_probes"}, 8080, "from_rest",
                 min_gap=1.5)
    truth = case.label["effect_params"]["pedestal"]
    ctx = build_context(case.recording, case.rig_file.rig, case.rig_file.estimator)
    _, bic0, _ = nominal_solution(ctx)
    fit = with_coupled_covariance(_refined(ctx, PedestalFlexibility("common", "absolute"), bic0))
    assert abs(fit.physical["pedestal_frequency_hz"] / truth["frequency_hz"] - 1) < 0.02, (fit.physical, truth)
    z = (fit.coefficients - np.array(case.label["true_coefficients"])) / fit.coefficients_std
    assert np.all(np.abs(z) < 3.0), np.round(z, 1)


@pytest.mark.slow
def test_an_unbalance_without_impact_is_unbalance_not_a_probe_map_under_the_coefficient_prior():
    """An arbitrary-plane unbalance at one speed without an impact (true gap >= 3x): the 1X is all the record
    says, and 8 coefficients plus 8 probe-map gains fit any 1X. Under the rig file's coefficient prior (MAP)
    and with unstable coefficients walled off, the 4 unbalance parameters explain it at coefficients near
    r0 and beat the probe map (before the prior, the nominal fit dragged kxx 20x to hold the 1X and the
    unbalance, refitted from there, lost to the probe map by ~330 in delta BIC)."""
    from rotor_estimator.diagnosis.effects import ProbeGainOrientation, ResidualUnbalance

    case = _case({"kind": "single", "form": "residual_unbalance:arbitrary_plane", "impact": False}, 9090, "steady",
                 min_gap=3.0)
    ctx = build_context(case.recording, case.rig_file.rig, case.rig_file.estimator)
    _, bic0, _ = nominal_solution(ctx)
    unbalance = _refined(ctx, ResidualUnbalance(), bic0)
    probe_map = _refined(ctx, ProbeGainOrientation(), bic0)
    assert unbalance.delta_bic > probe_map.delta_bic, (unbalance.delta_bic, probe_map.delta_bic)
    within = np.abs(unbalance.coefficients - ctx.prior.mean) / ctx.prior.std
    assert np.all(within < 3), within


@pytest.mark.slow
def test_a_light_foundation_ringing_below_the_running_speed_is_found_from_the_residual_peak():
    """A common foundation (5.35 kg, 40 Hz, damping ratio 0.059; probes fixed to ground; steady, one impact)
    rings after the impact at the whole system's mode, 31.5 Hz: the foundation carries the rotor. The
    pedestal's ringing starts turn that peak of the nominal residual into a foundation frequency within 10 %,
    and the refit from the effect's own starts recovers the frequency within 5 % and the mass within 20 %. From
    its fixed ladder of starts (60-500 Hz) alone it stopped at 75.7 Hz (delta BIC 6 659 against 19 598).

    Seed 10109 is the first of 10100-10120 drawn steady, with an impact, below 80 Hz and with a damping ratio below
    0.06. An independent seed-7416 record of the same form (44.8 Hz, 13x gap) had been called runout."""
    from rotor_estimator.diagnosis.effects import PedestalFlexibility

    case = _case({"kind": "single", "form": "pedestal:common_foundation:absolute_probes"}, 10109, "steady",
                 min_gap=3.0)
    truth = case.label["effect_params"]["pedestal"]
    ctx = build_context(case.recording, case.rig_file.rig, case.rig_file.estimator)
    effect = PedestalFlexibility("common", "absolute")
    starts_hz = [10 ** x[0] for x in effect.ringing_starts(ctx)]
    assert min(abs(f / truth["frequency_hz"] - 1) for f in starts_hz) < 0.1, (starts_hz, truth)
    _, bic0, _ = nominal_solution(ctx)
    fit = _refined(ctx, effect, bic0)
    assert abs(fit.physical["pedestal_frequency_hz"] / truth["frequency_hz"] - 1) < 0.05, (fit.physical, truth)
    assert abs(fit.physical["pedestal_mass_kg"] / truth["mass_kg"] - 1) < 0.2, (fit.physical, truth)


@pytest.mark.slow
def test_a_run_from_rest_without_an_impact_shows_its_start_transient_though_the_nominal_fit_is_dragged():
    """A misalignment (forward and backward 2X forces with a static preload) in a record from rest without an
    impact: the nominal fit absorbs the 2X and the start into coefficients at which the start columns explain
    nothing, so the test at the nominal fit alone said "steady" (on this seed, and on seed 7420's case 3). Fitted
    with and without the start transient (start_transient_shows_refitted), the record shows it. Since the
    first-order-hold mend of the re-simulation (9f8d6fe) the test at the nominal fit alone shows it on this seed
    too, so that premise is no longer asserted."""
    case = _case({"kind": "single", "form": "misalignment:forward_backward_2x+preload", "impact": False}, 9126,
                 "from_rest", min_gap=1.5)
    assert not case.label["impacts"]
    ctx = build_context(case.recording, case.rig_file.rig, case.rig_file.estimator)
    assert ctx.start_transient


@pytest.mark.slow
def test_a_coupling_offset_on_the_overhang_is_the_2x_and_backward_1x_form_with_an_unbalance():
    """A parallel offset through a flexible coupling on the shaft's overhang (a 1X and a 2X force along one fixed
    direction, so of both whirls, and a preload; a station outside the bearings): its 1X forward part is an
    unbalance's force, so the form that claims the rest, 2X and a backward 1X force at each bearing, with a
    residual unbalance beside it explains the record better than runout's free harmonics (the same 1X and 2X span
    at one speed, 16 gains more) and than the 2X form with the unbalance (it leaves the backward 1X: a ROSS
    coupling of this kind was called runout). Its forces equal the lever rule's pair at the bearings (the same
    force and moment on a rigid rotor) within 15 % where they exceed 10 N, and the direct stiffnesses are within
    15 % of the truth."""
    case = _case({"kind": "single", "form": "misalignment:coupling_offset_1x_2x+preload", "impact": True}, 200,
                 "steady", min_gap=3.0)
    ctx = build_context(case.recording, case.rig_file.rig, case.rig_file.estimator)
    _, bic0, _ = nominal_solution(ctx)
    runout = _refined(ctx, ProbeRunout(), bic0)
    pairs = {}
    for backward in (True, False):
        single = fit_effect(ctx, Misalignment(backward), reference_bic=bic0)
        pair = refine(ctx, ResidualUnbalance(), fit_effect(ctx, ResidualUnbalance(), (single,), reference_bic=bic0),
                      (single,), reference_bic=bic0, extra_starts=(ctx.prior_coefficients,), max_nfev=12)
        pairs[backward] = pair
    with_backward, without = pairs[True], pairs[False]
    # the misalignment's forces as the pair estimated them (its gains refitted beside the unbalance)
    forces_n = Misalignment(True).physical(np.zeros(0), with_backward.base_lin)
    assert with_backward.delta_bic > max(runout.delta_bic, without.delta_bic) + 10, \
        (with_backward.delta_bic, runout.delta_bic, without.delta_bic)
    params = case.label["effect_params"]["misalignment"]
    truth = {}
    for b, ((xr, xi), (yr, yi)) in zip(("b1", "b2"), params["bearing_force_1x_n"]):
        truth[f"force_1x_{b}_backward_n"] = abs(complex(xr, -xi) + 1j * complex(yr, -yi)) / 2
    for b, ((xr, xi), (yr, yi)) in zip(("b1", "b2"), params["bearing_force_2x_n"]):
        truth[f"force_2x_{b}_x_amplitude_n"], truth[f"force_2x_{b}_y_amplitude_n"] = abs(complex(xr, xi)), abs(
            complex(yr, yi))
    large = {k: v for k, v in truth.items() if v > 10.0}
    assert any(k.startswith("force_1x") for k in large), truth  # the backward 1X is there to find
    for k, v in large.items():
        assert abs(forces_n[k] / v - 1) < 0.15, (k, forces_n[k], v)
    r_true = np.asarray(case.label["true_coefficients"])
    direct = [0, 3]
    assert np.all(np.abs(with_backward.coefficients[direct] / r_true[direct] - 1) < 0.15), with_backward.coefficients


@pytest.mark.slow
def test_one_misoriented_probe_is_that_probes_form_with_its_angle_within_its_std():
    """One probe turned on its mount (the independent generator's single-probe misorientation, steady, a true gap
    of at least 1.3x): among the probe map's forms, after their joint refits, that probe's own (2 parameters) has
    the best BIC, it beats the per-channel delay (a 1X phase error it resembles), and its angle is within 3
    reported std of the truth."""
    from rotor_estimator.diagnosis.effects import CHANNELS, ProbeGainOrientation, TimingSkew

    case = _case({"kind": "single", "form": "probe_gain_orientation:single_probe_misorientation"}, 7700, "steady",
                 min_gap=1.3)
    truth = case.label["effect_params"]["probe_gain_orientation"]
    probe = CHANNELS.index(truth["channel"])
    ctx = build_context(case.recording, case.rig_file.rig, case.rig_file.estimator)
    _, bic0, _ = nominal_solution(ctx)
    forms = {f.probe: _refined(ctx, f, bic0) for f in ProbeGainOrientation().variants()}
    best = min(forms, key=lambda p: forms[p].bic)
    assert best == probe, {p: f.delta_bic for p, f in forms.items()}
    skew = _refined(ctx, TimingSkew(), bic0)
    assert forms[probe].delta_bic > skew.delta_bic, (forms[probe].delta_bic, skew.delta_bic)
    name = f"angle_error_{truth['channel']}_deg"
    angle, std = forms[probe].physical[name], forms[probe].physical_std[name]
    assert abs(angle - np.degrees(truth["angle_rad"])) < 3 * std, (angle, std, np.degrees(truth["angle_rad"]))


@pytest.mark.slow
def test_a_late_probe_plane_is_the_one_plane_delay_with_its_delay_within_its_std():
    """Both probes of one plane sampled whole samples late (the independent generator's one-plane delay, steady,
    without an impact, a true gap of at least 1.5x): among the timing skew's forms, after their joint refits, the
    late plane's one delay has the best BIC, and its delay is within 3 reported std of the truth."""
    from rotor_estimator.diagnosis.effects import TimingSkew

    case = _case({"kind": "single", "form": "timing_skew:whole_sample_delay:one_plane", "impact": False}, 7800,
                 "steady", min_gap=1.5)
    truth = case.label["effect_params"]["timing_skew"]
    ctx = build_context(case.recording, case.rig_file.rig, case.rig_file.estimator)
    _, bic0, _ = nominal_solution(ctx)
    fits = [_refined(ctx, f, bic0) for f in TimingSkew().variants()]
    best = min(fits, key=lambda f: f.bic)
    assert set(best.physical) == {f"skew_{ch}_s" for ch in truth["channels"]}, [(f.effect.form, f.delta_bic)
                                                                               for f in fits]
    name = f"skew_{truth['channels'][0]}_s"
    delay_s = truth["delay_samples"] / case.rig_file.rig.sample_rate_hz
    assert abs(best.physical[name] - delay_s) < 3 * best.physical_std[name], (best.physical[name],
                                                                              best.physical_std[name], delay_s)


@pytest.mark.slow
@pytest.mark.extended
def test_a_keyphasor_offset_beside_a_probe_error_is_that_pair_not_a_residual_unbalance():
    """A keyphasor offset with a probe error (the independent generator's pair of the two, any of its forms and
    starts, each effect's own gap at least 1.2x): the ranking's verdict is that pair (verdict and runner-up),
    not a residual unbalance, which takes up both with its four parameters; and the offset is within 3 reported
    std of the truth. The offset nests in the unbalance (:attr:`.Effect.nests_in`): without the substitution
    the pair was missed on four fresh seeds in a row (7431-7434). Case: the first drawn from seed 9100 whose
    true gap is at least 1.5x, chosen on the generator's draw without any fit (seed 9100: offset 13 deg, 3.5x;
    probe xp1 turned 14 deg, 2.2x; from rest, no impact); about 12 min. Before leaner_member_pairs (3bb0a7f) the
    verdict was the full probe map alone: its four turns took up the offset, the pair of the offset with the full
    map 7.7 in BIC behind it; the offset beside probe xp1's own entries is 50 ahead of it (offset 13.03 +- 0.13
    deg, true 13.07)."""
    for seed in range(9100, 9140):
        case = independent.make_case("t", {"kind": "pair", "families": ("tach_offset", "probe_gain_orientation")},
                                     seed)
        if case.label["true_gap"] >= 1.5:
            break
    else:
        raise AssertionError("no such case in 40 seeds")
    ctx = build_context(case.recording, case.rig_file.rig, case.rig_file.estimator)
    rk = rank_effects(ctx)
    verdict = {f.name for f in (rk.best, rk.second) if f is not None}
    assert verdict == {"tach_offset", "probe_gain_orientation"}, (verdict, case.label["form"],
                                                                   [(f.name, f.delta_bic) for f in rk.pairs[:4]])
    offset = next(f for f in (rk.best, rk.second) if f.name == "tach_offset")
    truth_deg = np.degrees(case.label["effect_params"]["tach_offset"]["offset_rad"])
    wrapped = (offset.physical["offset_deg"] - truth_deg + 180.0) % 360.0 - 180.0
    assert abs(wrapped) < 3 * offset.physical_std["offset_deg"], (offset.physical, offset.physical_std, truth_deg)
