# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Soak: replaying a long record keeps memory flat (streaming: nothing grows with the record)."""
from __future__ import annotations

import pytest

from rotor_estimator.io.bags import write_input_bag
from rotor_estimator.core.config import load_rig_file
from rotor_estimator.core.simulator import Scenario, paper_scenario, simulate


@pytest.mark.slow
def test_replay_rss_of_a_20_s_record_equals_that_of_a_1_s_record(tmp_path, cli_peak_rss):
    """Peak RSS of `replay` over 20 s of 20 kHz data (400 000 samples per plane, 2 passes) is within 10 MB
    of the peak over 1 s: anything kept per sample from 25 bytes up (three float64s) would show.
    Measured over 60 s: 218 MB and 220 MB; 20 s keeps the same per-sample bound at a third of the time."""
    rig = load_rig_file().rig
    base = paper_scenario("imbalance+impact")
    peaks = {}
    for seconds in (1.0, 20.0):
        rec = simulate(rig, Scenario(duration_s=seconds, discard_initial_s=base.discard_initial_s,
                                     impacts=base.impacts), seed=9).recording
        bag = write_input_bag(tmp_path / f"r{seconds:g}", rec)
        del rec
        out, peaks[seconds] = cli_peak_rss(['replay', bag, '--no-progress'])
        assert "samples:" in out
    assert peaks[20.0] - peaks[1.0] < 10.0, peaks
