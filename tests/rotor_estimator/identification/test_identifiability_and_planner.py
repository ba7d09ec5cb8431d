# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Identifiability report and excitation planner."""
import argparse
import json

import numpy as np
import pytest

from rotor_estimator.core.ekf import StreamingEKF, initial_covariance
from rotor_estimator.core.identifiability import (NOT_DETERMINED, report_from_filter,
                                                            report_from_information)
from rotor_estimator.identification.information import design_information
from rotor_estimator.identification.planner import Target, evaluate, plan
from rotor_estimator.identification.scenarios import design_from_scenario, multi_impact, simulate_design, sweep
from rotor_estimator.core.offline import shaft_inputs_from_recording
from rotor_estimator.core.simulator import paper_scenario, simulate


def _info(rig, arrays, model8, true8, design, unknown=False):
    recs = simulate_design(rig, design, seed=None, substeps=2, arrays=arrays)
    return design_information(arrays, model8, recs, true8, estimate_imbalance=unknown, noise_std_m=rig.noise_std_m)


def test_report_flags_seed_imbalance_only_and_clears_coast_down(seed_rig, arrays, model8, true8):
    starved = report_from_information(
        _info(seed_rig, arrays, model8, true8, design_from_scenario(seed_rig, paper_scenario("imbalance"))), true8)
    assert not starved.all_determined
    assert {"kxx", "kxy", "kyx", "kyy", "cxy", "cyx"} <= set(starved.names_with(NOT_DETERMINED))
    assert all(e.value_for_display is None for e in starved.entries if e.status == NOT_DETERMINED)
    assert "NOT DETERMINED" in starved.format()
    coast = report_from_information(_info(seed_rig, arrays, model8, true8, sweep("cd", 20000, 3000, 2.0)), true8)
    assert coast.all_determined, coast.format()


def test_report_from_a_running_ekf_flags_imbalance_only(seed_rig_file):
    """The node's path: P^-1 - P0^-1 of the streaming EKF after the seed's imbalance-only record."""
    rig, cfg = seed_rig_file.rig, seed_rig_file.estimator
    sim = simulate(rig, paper_scenario("imbalance"), seed=2)
    shaft = shaft_inputs_from_recording(sim.recording)
    ekf = StreamingEKF(rig, cfg)
    ekf.process_block(sim.recording.time_s(), sim.recording.probes_m, shaft.angle_rad, shaft.speed_rad_s,
                      shaft.accel_rad_s2, sim.recording.impact_force_n)
    p0 = initial_covariance(cfg)[8:, 8:]
    rep = report_from_filter(ekf.coefficient_covariance, p0, ekf.coefficients)
    assert not rep.all_determined
    assert len(rep.names_with(NOT_DETERMINED)) >= 4


def test_planner_recommends_the_shortest_test_meeting_the_target(seed_rig, true8):
    designs = [sweep("cd 2 s", 20000, 3000, 2.0), sweep("cd 0.25 s", 20000, 3000, 0.25),
               multi_impact("5 hits", 5, 1.03, 20000, discard_initial_s=0.03)]
    p = plan(seed_rig, Target(0.02, 0.30), designs=designs, unknown_imbalance=False)
    assert p.recommended.design.name == "cd 0.25 s"
    assert [c.design.name for c in p.candidates] == ["cd 0.25 s", "5 hits", "cd 2 s"]
    p = plan(seed_rig, Target(0.005, 0.06), designs=designs, unknown_imbalance=False)
    assert p.recommended.design.name == "cd 2 s"
    assert "recommended" in p.format()


def test_crlb_scales_with_noise_and_unknown_imbalance_widens_it(seed_rig, true8):
    d = sweep("cd", 20000, 3000, 0.25)
    a = evaluate(seed_rig, d, true8, unknown_imbalance=False)
    b = evaluate(seed_rig, d, true8, unknown_imbalance=False, noise_std_m=2e-6)
    c = evaluate(seed_rig, d, true8, unknown_imbalance=True)
    assert np.allclose(b.std, 2 * a.std, rtol=1e-6)
    assert np.all(c.std >= a.std * (1 - 1e-9))


def test_plan_command_json(capsys, seed_rig, monkeypatch):
    from rotor_estimator.cli import plan as plan_cli
    from rotor_estimator.identification import planner

    monkeypatch.setattr(planner, "candidate_designs", lambda rig, c, bearings16=False, hammer_force_n=515.0: [
        sweep("cd 0.25 s", 20000, 3000, 0.25)])
    parser = argparse.ArgumentParser()
    plan_cli.add_parser(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["plan", "--target", "5", "--json", "--no-progress"])
    monkeypatch.setattr("rotor_estimator.identification.planner.candidate_designs", planner.candidate_designs)
    assert args.func(args) == 0
    rows = json.loads(capsys.readouterr().out)
    assert {r["coefficient"] for r in rows} == {"kxx", "kxy", "kyx", "kyy", "cxx", "cxy", "cyx", "cyy"}


def test_bench_identification_json_keys(capsys):
    from rotor_estimator.cli import bench as bench_cli

    parser = argparse.ArgumentParser()
    bench_cli.add_parser(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["bench", "identification", "--runs", "2", "--only", "imbalance+impact",
                              "--methods", "ekf", "batch-ml", "--json", "--no-progress"])
    assert args.func(args) == 0
    rows = json.loads(capsys.readouterr().out)
    assert len(rows) == 16
    assert {"scenario", "method", "coefficient", "true", "mean", "std", "crlb_std"} <= set(rows[0])


@pytest.mark.parametrize("target,expected", [([5], (0.05, 0.05)), ([1, 10], (0.01, 0.10))])
def test_target_from_percent(target, expected):
    t = Target.from_percent(target)
    assert (t.direct, t.cross) == pytest.approx(expected)
