# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Virtual sensing: calibrated intervals on model-consistent data, honest flags otherwise, CLI."""
from __future__ import annotations

import argparse
import json
import math
from dataclasses import replace

import numpy as np
import pytest

from rotor_estimator.core.flexible import build_state_space, load_rotor_description, simulate, station_outputs
from rotor_estimator.virtual_sensing.estimator import (VirtualSensingConfig, confidence_ellipse, estimate_stations,
                                             leave_one_station_out)
from rotor_estimator.cli.bench import add_virtual_sensing_bench
from rotor_estimator.cli.virtual_sensing import add_parser


@pytest.fixture(scope="module")
def rig():
    ss = build_state_space(load_rotor_description("three_probe_rig"))
    return ss, simulate(ss, 4096, seed=11)


def test_coverage_on_model_consistent_data_is_near_95_percent(rig):
    ss, sim = rig
    report = leave_one_station_out(ss, sim.z, sim.u, VirtualSensingConfig(), x_true=sim.x)
    assert len(report.rows) == 6
    for row in report.rows:
        assert abs(row.coverage_measured - 0.95) < 0.03, row
        assert abs(row.coverage_true - 0.95) < 0.04, row
        assert row.calibrated
        # the estimate knows more than the prior: interval narrower than the signal's own +-1.96 std
        assert row.mean_state_interval_width < 2 * 1.96 * row.signal_rms
    assert abs(report.summary("m")["coverage"] - 0.95) < 0.015


def test_ukf_leave_one_out_equals_kalman_filter_on_flexible_model(rig):
    ss, sim = rig
    kf = leave_one_station_out(ss, sim.z[:800], sim.u[:800], VirtualSensingConfig(filter="kf"), hidden=["probe2"])
    ukf = leave_one_station_out(ss, sim.z[:800], sim.u[:800],
                                VirtualSensingConfig(filter="ukf", ukf_alpha=0.01), hidden=["probe2"])
    ekf = leave_one_station_out(ss, sim.z[:800], sim.u[:800], VirtualSensingConfig(filter="ekf"), hidden=["probe2"])
    for a, b, c in zip(kf.rows, ukf.rows, ekf.rows):
        assert b.rms_error == pytest.approx(a.rms_error, rel=1e-7)
        assert c.rms_error == pytest.approx(a.rms_error, rel=1e-7)
        assert a.mean_interval_width == pytest.approx(b.mean_interval_width, rel=1e-7)


def test_probes_and_housing_accelerometers_together_give_calibrated_coverage():
    """Mixed sensors on a pedestal (Neisi et al.'s Fig. 9 layout): hide a housing
    accelerometer pair and a probe plane in turn, estimate each from all the others."""
    ss = build_state_space(load_rotor_description("neisi_2022_like"))
    assert set(ss.channel_units) == {"m", "m/s^2"}
    sim = simulate(ss, 3000, seed=5)
    report = leave_one_station_out(ss, sim.z, sim.u, VirtualSensingConfig(), hidden=["acc1", "probe3"],
                                   x_true=sim.x)
    assert [r.unit for r in report.rows] == ["m/s^2", "m/s^2", "m", "m"]
    for row in report.rows:
        assert abs(row.coverage_measured - 0.95) < 0.03, row


def test_virtual_station_intervals_cover_the_true_motion_95_percent(rig):
    """The point of virtual sensing: at stations with no sensor (disks, mid-span) the
    noise-free truth lies inside the 95% interval about 95% of the time."""
    ss, sim = rig
    estimates = estimate_stations(ss, sim.t, sim.z, sim.u)
    assert [e.name for e in estimates] == ["disk1", "midspan", "disk2"]
    for e in estimates:
        C, D, _ = station_outputs(ss, e.station_axial_m)
        truth = sim.x @ C.T + sim.u @ D.T
        inside = np.abs(truth - e.mean) <= e.half_width
        assert np.all(np.abs(inside.mean(axis=0) - 0.95) < 0.04), (e.name, inside.mean(axis=0))
        a, b, _ = e.ellipse(100)
        assert a >= b > 0


def test_underestimated_process_noise_is_reported_as_low_coverage():
    """Data with 4x the filter's unknown forcing: coverage falls and the rows are flagged."""
    rotor = load_rotor_description("three_probe_rig")
    loud = replace(rotor, options=replace(rotor.options, process_noise_force_N_sqrt_s=0.2))
    sim = simulate(build_state_space(loud), 2048, seed=3)
    report = leave_one_station_out(build_state_space(rotor), sim.z, sim.u, VirtualSensingConfig())
    assert max(r.coverage_measured for r in report.rows) < 0.85
    assert not any(r.calibrated for r in report.rows)
    assert "NO" in report.format_table()


def test_overstated_sensor_noise_gives_wide_intervals_that_the_report_shows():
    """An R 20x too large puts nearly every sample 'inside' - the width/rms column gives it away."""
    rotor = load_rotor_description("three_probe_rig")
    ss = build_state_space(rotor)
    sim = simulate(ss, 2048, seed=4)
    noisy = replace(rotor, sensors=tuple(replace(s, noise_std=20 * s.noise_std) for s in rotor.sensors))
    report = leave_one_station_out(build_state_space(noisy), sim.z, sim.u, VirtualSensingConfig())
    honest = leave_one_station_out(ss, sim.z, sim.u, VirtualSensingConfig())
    for bad, good in zip(report.rows, honest.rows):
        assert bad.coverage_measured > 0.99 and not bad.calibrated
        assert bad.mean_interval_width > 5 * good.mean_interval_width
        assert bad.width_to_signal_rms > 5


def test_confidence_ellipse_of_isotropic_covariance_is_circle_with_chi2_radius():
    a, b, _ = confidence_ellipse(np.eye(2) * 4.0, 0.95)
    assert a == pytest.approx(2.0 * math.sqrt(5.991464547), rel=1e-6) and b == pytest.approx(a)
    a, b, angle = confidence_ellipse(np.diag([1.0, 9.0]), 0.95)
    assert a == pytest.approx(3 * b) and abs(math.cos(angle)) < 1e-12


def test_config_errors_name_the_field():
    from rotor_estimator.core.errors import ConfigError
    with pytest.raises(ConfigError, match="virtual_sensing.filter"):
        VirtualSensingConfig(filter="pf")
    with pytest.raises(ConfigError, match="virtual_sensing.ukf_alpha"):
        VirtualSensingConfig(ukf_alpha=0.0)


def _parser():
    parser = argparse.ArgumentParser(prog="rotor-estimator")
    sub = parser.add_subparsers(dest="command", required=True)
    add_parser(sub)
    add_virtual_sensing_bench(sub.add_parser("bench").add_subparsers(dest="bench_command", required=True))
    return parser


def test_cli_virtual_sensing_prints_json_table(capsys):
    args = _parser().parse_args(["virtual-sensing", "--samples", "600", "--json", "--hide", "probe1"])
    assert args.func(args) == 0
    out = json.loads(capsys.readouterr().out)
    assert [c["channel"] for c in out["channels"]] == ["probe1_x", "probe1_y"]
    assert {"coverage_measured", "mean_interval_width", "rms_error"} <= set(out["channels"][0])


def test_cli_virtual_sensing_reads_npz_and_writes_station_estimates(tmp_path, capsys, rig):
    ss, sim = rig
    data = {"t": sim.t[:1000]}
    for j, name in enumerate(ss.channel_names):
        data[name] = sim.z[:1000, j]
    data["probe3_y"][10:20] = np.nan  # dropouts are rejected and counted
    np.savez(tmp_path / "run.npz", **data)
    out_path = tmp_path / "est.npz"
    args = _parser().parse_args(["virtual-sensing", "--data", str(tmp_path / "run.npz"),
                                 "--estimates-out", str(out_path)])
    assert args.func(args) == 0
    text = capsys.readouterr().out
    assert "probe2_y" in text and "rejected: 10" in text
    est = np.load(out_path)
    assert est["disk1_displacement_x"].shape == (1000,) and "midspan_ellipse_semi_major_m" in est.files


def test_cli_reports_bad_input_with_exit_code_2(tmp_path, capsys):
    np.savez(tmp_path / "bad.npz", time=np.arange(10.0))
    args = _parser().parse_args(["virtual-sensing", "--data", str(tmp_path / "bad.npz")])
    assert args.func(args) == 2
    assert "needs an array 't'" in capsys.readouterr().err


# --------------------------------------------------------------------------- streaming pipeline
def _stamped(ss, sim, t0_ns=1_700_000_000_000_000_000):
    stamps = t0_ns + np.rint(sim.t * 1e9).astype(np.int64)
    period = 2 * np.pi / ss.rotor.speed_rad_s * 1e9
    pulses = t0_ns + np.rint(np.arange(int(sim.t[-1] * 1e9 / period) + 2) * period).astype(np.int64)
    return stamps, pulses


def _feed(pipe, ss, stamps, z, block=50, seed=0, keep=None):
    rng = np.random.default_rng(seed)
    outs = []
    for i in range(0, len(stamps), block):
        for j in rng.permutation(len(ss.rotor.sensors)):  # sensors arrive in any order
            sel = np.arange(i, min(i + block, len(stamps)))
            if keep is not None:
                sel = sel[keep[sel]]
            pipe.on_block(ss.rotor.sensors[j].name, stamps[sel], z[sel, 2 * j:2 * j + 2])
        outs += pipe.process()
    return outs + pipe.process(flush=True)


def test_live_pipeline_on_shuffled_blocks_equals_offline_estimate_stations(rig):
    """Same code path: the streaming pipeline (alignment, causal keyphasor fit, per-sample
    step) gives the offline estimates; the only difference is the shaft angle's fit."""
    from rotor_estimator.virtual_sensing.stream import VirtualSensingPipeline
    ss, sim = rig
    stamps, pulses = _stamped(ss, sim)
    pipe = VirtualSensingPipeline(ss)
    for p in pulses:
        pipe.on_pulse(int(p))
    outs = _feed(pipe, ss, stamps[:600], sim.z[:600])
    assert [o.stamp_ns for o in outs] == stamps[:600].tolist()
    for i, e in enumerate(estimate_stations(ss, sim.t[:600], sim.z[:600], sim.u[:600])):
        mean = np.array([o.mean[i] for o in outs])
        std = np.array([o.std[i] for o in outs])
        assert np.max(np.abs(mean - e.mean) / e.std) < 1e-4
        np.testing.assert_allclose(std, e.std, rtol=1e-9)
    st = pipe.status()
    assert st.level == 0 and abs(pipe.nis_coverage - 0.95) < 0.04, st


def test_pipeline_predicts_over_missing_samples_and_drops_late_ones(rig):
    from rotor_estimator.virtual_sensing.stream import PipelineOptions, VirtualSensingPipeline
    ss, sim = rig
    stamps, pulses = _stamped(ss, sim)
    keep = np.ones(len(stamps), bool)
    keep[100:104] = False
    pipe = VirtualSensingPipeline(ss, options=PipelineOptions(publish_rate_hz=256.0))
    for p in pulses:
        pipe.on_pulse(int(p))
    outs = _feed(pipe, ss, stamps[:400], sim.z[:400], keep=keep)
    assert pipe.counters["samples_predicted_over"] == 4 and pipe.counters["samples_filtered"] == 396
    assert [o.stamp_ns for o in outs][:3] == stamps[[0, 8, 16]].tolist()  # 2048 Hz decimated to 256 Hz
    pipe.on_block("probe1", stamps[50:60], sim.z[50:60, :2])
    assert pipe.aligner.counters["late_probe1"] == 10 and pipe.status().level == 1


def test_samples_before_any_keyphasor_pulse_are_dropped_and_counted(rig):
    from rotor_estimator.virtual_sensing.stream import VirtualSensingPipeline
    ss, sim = rig
    stamps, pulses = _stamped(ss, sim)
    pipe = VirtualSensingPipeline(ss)
    outs = _feed(pipe, ss, stamps[:100], sim.z[:100])
    assert outs == [] and pipe.counters["no_shaft_angle"] == 100
    assert "waiting" in pipe.status().message


def test_sensor_aligner_counts_duplicates_and_missing_sensors():
    from rotor_estimator.virtual_sensing.stream import SensorAligner
    al = SensorAligner(["a", "b"], period_ns=1000.0, reorder_window_ns=5000)
    al.add_block("a", np.arange(0, 10_000, 1000), np.zeros((10, 2)))
    al.add_block("a", np.array([3000]), np.ones((1, 2)))  # duplicate: the first copy wins
    al.add_block("b", np.arange(0, 10_000, 1000)[::2] + 100, np.ones((5, 2)))  # within tolerance
    out = al.pop_ready()
    assert out.stamps_ns.tolist() == [0, 1000, 2000, 3000, 4000]  # 9000 - 5000 is the horizon
    assert out.present[:, 1].tolist() == [True, False, True, False, True]
    assert al.counters["duplicate_a"] == 1 and al.counters["missing_b"] == 2
    assert np.all(out.values[:, 0] == 0.0)


def test_sensor_aligner_is_the_core_aligner_with_optional_sensors_and_keeps_its_counters():
    """The virtual-sensing aligner is the core StreamAligner (one implementation); its
    counters keep the names and order /diagnostics prints, and every sample received is
    released, late, duplicate or pending (NaN values pass to the filter)."""
    from rotor_estimator.core.alignment import StreamAligner
    from rotor_estimator.virtual_sensing.stream import SensorAligner
    al = SensorAligner(["a", "b"], period_ns=1000.0, reorder_window_ns=3000)
    assert isinstance(al.queue, StreamAligner)
    assert list(al.counters) == ["released", "received_a", "received_b", "late_a", "late_b", "duplicate_a",
                                 "duplicate_b", "missing_a", "missing_b"]
    al.add_block("a", np.arange(0, 8000, 1000), np.full((8, 2), np.nan))
    al.add_block("b", np.array([0, 1000, 1000]), np.ones((3, 2)))
    first = al.pop_ready()
    assert first.stamps_ns.tolist() == [0, 1000, 2000, 3000, 4000] and np.isnan(first.values[:, 0]).all()
    al.add_block("b", np.array([4000, 6000]), np.ones((2, 2)))           # 4000 was released: late
    al.pop_ready(flush=True)
    c = al.counters
    assert (c["late_b"], c["duplicate_b"], c["missing_b"], c["released"]) == (1, 1, 5, 8)
    assert c["received_b"] == 5 == 3 + c["late_b"] + c["duplicate_b"] and al.pending == 0


def test_sensor_aligner_output_does_not_depend_on_arrival_order():
    """Sensors with skewed stamps (within the tolerance) arriving within the reorder window give
    the same samples, stamped by the first sensor in rotor-file order, whichever block arrives
    first (the old first-arrival rule stamped them by the first block to arrive)."""
    from rotor_estimator.virtual_sensing.stream import SensorAligner
    t = np.arange(0, 20_000, 1000)
    blocks = {"a": (t + 100, np.zeros((20, 2))), "b": (t, np.ones((20, 2))), "c": (t - 100, np.full((20, 2), 2.0))}
    outs = []
    for order in (("a", "b", "c"), ("c", "b", "a"), ("b", "c", "a")):
        al = SensorAligner(["a", "b", "c"], period_ns=1000.0, reorder_window_ns=50_000)   # all in time
        parts = []
        for name in order:
            al.add_block(name, *blocks[name])
            parts.append(al.pop_ready())
        parts.append(al.pop_ready(flush=True))
        outs.append((np.concatenate([p.stamps_ns for p in parts]), np.concatenate([p.values for p in parts])))
    for stamps, values in outs:
        assert stamps.tolist() == (t + 100).tolist()
        assert np.array_equal(values, outs[0][1]) and np.array_equal(values[:, :, 0], [[0.0, 1.0, 2.0]] * 20)
