# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""True effect parameters from benchmark labels: each mapping agrees with the library's own ``physical()``."""
from __future__ import annotations

import math

import numpy as np
import pytest

from rotor_estimator.bench.diagnosis import score
from rotor_estimator.bench.parameter_truth import covered, independent_truth, lever_rule, own_truth
from rotor_estimator.diagnosis.effects.misalignment import Misalignment
from rotor_estimator.diagnosis.effects.probe_gain_orientation import ProbeGainOrientation
from rotor_estimator.diagnosis.effects.residual_unbalance import ResidualUnbalance


def test_lever_rule_keeps_the_force_and_its_moment():
    """Two plane masses replacing one on a rigid rotor: same resultant and same moment about any station."""
    u = 3e-6 * complex(math.cos(0.7), math.sin(0.7))
    z, planes = 0.031, (-0.05, 0.08)
    u1, u2 = lever_rule(u, z, planes)
    assert u1 + u2 == pytest.approx(u)
    assert u1 * planes[0] + u2 * planes[1] == pytest.approx(u * z)


def test_a_contacts_truth_reads_as_the_contact_form_reports_it():
    """The independent generator's contact (``contact_stiffness_n_per_m`` beyond ``clearance_m``) maps to the
    names the contact form's ``physical`` reports, with the same values (its nl: log10 stiffness and
    micrometres), so the benchmark's parameter coverage counts it; a radial cubic's label maps to ``k3``."""
    from rotor_estimator.diagnosis.effects.bearing_cubic import ClearanceContact

    truth = independent_truth("bearing_cubic", {"contact_stiffness_n_per_m": 2.0e7, "clearance_m": 3.1e-5},
                              (0.0, 1.0), 20e3)
    reported = ClearanceContact().physical(np.array([math.log10(2.0e7), 31.0, 5.0, -9.0]), np.zeros(0))
    assert set(truth) <= set(reported)
    for name, value in truth.items():
        assert reported[name] == pytest.approx(value)
    assert independent_truth("bearing_cubic", {"cubic_n_per_m3": 1e14}, (0.0, 1.0), 20e3) == {"k3_N_per_m3": 1e14}


@pytest.mark.parametrize("channel", range(4))
def test_misorientation_and_gain_read_as_the_library_reports_them(channel):
    """The independent generator's probe ``g (x cos b + y sin b)`` / ``g (-x sin b + y cos b)``, written as the
    library's per-plane map, gives back gain g - 1 and angle b through ``ProbeGainOrientation.physical``."""
    g, b = 1.25, 0.3
    lin = np.zeros(8)  # (axx - 1, axy, ayx, ayy - 1) per plane
    p, is_y = divmod(channel, 2)
    row = (-g * math.sin(b), g * math.cos(b)) if is_y else (g * math.cos(b), g * math.sin(b))
    if is_y:
        lin[4 * p + 2], lin[4 * p + 3] = row[0], row[1] - 1.0
    else:
        lin[4 * p], lin[4 * p + 1] = row[0] - 1.0, row[1]
    reported = ProbeGainOrientation().physical(np.zeros(0), lin)
    ch = ("xp1", "yp1", "xp2", "yp2")[channel]
    for params in ({"channel": ch, "gain": g}, {"channel": ch, "angle_rad": b}):
        truth = independent_truth("probe_gain_orientation", params, (0.0, 1.0), 20e3)
        name = f"gain_error_{ch}" if "gain" in params else f"angle_error_{ch}_deg"
        assert truth[name] == pytest.approx(reported[name])
        # every other channel is true to the model
        assert all(v == 0.0 for k, v in truth.items() if k != name)


def test_own_unbalance_reads_as_the_library_reports_it():
    """The own generator's (cos, sin) kg m per plane is the library's column pair (g mm): same size and phase."""
    u_kg_m = (2e-6, -1e-6, -3e-6, 0.5e-6)
    reported = ResidualUnbalance().physical(np.zeros(0), np.array(u_kg_m) * 1e6)
    truth = own_truth("residual_unbalance", {"residual_unbalance_kg_m": u_kg_m})
    for name, value in truth.items():
        assert value == pytest.approx(reported[name])


def test_a_1x_force_reads_as_the_backward_part_the_library_reports():
    """The generator's 1X force ``fx = Re(X e^{i theta})``, ``fy = Re(Y e^{i theta})`` at each bearing: the library's
    backward column pair ``(re cos + im sin, -re sin + im cos)`` written so gives back ``hypot(re, im)`` through
    ``Misalignment(True).physical``; a forward (unbalance) force has no backward part, a fixed-direction one half
    its amplitude."""
    re_im = ((3.0, -4.0), (0.5, 1.2))  # N, per bearing
    lin = np.concatenate([np.zeros(8), np.ravel(re_im)])
    reported = Misalignment(True).physical(np.zeros(0), lin)
    as_generated = [[[re, -im], [im, re]] for re, im in re_im]  # X = re - i im, Y = im + i re
    truth = independent_truth("misalignment", {"bearing_force_1x_n": as_generated,
                                               "bearing_force_2x_n": [[[0, 0], [0, 0]]] * 2}, (0.0, 1.0), 20e3)
    for b in ("b1", "b2"):
        assert truth[f"force_1x_{b}_backward_n"] == pytest.approx(reported[f"force_1x_{b}_backward_n"])
    f = complex(2.0, 1.0)
    forward = independent_truth("misalignment", {"bearing_force_1x_n": [[[f.real, f.imag], [(-1j * f).real,
                                                 (-1j * f).imag]]] * 2, "bearing_force_2x_n": []}, (0.0, 1.0), 20e3)
    assert forward["force_1x_b1_backward_n"] == pytest.approx(0.0, abs=1e-12)
    fixed = independent_truth("misalignment", {"bearing_force_1x_n": [[[6.0, 0.0], [0.0, 0.0]]] * 2,
                                               "bearing_force_2x_n": []}, (0.0, 1.0), 20e3)
    assert fixed["force_1x_b2_backward_n"] == pytest.approx(3.0)


def test_skew_is_the_delay_on_the_named_channels_only():
    """A 5-sample delay at 20 kHz on one plane is 250 us on its two channels and zero elsewhere."""
    truth = independent_truth("timing_skew", {"delay_samples": 5.0, "channels": ["xp2", "yp2"]}, (0.0, 1.0), 20e3)
    assert truth == {"skew_xp1_s": 0.0, "skew_yp1_s": 0.0, "skew_xp2_s": 250e-6, "skew_yp2_s": 250e-6}


def test_angles_are_covered_across_the_wrap():
    """359 deg estimated with a 1.5 deg std covers a true 1 deg (2 deg apart on the circle), not 10 deg."""
    assert covered("offset_deg", 359.0, 1.5, 1.0)
    assert not covered("offset_deg", 359.0, 1.5, 10.0)
    assert not covered("gain_error_xp1", 359.0, 1.5, 1.0)  # not an angle: no wrap


def test_parameter_coverage_scores_only_verdicts_holding_the_effect():
    """A verdict with the true effect scores each counterpart parameter; a parameter the verdict's form does not
    report is counted as without counterpart; a wrong verdict scores nothing."""
    lab = {"effects": ["tach_offset"], "generator": "effect_sim", "noise_rms_m": 1e-6,
           "effects_params": {"tach_offset_rad": math.radians(20.0)}}
    fit = {"name": "tach_offset", "parameters": {"offset_deg": {"value": 21.0, "std": 1.0}}}
    hit = {"case": "a", "best_effect": "tach_offset", "top_two": ["tach_offset", "x"], "before": 2e-6,
           "shrink_ratio": 2.0, "best_effect_fit": fit, "second_effect_fit": None}
    far = {**hit, "case": "b", "best_effect_fit": {**fit, "parameters": {"offset_deg": {"value": 25.0, "std": 1.0}}}}
    no_std = {**hit, "case": "c", "best_effect_fit": {**fit, "parameters": {"offset_deg": {"value": 20.0,
                                                                                           "std": float("nan")}}}}
    wrong = {**hit, "case": "d", "best_effect": "residual_unbalance",
             "best_effect_fit": {"name": "residual_unbalance", "parameters": {}}}
    s = score([hit, far, no_std, wrong], {k: lab for k in "abcd"})
    rows = {r["case"]: r for r in s["rows"]}
    assert rows["a"]["parameters_covered"] == {"tach_offset.offset_deg": True}
    assert rows["b"]["parameters_covered"] == {"tach_offset.offset_deg": False}
    assert rows["c"]["parameters_covered"] == {} and rows["c"]["parameters_without_counterpart"] == 1
    assert rows["d"]["parameters_covered"] == {} and rows["d"]["parameters_without_counterpart"] == 0
    assert s["parameter_coverage"] == 0.5 and s["n_parameters_scored"] == 2
    # a label without the effect's parameters (a ROSS case of the own generator): no counterpart, no crash
    bare = score([hit], {"a": {k: v for k, v in lab.items() if k != "effects_params"}})
    assert bare["rows"][0]["parameters_covered"] == {} and bare["n_parameters_without_counterpart"] == 1
