# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""A long record is diagnosed in bounded memory and time: the fits run on one reported window."""
from __future__ import annotations

import json

import numpy as np
import pytest

from rotor_estimator.io.bags import write_input_bag
from rotor_estimator.core.config import SEED_RIG_PATH, load_rig_file
from rotor_estimator.diagnosis.api import MAX_FIT_WINDOW_S, analysis_window
from rotor_estimator.core.recording import RigRecording
from rotor_estimator.core.simulator import Impact, Scenario, paper_scenario, simulate


def _recording(n: int, impacts_at: list[int]) -> RigRecording:
    stamps = np.arange(n, dtype=np.int64) * 50_000
    force = np.zeros((n, 2))
    for i in impacts_at:
        force[i:i + 2, 1] = -515.0
    return RigRecording(stamps, np.zeros((n, 4)), stamps[::60], force, {})


def test_analysis_window_is_the_whole_short_record_and_the_busiest_window_of_a_long_one():
    """<= MAX_FIT_WINDOW_S: everything. Longer: a window of that length holding the most impact onsets,
    starting before the first of them; no impact: the last window."""
    per = int(MAX_FIT_WINDOW_S * 20_000)
    assert analysis_window(_recording(per, [100])) == (0, per, "the whole record")
    n = 10 * per
    a, b, why = analysis_window(_recording(n, [2 * per, 5 * per, 5 * per + 1000, 5 * per + per // 2]))
    assert b - a == per and a < 5 * per < 5 * per + per // 2 < b and "3 of 4" in why
    a, b, why = analysis_window(_recording(n, []))
    assert (a, b) == (n - per, n) and "no impact" in why


@pytest.mark.slow
def test_a_60_s_record_is_diagnosed_under_500_mb_and_says_which_window_it_fitted(tmp_path, cli_peak_rss):
    """issue: ~150 MB per second of record (10 GB for 60 s). Now the peak RSS of `diagnose` on 60 s with
    30 impacts stays under 500 MB, and the JSON names the fitted window."""
    rig = load_rig_file().rig
    base = paper_scenario("imbalance+impact")
    impacts = tuple(Impact(0.5 + 2.0 * k, base.impacts[0].duration_s, 0.0, -515.0) for k in range(30))
    rec = simulate(rig, Scenario(duration_s=60.0, discard_initial_s=base.discard_initial_s, impacts=impacts),
                   seed=5).recording
    bag = write_input_bag(tmp_path / "long", rec)
    del rec
    out, peak_mb = cli_peak_rss(['diagnose', bag, '--rig', SEED_RIG_PATH, '--json'])
    summary = json.loads(out)
    window = summary["data"]["analysis_window"]
    assert window["stop_s"] - window["start_s"] <= MAX_FIT_WINDOW_S and window["record_s"] > 59
    assert summary["data"]["samples_in_record"] > 1_000_000
    assert peak_mb < 500, f"peak RSS {peak_mb:.0f} MB"
