# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""What a blind diagnosis case is, and the pieces both blind generators share (impacts, the
nominal-fit proxy of a case's gap)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rotor_estimator.core.config import RigFile
from rotor_estimator.core.model import imbalance_force, impact_force, rotor_matrices
from rotor_estimator.core.recording import RigRecording
from rotor_estimator.core.simulator import Impact
from rotor_estimator.diagnosis.context import fit_nominal, shaft_track
from rotor_estimator.diagnosis.linsim import SpeedSchedule

#: Start-up transient left out of the gap figures, s.
WARMUP_S = 0.010


@dataclass
class BlindCase:
    """One generated case: what the diagnosis sees (recording, rig file) and the withheld label."""

    case_id: str
    recording: RigRecording
    rig_file: RigFile
    label: dict


def random_impacts(rng, duration_s) -> tuple[Impact, ...]:
    """One to three hammer impacts of 200-600 N in random directions, on the 50 us sample grid."""
    out = []
    for _ in range(int(rng.integers(1, 4))):
        mag, ang = rng.uniform(200.0, 600.0), rng.uniform(0, 2 * np.pi)
        start = round(float(rng.uniform(0.03, 0.8 * duration_s)) / 50e-6) * 50e-6
        out.append(Impact(start, 50e-6, float(mag * np.cos(ang)), float(mag * np.sin(ang))))
    return tuple(out)


def nominal_unabsorbed_rms(recording: RigRecording, rig, starts, *, max_nfev: int = 25,
                           start_transient: bool = False) -> float:
    """RMS (m) of a noise-free record left after the diagnosis's own nominal output-error fit.

    A cheap proxy of the realized nominal residual: the shaft track from the keyphasor (as the
    diagnosis sees it) and the diagnosis's own nominal fit,
    :func:`~rotor_estimator.diagnosis.context.fit_nominal` (exact-discretization re-simulation,
    Levenberg-Marquardt over the 8 coefficients, DC projected out), from each of ``starts``; the
    smallest residual wins. No EKF (the diagnosis's
    EKF only supplies a start). ``recording.probes_m`` must be the clean signal. ``start_transient``: the
    start transient estimated too (what the diagnosis does for a record whose start shows one).
    """
    shaft = shaft_track(recording)
    mats = rotor_matrices(rig)
    t = recording.time_s()
    h = float(np.median(np.diff(t)))
    y = recording.probes_m
    mask = shaft.valid & (t >= t[0] + WARMUP_S)
    schedule = SpeedSchedule.from_speed(shaft.speed_rad_s)
    u_s = imbalance_force(mats, shaft.angle_rad, shaft.speed_rad_s, shaft.accel_rad_s2)
    u_z = impact_force(mats, recording.impact_force_n)

    res = fit_nominal(rig, mats, t, y, mask, shaft, schedule, u_s, u_z, h, starts, max_nfev=max_nfev,
                      start_transient=start_transient)
    return float("inf") if res is None else float(np.sqrt(2 * res.cost / res.fun.size)) * 1e-6
