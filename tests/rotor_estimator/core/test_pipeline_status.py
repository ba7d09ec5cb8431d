# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""The pipeline never reports success on nothing: causes named, exit codes, the rig's speed limit,
divergence kept visible, and accounting balanced at every instant."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from rotor_estimator.core.alignment import AlignmentConfig
from rotor_estimator.io.bags import write_input_bag
from rotor_estimator.cli.main import main
from rotor_estimator.core.config import load_rig_file
from rotor_estimator.core.pipeline import LEVEL_ERROR, LEVEL_WARN, REPEATED_DIVERGENCE, EstimatorPipeline
from rotor_estimator.core.recording import RigRecording
from rotor_estimator.core.simulator import paper_scenario, simulate
from rotor_estimator.core.tachometer import DEFAULT_MAX_SPEED_RAD_S, ShaftAngleTracker, TachometerConfig


@pytest.fixture(scope="module")
def rig_file():
    return load_rig_file()


@pytest.fixture(scope="module")
def recording(rig_file) -> RigRecording:
    return simulate(rig_file.rig, paper_scenario("imbalance+impact"), seed=4).recording


def _with_pulses(rec: RigRecording, pulses) -> RigRecording:
    return dataclasses.replace(rec, pulse_stamps_ns=np.asarray(pulses, dtype=np.int64))


@pytest.mark.parametrize("pulses,cause", [
    (lambda r: [], "no keyphasor pulse received"),
    (lambda r: r.pulse_stamps_ns[:1], "1 keyphasor pulse(s) received"),
    (lambda r: r.pulse_stamps_ns // 1_000_000, "keyphasor pulse"),  # stamps in ms: another clock entirely
])
def test_replay_with_no_usable_shaft_reference_exits_3_naming_the_cause(tmp_path, capsys, recording, pulses, cause):
    """No sample filtered -> exit 3 and the cause, not rc 0 with the prior r0 printed as 'the estimate'."""
    bag = write_input_bag(tmp_path / "bag", _with_pulses(recording, pulses(recording)))
    assert main(["replay", str(bag), "--no-progress"]) == 3
    out, err = capsys.readouterr()
    assert "no probe sample could be filtered" in err and cause in err and "kxx" not in out


def test_tracker_speed_limit_follows_the_rig():
    """A 90000 rpm rig: every pulse is accepted with the rig's limit; the old fixed 60000 rpm limit
    refused every other pulse (and so tracked half the speed)."""
    speed = 90000 / 60 * 2 * np.pi
    rig = dataclasses.replace(load_rig_file().rig, speed_rad_s=speed)
    pipe = EstimatorPipeline(rig, load_rig_file().estimator, None, AlignmentConfig(), 0.05)
    assert pipe.tach_config.max_speed_rad_s >= 2 * speed > DEFAULT_MAX_SPEED_RAD_S
    period_ns = int(round(2 * np.pi / speed * 1e9))
    pulses = 1_000_000_000 + np.arange(50) * period_ns
    accepted = {}
    for name, config in (("rig", pipe.tach_config), ("fixed", TachometerConfig())):
        trk = ShaftAngleTracker(config)
        for p in pulses:
            trk.add_pulse(int(p))
        accepted[name] = trk.counters["accepted"]
    assert accepted["rig"] == 50 and accepted["fixed"] <= 26


def test_repeated_divergence_keeps_the_status_at_error(rig_file):
    """Recoveries are judged on their total, not only on the change since the last status: after
    REPEATED_DIVERGENCE of them every later status is ERROR and says how many."""
    pipe = EstimatorPipeline(rig_file.rig, rig_file.estimator, None, AlignmentConfig(), 0.05)
    pipe._recoveries_retired = 1
    assert pipe.status().level == LEVEL_ERROR            # a new recovery
    assert pipe.status().level == LEVEL_WARN             # one, earlier: still named
    assert "diverged 1 time earlier" in pipe.status().message
    pipe._recoveries_retired = REPEATED_DIVERGENCE
    pipe.status()
    for _ in range(3):
        status = pipe.status()
        assert status.level == LEVEL_ERROR and f"diverged {REPEATED_DIVERGENCE} times" in status.message


def test_accounting_is_balanced_after_every_call_in_any_interleaving(rig_file, recording):
    """received == processed + rejected + pending per plane at every instant, including while one
    plane's samples are held back waiting for the other (they were pending but not received)."""
    rng = np.random.default_rng(7)
    pipe = EstimatorPipeline(rig_file.rig, rig_file.estimator, None, AlignmentConfig(), 0.05)
    n = len(recording)
    cursor = {1: 0, 2: 0}
    pulses = list(recording.pulse_stamps_ns)
    while cursor[1] < n or cursor[2] < n:
        p = int(rng.integers(1, 3))
        if cursor[p] >= n:
            p = 3 - p
        k = int(rng.integers(1, 300))
        sl = slice(cursor[p], min(cursor[p] + k, n))
        cursor[p] = sl.stop
        while pulses and pulses[0] <= recording.stamps_ns[sl.stop - 1]:
            pipe.on_pulse(int(pulses.pop(0)))
            assert pipe.accounting().balanced()
        pipe.on_probe_block(p, recording.stamps_ns[sl], recording.probes_m[sl, 2 * p - 2:2 * p])
        assert pipe.accounting().balanced()
        pipe.process()
        assert pipe.accounting().balanced()
    pipe.flush()
    acc = pipe.accounting()
    assert acc.balanced() and acc.processed > 0.9 * n


def test_a_stalled_probe_plane_is_named_in_the_status(rig_file, recording):
    """Plane 2 stops publishing while plane 1 goes on: the status names plane 2 as stalled (before:
    'no sample filtered yet' or a plain 'not converged', naming no topic)."""
    pipe = EstimatorPipeline(rig_file.rig, rig_file.estimator, None, AlignmentConfig(), 0.05)
    rec = recording
    cut = len(rec) // 4
    for p in recording.pulse_stamps_ns:
        pipe.on_pulse(int(p))
    pipe.on_probe_block(1, rec.stamps_ns, rec.probes_m[:, :2])
    pipe.on_probe_block(2, rec.stamps_ns[:cut], rec.probes_m[:cut, 2:])
    pipe.process()
    behind_s = (rec.stamps_ns[-1] - rec.stamps_ns[cut - 1]) * 1e-9
    pipe.options = dataclasses.replace(pipe.options, plane_skew_s=behind_s / 2)
    status = pipe.status()
    assert status.level >= LEVEL_WARN and "probe plane 2 stalled" in status.message
