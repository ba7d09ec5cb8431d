# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Rig data as plain arrays: what the estimator node's input topics carry.

A :class:`RigRecording` is what the simulator makes, what ``import`` reads from a
DAQ file and what a bag's input topics decode to. Stamps are integer nanoseconds
(``*_ns``); the numerical core converts once, to seconds relative to
``stamps_ns[0]``, with :meth:`RigRecording.time_s`.

Impact force convention (zero-order hold): the force sample at stamp ``t_k``
acts on the shaft from ``t_k`` until the next probe sample ``t_{k+1}``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rotor_estimator.core.errors import InputError


@dataclass
class RigRecording:
    """Sampled probe displacements, keyphasor pulses and impact force.

    * ``stamps_ns`` (N,) int64: sample stamps, strictly increasing.
    * ``probes_m`` (N, 4) float64: ``[xp1, yp1, xp2, yp2]`` in metres (x horizontal, y vertical).
    * ``pulse_stamps_ns`` (P,) int64: once-per-revolution keyphasor pulses (shaft angle 0).
    * ``impact_force_n`` (N, 2) float64: hammer force ``[fx, fy]`` in newtons, held over
      each sample period (zeros where no impact).
    * ``meta``: free-form provenance (scenario, seed); never read by estimators.
    """

    stamps_ns: np.ndarray
    probes_m: np.ndarray
    pulse_stamps_ns: np.ndarray
    impact_force_n: np.ndarray
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.stamps_ns = np.asarray(self.stamps_ns, dtype=np.int64)
        self.probes_m = np.asarray(self.probes_m, dtype=float)
        self.pulse_stamps_ns = np.asarray(self.pulse_stamps_ns, dtype=np.int64)
        self.impact_force_n = np.asarray(self.impact_force_n, dtype=float)
        n = self.stamps_ns.shape[0]
        if self.stamps_ns.ndim != 1:
            raise InputError("stamps_ns must be one-dimensional")
        if self.probes_m.shape != (n, 4):
            raise InputError(f"probes_m must have shape ({n}, 4), got {self.probes_m.shape}")
        if self.impact_force_n.shape != (n, 2):
            raise InputError(f"impact_force_n must have shape ({n}, 2), got {self.impact_force_n.shape}")
        if n > 1 and np.any(np.diff(self.stamps_ns) <= 0):
            raise InputError("stamps_ns must be strictly increasing")

    def __len__(self) -> int:
        return int(self.stamps_ns.shape[0])

    @property
    def start_ns(self) -> int:
        return int(self.stamps_ns[0]) if len(self) else 0

    def time_s(self) -> np.ndarray:
        """Sample times in seconds after the first sample."""
        return (self.stamps_ns - self.start_ns) * 1e-9

    def pulse_time_s(self) -> np.ndarray:
        """Keyphasor pulse times in seconds after the first sample."""
        return (self.pulse_stamps_ns - self.start_ns) * 1e-9

    @property
    def sample_period_s(self) -> float:
        """Median sample period (s)."""
        if len(self) < 2:
            raise InputError("a recording needs at least two samples to have a sample period")
        return float(np.median(np.diff(self.stamps_ns))) * 1e-9

    def slice(self, start: int, stop: int) -> "RigRecording":
        """Samples ``start:stop`` with the pulses that fall in (and one revolution around) them."""
        stamps = self.stamps_ns[start:stop]
        if stamps.size == 0:
            return RigRecording(stamps, self.probes_m[start:stop], self.pulse_stamps_ns[:0],
                                self.impact_force_n[start:stop], dict(self.meta))
        return RigRecording(stamps, self.probes_m[start:stop], self.pulse_stamps_ns,
                            self.impact_force_n[start:stop], dict(self.meta))
