# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""``rotor-estimator bench identification``: every method on every scenario against the CRLB.

Each run simulates the scenario with the core simulator (its own noise seed), reads the
shaft angle, speed and acceleration back through the tachometer from the simulated
keyphasor pulses, and runs the EKF, the UKF, EKF + RTS and the batch ML fit, all from
the rig file's prior (r0 of the paper, 40% off). Over the runs: bias of the mean and
spread in units of the CRLB of the same samples (initial state unknown; imbalance
unknown where the scenario says so), and the mean run time.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from rotor_estimator.batch.runner import map_ordered
from rotor_estimator.core.config import COEFFICIENT_NAMES, load_rig_file
from rotor_estimator.core.errors import RotorEstimatorError
from rotor_estimator.core.simulator import Impact, Scenario, paper_scenario, simulate
from rotor_estimator.core.fisher import bound
from rotor_estimator.identification.information import design_information
from rotor_estimator.identification.methods import METHODS, identify
from rotor_estimator.identification.problem import CoefficientModel, RigArrays, record_from_recording
from rotor_estimator.identification.scenarios import design_from_scenario, simulate_design

RPM = 2.0 * np.pi / 60.0


@dataclass(frozen=True)
class BenchScenario:
    name: str
    scenario: Scenario
    unknown_imbalance: bool


def scenarios() -> tuple[BenchScenario, ...]:
    sweep: dict[str, Any] = dict(impacts=(), speed_start_rad_s=20000 * RPM, speed_end_rad_s=3000 * RPM,
                                 discard_initial_s=0.01)
    # the paper's 515 N, 50 us hit, alternating -y and -x, every 0.2 s from 40 ms
    five = tuple(Impact(0.04 + 0.2 * i, 50e-6, *((0.0, -515.0) if i % 2 == 0 else (-515.0, 0.0)))
                 for i in range(5))
    return (
        BenchScenario("seed imbalance+impact", paper_scenario("imbalance+impact"), False),
        BenchScenario("seed imbalance only", paper_scenario("imbalance"), False),
        BenchScenario("coast-down 0.5 s, imbalance known", Scenario(duration_s=0.5, name="cd0.5", **sweep), False),
        BenchScenario("coast-down 0.5 s, imbalance unknown", Scenario(duration_s=0.5, name="cd0.5", **sweep), True),
        BenchScenario("coast-down 2 s, imbalance known", Scenario(duration_s=2.0, name="cd2", **sweep), False),
        BenchScenario("coast-down 2 s, imbalance unknown", Scenario(duration_s=2.0, name="cd2", **sweep), True),
        BenchScenario("5 impacts x/y in 1 s", Scenario(duration_s=1.03, discard_initial_s=0.03, impacts=five,
                                                       name="5imp"), False),
    )


def scenario_crlb(rig_file, bs: BenchScenario) -> np.ndarray:
    rig = rig_file.rig
    arrays = RigArrays.build(rig)
    model = CoefficientModel()
    recs = simulate_design(rig, design_from_scenario(rig, bs.scenario), seed=None, arrays=arrays)
    fim = design_information(arrays, model, recs, rig.true_coefficients.as_array(),
                             estimate_imbalance=bs.unknown_imbalance, noise_std_m=rig.noise_std_m)
    return bound(fim, 8).std


def _one_run(args) -> dict:
    rig_path, bs, seed, methods = args
    rig_file = load_rig_file(rig_path)
    rig = rig_file.rig
    arrays = RigArrays.build(rig)
    sim = simulate(rig, bs.scenario, seed=seed)
    rec = record_from_recording(rig, sim.recording)
    out = {}
    for m in methods:
        t0 = time.perf_counter()
        try:
            res = identify(arrays, rig_file.estimator, rec, method=m, estimate_imbalance=bs.unknown_imbalance)
            theta = res.theta
        except (RotorEstimatorError, np.linalg.LinAlgError, FloatingPointError):
            theta = np.full(8, np.nan)
        out[m] = (theta, time.perf_counter() - t0)
    return out


@dataclass
class CellResult:
    scenario: str
    method: str
    true: np.ndarray
    estimates: np.ndarray   # (runs, 8), NaN rows for failures
    runtimes_s: np.ndarray
    crlb_std: np.ndarray

    @property
    def ok(self) -> np.ndarray:
        return np.all(np.isfinite(self.estimates), axis=1)

    @property
    def mean(self) -> np.ndarray:
        return self.estimates[self.ok].mean(axis=0) if self.ok.any() else np.full(8, np.nan)

    @property
    def std(self) -> np.ndarray:
        return self.estimates[self.ok].std(axis=0, ddof=1) if self.ok.sum() > 1 else np.full(8, np.nan)

    @property
    def bias_over_crlb(self) -> np.ndarray:
        return (self.mean - self.true) / self.crlb_std

    @property
    def std_over_crlb(self) -> np.ndarray:
        return self.std / self.crlb_std


def run(runs: int = 20, *, rig_path=None, methods: tuple[str, ...] = METHODS, jobs: int = 1, first_seed: int = 1,
        only: tuple[str, ...] = (), progress=None) -> list[CellResult]:
    rig_file = load_rig_file(rig_path)
    true = rig_file.rig.true_coefficients.as_array()
    chosen = [s for s in scenarios() if not only or any(o in s.name for o in only)]
    tasks = [(rig_path, bs, first_seed + i, methods) for bs in chosen for i in range(runs)]
    # jobs > 1: a local Dask cluster of single-thread processes (rotor_estimator.batch.runner); 1: here
    outs = map_ordered(_one_run, tasks, workers=jobs, progress=progress)
    cells = []
    for j, bs in enumerate(chosen):
        crlb = scenario_crlb(rig_file, bs)
        block = outs[j * runs:(j + 1) * runs]
        for m in methods:
            cells.append(CellResult(bs.name, m, true, np.array([o[m][0] for o in block]),
                                    np.array([o[m][1] for o in block]), crlb))
    return cells


def format_results(cells: list[CellResult]) -> str:
    lines = ["bias/CRLB and spread/CRLB per coefficient (kxx kxy kyx kyy cxx cxy cyx cyy); target: spread within "
             "1.3x the CRLB and |bias| under 0.3 of it. CRLB % = bound relative to the true value."]
    scen = None
    for c in cells:
        if c.scenario != scen:
            scen = c.scenario
            lines.append(f"\n== {scen}  ({len(c.estimates)} runs)   CRLB %: "
                         + " ".join(f"{100 * s / abs(t):.3g}" for s, t in zip(c.crlb_std, c.true)))
            lines.append(f"{'method':<10}{'quantity':<12}" + "".join(f"{n:>8}" for n in COEFFICIENT_NAMES)
                         + f"{'max':>8}{'time s':>9}{'fails':>6}")
        fails = int((~c.ok).sum())
        for q, v in (("bias/CRLB", c.bias_over_crlb), ("std/CRLB", c.std_over_crlb)):
            tail = f"{np.nanmax(np.abs(v)):>8.2f}" if np.isfinite(v).any() else f"{'nan':>8}"
            if q == "bias/CRLB":
                tail += f"{np.mean(c.runtimes_s):>9.3f}{fails:>6}"
            lines.append(f"{c.method:<10}{q:<12}" + "".join(f"{x:>8.2f}" for x in v) + tail)
    return "\n".join(lines)


def to_rows(cells: list[CellResult]) -> list[dict]:
    rows = []
    for c in cells:
        for i, n in enumerate(COEFFICIENT_NAMES):
            rows.append({"scenario": c.scenario, "method": c.method, "coefficient": n, "true": float(c.true[i]),
                         "mean": float(c.mean[i]), "std": float(c.std[i]), "crlb_std": float(c.crlb_std[i]),
                         "bias_over_crlb": float(c.bias_over_crlb[i]), "std_over_crlb": float(c.std_over_crlb[i]),
                         "runtime_s": float(np.mean(c.runtimes_s)), "runs": int(len(c.estimates)),
                         "failures": int((~c.ok).sum())})
    return rows
