# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""plan -> simulate -> identify, closed: the commands `plan` prints make the test it recommends, and
identifying from it meets the precision it promised."""
from __future__ import annotations

import json
import shlex

import pytest

from rotor_estimator.cli.main import main


@pytest.mark.slow
def test_the_recommended_test_run_through_simulate_and_identify_meets_the_promised_precision(tmp_path, capsys,
                                                                                              monkeypatch):
    """Target 25 %: every coefficient's data-only std from the identification is within 1.3x of the
    target (the plan's bound is at the expected coefficients, the identification's at its estimate),
    and the fit is consistent."""
    monkeypatch.chdir(tmp_path)
    assert main(["plan", "--target", "25", "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "Critical speeds of the rig" in out and "the test passes" in out
    commands = [ln.strip() for ln in out.split("Make the recommended test", 1)[1].splitlines()[1:] if ln.strip()]
    assert commands[0].startswith("rotor-estimator simulate --design") and commands[-1].startswith(
        "rotor-estimator identify")
    for line in commands[:-1]:
        assert main(shlex.split(line)[1:]) == 0
    capsys.readouterr()
    assert main(shlex.split(commands[-1])[1:] + ["--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["fit"]["model_mismatch"] is False
    for c in result["coefficients"]:
        assert c["relative_std"] <= 1.3 * 0.25, c


def test_plan_respects_the_achievable_deceleration_and_states_the_hammer():
    """A test that needs a faster speed change than --decel-rpm-per-s is never recommended."""
    import numpy as np

    from rotor_estimator.core.config import load_rig_file
    from rotor_estimator.identification.planner import (Target, candidate_designs, plan,
                                                        required_decel_rpm_per_s)

    rig = load_rig_file().rig
    coefficients = rig.true_coefficients.as_array()
    designs = [d for d in candidate_designs(rig, coefficients, hammer_force_n=200.0)
               if d.duration_s <= 0.6]
    assert any(imp.force_y_n == -200.0 for d in designs for imp in d.impacts)
    free = plan(rig, Target(0.25, 0.25), coefficients=coefficients, designs=designs)
    assert free.recommended is not None and required_decel_rpm_per_s(free.recommended.design) > 1000
    limited = plan(rig, Target(0.25, 0.25), coefficients=coefficients, designs=designs, max_decel_rpm_per_s=1000)
    assert limited.recommended is None or required_decel_rpm_per_s(limited.recommended.design) <= 1000
    assert "needs" in limited.format()
    assert np.isfinite(free.recommended.max_direct())
