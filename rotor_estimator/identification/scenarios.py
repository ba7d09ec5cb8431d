# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Test definitions: sweeps, dwells, multi-impact tests, trial weights; and their simulation.

A :class:`TestDesign` is what an engineer runs: a speed profile made of linear
segments (a coast-down or run-up is one segment, a dwell is a segment with equal end
speeds), hammer impacts (time, direction, force, axial station), optional trial
weights (each adds one more record of the same profile with the weight attached: the
classic influence-coefficient procedure) and the probe noise.

:func:`simulate_design` integrates the generalized model (:mod:`.passes` over
:mod:`rotor_estimator.core.filter_kernel`, RK4 with
``substeps`` per sample, from rest at equilibrium like the core simulator) and returns
one :class:`~.problem.Record` per run plus the noise-free truth. The shaft state of each
record is the true one (planning) or read back through the tachometer from simulated
keyphasor pulses (``through_tachometer=True``), as the product does with real data.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rotor_estimator.core.config import RigConfig
from rotor_estimator.core.errors import ConfigError
from rotor_estimator.core.model import point_force_weights
from rotor_estimator.core.simulator import Impact, Scenario
from rotor_estimator.identification import passes
from rotor_estimator.identification.problem import CoefficientModel, Record, RigArrays

RPM = 2.0 * math.pi / 60.0


@dataclass(frozen=True)
class SpeedSegment:
    """Linear speed ramp ``speed_start_rad_s -> speed_end_rad_s`` over ``duration_s`` (a dwell when equal)."""

    duration_s: float
    speed_start_rad_s: float
    speed_end_rad_s: float

    def validate(self, path: str) -> "SpeedSegment":
        if not (math.isfinite(self.duration_s) and self.duration_s > 0):
            raise ConfigError(f"{path}.duration_s: must be > 0 s, got {self.duration_s!r}")
        for name in ("speed_start_rad_s", "speed_end_rad_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ConfigError(f"{path}.{name}: must be >= 0 rad/s, got {v!r}")
        return self


@dataclass(frozen=True)
class ImpactSpec:
    """A hammer pulse of ``force_x_n``/``force_y_n`` (N) from ``start_s`` for ``duration_s`` at
    ``axial_position_m`` (None: the rig's impact station)."""

    start_s: float
    force_x_n: float
    force_y_n: float
    duration_s: float = 50e-6
    axial_position_m: float | None = None

    def validate(self, path: str) -> "ImpactSpec":
        Impact(self.start_s, self.duration_s, self.force_x_n, self.force_y_n).validate(path)
        if self.axial_position_m is not None and not math.isfinite(self.axial_position_m):
            raise ConfigError(f"{path}.axial_position_m: must be finite (m)")
        return self


@dataclass(frozen=True)
class TrialWeight:
    """A trial mass ``mass_kg`` at ``radius_m`` and ``phase_rad`` in imbalance plane ``plane`` (index)."""

    mass_kg: float
    radius_m: float
    phase_rad: float
    plane: int = 0

    def imbalance_vector(self, n_planes: int) -> np.ndarray:
        if not 0 <= self.plane < n_planes:
            raise ConfigError(f"trial_weight.plane: must be 0..{n_planes - 1}, got {self.plane}")
        b = np.zeros(2 * n_planes)
        u = self.mass_kg * self.radius_m
        b[2 * self.plane] = u * math.cos(self.phase_rad)
        b[2 * self.plane + 1] = u * math.sin(self.phase_rad)
        return b


@dataclass(frozen=True)
class TestDesign:
    """One candidate test (see module docstring). Times from the start of the run (s)."""

    __test__ = False  # not a pytest class

    name: str
    segments: tuple[SpeedSegment, ...]
    impacts: tuple[ImpactSpec, ...] = ()
    trial_weights: tuple[TrialWeight, ...] = ()
    discard_initial_s: float = 0.01
    noise_std_m: float | None = None
    imbalance_scale: float = 1.0
    description: str = ""

    def __post_init__(self) -> None:
        if not self.segments:
            raise ConfigError(f"design[{self.name}].segments: at least one speed segment is needed")
        for i, s in enumerate(self.segments):
            s.validate(f"design[{self.name}].segments[{i}]")
        for i, imp in enumerate(self.impacts):
            imp.validate(f"design[{self.name}].impacts[{i}]")
        if not 0 <= self.discard_initial_s < self.duration_s:
            raise ConfigError(f"design[{self.name}].discard_initial_s: must be in [0, duration_s)")
        if self.noise_std_m is not None and not 0 < self.noise_std_m < 1e-2:
            raise ConfigError(f"design[{self.name}].noise_std_m: must be in (0, 0.01) m")

    @property
    def duration_s(self) -> float:
        return float(sum(s.duration_s for s in self.segments))

    @property
    def n_records(self) -> int:
        return 1 + len(self.trial_weights)

    @property
    def total_time_s(self) -> float:
        """Machine time the test takes (all records)."""
        return self.duration_s * self.n_records

    def shaft_profile(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Exact shaft angle (unwrapped, rad), speed (rad/s) and acceleration (rad/s^2) at ``t_s``."""
        t = np.asarray(t_s, dtype=float)
        angle = np.zeros_like(t)
        speed = np.zeros_like(t)
        accel = np.zeros_like(t)
        t0, a0 = 0.0, 0.0
        for i, s in enumerate(self.segments):
            alpha = (s.speed_end_rad_s - s.speed_start_rad_s) / s.duration_s
            last = i == len(self.segments) - 1
            sel = (t >= t0) & ((t < t0 + s.duration_s) | last)
            u = t[sel] - t0
            angle[sel] = a0 + s.speed_start_rad_s * u + 0.5 * alpha * u * u
            speed[sel] = s.speed_start_rad_s + alpha * u
            accel[sel] = alpha
            a0 += s.speed_start_rad_s * s.duration_s + 0.5 * alpha * s.duration_s ** 2
            t0 += s.duration_s
        return angle, speed, accel


def sweep(name: str, speed_start_rpm: float, speed_end_rpm: float, duration_s: float, **kw: Any) -> TestDesign:
    """A linear coast-down (start > end) or run-up with the rotor's own imbalance."""
    return TestDesign(name=name, segments=(SpeedSegment(duration_s, speed_start_rpm * RPM, speed_end_rpm * RPM),),
                      description=kw.pop("description", f"linear sweep {speed_start_rpm:.0f} -> {speed_end_rpm:.0f} "
                                                        f"rpm in {duration_s:g} s"), **kw)


def multi_impact(name: str, n_impacts: int, duration_s: float, speed_rpm: float, *, force_n: float = 515.0,
                 positions_m: tuple[float | None, ...] = (None,), first_s: float = 0.04, **kw: Any) -> TestDesign:
    """``n_impacts`` hammer hits alternating in -y and -x (and over ``positions_m``), evenly spaced."""
    spacing = (duration_s - first_s) / max(n_impacts, 1)
    impacts = []
    for i in range(n_impacts):
        fx, fy = (0.0, -force_n) if i % 2 == 0 else (-force_n, 0.0)
        impacts.append(ImpactSpec(round((first_s + i * spacing) / 50e-6) * 50e-6, fx, fy,
                                  axial_position_m=positions_m[i % len(positions_m)]))
    return TestDesign(name=name, segments=(SpeedSegment(duration_s, speed_rpm * RPM, speed_rpm * RPM),),
                      impacts=tuple(impacts),
                      description=kw.pop("description", f"{n_impacts} impacts (x/y alternating) in {duration_s:g} s "
                                                        f"at {speed_rpm:.0f} rpm"), **kw)


def dwell(name: str, speeds_rpm: tuple[float, ...], dwell_s: float, *, ramp_s: float = 0.02,
          trial_weights: tuple[TrialWeight, ...] = (), **kw: Any) -> TestDesign:
    """Dwells at ``speeds_rpm`` (each ``dwell_s``), joined by ramps of ``ramp_s``."""
    segs = []
    for i, s in enumerate(speeds_rpm):
        if i:
            segs.append(SpeedSegment(ramp_s, speeds_rpm[i - 1] * RPM, s * RPM))
        segs.append(SpeedSegment(dwell_s, s * RPM, s * RPM))
    return TestDesign(name=name, segments=tuple(segs), trial_weights=trial_weights,
                      description=kw.pop("description", "dwells at " + "/".join(f"{s:.0f}" for s in speeds_rpm)
                                         + f" rpm, {dwell_s:g} s each" + (f", + {len(trial_weights)} trial-weight "
                                                                          f"run(s)" if trial_weights else "")), **kw)


def design_from_scenario(rig: RigConfig, scenario: Scenario) -> TestDesign:
    """The core simulator's :class:`~rotor_estimator.core.simulator.Scenario` as a design (impacts at the
    rig station)."""
    w0 = rig.speed_rad_s if scenario.speed_start_rad_s is None else scenario.speed_start_rad_s
    w1 = w0 if scenario.speed_end_rad_s is None else scenario.speed_end_rad_s
    return TestDesign(name=scenario.name, segments=(SpeedSegment(scenario.duration_s, w0, w1),),
                      impacts=tuple(ImpactSpec(i.start_s, i.force_x_n, i.force_y_n, i.duration_s) for i in
                                    scenario.impacts),
                      discard_initial_s=scenario.discard_initial_s, noise_std_m=scenario.noise_std_m,
                      imbalance_scale=scenario.imbalance_scale)


# ----------------------------------------------------------------------------------- simulation
@dataclass
class SimulatedRecord:
    """One simulated record and its truth (state at the first recorded sample, imbalance)."""

    record: Record
    q0_true: np.ndarray
    imbalance_true_kg_m: np.ndarray      # total imbalance acting (rotor + trial weight)
    trial_imbalance_kg_m: np.ndarray     # the known trial part
    probes_clean_m: np.ndarray
    pulse_times_s: np.ndarray = field(default_factory=lambda: np.zeros(0))


def _impact_forces(rig: RigConfig, design: TestDesign, t_s: np.ndarray, dt: float) -> np.ndarray:
    """Generalized impact force per sample period (zero-order hold, exact overlap fraction)."""
    f = np.zeros((t_s.size, 4))
    for imp in design.impacts:
        pos = rig.impact_position_m if imp.axial_position_m is None else imp.axial_position_m
        w1, w2 = point_force_weights(rig, pos)
        overlap = np.clip(np.minimum(t_s + dt, imp.start_s + imp.duration_s) - np.maximum(t_s, imp.start_s), 0, None)
        frac = np.round(overlap / dt, 9)
        f += frac[:, None] * np.array([w1 * imp.force_x_n, w1 * imp.force_y_n, w2 * imp.force_x_n,
                                       w2 * imp.force_y_n])[None, :]
    return f


def pulse_times(design: TestDesign, t_end_s: float, resolution_s: float = 1e-6) -> np.ndarray:
    """Instants the shaft angle passes 2*pi*n (keyphasor pulses), by bisection-free root finding
    on the piecewise-quadratic angle."""
    out = []
    t0, a0 = 0.0, 0.0
    for s in design.segments:
        alpha = (s.speed_end_rad_s - s.speed_start_rad_s) / s.duration_s
        a1 = a0 + s.speed_start_rad_s * s.duration_s + 0.5 * alpha * s.duration_s ** 2
        n = np.arange(math.ceil(a0 / (2 * math.pi) - 1e-12), math.floor(a1 / (2 * math.pi)) + 1)
        target = 2 * math.pi * n - a0
        if abs(alpha) < 1e-12:
            u = target / s.speed_start_rad_s if s.speed_start_rad_s > 0 else np.zeros(0)
        else:
            disc = np.maximum(s.speed_start_rad_s ** 2 + 2 * alpha * target, 0.0)
            u = (-s.speed_start_rad_s + np.sqrt(disc)) / alpha
        out.append(t0 + u)
        t0 += s.duration_s
        a0 = a1
    p = np.unique(np.round(np.concatenate(out) / resolution_s) * resolution_s) if out else np.zeros(0)
    return p[p <= t_end_s]


def simulate_design(rig: RigConfig, design: TestDesign, *, coefficients: np.ndarray | None = None,
                    coefficient_model: CoefficientModel | None = None, theta: np.ndarray | None = None,
                    seed: int | None = 0, substeps: int = 8, through_tachometer: bool = False,
                    arrays: RigArrays | None = None) -> list[SimulatedRecord]:
    """Simulate every record of ``design`` (noise from ``seed``; ``None``: noise-free).

    Coefficients: ``coefficients`` (8 or 16, constant) or ``coefficient_model`` + ``theta``
    (e.g. speed-dependent truth); default the rig's true coefficients.
    """
    arrays = arrays or RigArrays.build(rig)
    cm = coefficient_model or CoefficientModel(identical_bearings=True)
    if theta is None:
        c = coefficients if coefficients is not None else (
            rig.true_coefficients.as_array() if rig.true_coefficients is not None else None)
        if c is None:
            raise ConfigError("rig.true_coefficients: simulation needs coefficients")
        c = np.asarray(c, dtype=float)
        cm = CoefficientModel(identical_bearings=c.size == 8)
        theta = cm.theta_from_coefficients(c)
    dt = rig.sample_period_s
    n_total = int(round(design.duration_s / dt))
    t = np.arange(n_total) * dt
    angle, speed, accel = design.shaft_profile(t)
    # acceleration must be constant over each step: take the segment of the step's start
    fgen = _impact_forces(rig, design, t, dt)
    first = int(round(design.discard_initial_s / dt))
    noise_std = rig.noise_std_m if design.noise_std_m is None else design.noise_std_m
    rng = np.random.default_rng(seed) if seed is not None else None
    base_b = arrays.imbalance_nominal_kg_m * design.imbalance_scale
    trials = [np.zeros_like(base_b)] + [w.imbalance_vector(arrays.n_imbalance // 2) for w in design.trial_weights]
    out = []
    for i, trial_b in enumerate(trials):
        bvec = base_b + trial_b
        states = passes.simulate_states(np.zeros(8), np.ascontiguousarray(theta, dtype=float), bvec,
                                         np.full(n_total - 1, dt), substeps, angle, speed, accel, fgen, cm.dmap(),
                                         cm.powers(), cm.speed_ref_rad_s, cm.speed_scale_rad_s, arrays.minv,
                                         arrays.gyro, arrays.wimb)
        rec_states = states[first:]
        clean = rec_states[:, 4:] @ arrays.hp.T
        noisy = clean + (rng.standard_normal(clean.shape) * noise_std if rng is not None else 0.0)
        t_rec = t[first:]
        pulses = pulse_times(design, t[-1])
        a, w, al = angle[first:], speed[first:], accel[first:]
        use = None
        if through_tachometer:
            from rotor_estimator.core.tachometer import shaft_states_from_pulses

            stamps = np.round(t_rec * 1e9).astype(np.int64)
            states_tach, _ = shaft_states_from_pulses(np.round(pulses * 1e9).astype(np.int64), stamps)
            a, w, al = states_tach.angle_rad, states_tach.speed_rad_s, states_tach.accel_rad_s2
            use = np.asarray(states_tach.valid, dtype=bool)
        record = Record(t_s=t_rec - t_rec[0], angle_rad=a, speed_rad_s=w, accel_rad_s2=al,
                        force_gen_n=fgen[first:], probes_m=noisy, use=use,
                        meta={"design": design.name, "record": i, "seed": seed})
        out.append(SimulatedRecord(record=record, q0_true=rec_states[0].copy(), imbalance_true_kg_m=bvec,
                                   trial_imbalance_kg_m=trial_b, probes_clean_m=clean, pulse_times_s=pulses))
    return out
