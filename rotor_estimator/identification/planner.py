# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Excitation planner: the Cramér-Rao bound of candidate tests and the shortest one meeting a target.

For each candidate :class:`~.scenarios.TestDesign` the noise-free response is simulated
at the expected coefficients (the rig file's ``true_coefficients`` when present, else
the estimator's initial guess: the bound is local, so plan with your best guess) and
the Fisher information of :mod:`.information` gives the CRLB of every coefficient,
with each record's initial state unknown and, by default, the rotor's imbalance
unknown too. The bound scales exactly with the probe noise (``F ~ 1/sigma^2``), so
one computation serves every noise level.

A target is a maximum relative std (fraction of each coefficient's magnitude) for
the direct (kxx kyy cxx cyy) and the cross-coupled (kxy kyx cxy cyx) coefficients;
the recommended test is the feasible one with the least machine time (ties: fewer
hammer hits, then fewer records).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from rotor_estimator.core.config import RigConfig
from rotor_estimator.core.errors import ConfigError
from rotor_estimator.core.model import eigenfrequencies, rotor_matrices
from rotor_estimator.core.fisher import bound
from rotor_estimator.identification.information import design_information
from rotor_estimator.identification.problem import CoefficientModel, RigArrays
from rotor_estimator.identification.scenarios import (RPM, SpeedSegment, TestDesign, TrialWeight, dwell, multi_impact,
                                                      simulate_design, sweep)

DIRECT = np.array([True, False, False, True, True, False, False, True])


@dataclass(frozen=True)
class Target:
    """Maximum relative CRLB std: ``direct`` for kxx kyy cxx cyy, ``cross`` for kxy kyx cxy cyx."""

    direct: float = 0.05
    cross: float = 0.05

    def __post_init__(self) -> None:
        if not (self.direct > 0 and self.cross > 0):
            raise ConfigError("plan.target: must be > 0 (%)")

    @classmethod
    def from_percent(cls, values: list[float] | tuple[float, ...]) -> "Target":
        vals = list(values)
        if not 1 <= len(vals) <= 2:
            raise ConfigError("plan --target: one value (all coefficients) or two (direct, cross-coupled), in %")
        return cls(vals[0] / 100.0, (vals[1] if len(vals) == 2 else vals[0]) / 100.0)


@dataclass(frozen=True)
class CandidateBound:
    design: TestDesign
    std: np.ndarray            # CRLB std (SI) at the design's noise (the rig's by default)
    relative: np.ndarray       # std / |coefficient|
    noise_std_m: float

    def max_direct(self, identical: bool = True) -> float:
        mask = np.tile(DIRECT, self.relative.size // 8)
        return float(self.relative[mask].max())

    def max_cross(self) -> float:
        mask = np.tile(~DIRECT, self.relative.size // 8)
        return float(self.relative[mask].max())

    def meets(self, target: Target) -> bool:
        return self.max_direct() <= target.direct and self.max_cross() <= target.cross


def required_decel_rpm_per_s(design: TestDesign) -> float:
    """The fastest speed change a design asks of the machine (rpm/s, over all its segments)."""
    return max(abs(s.speed_end_rad_s - s.speed_start_rad_s) / s.duration_s / RPM for s in design.segments)


def swept_critical_speeds_rad_s(design: TestDesign, critical_rad_s: list[float]) -> list[float]:
    """The critical speeds a design passes through or dwells within 5 % of."""
    out = []
    for w in critical_rad_s:
        for s in design.segments:
            lo, hi = sorted((s.speed_start_rad_s, s.speed_end_rad_s))
            if lo * 0.95 <= w <= hi * 1.05:
                out.append(w)
                break
    return out


def critical_speeds_rad_s(rig: RigConfig, coefficients: np.ndarray, speed_max_rad_s: float) -> list[float]:
    """Speeds below ``speed_max_rad_s`` where a rigid-body whirl frequency equals the speed
    (the modes a sweep must cross), by scanning the Campbell diagram of Eq. 2."""
    mats = rotor_matrices(rig)
    grid = np.linspace(speed_max_rad_s * 0.02, speed_max_rad_s, 400)
    out = []
    freqs = np.array([eigenfrequencies(mats, coefficients, w) for w in grid])
    for j in range(freqs.shape[1]):
        d = freqs[:, j] - grid
        for i in np.flatnonzero(np.sign(d[:-1]) != np.sign(d[1:])):
            out.append(float(grid[i] - d[i] * (grid[i + 1] - grid[i]) / (d[i + 1] - d[i])))
    return sorted(out)


def candidate_designs(rig: RigConfig, coefficients: np.ndarray, *, bearings16: bool = False,
                      hammer_force_n: float = 515.0) -> list[TestDesign]:
    """A catalogue an engineer can run on ``rig``: constant speed (imbalance only, with trial
    weights), 1-8 hammer hits of ``hammer_force_n`` (x/y alternating; at two stations for 16
    coefficients), coast-downs through the rigid-body modes of 0.25-8 s, and dwells near the
    critical speeds."""
    if not (math.isfinite(hammer_force_n) and hammer_force_n > 0):
        raise ConfigError(f"plan.hammer_force_n: must be > 0 N, got {hammer_force_n!r}")
    w_max = rig.speed_rad_s
    rpm_max = w_max / RPM
    crit = critical_speeds_rad_s(rig, coefficients, w_max)
    low_rpm = max(0.5 * min(crit) / RPM, 0.05 * rpm_max) if crit else 0.15 * rpm_max
    designs = [
        TestDesign(name=f"imbalance only, {d:g} s at {rpm_max:.0f} rpm", segments=(SpeedSegment(d, w_max, w_max),),
                   discard_initial_s=0.03, description="constant speed, the rotor's own imbalance")
        for d in (0.125, 1.0, 10.0)]
    # trial weights: twice the first plane's imbalance mass at its radius
    u0 = rig.imbalances[0]
    trial = tuple(TrialWeight(2 * u0.mass_kg, u0.radius_m, ph, plane=p)
                  for p, ph in ((0, 0.0), (len(rig.imbalances) - 1, math.pi / 2)))
    designs.append(dwell(f"imbalance + 2 trial-weight runs, 1 s each at {rpm_max:.0f} rpm", (rpm_max,), 1.0,
                         trial_weights=trial, discard_initial_s=0.03))
    # for 16 coefficients: two stations, each hit in both directions (y, x at station 1, then at station 2)
    s1 = rig.bearing1_position_m + 0.25 * rig.bearing_span_m
    s2 = rig.bearing2_position_m - 0.25 * rig.bearing_span_m
    positions = (None,) if not bearings16 else (s1, s1, s2, s2)
    for n, d in ((1, 0.125), (2, 0.25), (3, 0.5), (5, 0.5), (5, 1.0), (8, 1.0)):
        designs.append(multi_impact(f"{n} impact(s) in {d:g} s at {rpm_max:.0f} rpm" +
                                    (" (2 stations)" if bearings16 else ""), n, d + 0.03, rpm_max,
                                    positions_m=positions, discard_initial_s=0.03, first_s=0.04,
                                    force_n=hammer_force_n))
    for d in (0.25, 0.5, 1.0, 2.0, 4.0, 8.0):
        designs.append(sweep(f"coast-down {rpm_max:.0f} -> {low_rpm:.0f} rpm in {d:g} s", rpm_max, low_rpm, d))
    for d in (0.5, 1.0, 2.0):
        base = sweep("", rpm_max, low_rpm, d)
        designs.append(TestDesign(name=f"2 coast-downs {rpm_max:.0f} -> {low_rpm:.0f} rpm in {d:g} s, 2nd with a "
                                       f"trial weight", segments=base.segments, trial_weights=trial[:1],
                                  description=base.description + " + the same with a trial weight"))
    if crit:
        lo_c, hi_c = min(crit) / RPM, max(crit) / RPM
        top = min(1.5 * hi_c, rpm_max)
        for d in (0.25, 0.5, 1.0):
            designs.append(sweep(f"coast-down {top:.0f} -> {low_rpm:.0f} rpm (through the modes) in {d:g} s",
                                 top, low_rpm, d))
        speeds = (round(0.8 * lo_c, -1), round(0.5 * (lo_c + hi_c), -1), round(1.2 * hi_c, -1))
        for d in (0.25, 0.5):
            designs.append(dwell(f"dwells at {'/'.join(f'{s:.0f}' for s in speeds)} rpm, {d:g} s each", speeds, d))
            designs.append(dwell(f"dwells at {'/'.join(f'{s:.0f}' for s in speeds)} rpm, {d:g} s each "
                                 "+ 1 trial-weight run", speeds, d, trial_weights=trial[:1]))
    return designs


def evaluate(rig: RigConfig, design: TestDesign, coefficients: np.ndarray, *, unknown_imbalance: bool = True,
             bearings16: bool = False, noise_std_m: float | None = None, substeps: int = 2,
             arrays: RigArrays | None = None) -> CandidateBound:
    """CRLB of the coefficients for one candidate test."""
    arrays = arrays or RigArrays.build(rig)
    model = CoefficientModel(identical_bearings=not bearings16)
    c = np.asarray(coefficients, dtype=float)
    theta = model.theta_from_coefficients(c)
    records = simulate_design(rig, design, coefficients=c, seed=None, substeps=substeps, arrays=arrays)
    sigma = noise_std_m or design.noise_std_m or rig.noise_std_m
    fim = design_information(arrays, model, records, theta, estimate_imbalance=unknown_imbalance,
                             noise_std_m=sigma)
    std = bound(fim, model.n_theta).std
    return CandidateBound(design=design, std=std, relative=std / np.abs(theta), noise_std_m=sigma)


@dataclass(frozen=True)
class Plan:
    target: Target
    candidates: tuple[CandidateBound, ...]   # sorted by machine time
    recommended: CandidateBound | None
    max_decel_rpm_per_s: float | None = None
    critical_speeds_rad_s: tuple[float, ...] = ()

    def feasible(self, c: CandidateBound) -> bool:
        """The machine can run it: no speed change faster than the achievable deceleration."""
        return self.max_decel_rpm_per_s is None or required_decel_rpm_per_s(c.design) <= self.max_decel_rpm_per_s

    def format(self) -> str:
        lines = [f"Target: direct <= {100 * self.target.direct:g}%, cross-coupled <= {100 * self.target.cross:g}% "
                 f"(CRLB std relative to each coefficient)"]
        head = f"{'test':<70}{'time s':>8}{'rpm/s':>8}{'max direct %':>14}{'max cross %':>13}  meets"
        lines += [head, "-" * len(head)]
        for c in self.candidates:
            def fmt(v):
                return f"{100 * v:.3g}" if np.isfinite(v) and v < 1e4 else "inf"

            mark = "yes" if c.meets(self.target) else "no"
            if not self.feasible(c):
                mark = f"no (needs {required_decel_rpm_per_s(c.design):.0f} rpm/s)"
            if c is self.recommended:
                mark += "  <== recommended"
            lines.append(f"{c.design.name:<70}{c.design.total_time_s:>8.3g}"
                         f"{required_decel_rpm_per_s(c.design):>8.0f}{fmt(c.max_direct()):>14}"
                         f"{fmt(c.max_cross()):>13}  {mark}")
        if self.recommended is None:
            blocked = [c for c in self.candidates if c.meets(self.target) and not self.feasible(c)]
            lines.append("No candidate meets the target" + (
                f" at {self.max_decel_rpm_per_s:g} rpm/s ({len(blocked)} would with a faster speed change)"
                if blocked else "") + ": lower the noise (average, better probes), lengthen the sweep, add "
                "impacts or trial weights, or relax the target.")
        else:
            r = self.recommended
            lines.append(f"\nRecommended: {r.design.name} ({r.design.description}); machine time "
                         f"{r.design.total_time_s:g} s.")
            lines.append("Per-coefficient CRLB of the recommended test (% of value): " + ", ".join(
                f"{n} {100 * v:.3g}" for n, v in zip(_names(r.relative.size), r.relative)))
            crit = swept_critical_speeds_rad_s(r.design, list(self.critical_speeds_rad_s))
            all_crit = ", ".join(f"{w / RPM:.0f} rpm ({w / (2 * math.pi):.1f} Hz)" for w in self.critical_speeds_rad_s)
            lines.append(f"Critical speeds of the rig (rigid-body modes at the expected coefficients): "
                         f"{all_crit or 'none below the running speed'}; the test passes "
                         + (", ".join(f"{w / RPM:.0f} rpm" for w in crit) if crit else "none of them"))
            for k, w in enumerate(r.design.trial_weights):
                lines.append(f"Trial weight of record {k + 1}: {w.mass_kg * 1e3:.4g} g at {w.radius_m * 1e3:.4g} mm, "
                             f"imbalance plane {w.plane + 1}, {math.degrees(w.phase_rad):.0f} deg "
                             f"from the keyphasor mark")
            if r.design.impacts:
                f = max(max(abs(i.force_x_n), abs(i.force_y_n)) for i in r.design.impacts)
                lines.append(f"Hammer: {len(r.design.impacts)} hit(s) of {f:g} N peak, "
                             f"{r.design.impacts[0].duration_s * 1e6:.0f} us")
        return "\n".join(lines)

    def as_rows(self) -> list[dict]:
        rows = []
        for c in self.candidates:
            for n, s, r in zip(_names(c.std.size), c.std, c.relative):
                rows.append({"test": c.design.name, "time_s": c.design.total_time_s,
                             "required_decel_rpm_per_s": required_decel_rpm_per_s(c.design),
                             "machine_can_run_it": self.feasible(c), "coefficient": n,
                             "crlb_std": float(s), "crlb_relative": float(r), "meets_target": c.meets(self.target),
                             "recommended": c is self.recommended, "noise_std_m": c.noise_std_m})
        return rows


def _names(n: int) -> tuple[str, ...]:
    from rotor_estimator.identification.problem import BEARING_COEFFICIENT_NAMES
    from rotor_estimator.core.config import COEFFICIENT_NAMES

    return COEFFICIENT_NAMES if n == 8 else BEARING_COEFFICIENT_NAMES


def plan(rig: RigConfig, target: Target, *, coefficients: np.ndarray | None = None,
         designs: list[TestDesign] | None = None, unknown_imbalance: bool = True, bearings16: bool = False,
         noise_std_m: float | None = None, progress: Callable[[int], object] | None = None,
         max_decel_rpm_per_s: float | None = None) -> Plan:
    """Evaluate the candidates and recommend the shortest test meeting ``target``."""
    if coefficients is None:
        if rig.true_coefficients is None:
            raise ConfigError("plan: the rig file has no true_coefficients; pass the expected coefficients")
        coefficients = rig.true_coefficients.as_array()
    coefficients = np.asarray(coefficients, dtype=float)
    designs = designs or candidate_designs(rig, coefficients, bearings16=bearings16)
    arrays = RigArrays.build(rig)
    out = []
    for d in designs:
        out.append(evaluate(rig, d, coefficients, unknown_imbalance=unknown_imbalance, bearings16=bearings16,
                            noise_std_m=noise_std_m, arrays=arrays))
        if progress:
            progress(1)
    out.sort(key=lambda c: (c.design.total_time_s, len(c.design.impacts), c.design.n_records))
    if max_decel_rpm_per_s is not None and not max_decel_rpm_per_s > 0:
        raise ConfigError(f"plan.max_decel_rpm_per_s: must be > 0, got {max_decel_rpm_per_s!r}")
    crit = tuple(critical_speeds_rad_s(rig, coefficients, rig.speed_rad_s))
    result = Plan(target=target, candidates=tuple(out), recommended=None, max_decel_rpm_per_s=max_decel_rpm_per_s,
                  critical_speeds_rad_s=crit)
    feasible = [c for c in out if c.meets(target) and result.feasible(c)]
    from dataclasses import replace

    return replace(result, recommended=feasible[0] if feasible else None)
