# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""``rotor-estimator bench speed``: our EKF against a filterpy EKF of the same model, same process.

Timings are reported as measured and as a ratio (speedup) of two runs in the same
process on the same samples, the figure that survives a shared, noisy machine.
"""
from __future__ import annotations

import time

import numpy as np

from rotor_estimator.core.config import load_rig_file
from rotor_estimator.core.ekf import StreamingEKF
from rotor_estimator.core.offline import shaft_inputs_from_recording
from rotor_estimator.core.simulator import paper_scenario, simulate
from rotor_estimator.bench.filterpy_baseline import run_filterpy
from rotor_estimator.bench.frontend import run as run_frontend


def run(n_filterpy_samples: int = 1500, repeats: int = 5, rig_path=None) -> dict:
    rig_file = load_rig_file(rig_path)
    rig, config = rig_file.rig, rig_file.estimator
    sim = simulate(rig, paper_scenario("imbalance+impact"), seed=7)
    rec = sim.recording
    shaft = shaft_inputs_from_recording(rec)
    t = rec.time_s()
    args = (t, rec.probes_m, shaft.angle_rad, shaft.speed_rad_s, shaft.accel_rad_s2, rec.impact_force_n)

    ekf = StreamingEKF(rig, config)
    ekf.process_block(*args)  # compile + warm up
    block_times = []
    for _ in range(repeats):
        ekf.reset()
        t0 = time.perf_counter()
        ekf.process_block(*args)
        block_times.append(time.perf_counter() - t0)
    us_block = 1e6 * min(block_times) / len(t)

    # per-sample API (one kernel call per sample, as a node with one message per sample does)
    n_step = min(len(t), 1000)
    ekf.reset()
    t0 = time.perf_counter()
    for k in range(n_step):
        ekf.step(t[k], rec.probes_m[k], shaft.angle_rad[k], shaft.speed_rad_s[k], shaft.accel_rad_s2[k],
                 rec.impact_force_n[k])
    us_step = 1e6 * (time.perf_counter() - t0) / n_step

    # filterpy baseline on the first n samples, from the same initial state
    n = min(n_filterpy_samples, len(t))
    ekf.reset()
    ekf.process_block(*(a[:1] for a in args))
    x0, p0 = ekf.x.copy(), ekf.P.copy()
    t0 = time.perf_counter()
    fp = run_filterpy(ekf.model, x0, p0, *(a[:n] for a in args))
    us_filterpy = 1e6 * (time.perf_counter() - t0) / (n - 1)
    ekf.reset()
    ekf.process_block(*(a[:n] for a in args))
    rel = np.abs(ekf.coefficients - fp.x.ravel()[8:]) / np.abs(rig.true_coefficients.as_array())
    return {
        **run_frontend(us_block),
        "us_per_sample": us_block,
        "us_per_sample_step_api": us_step,
        "filterpy_us_per_sample": us_filterpy,
        "speedup": us_filterpy / us_block,
        "samples_per_second": 1e6 / us_block,
        "realtime_factor_at_20khz": (1e6 / us_block) / 20000.0,
        "max_relative_difference_vs_filterpy": float(rel.max()),
        "samples_compared": n,
    }


def format_result(r: dict) -> str:
    return "\n".join([
        "EKF speed, 16 states, 4 probe channels (seed rig, imbalance+impact)",
        f"  rotor_estimator (block kernel): {r['us_per_sample']:8.2f} us/sample  "
        f"({r['samples_per_second']:,.0f} samples/s = {r['realtime_factor_at_20khz']:.1f}x real time at 20 kHz)",
        f"  rotor_estimator (step() API):   {r['us_per_sample_step_api']:8.2f} us/sample",
        f"  filterpy ExtendedKalmanFilter:  {r['filterpy_us_per_sample']:8.2f} us/sample",
        f"  speedup (same process, same samples): {r['speedup']:.1f}x",
        f"  estimates agree with filterpy to {r['max_relative_difference_vs_filterpy']:.1e} "
        f"(relative, after {r['samples_compared']} samples)",
        "Front end per sample (ratio to the EKF block kernel, same process):",
        *(f"  {name:26s} {r[name + '_us_per_sample']:8.3f} us/sample = {r[name + '_to_ekf_ratio']:.2f}x the EKF"
          for name in ("aligner", "tachometer_query", "probe_message_round_trip")),
    ])
