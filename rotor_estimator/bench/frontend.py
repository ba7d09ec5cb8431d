# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Front-end cost per sample (probe-plane alignment, keyphasor angle query, probe-block message
encode + decode), each as a ratio to the EKF's own cost per sample measured in the same process.

These were wall-clock bounds in the tests (a loaded CI machine failed one at 5.3 % for 5 %); a
ratio of two runs in the same process survives a shared, noisy machine, and a figure is printed
rather than asserted.
"""
from __future__ import annotations

import time

import numpy as np

PERIOD_NS = 50_000  # 20 kHz
BLOCK = 200


def _best_of(fn, repeats: int = 5) -> float:
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def aligner_seconds(n_samples: int) -> float:
    """Two probe planes in 200-sample blocks through the estimator's aligner, popped after every pair."""
    from rotor_estimator.core.alignment import probe_aligner

    k = np.arange(n_samples)
    t = (1_000_000_000 + k * PERIOD_NS).astype(np.int64)
    p1 = np.stack([k * 1e-9, -k * 1e-9], axis=1)
    p2 = 2 * p1
    blocks = [(t[i:i + BLOCK], p1[i:i + BLOCK], p2[i:i + BLOCK]) for i in range(0, n_samples, BLOCK)]

    def run():
        al = probe_aligner()
        for tb, a, b in blocks:
            al.add_block("plane1", tb, a)
            al.add_block("plane2", tb, b)
            al.pop_ready()

    return _best_of(run)


def tachometer_seconds(n_queries: int) -> float:
    """``ShaftAngleTracker.query`` once per sample (the live node's per-sample angle)."""
    from rotor_estimator.core.tachometer import ShaftAngleTracker

    trk = ShaftAngleTracker()
    pulses = [1_000_000_000 + j * 3_000_000 for j in range(20)]
    for p in pulses:
        trk.add_pulse(p)
    stamps = [pulses[-1] + j * 100 for j in range(n_queries)]

    def run():
        for s in stamps:
            trk.query(s)

    return _best_of(run)


def message_seconds(n_samples: int) -> float:
    """Probe blocks of 1000 samples encoded to a rosbags PointCloud2 and decoded back."""
    import msg_adapters as ma

    factory = ma.TypestoreFactory(ma.default_typestore())
    stamps = 1_000_000_000 + np.arange(1000, dtype=np.int64) * PERIOD_NS
    xy = np.random.default_rng(1).normal(scale=1e-5, size=(1000, 2))
    n_blocks = max(1, n_samples // 1000)

    def run():
        for _ in range(n_blocks):
            ma.probe_block_from_msg(ma.probe_block_to_msg(factory, stamps, xy, frame_id="probe1"))

    return _best_of(run) * n_samples / (n_blocks * 1000)


def run(ekf_us_per_sample: float, n_samples: int = 20_000) -> dict:
    """Per-sample front-end costs (us) and their ratio to ``ekf_us_per_sample`` (same process)."""
    out = {}
    for name, seconds in (("aligner", aligner_seconds(n_samples)), ("tachometer_query", tachometer_seconds(n_samples)),
                          ("probe_message_round_trip", message_seconds(n_samples))):
        us = 1e6 * seconds / n_samples
        out[f"{name}_us_per_sample"] = us
        out[f"{name}_to_ekf_ratio"] = us / ekf_us_per_sample
    return out
