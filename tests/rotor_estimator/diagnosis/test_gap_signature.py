# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""A gap not in the library is described by its signature (order and whirl, fixed-frequency peak, time span)."""
from __future__ import annotations

import numpy as np
import pytest

from rotor_estimator.diagnosis.api import gap_signature
from rotor_estimator.diagnosis.residuals import budget

FS_HZ, SPEED_RAD_S = 20_000.0, 2 * np.pi * 300.0


def _budget(e: np.ndarray, impacts_at: tuple[int, ...] = ()) -> dict:
    n = e.shape[0]
    t = np.arange(n) / FS_HZ
    force = np.zeros((n, 2))
    for k in impacts_at:
        force[k:k + 2] = 300.0
    noise = np.random.default_rng(0).normal(scale=1e-7, size=e.shape)
    return budget(t, e + noise, SPEED_RAD_S * t, np.full(n, SPEED_RAD_S), force, np.full(4, 1e-7))


@pytest.mark.parametrize("xy,expect", [((1.0, 0.0), "2X fixed in direction"), ((1.0, 1.0), "2X forward whirl"),
                                       ((1.0, -1.0), "2X backward whirl")])
def test_a_2x_gap_is_named_with_its_whirl(xy, expect):
    """A 2X residual along one line (x only) has equal forward and backward whirl: "fixed in direction"; x = cos,
    y = +-sin is a pure forward or backward circle."""
    t = np.arange(8000) / FS_HZ
    e = np.zeros((t.size, 4))
    e[:, 2] = 2e-6 * np.cos(2 * SPEED_RAD_S * t)
    e[:, 3] = 2e-6 * np.sign(xy[1]) * np.sin(2 * SPEED_RAD_S * t) if xy[1] else 0.0
    sig = gap_signature(_budget(e))
    assert sig.startswith(expect), sig
    assert sig.endswith("xp2") or sig.endswith("yp2"), sig


def test_a_fixed_frequency_peak_is_named_with_its_frequency():
    """A 137 Hz line (not an order of 300 Hz) is reported as a fixed-frequency peak at 137 Hz."""
    t = np.arange(8000) / FS_HZ
    e = np.zeros((t.size, 4))
    e[:, 0] = 2e-6 * np.sin(2 * np.pi * 137.0 * t)
    sig = gap_signature(_budget(e))
    assert sig.startswith("fixed-frequency peak(s) at 137") and sig.endswith("on xp1"), sig


def test_a_gap_after_the_impact_says_so():
    """A decaying ring-down after each impact is strongest in the 50 ms after the impacts."""
    t = np.arange(8000) / FS_HZ
    e = np.zeros((t.size, 4))
    for k in (1000, 5000):
        tau = np.clip(t - t[k], 0, None)
        e[:, 1] += np.where(t >= t[k], 3e-6 * np.exp(-tau / 0.01) * np.sin(2 * np.pi * 1700 * tau), 0.0)
    assert "strongest in the 50 ms after the impacts" in gap_signature(_budget(e, (1000, 5000)))


def test_orders_above_the_flat_band_of_a_decimated_rate_are_not_tracked_and_do_not_hide_a_line():
    """At 5 kHz (a record decimated by 4) and 400 Hz, 6X-8X (2.4-3.2 kHz) are above 0.45 of the rate: they are
    not fitted (zero power), so a fixed-frequency line at 1.8 kHz, where 8X's columns alias (5 - 3.2 kHz), is still
    reported as a peak; 1X-5X are tracked."""
    fs, speed = 5000.0, 2 * np.pi * 400.0
    t = np.arange(4000) / fs
    e = np.zeros((t.size, 4))
    e[:, 0] = 2e-6 * np.sin(2 * np.pi * 1800.0 * t + 0.3) + 1e-6 * np.cos(speed * t)
    noise = np.random.default_rng(1).normal(scale=1e-7, size=e.shape)
    b = budget(t, e + noise, speed * t, np.full(t.size, speed), np.zeros((t.size, 2)), np.full(4, 1e-7))
    bands = {r["band"]: r for r in b["bands"]}
    assert all(bands[f"{h}X"]["rms_m"] == 0.0 for h in (6, 7, 8))
    assert bands["1X"]["per_channel_rms_m"][0] == pytest.approx(1e-6 / np.sqrt(2), rel=0.02)
    assert [round(p["frequency_hz"]) for p in b["nonsync_peaks"]][:1] == [1800]
