# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Timing skew: a delay of one probe channel against the others."""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from rotor_estimator.diagnosis.effects.base import CHANNELS, UNIT_SKEW_S, Effect


def delayed(y_m: np.ndarray, v_m_s: np.ndarray, delay_s: float, period_s: float) -> np.ndarray:
    """``y(t - delay)`` of a sampled signal by cubic Hermite interpolation on samples and derivatives (N,)."""
    n = y_m.size
    shift = delay_s / period_s
    k0 = np.arange(n) - int(np.ceil(shift))
    u = (np.arange(n) - shift) - k0
    k0 = np.clip(k0, 0, n - 2)
    p0, p1, m0, m1 = y_m[k0], y_m[k0 + 1], v_m_s[k0] * period_s, v_m_s[k0 + 1] * period_s
    u2, u3 = u * u, u * u * u
    return ((2 * u3 - 3 * u2 + 1) * p0 + (u3 - 2 * u2 + u) * m0 + (-2 * u3 + 3 * u2) * p1 + (u3 - u2) * m1)


@dataclass(frozen=True)
class TimingSkew(Effect):
    """Sampling skew between channels: ``y_c(t - tau_c)``, tau relative to xp1 (exact delay, not a derivative).

    The delays are nonlinear parameters: the skewed channel is the nominal output delayed
    by cubic Hermite interpolation on the nominal probe displacement and velocity, so a
    delay of a sizeable fraction of a revolution is modelled as well as a small one.
    The search starts from the derivative (first-order) estimate ``tau = -<e, v>/<v, v>``.
    """

    name: ClassVar[str] = "timing_skew"
    responses: ClassVar[dict[str, str]] = {
        "daq_test_signal": "the channels show a time offset on the common signal",
        "speed_change": "the phase error grows in proportion to speed",
    }
    description: ClassVar[str] = "timing skew between probe channels (relative to xp1)"
    nl_names: ClassVar[tuple[str, ...]] = ("skew_yp1_us", "skew_xp2_us", "skew_yp2_us")

    def lin_names(self, ctx):
        return ()

    def nl_grid(self, ctx):
        v = ctx.v_nom_m_s[ctx.mask]
        e = ctx.residual_m[ctx.mask]
        tau = np.array([-(e[:, c] @ v[:, c]) / max(float(v[:, c] @ v[:, c]), 1e-300) for c in (1, 2, 3)])
        bound = self.nl_bounds(ctx)[1][0]
        return [np.clip(tau / UNIT_SKEW_S, -0.9 * bound, 0.9 * bound), np.zeros(3)]

    def nl_bounds(self, ctx):
        b = 0.25 * 2 * np.pi / max(ctx.mean_speed_rad_s, 1.0) / UNIT_SKEW_S  # a quarter revolution
        return np.full(3, -b), np.full(3, b)

    def basis(self, ctx, nl):
        y, v = ctx.y_nom_m, ctx.v_nom_m_s
        off = np.zeros_like(y)
        for i, c in enumerate((1, 2, 3)):
            if nl[i] != 0.0:
                off[:, c] = delayed(y[:, c], v[:, c], nl[i] * UNIT_SKEW_S, ctx.period_s) - y[:, c]
        return off, np.zeros((y.shape[0], 4, 0))

    def physical(self, nl, lin):
        return {f"skew_{ch}_s": float(v * UNIT_SKEW_S) for ch, v in zip(CHANNELS[1:], nl)}

    transforms_signal: ClassVar[bool] = True

    def transform(self, ctx, nl, signal_m):
        """Another contribution delayed like the probe it appears on (derivative by central differences)."""
        out = np.array(signal_m, dtype=float, copy=True)
        if out.size == 0:
            return out
        flat = out.reshape(out.shape[0], 4, -1)
        for i, c in enumerate((1, 2, 3)):
            if nl[i] == 0.0:
                continue
            for k in range(flat.shape[2]):
                sig = flat[:, c, k].copy()
                flat[:, c, k] = delayed(sig, np.gradient(sig, ctx.period_s), nl[i] * UNIT_SKEW_S, ctx.period_s)
        return flat.reshape(out.shape)
