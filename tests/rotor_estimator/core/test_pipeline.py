# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Properties of the node's logic on plain arrays (rotor_estimator.core.pipeline)."""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

import msg_adapters as ma
from rotor_estimator.core.alignment import AlignmentConfig
from rotor_estimator.ros.pipeline_io import feed_message
from rotor_estimator.core.pipeline import LEVEL_ERROR, EstimatorPipeline, PipelineOptions
from rotor_estimator.core.recording import RigRecording

DIRECT = [0, 3, 4, 7]


def make(rig_file, period_s: float = 0.01, **options) -> EstimatorPipeline:
    return EstimatorPipeline(rig_file.rig, rig_file.estimator, None, AlignmentConfig(), period_s,
                             options=PipelineOptions(**options) if options else None)


def feed(pipe: EstimatorPipeline, rec: RigRecording, block: int = 200, *, planes=None, pulses=None,
         order=None, arrival=None) -> list:
    """Feed a recording like a live stream: pulses up to each block's last stamp, then the
    block of each plane (``planes``: per-plane (stamps, xy) overrides), then impacts."""
    pulses = list(rec.pulse_stamps_ns if pulses is None else pulses)
    n = len(rec)
    planes = planes or {1: (rec.stamps_ns, rec.probes_m[:, :2]), 2: (rec.stamps_ns, rec.probes_m[:, 2:])}
    starts = list(range(0, n, block)) if order is None else order
    outs = []
    for i in starts:
        sl = slice(i, min(i + block, n))
        while pulses and pulses[0] <= rec.stamps_ns[sl][-1]:
            pipe.on_pulse(int(pulses.pop(0)))
        for p in (1, 2):
            pipe.on_probe_block(p, planes[p][0][sl], planes[p][1][sl],
                                None if arrival is None else arrival(i))
        nz = np.flatnonzero(np.any(rec.impact_force_n[sl] != 0, axis=1))
        if nz.size:
            pipe.on_impact_block(rec.stamps_ns[sl][nz], rec.impact_force_n[sl][nz])
        outs += pipe.process()
    for p in pulses:
        pipe.on_pulse(int(p))
    return outs + pipe.flush()


def rel_error(coef: np.ndarray, rig) -> np.ndarray:
    truth = rig.true_coefficients.as_array()
    return np.abs(coef - truth) / np.abs(truth)


def test_per_sample_and_block_inputs_give_identical_estimates(seed_rig_file, impact_sim):
    rec = impact_sim.recording
    a = feed(make(seed_rig_file), rec, 200)
    b = feed(make(seed_rig_file), rec, 1)
    assert [o.stamp_ns for o in a] == [o.stamp_ns for o in b]
    assert all(np.array_equal(x.coefficients, y.coefficients) and np.array_equal(x.covariance, y.covariance)
               for x, y in zip(a, b))


def test_converges_on_the_papers_data_within_generous_bounds(seed_rig_file, impact_sim):
    pipe = make(seed_rig_file)
    outs = feed(pipe, impact_sim.recording)
    final = outs[-1]
    err = rel_error(final.coefficients, seed_rig_file.rig)
    assert np.all(err[DIRECT] < 0.1), err
    assert np.all(err[[1, 2]] < 0.2), err
    assert final.diagnostics.converged and final.diagnostics.level == 0
    assert pipe.accounting().processed == len(impact_sim.recording)
    assert final.stamp_ns == impact_sim.recording.stamps_ns[-1]
    assert np.all(np.diff([o.stamp_ns for o in outs]) > 0)


def test_shuffled_duplicated_and_late_samples_are_counted_as_such(seed_rig_file, impact_sim):
    rec = impact_sim.recording
    reference = feed(make(seed_rig_file), rec, 100)[-1].coefficients
    # swap neighbouring 100-sample blocks (10 ms window > 5 ms blocks): reordered, same estimate
    order = list(range(0, len(rec), 100))
    for k in range(0, len(order) - 1, 2):
        order[k], order[k + 1] = order[k + 1], order[k]
    pipe = make(seed_rig_file)
    out = feed(pipe, rec, 100, order=order)
    acc = pipe.accounting()
    assert acc.reordered[1] > 0 and acc.reordered[2] > 0
    assert np.array_equal(out[-1].coefficients, reference)
    assert acc.processed == len(rec) and acc.balanced()

    pipe = make(seed_rig_file)
    pipe.on_pulse(int(rec.pulse_stamps_ns[0]))
    feed(pipe, RigRecording(rec.stamps_ns[:1000], rec.probes_m[:1000], rec.pulse_stamps_ns, rec.impact_force_n[:1000]))
    pipe.on_probe_block(1, rec.stamps_ns[990:1000], rec.probes_m[990:1000, :2])       # duplicates
    pipe.on_probe_block(2, rec.stamps_ns[1000:1010] - 500_000_000, rec.probes_m[1000:1010, 2:])  # late
    pipe.flush()
    acc = pipe.accounting()
    assert acc.aligner_rejected[1]["duplicate"] == 10
    assert acc.aligner_rejected[2]["late"] == 10
    assert acc.balanced()


def test_every_input_sample_is_processed_or_rejected_with_a_reason(seed_rig_file, impact_sim):
    rec = impact_sim.recording
    rng = np.random.default_rng(0)
    p1 = rec.probes_m[:, :2].copy()
    p2 = rec.probes_m[:, 2:].copy()
    p1[rng.choice(len(rec), 7, replace=False), 0] = np.nan
    p2[rng.choice(len(rec), 3, replace=False), 1] = np.inf
    spikes = rng.choice(np.arange(200, len(rec)), 5, replace=False)
    p1[spikes] += 5e-4
    keep2 = np.ones(len(rec), bool)
    keep2[rng.choice(len(rec), 11, replace=False)] = False               # plane-2 samples never sent
    pipe = make(seed_rig_file)
    stamps = rec.stamps_ns
    planes = {1: (stamps, p1), 2: (stamps, p2)}
    pulses = list(rec.pulse_stamps_ns)
    outs = []
    for i in range(0, len(rec), 200):
        sl = slice(i, i + 200)
        while pulses and pulses[0] <= stamps[sl][-1]:
            pipe.on_pulse(int(pulses.pop(0)))
        pipe.on_probe_block(1, *(a[sl] for a in planes[1]))
        m = keep2[sl]
        pipe.on_probe_block(2, stamps[sl][m], p2[sl][m])
        outs += pipe.process()
    outs += pipe.flush()
    acc = pipe.accounting()
    assert acc.balanced()
    assert acc.received[1] == len(rec) and acc.received[2] == keep2.sum()
    total = acc.processed + sum(acc.ekf_rejected.values()) + sum(acc.aligner_rejected[1].values())
    assert total == acc.received[1] and acc.pending[1] == 0
    assert acc.aligner_rejected[1]["non_finite"] >= 6 and acc.aligner_rejected[2]["non_finite"] >= 2
    assert acc.aligner_rejected[1]["unmatched"] >= 10
    assert acc.ekf_rejected["gated_outlier"] >= 4                     # the 0.5 mm spikes
    assert outs[-1].diagnostics.samples["rejected"] == sum(acc.rejected_by_reason().values())


def test_gaps_are_counted_and_filtered_across(seed_rig_file, impact_sim):
    rec = impact_sim.recording
    keep = np.ones(len(rec), bool)
    keep[700:800] = False                  # 5 ms gap: predicted across
    keep[1200:1800] = False                # 30 ms gap (> max_gap_s): motion states restart
    sub = RigRecording(rec.stamps_ns[keep], rec.probes_m[keep], rec.pulse_stamps_ns, rec.impact_force_n[keep])
    pipe = make(seed_rig_file)
    outs = feed(pipe, sub)
    acc = pipe.accounting()
    assert acc.missing == {1: 700, 2: 700}
    assert outs[-1].diagnostics.extra["motion_restarts"] == 1
    assert acc.processed == keep.sum() and acc.balanced()
    assert np.all(rel_error(outs[-1].coefficients, seed_rig_file.rig)[DIRECT] < 0.2)


def test_clock_jump_backwards_restarts_the_timeline_without_crashing(seed_rig_file, impact_sim):
    rec = impact_sim.recording
    jump = 5_000_000_000
    stamps = rec.stamps_ns.copy()
    stamps[1000:] -= jump
    pulses = rec.pulse_stamps_ns.copy()
    pulses[pulses >= rec.stamps_ns[1000]] -= jump
    pipe = make(seed_rig_file)
    for p in pulses[pulses < stamps[0]]:
        pipe.on_pulse(int(p))
    rest = list(pulses[pulses >= stamps[0]])
    outs = []
    for i in range(0, len(rec), 200):
        sl = slice(i, i + 200)
        while rest and (rest[0] <= stamps[sl][-1] or (i >= 1000 and rest[0] > rec.stamps_ns[999])):
            pipe.on_pulse(int(rest.pop(0)))
        pipe.on_probe_block(1, stamps[sl], rec.probes_m[sl, :2])
        pipe.on_probe_block(2, stamps[sl], rec.probes_m[sl, 2:])
        outs += pipe.process()
    outs += pipe.flush()
    acc = pipe.accounting()
    assert outs[-1].diagnostics.extra["clock_jumps"] == 1
    assert acc.balanced() and acc.pending == {1: 0, 2: 0}
    assert acc.processed > 1500                        # the new timeline is filtered after re-locking
    assert outs[-1].stamp_ns == stamps[-1]
    assert np.all(np.isfinite(outs[-1].coefficients))


def test_missing_and_jittery_pulses_still_track_the_shaft(seed_rig_file, impact_sim):
    rec = impact_sim.recording
    rng = np.random.default_rng(5)
    pulses = rec.pulse_stamps_ns.copy()
    pulses = np.delete(pulses, np.arange(12, pulses.size, 7))                     # every 7th missing
    pulses = pulses + rng.integers(-500, 500, pulses.size)                         # +-0.5 us jitter
    pipe = make(seed_rig_file)
    outs = feed(pipe, rec, pulses=pulses)
    assert pipe.tracker.counters["missed_pulses"] >= 3
    assert pipe.accounting().ekf_rejected["no_shaft_reference"] == 0
    assert np.all(rel_error(outs[-1].coefficients, seed_rig_file.rig)[DIRECT] < 0.1)


def test_no_pulses_or_zero_speed_rejects_samples_as_no_shaft_reference(seed_rig_file, impact_sim):
    rec = impact_sim.recording
    pipe = make(seed_rig_file)
    outs = feed(pipe, rec, pulses=[])
    acc = pipe.accounting()
    assert acc.ekf_rejected["no_shaft_reference"] == len(rec) and acc.processed == 0 and acc.balanced()
    assert "no shaft reference" in outs[-1].diagnostics.message and outs[-1].diagnostics.level >= 1
    slow = rec.stamps_ns[0] - 1_000_000_000 + np.arange(4) * 900_000_000           # 1.1 rad/s: "stopped"
    pipe = make(seed_rig_file)
    feed(pipe, rec, pulses=slow)
    assert pipe.accounting().ekf_rejected["no_shaft_reference"] == len(rec)


def test_keyphasor_delivered_behind_the_probes_is_waited_for_not_rejected(seed_rig_file, impact_sim):
    """Live (wall clock given): pulses reach the pipeline 30 ms (3x shaft_wait_s) behind the
    probes and keep arriving after the probes stop (a loaded node takes one message per topic
    per executor round). While pulses arrive, the idle wall-clock release waits for them:
    every sample gets its shaft reference, as when the pulses come first."""
    rec = impact_sim.recording
    lag_ns, block = 30_000_000, 100
    pipe = make(seed_rig_file, shaft_wait_s=0.01)
    pulses = [int(p) for p in rec.pulse_stamps_ns]
    now = 0
    for i in range(0, len(rec), block):
        sl = slice(i, min(i + block, len(rec)))
        now = int(rec.stamps_ns[sl][-1])                  # zero transport delay for the probes
        while pulses and pulses[0] <= now - lag_ns:
            pipe.on_pulse(pulses.pop(0), now)
        for p in (1, 2):
            pipe.on_probe_block(p, rec.stamps_ns[sl], rec.probes_m[sl, 2 * p - 2:2 * p], now)
        pipe.on_impact_block(rec.stamps_ns[sl], rec.impact_force_n[sl])
        pipe.process()
    assert len(pulses) >= 5                               # the test needs pulses after the probes
    while pulses:                                         # probes idle, pulses one per ms of wall time
        now += 1_000_000
        pipe.on_pulse(pulses.pop(0), now)
        pipe.process(now)
    pipe.flush()
    acc = pipe.accounting()
    in_time = make(seed_rig_file, shaft_wait_s=0.01)
    feed(in_time, rec)                                    # pulses delivered ahead of the probes
    assert acc.ekf_rejected["no_shaft_reference"] == 0 and acc.balanced()
    assert acc.processed == in_time.accounting().processed
    # once pulses stop arriving, the wall clock decides the samples still waiting (as before)
    pipe = make(seed_rig_file, shaft_wait_s=0.01)
    for p in (1, 2):
        pipe.on_probe_block(p, rec.stamps_ns, rec.probes_m[:, 2 * p - 2:2 * p], int(rec.stamps_ns[-1]))
    pipe.on_pulse(int(rec.pulse_stamps_ns[0]), int(rec.stamps_ns[-1]))
    pipe.process(int(rec.stamps_ns[-1]) + 100_000_000)
    acc = pipe.accounting()                               # all but the aligner's held-back newest sample
    assert acc.processed + acc.ekf_rejected["no_shaft_reference"] == len(rec) - 1


def test_wrong_message_type_or_layout_is_counted_never_raised(seed_rig_file):
    pipe = make(seed_rig_file)
    fac = ma.TypestoreFactory()
    assert not feed_message(pipe, "probe1", ma.pulse_to_msg(fac, 1000))
    bad_cloud = ma.cloud_from_columns(fac, 1000, "probe1", [("fx_n", 8, np.zeros(3)), ("fy_n", 8, np.zeros(3)),
                                                            ("t_offset_ns", 6, np.zeros(3, np.uint32))])
    assert not feed_message(pipe, "probe2", bad_cloud)
    assert not feed_message(pipe, "keyphasor", ma.probe_sample_to_msg(fac, 5, 0.0, 0.0, frame_id="x"))
    assert not feed_message(pipe, "impact", object())
    acc = pipe.accounting()
    assert acc.bad_messages == {"probe1": {"wrong_type": 1}, "probe2": {"undecodable": 1},
                                "keyphasor": {"wrong_type": 1}, "impact": {"wrong_type": 1}}
    status = pipe.status()
    assert status.level >= 1 and "wrong type" in status.message


def test_divergence_is_reported_and_recovered(seed_rig_file, impact_sim):
    rec = impact_sim.recording
    probes = rec.probes_m.copy()
    probes[1000:1500] += 3e-4                      # a sustained 0.3 mm step: every update gated
    bad = RigRecording(rec.stamps_ns, probes, rec.pulse_stamps_ns, rec.impact_force_n)
    pipe = make(seed_rig_file)
    outs = feed(pipe, bad)
    assert pipe.divergence_recoveries >= 1
    errors = [o for o in outs if o.diagnostics.level == LEVEL_ERROR]
    assert errors and "diverged" in errors[0].diagnostics.message
    assert pipe.accounting().ekf_rejected["gated_outlier"] >= 400
    assert np.all(np.isfinite(outs[-1].coefficients)) and outs[-1].diagnostics.level < LEVEL_ERROR
    assert np.all(rel_error(outs[-1].coefficients, seed_rig_file.rig)[[0, 3]] < 0.3)


def test_falling_behind_is_reported_when_input_is_handled_late(seed_rig_file, impact_sim):
    rec = impact_sim.recording
    pipe = make(seed_rig_file, falling_behind_s=0.05)
    # each block is handled 20 ms later than the one before (relative to its stamps)
    outs = feed(pipe, rec, arrival=lambda i: int(rec.stamps_ns[min(i + 199, len(rec) - 1)]) + i * 100_000)
    statuses = [o.diagnostics for o in outs]
    assert any(s.falling_behind for s in statuses) and statuses[-1].extra["falling_behind_events"] == 1
    assert any("falling behind" in s.message for s in statuses)


def test_reset_restarts_the_estimation_and_keeps_the_accounting(seed_rig_file, impact_sim):
    rec = impact_sim.recording
    pipe = make(seed_rig_file)
    half = RigRecording(rec.stamps_ns[:950], rec.probes_m[:950], rec.pulse_stamps_ns, rec.impact_force_n[:950])
    feed(pipe, half)
    pipe.reset()
    np.testing.assert_array_equal(pipe.ekf.coefficients, seed_rig_file.estimator.initial_coefficients.as_array())
    assert pipe.accounting().received[1] == 950 and pipe.accounting().balanced()


def test_pipeline_core_imports_neither_rclpy_nor_rosbags():
    code = ("import sys, rotor_estimator.core.pipeline; "
            "bad = [m for m in ('rclpy', 'rosbags') if m in sys.modules]; assert not bad, bad")
    subprocess.run([sys.executable, "-c", code], check=True, cwd=str(__import__("pathlib").Path(__file__)
                                                                     .resolve().parents[3]))


@pytest.mark.parametrize("field,value", [("max_gap_s", 0.0), ("clock_jump_s", float("nan"))])
def test_options_errors_name_the_bad_field(field, value):
    from rotor_estimator.core.errors import ConfigError

    with pytest.raises(ConfigError, match=field):
        PipelineOptions(**{field: value})


def test_identifiability_flags_imbalance_only_stiffness_and_clears_the_impact_case(seed_rig_file, impact_sim):
    """Every output carries an identifiability report; imbalance-only data leave stiffness not determined."""
    from rotor_estimator.core.identifiability import NOT_DETERMINED
    from rotor_estimator.core.simulator import paper_scenario, simulate

    impact_final = feed(make(seed_rig_file), impact_sim.recording)[-1].identifiability
    assert impact_final.names_with(NOT_DETERMINED) == []
    starved = simulate(seed_rig_file.rig, paper_scenario("imbalance"), seed=3).recording
    starved_final = feed(make(seed_rig_file), starved)[-1].identifiability
    assert {"kxx", "kxy", "kyx", "kyy", "cxy", "cyx"} <= set(starved_final.names_with(NOT_DETERMINED))
    assert all(e.value_for_display is None for e in starved_final.entries if e.status == NOT_DETERMINED)
