# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Probe runout: electrical/mechanical runout of the probe track, harmonics of the shaft angle."""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from rotor_estimator.diagnosis.effects.base import CHANNELS, UNIT_RUNOUT_M, Effect


@dataclass(frozen=True)
class ProbeRunout(Effect):
    """Mechanical/electrical runout: a pattern fixed in shaft angle, Fourier series per probe."""

    name: ClassVar[str] = "probe_runout"
    kind: ClassVar[str] = "measurement"
    responses: ClassVar[dict[str, str]] = {
        "slow_roll": "persists at full amplitude (surface/electrical runout)",
        "speed_change": "same amplitude and angle at every speed",
    }
    description: ClassVar[str] = "probe runout fixed in shaft angle (harmonics 1..H per channel)"
    harmonics: int = 4

    def lin_names(self, ctx):
        return tuple(f"{ch}_{h}x_{cs}_um" for ch in CHANNELS for h in range(1, self.harmonics + 1)
                     for cs in ("cos", "sin"))

    def basis(self, ctx, nl):
        # a function of the shaft angle alone, which every context of a record shares: built once per track
        # (read-only, so that no caller can change the shared copy); the joint refits ask for it ~10^3 times
        key = ("probe_runout_columns", self.harmonics)
        cached = ctx.shaft.__dict__.get(key)
        if cached is not None and cached[0] is ctx.shaft.angle_rad:
            return None, cached[1]
        n = ctx.t_s.size
        cols = np.zeros((n, 4, 8 * self.harmonics))
        i = 0
        for c in range(4):
            for h in range(1, self.harmonics + 1):
                cols[:, c, i] = np.cos(h * ctx.shaft.angle_rad) * UNIT_RUNOUT_M
                cols[:, c, i + 1] = np.sin(h * ctx.shaft.angle_rad) * UNIT_RUNOUT_M
                i += 2
        cols.flags.writeable = False
        ctx.shaft.__dict__[key] = (ctx.shaft.angle_rad, cols)
        return None, cols

    def physical(self, nl, lin):
        amp = np.abs(lin[0::2] + 1j * lin[1::2]).reshape(4, self.harmonics) * UNIT_RUNOUT_M
        out = {f"{ch}_runout_peak_m": float(np.sqrt((a ** 2).sum() * 2)) for ch, a in zip(CHANNELS, amp)}
        for h in range(self.harmonics):
            out[f"mean_{h + 1}x_amplitude_m"] = float(amp[:, h].mean())
        return out
