# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Timing skew: a delay of one probe channel against the others."""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from rotor_estimator.core.jit import njit
from rotor_estimator.diagnosis.effects.base import CHANNELS, UNIT_SKEW_S, Effect


@njit(cache=True)
def _hermite_delayed(y, m, shift, out):
    """``out[i] = y(i - shift)`` (samples) by cubic Hermite interpolation on the samples ``y`` (N, K) and their
    slopes per sample ``m`` (N, K); a time before the first sample or after the last takes that sample's value
    (the record does not say what came before or after it)."""
    n = y.shape[0]
    whole = int(np.ceil(shift))
    for i in range(n):
        k0 = i - whole
        u = (i - shift) - k0
        if k0 < 0:
            k0 = 0
            u = 0.0
        elif k0 > n - 2:
            k0 = n - 2
            u = 1.0
        u2 = u * u
        u3 = u2 * u
        h00 = 2 * u3 - 3 * u2 + 1
        h10 = u3 - 2 * u2 + u
        h01 = -2 * u3 + 3 * u2
        h11 = u3 - u2
        for j in range(y.shape[1]):
            out[i, j] = h00 * y[k0, j] + h10 * m[k0, j] + h01 * y[k0 + 1, j] + h11 * m[k0 + 1, j]


@njit(cache=True)
def _slopes_per_sample(y, out):
    """``np.gradient(y, axis=0)`` of (N, K) samples (central differences, one-sided at the ends), per sample."""
    n = y.shape[0]
    for j in range(y.shape[1]):
        out[0, j] = y[1, j] - y[0, j]
        out[n - 1, j] = y[n - 1, j] - y[n - 2, j]
        for i in range(1, n - 1):
            out[i, j] = 0.5 * (y[i + 1, j] - y[i - 1, j])


def delayed(y_m: np.ndarray, v_m_s: np.ndarray | None, delay_s: float, period_s: float) -> np.ndarray:
    """``y(t - delay)`` of a sampled signal by cubic Hermite interpolation on samples and derivatives.

    ``y_m`` and ``v_m_s`` are (N,) or (N, K): K signals delayed alike, along the first axis. ``v_m_s=None``:
    the derivative by central differences of the samples (``np.gradient``)."""
    y = np.asarray(y_m, dtype=float)
    y2 = y.reshape(y.shape[0], -1)
    if v_m_s is None:
        m2 = np.empty_like(y2)
        _slopes_per_sample(y2, m2)
    else:
        m2 = np.asarray(v_m_s, dtype=float).reshape(y2.shape) * period_s
    out = np.empty(y2.shape)
    _hermite_delayed(y2, m2, float(delay_s / period_s), out)
    return out.reshape(y.shape)


#: Whole-sample delays tried per channel for the search's scan start (a DAQ that drops or buffers samples).
SCAN_SAMPLES = 6


#: The channel groups of the one-delay forms (:class:`GroupTimingSkew`): each probe alone (a channel whose
#: converter or cable lags), then each probe plane (both channels of one acquisition card or one sensor head).
#: A fault usually delays one channel or one card, and the all-channel form pays for three delays the data
#: do not need: a probe plane 5 samples late in a steady record without an impact, fitted with four delays,
#: lost the race to a three-parameter shaft bending (independent seed 7430, case 36).
DELAY_GROUPS: tuple[tuple[int, ...], ...] = ((0,), (1,), (2,), (3,), (0, 1), (2, 3))


@dataclass(frozen=True)
class TimingSkew(Effect):
    """Sampling skew of each channel against the model's clock: ``y_c(t - tau_c)`` (exact delay, not a derivative).

    All four channels carry a delay, xp1 included, so a late probe plane (both its channels behind
    the keyphasor and the hammer's force channel) is one effect, not a phase error forced onto an
    unbalance or a probe map. The delays are nonlinear parameters: the skewed channel is the
    nominal output delayed by cubic Hermite interpolation on the nominal probe displacement and
    velocity, so a delay of several samples, up to a quarter revolution, is modelled as well as a
    small one. The search starts from the derivative (first-order) estimate
    ``tau = -<e, v>/<v, v>`` and from a per-channel scan over whole-sample delays
    (+-:data:`SCAN_SAMPLES`). Its other forms (:meth:`variants`) delay one channel or one probe plane by one
    delay (:class:`GroupTimingSkew`).
    """

    name: ClassVar[str] = "timing_skew"
    kind: ClassVar[str] = "signal_transform"
    responses: ClassVar[dict[str, str]] = {
        "daq_test_signal": "the channels show a time offset on the common signal",
        "speed_change": "the phase error grows in proportion to speed",
    }
    description: ClassVar[str] = "timing skew of each probe channel (whole or fractional samples)"
    nl_names: ClassVar[tuple[str, ...]] = tuple(f"skew_{c}_us" for c in CHANNELS)

    def variants(self):
        return (self, *(GroupTimingSkew(g) for g in DELAY_GROUPS))

    @property
    def form(self) -> str:
        return "a delay per channel"

    def groups(self) -> tuple[tuple[int, ...], ...]:
        """The channels (indices into :data:`CHANNELS`) that share each delay, one group per parameter."""
        return ((0,), (1,), (2,), (3,))

    def channel_delays_us(self, nl) -> np.ndarray:
        """The delay of each of the four channels (us) for the parameters ``nl`` (0 on a channel none names)."""
        out = np.zeros(4)
        for g, tau in zip(self.groups(), np.asarray(nl, float)):
            out[list(g)] = tau
        return out

    def lin_names(self, ctx):
        return ()

    def nl_grid(self, ctx):
        v = ctx.v_nom_m_s[ctx.mask]
        e = ctx.residual_m[ctx.mask]
        bound = 0.9 * self.nl_bounds(ctx)[1][0]
        tau = np.array([-sum(float(e[:, c] @ v[:, c]) for c in g) / max(sum(float(v[:, c] @ v[:, c]) for c in g),
                                                                         1e-300) for g in self.groups()])
        return [np.clip(tau / UNIT_SKEW_S, -bound, bound), np.clip(self._scan(ctx), -bound, bound),
                np.zeros(len(self.groups()))]

    def _scan(self, ctx) -> np.ndarray:
        """Per group, the whole-sample delay (us) that best matches its measured channels to the delayed nominal."""
        y, v, measured = ctx.y_nom_m, ctx.v_nom_m_s, ctx.y_m
        costs = np.zeros((4, 2 * SCAN_SAMPLES + 1))
        for c in sorted({c for g in self.groups() for c in g}):
            for j, k in enumerate(range(-SCAN_SAMPLES, SCAN_SAMPLES + 1)):
                d = measured[:, c] - delayed(y[:, c], v[:, c], k * ctx.period_s, ctx.period_s)
                d = d[ctx.mask] - np.mean(d[ctx.mask])  # the DC offsets are free
                costs[c, j] = float(d @ d)
        best = [int(np.argmin(costs[list(g)].sum(axis=0))) - SCAN_SAMPLES for g in self.groups()]
        return np.asarray(best, float) * ctx.period_s / UNIT_SKEW_S

    def nl_bounds(self, ctx):
        b = 0.25 * 2 * np.pi / max(ctx.mean_speed_rad_s, 1.0) / UNIT_SKEW_S  # a quarter revolution
        n = len(self.groups())
        return np.full(n, -b), np.full(n, b)

    def basis(self, ctx, nl):
        y, v = ctx.y_nom_m, ctx.v_nom_m_s
        off = np.zeros_like(y)
        for c, tau in enumerate(self.channel_delays_us(nl)):
            if tau != 0.0:
                off[:, c] = delayed(y[:, c], v[:, c], tau * UNIT_SKEW_S, ctx.period_s) - y[:, c]
        return off, np.zeros((y.shape[0], 4, 0))

    def physical(self, nl, lin):
        delays = self.channel_delays_us(nl)
        named = sorted({c for g in self.groups() for c in g})
        return {f"skew_{CHANNELS[c]}_s": float(delays[c] * UNIT_SKEW_S) for c in named}

    transforms_signal: ClassVar[bool] = True

    def transform(self, ctx, nl, signal_m):
        """Another contribution delayed like the probe it appears on (derivative by central differences)."""
        out = np.array(signal_m, dtype=float, copy=True)
        if out.size == 0:
            return out
        flat = out.reshape(out.shape[0], 4, -1)
        for c, tau in enumerate(self.channel_delays_us(nl)):
            if tau == 0.0:
                continue
            # every column of the channel at once (the derivative by central differences)
            flat[:, c, :] = delayed(flat[:, c, :], None, tau * UNIT_SKEW_S, ctx.period_s)
        return flat.reshape(out.shape)


@dataclass(frozen=True)
class GroupTimingSkew(TimingSkew):
    """One delay shared by a group of channels (:data:`DELAY_GROUPS`: one probe, or both probes of a plane); the
    other channels are on the model's clock."""

    channels: tuple[int, ...] = (0,)
    nl_names: ClassVar[tuple[str, ...]] = ("skew_us",)

    def variants(self):
        return (self,)

    @property
    def form(self) -> str:
        names = " and ".join(CHANNELS[c] for c in self.channels)
        return f"one delay of {names}" + (" (a probe plane)" if len(self.channels) == 2 else "")

    def groups(self) -> tuple[tuple[int, ...], ...]:
        return (tuple(self.channels),)
