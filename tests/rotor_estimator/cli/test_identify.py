# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""`identify`: imbalance estimated by default, fit quality reported, a wrong stated imbalance caught,
several records with trial weights fitted together."""
from __future__ import annotations

import dataclasses
import json
import math

import pytest
import yaml

from rotor_estimator.io.bags import write_input_bag
from rotor_estimator.cli.main import main
from rotor_estimator.core.config import Imbalance, SEED_RIG_PATH, load_rig_file
from rotor_estimator.core.simulator import paper_scenario, simulate


@pytest.fixture(scope="module")
def bags(tmp_path_factory):
    """The seed case, and the same rotor with a 2 g trial weight at 30 mm, plane 1, 90 degrees."""
    d = tmp_path_factory.mktemp("identify")
    rig = load_rig_file().rig
    base = write_input_bag(d / "base", simulate(rig, paper_scenario("imbalance+impact"), seed=11).recording)
    plane1 = rig.imbalances[0].axial_position_m
    trial_rig = dataclasses.replace(rig, imbalances=rig.imbalances + (Imbalance(2e-3, 0.03, math.pi / 2, plane1),))
    trial = write_input_bag(d / "trial", simulate(trial_rig, paper_scenario("imbalance+impact"), seed=12).recording)
    return d, base, trial


def _identify(capsys, *args):
    code = main(["identify", *args, "--json"])
    out, err = capsys.readouterr()
    assert code == 0, err
    return json.loads(out)


def test_imbalance_is_estimated_by_default_and_the_fit_is_consistent(bags, capsys):
    """Default: the imbalance is a fitted unknown (as `plan` assumes), reported in g*mm at an angle, and the
    residual is at the noise (mean normalized squared residual inside its band)."""
    _, base, _ = bags
    r = _identify(capsys, "--bag", str(base))
    assert r["imbalance_estimated"] and r["fit"]["model_mismatch"] is False
    assert 0.9 < r["fit"]["residual_over_noise"] < 1.1
    truth = [0.5e-3 * 0.01842 * 1e6] * 2  # the seed rig: 9.21 g*mm per plane, at 0 and 90 degrees
    for row, g_mm, angle in zip(r["imbalance"], truth, (0.0, 90.0)):
        assert abs(row["g_mm"] - g_mm) < 4 * row["std_g_mm"] + 0.05 * g_mm and abs(row["angle_deg"] - angle) < 5


def test_a_10_degree_error_in_a_stated_imbalance_is_a_model_mismatch_not_determined_coefficients(bags, tmp_path,
                                                                                                   capsys):
    """--known-imbalance with a rig file whose imbalance phase is 10 degrees off: flagged, and no coefficient is
    called determined (before: all 8 'determined' while 18-40 sigma off); estimating it absorbs the error."""
    _, base, _ = bags
    data = yaml.safe_load(SEED_RIG_PATH.read_text())
    data["rig"]["imbalances"][0]["phase_deg"] += 10.0
    data["rig"]["imbalances"][1]["phase_deg"] += 10.0
    rig = tmp_path / "wrong_phase.yaml"
    rig.write_text(yaml.safe_dump(data))
    fixed = _identify(capsys, "--bag", str(base), "--rig", str(rig), "--known-imbalance")
    assert fixed["fit"]["model_mismatch"] is True
    main(["identify", "--bag", str(base), "--rig", str(rig), "--known-imbalance"])
    text = capsys.readouterr().out
    assert "MODEL MISMATCH" in text and "drop --known-imbalance" in text
    assert " determined" not in text.split("status\n", 1)[1].split("status from")[0].replace("not determined", "")
    free = _identify(capsys, "--bag", str(base), "--rig", str(rig))
    assert free["fit"]["model_mismatch"] is False


def test_several_records_with_their_trial_weights_are_fitted_together(bags, capsys):
    """Two --bag records, each with its trial weight, are one batch fit: the data-only std of every
    coefficient is below that of either record alone, and the estimate stays consistent."""
    _, base, trial = bags
    one = _identify(capsys, "--bag", str(base))
    both = _identify(capsys, "--bag", str(base), "--trial-weight", "none", "--bag", str(trial),
                     "--trial-weight", "2,30,1,90")
    assert both["records"] == 2 and both["fit"]["model_mismatch"] is False
    for a, b in zip(one["coefficients"], both["coefficients"]):
        assert b["predicted_std"] < a["predicted_std"]
    wrong = _identify(capsys, "--bag", str(base), "--trial-weight", "none", "--bag", str(trial),
                      "--trial-weight", "2,30,1,270")  # the trial weight at the wrong angle: the fit says so
    assert wrong["fit"]["model_mismatch"] is True


def test_trial_weights_must_match_the_bags_one_to_one(bags, capsys):
    _, base, trial = bags
    code = main(["identify", "--bag", str(base), "--bag", str(trial), "--trial-weight", "2,30,1,90"])
    assert code == 2 and "one per --bag" in capsys.readouterr().err
