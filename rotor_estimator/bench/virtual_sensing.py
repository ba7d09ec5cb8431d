# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Paper-scale virtual-sensing benchmark (Neisi et al. 2022: UKF, 150 states, 8 observations, 8192 samples)."""
from __future__ import annotations

import time
from typing import Any

import numpy as np

from rotor_estimator.core.flexible.description import load_rotor_description
from rotor_estimator.core.flexible.state_space import build_state_space, periodic_steady_state, simulate
from rotor_estimator.core.linear_filters import KalmanFilter, LinearGaussianModel, UnscentedKalmanFilter
from rotor_estimator.virtual_sensing.estimator import VirtualSensingConfig, leave_one_station_out

#: The paper-scale rotor of the benchmark (bundled description).
BENCH_ROTOR = "neisi_2022_like"


def bench_virtual_sensing(samples: int = 8192, seed: int = 0, alpha: float = 0.01, beta: float = 2.0,
                          kappa: float = 0.0) -> dict[str, Any]:
    """Paper-scale run: 75 modes (150 states), the 8 housing-accelerometer channels, UKF
    and KF timed on the same simulated data; then leave-one-station-out (KF) hiding each
    probe plane, with all other channels (probes and accelerometers) used together."""
    rotor = load_rotor_description(BENCH_ROTOR)
    ss = build_state_space(rotor, n_modes=75)
    sim = simulate(ss, samples, seed=seed)
    acc = [j for j, unit in enumerate(ss.channel_units) if unit == "m/s^2"]
    m = ss.model
    m8 = LinearGaussianModel(m.F, m.Q, m.H[acc], m.R[np.ix_(acc, acc)], m.B, None if m.D is None else m.D[acc])
    x0 = periodic_steady_state(ss)
    t0 = time.perf_counter()
    ukf = UnscentedKalmanFilter.from_linear(m8, x0, ss.P0, alpha, beta, kappa).run(sim.z[:, acc], sim.u)
    t_ukf = time.perf_counter() - t0
    t0 = time.perf_counter()
    kf = KalmanFilter(m8, x0, ss.P0).run(sim.z[:, acc], sim.u)
    t_kf = time.perf_counter() - t0
    probes = [s.name for s in rotor.sensors if s.kind == "probe"]
    report = leave_one_station_out(ss, sim.z, sim.u, VirtualSensingConfig(filter="kf"), hidden=probes,
                                   x_true=sim.x)
    rows = [r for r in report.rows if r.unit == "m"]
    return {
        "rotor": rotor.name, "n_states": ss.n_states, "n_observations": len(acc), "n_samples": samples,
        "ukf_alpha": alpha, "ukf_beta": beta, "ukf_kappa": kappa,
        "ukf_150_seconds": t_ukf, "ukf_ms_per_sample": 1e3 * t_ukf / samples,
        "kf_150_seconds": t_kf, "kf_ms_per_sample": 1e3 * t_kf / samples,
        "max_mean_difference_in_kf_sigmas": float(np.max(np.abs(ukf.x - kf.x) / np.sqrt(kf.P_diag))),
        "max_variance_relative_difference": float(np.max(np.abs(ukf.P_diag - kf.P_diag) / kf.P_diag)),
        "coverage_95": float(np.mean([r.coverage_measured for r in rows])),
        "coverage_95_true_state": float(np.mean([r.coverage_true for r in rows])),
        "interval_width_m": float(np.mean([r.mean_interval_width for r in rows])),
        "hidden_signal_rms_m": float(np.mean([r.signal_rms for r in rows])),
        "leave_one_station_out": report.to_dict(),
        "_table": report.format_table(),
    }
