# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Reproduction of Miller & Howard's Table 3 (and the imbalance-only case), with the CRLB.

Each run simulates the paper's protocol with its own noise seed, tracks the shaft
angle from the simulated keyphasor pulses, runs the EKF (``passes`` passes, the
paper's multi-pass use) and keeps the final coefficients and the filter's own
standard deviation. Over the runs we report the mean, the % error of the mean, the
spread (% std), the Cramér-Rao bound of the same samples (:mod:`rotor_estimator.core.crlb`),
the bias and spread in units of that bound, and the filter's consistency (mean
reported std divided by the actual spread: 1 is honest).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from rotor_estimator.core.config import COEFFICIENT_NAMES, COEFFICIENT_UNITS, RigFile
from rotor_estimator.core.crlb import bound_from_fisher, fisher_information
from rotor_estimator.core.ekf import FilterModel
from rotor_estimator.core.offline import estimate, shaft_inputs_from_recording
from rotor_estimator.core.simulator import paper_scenario, simulate

#: Miller & Howard's Table 3 (imbalance + impact, 20 runs): mean, std, % error, % std.
PAPER_TABLE3 = {
    "cxx": (1095.0, 9.2, -0.455, 0.840),
    "cxy": (39.6, 9.3, -20.8, 18.6),
    "cyx": (-73.4, 11.2, 83.5, 28.0),
    "cyy": (1208.3, 13.5, 0.692, 1.13),
    "kxx": (520094.0, 21644.0, 4.02, 4.33),
    "kxy": (388402.0, 20732.0, -2.90, 5.18),
    "kyx": (-311207.0, 21843.0, -11.1, 7.28),
    "kyy": (533420.0, 21110.0, -11.1, 3.52),
}
CASES = ("imbalance+impact", "imbalance")


@dataclass
class CaseResult:
    """All runs of one case."""

    case: str
    true: np.ndarray
    estimates: np.ndarray       # (runs, 8)
    reported_std: np.ndarray    # (runs, 8)
    crlb_std: np.ndarray        # (8,)
    nis_mean: np.ndarray        # (runs,)
    example: dict = field(default_factory=dict)  # one run's history for the figures

    @property
    def mean(self) -> np.ndarray:
        return self.estimates.mean(axis=0)

    @property
    def std(self) -> np.ndarray:
        return self.estimates.std(axis=0, ddof=1) if len(self.estimates) > 1 else np.full(8, np.nan)

    @property
    def bias_over_crlb(self) -> np.ndarray:
        return (self.mean - self.true) / self.crlb_std

    @property
    def spread_over_crlb(self) -> np.ndarray:
        return self.std / self.crlb_std

    @property
    def consistency(self) -> np.ndarray:
        """Mean filter-reported std over the actual spread (1 = the published covariance is honest)."""
        return self.reported_std.mean(axis=0) / self.std

    def identifiable(self) -> np.ndarray:
        """Not "not determined" by the identifiability rule (CRLB within 25 % of the coefficient's
        scale; :mod:`rotor_estimator.core.identifiability`), judged at the true values."""
        from rotor_estimator.core.identifiability import NOT_DETERMINED, report_from_std

        report = report_from_std(self.crlb_std, self.true)
        return np.array([e.status != NOT_DETERMINED for e in report.entries])


def case_crlb(rig_file: RigFile, case: str) -> np.ndarray:
    """CRLB std of the coefficients for the samples of ``case`` (noise-free trajectory, unknown initial state)."""
    rig = rig_file.rig
    sim = simulate(rig, paper_scenario(case), seed=None)
    rec = sim.recording
    model = FilterModel.build(rig, rig_file.estimator)
    t = rec.time_s()
    x0 = np.concatenate([sim.bearing_velocity_m_s[0], sim.bearing_displacement_m[0], sim.coefficients])
    fim = fisher_information(model, x0, t, sim.angle_rad, sim.speed_rad_s, np.zeros_like(t), rec.impact_force_n)
    return bound_from_fisher(fim, len(t)).coefficient_std


def reproduce_run(task: tuple[RigFile, str, int, bool]) -> dict:
    """One Monte Carlo run of ``case`` with noise ``seed``: the final coefficients, the filter's std,
    the mean NIS (and, ``keep_example``, the history and recording for the figures)."""
    rig_file, case, seed, keep_example = task
    rig, config = rig_file.rig, rig_file.estimator
    sim = simulate(rig, paper_scenario(case), seed=seed)
    shaft = shaft_inputs_from_recording(sim.recording)
    history_every = 10 if keep_example else 0
    est = estimate(sim.recording, rig, config, shaft=shaft, history_every=history_every)
    example: dict = {}
    if history_every:
        example = {"t_s": est.history_t_s[0], "coefficients": est.history_coefficients[0],
                   "recording": sim.recording, "estimate": est.coefficients}
    return {"coefficients": est.coefficients, "std": est.std, "nis": float(np.nanmean(est.last_pass.nis)),
            "example": example}


def run_case(rig_file: RigFile, case: str, runs: int, *, first_seed: int = 1,
             progress: Callable[[int], None] | None = None, keep_example: bool = False, workers: int = 1,
             scheduler: str | None = None) -> CaseResult:
    """``runs`` seeded runs of ``case``: in this process (``workers`` 1), or on a local Dask cluster of
    ``workers`` single-thread processes or the cluster at ``scheduler`` (:mod:`rotor_estimator.batch.runner`);
    the same numbers either way."""
    from rotor_estimator.batch.runner import map_ordered

    rig = rig_file.rig
    if rig.true_coefficients is None:
        raise ValueError("the rig file has no true_coefficients: the reproduction needs them to simulate")
    true = rig.true_coefficients.as_array()
    tasks = [(rig_file, case, first_seed + i, keep_example and i == 0) for i in range(runs)]
    outs = map_ordered(reproduce_run, tasks, workers=workers, scheduler=scheduler, progress=progress)
    example = outs[0]["example"] if outs else {}
    return CaseResult(case=case, true=true, estimates=np.array([o["coefficients"] for o in outs]),
                      reported_std=np.array([o["std"] for o in outs]), crlb_std=case_crlb(rig_file, case),
                      nis_mean=np.array([o["nis"] for o in outs]), example=example)


def format_table(result: CaseResult) -> str:
    """Table 3 side by side: exact, paper (mean, % err, % std), ours (mean, % err, % std), CRLB."""
    lines = [f"Case: {result.case}  ({len(result.estimates)} runs; CRLB from the same samples, initial state unknown)"]
    head = (f"{'coef':<5}{'unit':>7}{'exact':>12} | {'paper mean':>11}{'%err':>8}{'%std':>7} | "
            f"{'our mean':>11}{'%err':>8}{'%std':>7} | {'CRLB %':>8}{'bias/CRLB':>10}{'std/CRLB':>9}"
            f"{'rep/std':>8}")
    lines += [head, "-" * len(head)]
    ident = result.identifiable()
    for i, (name, unit) in enumerate(zip(COEFFICIENT_NAMES, COEFFICIENT_UNITS)):
        true = result.true[i]
        scale = abs(true)
        mean, std = result.mean[i], result.std[i]
        if result.case == "imbalance+impact":
            pm, _ps, pe, pstd = PAPER_TABLE3[name]
            paper = f"{pm:>11.6g}{pe:>8.3g}{pstd:>7.3g}"
        else:
            paper = f"{'(failed)':>11}{'':>8}{'':>7}"
        crlb_pct = 100 * result.crlb_std[i] / scale
        flag = "" if ident[i] else "  NOT DETERMINED by these data"
        lines.append(
            f"{name:<5}{unit:>7}{true:>12.6g} | {paper} | {mean:>11.6g}{100 * (mean - true) / scale:>8.3g}"
            f"{100 * std / scale:>7.3g} | {crlb_pct:>8.3g}{result.bias_over_crlb[i]:>10.2f}"
            f"{result.spread_over_crlb[i]:>9.2f}{result.consistency[i]:>8.2f}{flag}")
    lines.append(f"mean NIS over runs: {np.mean(result.nis_mean):.3f} (4 probe channels: 4 is consistent)")
    if not ident.all():
        names = ", ".join(n for n, ok in zip(COEFFICIENT_NAMES, ident) if not ok)
        lines.append(f"WARNING: {names}: the CRLB exceeds 25% of the coefficient's scale; these data cannot pin "
                     "them down, whatever the estimator. Use a coast-down/run-up or impacts "
                     "(see `rotor-estimator plan`).")
    return "\n".join(lines)


def to_json_rows(result: CaseResult) -> list[dict]:
    """Machine-readable rows: case, coefficient, true, mean, std, crlb_std (+ diagnostics)."""
    rows = []
    for i, name in enumerate(COEFFICIENT_NAMES):
        rows.append({
            "case": result.case, "coefficient": name, "true": float(result.true[i]),
            "mean": float(result.mean[i]), "std": float(result.std[i]), "crlb_std": float(result.crlb_std[i]),
            "bias_over_crlb": float(result.bias_over_crlb[i]), "std_over_crlb": float(result.spread_over_crlb[i]),
            "reported_std_over_std": float(result.consistency[i]), "identifiable": bool(result.identifiable()[i]),
            "runs": int(len(result.estimates)),
        })
    return rows
