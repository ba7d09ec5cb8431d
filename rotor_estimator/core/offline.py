# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Run the EKF over a whole recording held in memory (arrays, no ROS).

Used by the reproduction, the benchmarks and the diagnosis. Bags go through
:mod:`rotor_estimator.core.pipeline` instead, which adds the node's time ordering and
alignment in front of the same :class:`~rotor_estimator.core.ekf.StreamingEKF`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from rotor_estimator.core.config import EstimatorConfig, RigConfig
from rotor_estimator.core.ekf import BlockResult, StreamingEKF
from rotor_estimator.core.errors import InputError
from rotor_estimator.core.recording import RigRecording

if TYPE_CHECKING:
    from rotor_estimator.core.tachometer import TachometerConfig


@dataclass
class ShaftInputs:
    """Shaft angle (rad), speed (rad/s) and angular acceleration (rad/s^2) at each sample, and validity."""

    angle_rad: np.ndarray
    speed_rad_s: np.ndarray
    accel_rad_s2: np.ndarray
    valid: np.ndarray


def shaft_inputs_from_recording(recording: RigRecording, tach_config: TachometerConfig | None = None, *,
                                running_speed_rad_s: float = 0.0) -> ShaftInputs:
    """Shaft state at every sample from the keyphasor pulses (centered, offline fit); the tracker's
    speed limit follows ``running_speed_rad_s`` (see :func:`tachometer.max_speed_for_rig`)."""
    from rotor_estimator.core.tachometer import TachometerConfig, max_speed_for_rig, shaft_states_from_pulses

    if recording.pulse_stamps_ns.size < 2:
        raise InputError("the recording has fewer than 2 keyphasor pulses: the shaft angle, which phases the "
                         "imbalance force, cannot be tracked")
    states, _pulse_counters = shaft_states_from_pulses(recording.pulse_stamps_ns, recording.stamps_ns,
                                                       tach_config or TachometerConfig(
                                                           max_speed_rad_s=max_speed_for_rig(running_speed_rad_s)))
    return ShaftInputs(angle_rad=np.asarray(states.angle_rad, dtype=float),
                       speed_rad_s=np.asarray(states.speed_rad_s, dtype=float),
                       accel_rad_s2=np.asarray(states.accel_rad_s2, dtype=float),
                       valid=np.asarray(states.valid, dtype=bool))


@dataclass
class OfflineEstimate:
    """Final estimate of a (multi-pass) run and, optionally, the coefficient history of each pass."""

    coefficients: np.ndarray
    covariance: np.ndarray
    last_pass: BlockResult
    counts: dict
    history_t_s: list = field(default_factory=list)          # per pass: (H,) times
    history_coefficients: list = field(default_factory=list)  # per pass: (H, 8)
    history_std: list = field(default_factory=list)            # per pass: (H, 8)

    @property
    def std(self) -> np.ndarray:
        return np.sqrt(np.diag(self.covariance))


def estimate(recording: RigRecording, rig: RigConfig, config: EstimatorConfig, *, passes: int | None = None,
             shaft: ShaftInputs | None = None, history_every: int = 0,
             initial_coefficients: np.ndarray | None = None, imbalance_scale: float = 1.0) -> OfflineEstimate:
    """Filter ``recording`` ``passes`` times (the paper's multi-pass use: each pass starts from
    the previous pass's final coefficients with the configured P0)."""
    passes = config.passes if passes is None else passes
    shaft = shaft or shaft_inputs_from_recording(recording, running_speed_rad_s=rig.speed_rad_s)
    t = recording.time_s()
    ekf = StreamingEKF(rig, config, initial_coefficients=initial_coefficients, imbalance_scale=imbalance_scale)
    skip = ~shaft.valid
    out = OfflineEstimate(coefficients=ekf.coefficients, covariance=ekf.coefficient_covariance, last_pass=None,
                          counts={})
    for p in range(passes):
        if p:
            ekf.reset(ekf.coefficients)
        if history_every > 0:
            hist_t, hist_c, hist_s, parts = [], [], [], []
            for start in range(0, len(t), history_every):
                sl = slice(start, min(start + history_every, len(t)))
                parts.append(ekf.process_block(t[sl], recording.probes_m[sl], shaft.angle_rad[sl],
                                               shaft.speed_rad_s[sl], shaft.accel_rad_s2[sl],
                                               recording.impact_force_n[sl], skip[sl]))
                hist_t.append(t[sl.stop - 1])
                hist_c.append(ekf.coefficients)
                hist_s.append(ekf.coefficient_std)
            result = BlockResult(*(np.concatenate([getattr(b, f) for b in parts])
                                   for f in ("status", "nis", "innovation_m", "innovation_std_m")))
            out.history_t_s.append(np.array(hist_t))
            out.history_coefficients.append(np.array(hist_c))
            out.history_std.append(np.array(hist_s))
        else:
            result = ekf.process_block(t, recording.probes_m, shaft.angle_rad, shaft.speed_rad_s,
                                       shaft.accel_rad_s2, recording.impact_force_n, skip)
        out.last_pass = result
    out.coefficients = ekf.coefficients
    out.covariance = ekf.coefficient_covariance
    out.counts = dict(ekf.health.counts)
    return out
